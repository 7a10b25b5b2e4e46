#!/usr/bin/python3
"""Write the regression inputs that declare far more data than they hold (issue 38, item 8).

Each file is a few hundred bytes (the Keras one a few kilobytes) whose declared shapes or counts
would make an importer that sizes its buffers from them allocate gigabytes before it compares them
with the bytes the file holds. fuzz_onnx_import found the first (libFuzzer out-of-memory in
Importer::GetFloats, 39 s into `tools/fuzz.sh 150 onnx_import`); the others reach the same mistake
by the other paths that decode a declared shape. tests/fuzz/importer_allocation_test.cc checks that
every importer refuses each of them, naming the tensor, while allocating at most a small constant
plus a multiple of the file's size; fuzz.<target>.regression replays them.

Written into tests/fuzz/regression/<target>/ (the committed files are this script's output):
  onnx_import   oom-conv-weight-declares-2-gb-holds-4-bytes.onnx     (raw_data, the fuzzer's)
                oom-conv-weight-declares-2-gb-holds-1-float.onnx     (float_data)
                oom-slice-starts-declare-2-gb-hold-8-bytes.onnx      (an INT64 initializer)
                oom-constant-declares-4-gb-holds-16-bytes.onnx       (a Constant node)
                oom-concat-of-300-copies-of-an-8-mb-constant.onnx    (evaluated constants)
                alloc-constant-of-shape-64-mb-from-a-tiny-file.onnx  (an evaluated constant)
  keras_import  oom-kernel-declares-2-gb-never-stored.h5             (an unwritten dataset)
  npy           oom-shape-declares-4-gb-without-data.npy
Run with Debian's /usr/bin/python3 (python3-onnx, python3-h5py, python3-numpy).
Usage: make_allocation_cases.py [--out-dir DIR]   (default: tests/fuzz/regression)
"""

import argparse
import json
import os
import struct

import h5py
import numpy as np
from onnx import TensorProto, helper

HERE = os.path.dirname(os.path.abspath(__file__))


def write(path, data):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "wb") as f:
        f.write(data)


def onnx_model(nodes, initializers, height=40, width=40):
    """A graph reading x (1, 1, H, W) and computing y, serialised as the exporters write it."""
    x = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 1, height, width])
    y = helper.make_tensor_value_info("y", TensorProto.FLOAT, None)
    graph = helper.make_graph(nodes, "g", [x], [y], initializer=initializers)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    model.ClearField("producer_name")
    return model.SerializeToString()


def raw_tensor(name, data_type, dims, raw):
    t = TensorProto()
    t.name = name
    t.data_type = data_type
    t.dims.extend(dims)
    t.raw_data = raw
    return t


def nearest_resize(scales):
    return helper.make_node("Resize", ["t", "", scales], ["y"], name="up0",
                            coordinate_transformation_mode="asymmetric", mode="nearest",
                            nearest_mode="floor")


def onnx_cases(out):
    conv = helper.make_node("Conv", ["x", "w"], ["t"], name="conv0")
    one = raw_tensor("w", TensorProto.FLOAT, [1, 1, 1, 1], struct.pack("<f", 0.1))
    scales = raw_tensor("scales", TensorProto.FLOAT, [4], struct.pack("<4f", 1, 1, 2, 1))

    # The fuzzer's input: regression/onnx_import/loader-limit-resize-factor-65.onnx with the
    # weight's dims [1, 1, 1, 1] mutated into [1, 536870890]. 4 bytes held, 2147483560 needed.
    w = raw_tensor("w", TensorProto.FLOAT, [1, 536870890], struct.pack("<f", 0.1))
    scales65 = raw_tensor("scales", TensorProto.FLOAT, [4], struct.pack("<4f", 1, 1, 65, 1))
    write(os.path.join(out, "oom-conv-weight-declares-2-gb-holds-4-bytes.onnx"),
          onnx_model([conv, nearest_resize("scales")], [w, scales65]))

    # The same weight held as float_data (one value) instead of raw bytes.
    w = TensorProto()
    w.name = "w"
    w.data_type = TensorProto.FLOAT
    w.dims.extend([1, 536870890])
    w.float_data.append(0.1)
    write(os.path.join(out, "oom-conv-weight-declares-2-gb-holds-1-float.onnx"),
          onnx_model([conv, nearest_resize("scales")], [w, scales]))

    # An integer initializer (decoded as a constant, 8 bytes per value): 268435455 starts.
    starts = raw_tensor("starts", TensorProto.INT64, [268435455], struct.pack("<q", 0))
    ends = raw_tensor("ends", TensorProto.INT64, [1], struct.pack("<q", 8))
    axes = raw_tensor("axes", TensorProto.INT64, [1], struct.pack("<q", 2))
    slice_node = helper.make_node("Slice", ["t", "starts", "ends", "axes"], ["y"], name="crop0")
    write(os.path.join(out, "oom-slice-starts-declare-2-gb-hold-8-bytes.onnx"),
          onnx_model([conv, slice_node], [one, starts, ends, axes]))

    # A Constant node's value: 536870890 floats (decoded as doubles: 4 GB) in 16 bytes.
    value = raw_tensor("", TensorProto.FLOAT, [536870890], struct.pack("<4f", 1, 1, 2, 1))
    constant = helper.make_node("Constant", [], ["scales"], name="scales0", value=value)
    write(os.path.join(out, "oom-constant-declares-4-gb-holds-16-bytes.onnx"),
          onnx_model([constant, conv, nearest_resize("scales")], [one]))

    # Evaluated constants: one of 2^20 zeros (8 MB), then 300 copies of it as the inputs of one
    # Concat (2.4 GB before the Concat's own size is known). The file holds neither.
    shape = raw_tensor("", TensorProto.INT64, [1], struct.pack("<q", 1 << 20))
    nodes = [helper.make_node("Constant", [], ["n"], name="n0", value=shape),
             helper.make_node("ConstantOfShape", ["n"], ["z"], name="zeros0"),
             helper.make_node("Concat", ["z"] * 300, ["scales"], name="cat0", axis=0),
             conv, nearest_resize("scales")]
    write(os.path.join(out, "oom-concat-of-300-copies-of-an-8-mb-constant.onnx"),
          onnx_model(nodes, [one]))

    # One evaluated constant of 2^23 zeros: 64 MB (as doubles) from a file of 300 bytes, under the
    # importer's old per-constant limit (2^24 values) but past what a small file may cost.
    shape = raw_tensor("", TensorProto.INT64, [1], struct.pack("<q", 1 << 23))
    nodes = [helper.make_node("Constant", [], ["n"], name="n0", value=shape),
             helper.make_node("ConstantOfShape", ["n"], ["scales"], name="zeros0"),
             conv, nearest_resize("scales")]
    write(os.path.join(out, "alloc-constant-of-shape-64-mb-from-a-tiny-file.onnx"),
          onnx_model(nodes, [one]))


