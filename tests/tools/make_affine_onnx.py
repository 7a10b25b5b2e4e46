#!/usr/bin/python3
"""A graph whose batch normalisation has no convolution before it to fold into (it follows a
Concat), as ONNX: sfrt export makes it a ChannelAffine layer, which the export summary counts.

usage: make_affine_onnx.py OUT.onnx
"""
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

rng = np.random.RandomState(2)
initializers = [
    numpy_helper.from_array((rng.randn(4, 12, 3, 3) * 0.05).astype(np.float32), "wa"),
    numpy_helper.from_array((rng.randn(4, 12, 3, 3) * 0.05).astype(np.float32), "wb"),
    numpy_helper.from_array((rng.randn(3, 8, 3, 3) * 0.05).astype(np.float32), "wc"),
    numpy_helper.from_array(rng.uniform(0.5, 1.5, 8).astype(np.float32), "gamma"),
    numpy_helper.from_array(rng.randn(8).astype(np.float32), "beta"),
    numpy_helper.from_array(rng.randn(8).astype(np.float32), "mean"),
    numpy_helper.from_array(rng.uniform(0.5, 2.0, 8).astype(np.float32), "var"),
]
nodes = [
    helper.make_node("Conv", ["x", "wa"], ["a"], pads=[1, 1, 1, 1]),
    helper.make_node("Conv", ["x", "wb"], ["b"], pads=[1, 1, 1, 1]),
    helper.make_node("Concat", ["a", "b"], ["ab"], axis=1),
    helper.make_node("BatchNormalization", ["ab", "gamma", "beta", "mean", "var"], ["n"]),
    helper.make_node("Conv", ["n", "wc"], ["y"], pads=[1, 1, 1, 1]),
]
graph = helper.make_graph(
    nodes, "affine_after_concat",
    [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 12, 48, 64])],
    [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 3, 48, 64])],
    initializers)
onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)]), sys.argv[1])
