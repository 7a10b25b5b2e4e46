#!/usr/bin/python3
"""Checks tools/bench/make_qdq_onnx.py on a SceneEDNet fixture.

usage: check_qdq_onnx.py MODEL.onnx HEIGHT WIDTH WORKDIR [--ort]

Without --ort: makes the QDQ model and checks its structure: every Conv reads DequantizeLinear
outputs only (uint8 activation, int8 weights per output channel on axis 0, int32 bias) and its
output goes to one QuantizeLinear only; every LeakyRelu reads a DequantizeLinear and feeds one
QuantizeLinear; the graph output stays float32.
With --ort: runs it through ONNX Runtime (tools/bench/ort_bench.mjs, profiler on, the float
model as reference) and checks that every convolution ran as QLinearConv and none as a float
Conv, and that the output stays close to float32. Exit 77 (ctest: skipped) when node or
onnxruntime-node (tools/bench/node_modules) is missing.
"""
import json
import os
import shutil
import subprocess
import sys

import onnx
from onnx import TensorProto, numpy_helper

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..")
BENCH = os.path.join(ROOT, "tools", "bench")
CONVS = 11
LEAKY_RELUS = 10


def fail(msg):
    sys.exit(f"check_qdq_onnx.py: FAIL: {msg}")


def check_structure(path):
    m = onnx.load(path)
    g = m.graph
    producer = {o: n for n in g.node for o in n.output}
    consumers = {}
    for n in g.node:
        for i in n.input:
            consumers.setdefault(i, []).append(n)
    inits = {i.name: i for i in g.initializer}
    opset = next(o.version for o in m.opset_import if o.domain in ("", "ai.onnx"))
    if opset < 13:
        fail(f"opset {opset} < 13")
    convs = [n for n in g.node if n.op_type == "Conv"]
    if len(convs) != CONVS:
        fail(f"{len(convs)} Conv nodes, expected {CONVS}")
    for n in convs:
        dqs = [producer.get(i) for i in n.input]
        if len(dqs) != 3 or any(d is None or d.op_type != "DequantizeLinear" for d in dqs):
            fail(f"Conv {n.name}: an input does not come from DequantizeLinear")
        x, w, b = dqs
        zp = inits.get(x.input[2])
        if zp is None or zp.data_type != TensorProto.UINT8:
            fail(f"Conv {n.name}: activation zero point not a uint8 initializer")
        wq, wz = inits.get(w.input[0]), inits.get(w.input[2])
        if wq is None or wq.data_type != TensorProto.INT8 or wz.data_type != TensorProto.INT8:
            fail(f"Conv {n.name}: weights not int8 initializers")
        axis = next((a.i for a in w.attribute if a.name == "axis"), 1)
        scales = numpy_helper.to_array(inits[w.input[1]])
        if axis != 0 or scales.shape != (wq.dims[0],):
            fail(f"Conv {n.name}: weight scales not per output channel (axis {axis}, "
                 f"shape {scales.shape})")
        bq = inits.get(b.input[0])
        if bq is None or bq.data_type != TensorProto.INT32:
            fail(f"Conv {n.name}: bias not int32")
        after = consumers.get(n.output[0], [])
        if len(after) != 1 or after[0].op_type != "QuantizeLinear":
            fail(f"Conv {n.name}: output not consumed by exactly one QuantizeLinear")
    leaky = [n for n in g.node if n.op_type == "LeakyRelu"]
    if len(leaky) != LEAKY_RELUS:
        fail(f"{len(leaky)} LeakyRelu nodes, expected {LEAKY_RELUS}")
    for n in leaky:
        before = producer.get(n.input[0])
        after = consumers.get(n.output[0], [])
        if before is None or before.op_type != "DequantizeLinear" or len(after) != 1 or \
                after[0].op_type != "QuantizeLinear":
            fail(f"LeakyRelu {n.name}: not DequantizeLinear -> LeakyRelu -> QuantizeLinear")
    out = g.output[0]
    if out.type.tensor_type.elem_type != TensorProto.FLOAT or \
            producer[out.name].op_type != "DequantizeLinear":
        fail("graph output is not a float32 DequantizeLinear output")
    print(f"structure ok: {CONVS} DQ -> Conv -> Q groups (u8 activations, s8 weights per "
          f"channel, s32 bias), {LEAKY_RELUS} DQ -> LeakyRelu -> Q, opset {opset}")


def check_ort(qdq, model, height, width, work):
    node = shutil.which("node")
    if node is None or not os.path.isdir(os.path.join(BENCH, "node_modules", "onnxruntime-node")):
        print("skipped: node or tools/bench/node_modules/onnxruntime-node missing "
              "(cd tools/bench && ONNXRUNTIME_NODE_INSTALL=skip npm install)")
        sys.exit(77)
    res = subprocess.run([node, os.path.join(BENCH, "ort_bench.mjs"),
                          f"--profile={os.path.join(work, 'qdq_profile')}", f"--reference={model}",
                          qdq, str(height), str(width), "1", "1", "0"],
                         check=False, capture_output=True, text=True)
    if res.returncode != 0:
        fail(f"ort_bench.mjs exited {res.returncode}: {res.stderr.strip()[-2000:]}")
    j = json.loads(res.stdout.strip().splitlines()[-1])
    ops = j["ops"]
    print("ORT ran: " + ", ".join(f"{k} x{v['nodes']}" for k, v in sorted(ops.items())))
    if ops.get("QLinearConv", {}).get("nodes") != CONVS:
        fail(f"expected {CONVS} QLinearConv nodes in the profile")
    float_convs = [k for k in ops if k in ("Conv", "FusedConv", "NhwcFusedConv")]
    if float_convs:
        fail(f"float convolutions ran: {float_convs}")
    rms = j["vs_reference"]["rms_rel"]
    print(f"output rms error relative to float32: {rms:.3g}")
    if not rms < 0.2:
        fail(f"int8 output too far from float32 (rms relative {rms:.3g} >= 0.2)")


def main():
    args = [a for a in sys.argv[1:] if a != "--ort"]
    if len(args) != 4:
        sys.exit(__doc__)
    model, height, width, work = args[0], int(args[1]), int(args[2]), args[3]
    os.makedirs(work, exist_ok=True)
    qdq = os.path.join(work, "qdq.onnx")
    res = subprocess.run([sys.executable, os.path.join(BENCH, "make_qdq_onnx.py"), model,
                          "-o", qdq], check=False, capture_output=True, text=True)
    if res.returncode != 0:
        fail(f"make_qdq_onnx.py exited {res.returncode}: {res.stderr.strip()[-2000:]}")
    print(res.stdout.strip())
    if "--ort" in sys.argv[1:]:
        check_ort(qdq, model, height, width, work)
    else:
        check_structure(qdq)
    print("PASS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