def keras_cases(out):
    """A Keras 2 model (the layout of tests/fixtures/gen_keras_h5.py) whose one Conv2D of
    8192 -> 8192 channels has a 3x3 kernel dataset created but never written: 2.4 GB declared,
    nothing stored (HDF5 reads unwritten values as the fill value)."""
    channels = 8192
    layers = [
        {"class_name": "InputLayer",
         "config": {"batch_input_shape": [None, 8, 8, channels], "dtype": "float32",
                    "sparse": False, "name": "input_1"}},
        {"class_name": "Conv2D",
         "config": {"name": "conv0", "trainable": True, "filters": channels,
                    "kernel_size": [3, 3], "strides": [1, 1], "padding": "same",
                    "data_format": "channels_last", "dilation_rate": [1, 1],
                    "activation": "linear", "use_bias": True}},
    ]
    entries = []
    prev = None
    for layer in layers:
        name = layer["config"]["name"]
        entries.append({"name": name, "class_name": layer["class_name"],
                        "config": layer["config"],
                        "inbound_nodes": [[[prev, 0, 0, {}]]] if prev else []})
        prev = name
    config = {"name": "model_1", "layers": entries, "input_layers": [["input_1", 0, 0]],
              "output_layers": [["conv0", 0, 0]]}
    path = os.path.join(out, "oom-kernel-declares-2-gb-never-stored.h5")
    os.makedirs(out, exist_ok=True)
    tmp = path + ".tmp"
    with h5py.File(tmp, "w") as f:
        f.attrs["keras_version"] = np.bytes_(b"2.2.4")
        f.attrs["backend"] = np.bytes_(b"tensorflow")
        text = json.dumps({"class_name": "Model", "config": config})
        f.attrs["model_config"] = np.bytes_(text.encode("utf8"))
        root = f.create_group("model_weights")
        root.attrs["layer_names"] = np.array([b"input_1", b"conv0"], dtype=bytes)
        root.attrs["backend"] = np.bytes_(b"tensorflow")
        root.attrs["keras_version"] = np.bytes_(b"2.2.4")
        root.create_group("input_1").attrs["weight_names"] = []
        g = root.create_group("conv0")
        g.attrs["weight_names"] = np.array([b"conv0/kernel:0", b"conv0/bias:0"], dtype=bytes)
        g.create_dataset("conv0/kernel:0", (3, 3, channels, channels), dtype="<f4")
        g.create_dataset("conv0/bias:0", data=np.zeros(channels, dtype="<f4"))
    os.replace(tmp, path)


def npy_cases(out):
    header = "{'descr': '<f4', 'fortran_order': False, 'shape': (1073741824,), }"
    header += " " * ((64 - (10 + len(header) + 1) % 64) % 64) + "\n"
    write(os.path.join(out, "oom-shape-declares-4-gb-without-data.npy"),
          b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode("ascii"))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out-dir", default=os.path.join(HERE, "regression"))
    args = parser.parse_args()
    onnx_cases(os.path.join(args.out_dir, "onnx_import"))
    keras_cases(os.path.join(args.out_dir, "keras_import"))
    npy_cases(os.path.join(args.out_dir, "npy"))


if __name__ == "__main__":
    main()
