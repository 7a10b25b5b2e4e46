#!/usr/bin/python3
"""A network of 12 input channels (four stereo images) and 5 output channels, as ONNX: an output
that is not 3-D flow, for the tests of what sfrt does with one (issue #38, item 13).

usage: make_five_channel_onnx.py OUT.onnx
"""
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

weights = (np.random.RandomState(1).randn(5, 12, 3, 3) * 0.01).astype(np.float32)
conv = helper.make_node("Conv", ["x", "w"], ["y"], pads=[1, 1, 1, 1])
graph = helper.make_graph(
    [conv], "five_channels",
    [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 12, 48, 64])],
    [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 5, 48, 64])],
    [numpy_helper.from_array(weights, "w")])
onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)]), sys.argv[1])
