#!/usr/bin/python3
"""Turns a float SceneEDNet ONNX file (tests/fixtures/gen_sceneednet.py) into a QDQ int8 one for
ONNX Runtime, the ORT int8 peer of compare_peers.sh.

usage: make_qdq_onnx.py MODEL.onnx -o OUT.onnx [--calibration CAL.npy | --calibration-size HxW
                        --calibration-frames N --seed S] [--method percentile:P|minmax]

Weights: int8, symmetric, one scale per output channel (DequantizeLinear axis 0 on OIHW); bias
int32 with scale input scale x weight scale (zero point 0). Activations: uint8, one scale and
zero point per tensor, on the model input, after every Conv and after every LeakyRelu:

  Q(input) -> [Pad] -> DQ -> Conv -> Q -> DQ -> LeakyRelu -> Q -> [Resize, Slice, Pad] -> DQ -> Conv
  ... -> DQ -> Conv(output) -> Q -> DQ -> scene_flow (float32)

so ONNX Runtime fuses each DQ -> Conv -> Q into QLinearConv (u8 x s8, int32 accumulation) and
each DQ -> LeakyRelu -> Q into QLinearLeakyRelu (com.microsoft); a Conv without a Q after it
stays a float Conv between DQ nodes. The nearest Resize, the crop Slices and the Pads run on
the uint8 tensors (exact: a Pad fills with the zero point, i.e. 0.0), and the Shape nodes that
compute the pad and crop amounts read the uint8 tensors, so no float copy is kept.

Activation ranges come from a float32 forward of the same network in PyTorch
(tools/train/sceneednet.py with the file's weights) over the calibration frames: percentile:P
keeps the central P percent of each tensor's values over all frames (as `sfrt export
--calibration-method`; default 99.99), minmax the extremes; LeakyRelu outputs take the
LeakyRelu of their Conv's range (it is monotonic); every range includes 0. --calibration: the
float32 .npy (N,H,W,12) or (H,W,12) that `sfrt export --precision int8 --calibration` reads
(values as the network is fed); without it, N seeded frames of integers 0..255 (uniform) at
--calibration-size. Deterministic. Opset: the source's, at least 13 (per-axis DequantizeLinear).
Needs Debian's /usr/bin/python3 with python3-onnx, python3-numpy and python3-torch.
"""

import argparse
import os
import re
import sys

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402
import torch_bench  # noqa: E402  (read_onnx; it imports torch and tools/train/sceneednet.py)
import onnx  # noqa: E402
from onnx import helper, numpy_helper, version_converter  # noqa: E402
import torch  # noqa: E402
from sceneednet import LEAKY_ALPHA, SceneEDNet  # noqa: E402

torch_bench.PROG = "make_qdq_onnx.py"
fail = torch_bench.fail
MIN_OPSET = 13
# Ops that may read a uint8 activation: they move or select values (or only read the shape),
# so they run on the quantised tensor unchanged.
UINT8_PASS_THROUGH = ("Pad", "Resize", "Slice")


def parse_method(text):
    if text == "minmax":
        return 100.0
    m = re.fullmatch(r"percentile:([0-9.]+)", text)
    if not m or not 50.0 <= float(m.group(1)) <= 100.0:
        raise argparse.ArgumentTypeError(f"expected percentile:P (50 <= P <= 100) or minmax, "
                                         f"got {text!r}")
    return float(m.group(1))


def value_range(values, central):
    """(low, high) of the central `central` percent of the values (100: min and max)."""
    flat = values.reshape(-1)
    if central >= 100.0:
        return float(flat.min()), float(flat.max())
    tail = (100.0 - central) / 2.0
    lo, hi = np.percentile(flat, [tail, 100.0 - tail])
    return float(lo), float(hi)


def uint8_params(lo, hi):
    """Per-tensor asymmetric uint8 scale and zero point for [lo, hi] widened to include 0."""
    lo, hi = min(lo, 0.0), max(hi, 0.0)
    scale = (hi - lo) / 255.0
    if not scale > 0.0:
        scale = 1.0
    zp = int(np.clip(np.rint(-lo / scale), 0, 255))
    return np.float32(scale), np.uint8(zp)


def calibration_frames(args):
    """Float32 NCHW (N, 12, H, W) calibration inputs."""
    if args.calibration:
        try:
            cal = np.load(args.calibration)
        except (OSError, ValueError) as exc:
            fail(f"cannot read --calibration {args.calibration!r}: {exc}")
        if cal.ndim == 3:
            cal = cal[None]
        if cal.ndim != 4 or cal.shape[3] != 12 or cal.shape[0] < 1:
            fail(f"--calibration {args.calibration}: shape {cal.shape}, expected (N,H,W,12) "
                 f"or (H,W,12)")
        cal = cal[:args.calibration_frames].astype(np.float32)
        if not np.all(np.isfinite(cal)):
            fail(f"--calibration {args.calibration}: values that are not finite")
    else:
        h, w = args.calibration_size
        rng = np.random.default_rng(args.seed)
        cal = rng.integers(0, 256, size=(args.calibration_frames, h, w, 12)).astype(np.float32)
    return np.ascontiguousarray(cal.transpose(0, 3, 1, 2))


def observe(model_path, frames, central):
    """Calibration ranges: {'input': (lo, hi), 'conv0': (lo, hi), ..., 'output': (lo, hi)} of
    the Conv outputs (before LeakyRelu) and of the network input."""
    state, width_div, padding = torch_bench.read_onnx(model_path)
    net = SceneEDNet(width_div, padding)
    net.load_state_dict(state, strict=True)
    net.eval()
    seen = {}
    convs = {f"conv{i}": c for i, c in enumerate(net.hidden_convs())}
    convs["output"] = net.output
    for name, conv in convs.items():
        conv.register_forward_hook(
            lambda _m, _i, y, name=name: seen.setdefault(name, []).append(y.numpy().copy()))
    with torch.inference_mode():
        for frame in frames:
            net(torch.from_numpy(frame[None]))
    ranges = {"input": value_range(frames, central)}
    for name in convs:
        ranges[name] = value_range(np.concatenate([a.reshape(-1) for a in seen[name]]), central)
    return ranges


def leaky(v):
    return v if v >= 0.0 else v * LEAKY_ALPHA


def quantize(model, ranges):
    """Rewrites the graph in place (see the module docstring)."""
    g = model.graph
    inits = {i.name: numpy_helper.to_array(i) for i in g.initializer}
    added = []  # new initializers
    nodes = []
    qparams = {}  # uint8 tensor -> (scale name, zero point name, scale value)
    rename = {}  # float tensor -> the tensor its later readers read instead
    conv_of = {}  # dequantised Conv output -> its layer (conv0 ... output)

    def const(name, array):
        added.append(numpy_helper.from_array(array, name))
        return name

    def new_params(base, lo, hi):
        scale, zp = uint8_params(lo, hi)
        return (const(base + "_scale", np.array(scale, np.float32)),
                const(base + "_zero_point", np.array(zp, np.uint8)), float(scale))

    def add_q(src, dst, params):
        nodes.append(helper.make_node("QuantizeLinear", [src, params[0], params[1]], [dst],
                                      name=dst + "_QuantizeLinear"))
        qparams[dst] = params

    def add_dq(src, dst, params):
        nodes.append(helper.make_node("DequantizeLinear", [src, params[0], params[1]], [dst],
                                      name=dst + "_DequantizeLinear"))

    graph_out = {o.name for o in g.output}
    graph_in = g.input[0].name
    add_q(graph_in, graph_in + "_q", new_params(graph_in, *ranges["input"]))
    rename[graph_in] = graph_in + "_q"
    convs_done = 0
    for node in g.node:
        for k, name in enumerate(node.input):
            if name in rename:
                node.input[k] = rename[name]
        data = node.input[0] if node.input else ""
        if node.op_type == "Conv":
            weight_name = node.input[1]
            layer = weight_name[:-len(".weight")] if weight_name.endswith(".weight") else None
            if layer not in ranges or len(node.input) < 3:
                fail(f"Conv {node.name!r}: weight {weight_name!r} with a bias expected to be "
                     f"one of conv0.weight ... output.weight")
            if data not in qparams:
                fail(f"Conv {node.name!r}: its input {data!r} is not quantised (the graph is "
                     f"not the Pad/Conv/LeakyRelu/Resize/Slice chain this script knows)")
            x_params = qparams[data]
            add_dq(data, data + "_dq", x_params)
            node.input[0] = data + "_dq"
            # Weights: int8 symmetric per output channel.
            w = inits[weight_name].astype(np.float64)
            w_scale = np.abs(w).reshape(w.shape[0], -1).max(axis=1) / 127.0
            w_scale[w_scale == 0.0] = 1.0
            w_scale = w_scale.astype(np.float32)
            w_q = np.clip(np.rint(w / w_scale.reshape(-1, 1, 1, 1)), -127, 127).astype(np.int8)
            const(layer + ".weight_q", w_q)
            const(layer + ".weight_scale", w_scale)
            const(layer + ".weight_zero_point", np.zeros(w.shape[0], np.int8))
            nodes.append(helper.make_node(
                "DequantizeLinear", [layer + ".weight_q", layer + ".weight_scale",
                                     layer + ".weight_zero_point"],
                [layer + ".weight_dq"], name=layer + ".weight_DequantizeLinear", axis=0))
            node.input[1] = layer + ".weight_dq"
            # Bias: int32 at scale input scale x weight scale.
            bias_name = node.input[2]
            b_scale = (np.float64(x_params[2]) * w_scale.astype(np.float64))
            b_q = np.clip(np.rint(inits[bias_name].astype(np.float64) / b_scale),
                          -2 ** 31, 2 ** 31 - 1).astype(np.int32)
            const(layer + ".bias_q", b_q)
            const(layer + ".bias_scale", b_scale.astype(np.float32))
            const(layer + ".bias_zero_point", np.zeros(b_q.shape[0], np.int32))
            nodes.append(helper.make_node(
                "DequantizeLinear", [layer + ".bias_q", layer + ".bias_scale",
                                     layer + ".bias_zero_point"],
                [layer + ".bias_dq"], name=layer + ".bias_DequantizeLinear", axis=0))
            node.input[2] = layer + ".bias_dq"
            # Output: Q -> DQ, so the Conv becomes QLinearConv.
            out = node.output[0]
            if out in graph_out:
                node.output[0] = out + "_conv"
                src, dst = out + "_conv", out
            else:
                src, dst = out, out + "_dq"
                rename[out] = dst
            params = new_params(layer + "_out", *ranges[layer])
            nodes.append(node)
            add_q(src, src + "_q", params)
            add_dq(src + "_q", dst, params)
            conv_of[dst] = layer
            convs_done += 1
            continue
        nodes.append(node)
        if node.op_type == "LeakyRelu":
            layer = conv_of.get(data)
            if layer is None:
                fail(f"LeakyRelu {node.name!r} does not follow a quantised Conv")
            alpha = next((a.f for a in node.attribute if a.name == "alpha"), 0.01)
            if abs(alpha - LEAKY_ALPHA) > 1e-6:
                fail(f"LeakyRelu {node.name!r}: alpha {alpha}, expected {LEAKY_ALPHA}")
            lo, hi = ranges[layer]
            out = node.output[0]
            add_q(out, out + "_q", new_params(layer + "_act", leaky(lo), leaky(hi)))
            rename[out] = out + "_q"
        elif node.op_type in UINT8_PASS_THROUGH and data in qparams:
            if node.op_type == "Pad":
                mode = next((a.s for a in node.attribute if a.name == "mode"), b"constant")
                if mode != b"constant":
                    fail(f"Pad {node.name!r}: mode {mode!r}, only constant is handled")
                while len(node.input) < 3:
                    node.input.append("")
                node.input[2] = qparams[data][1]  # pad with the zero point: 0.0
            if node.op_type == "Resize":
                mode = next((a.s for a in node.attribute if a.name == "mode"), b"nearest")
                if mode != b"nearest":
                    fail(f"Resize {node.name!r}: mode {mode!r}, only nearest is exact on uint8")
            qparams[node.output[0]] = qparams[data]
        elif node.op_type != "Shape" and any(i in qparams for i in node.input):
            fail(f"{node.op_type} {node.name!r} reads a quantised tensor; this script only "
                 f"handles {', '.join(UINT8_PASS_THROUGH)}, Shape, Conv and LeakyRelu there")
    if convs_done == 0:
        fail("no Conv in the graph")

    used = {i for n in nodes for i in n.input}
    kept = [i for i in g.initializer if i.name in used]
    del g.initializer[:]
    g.initializer.extend(kept + [i for i in added if i.name in used])
    del g.node[:]
    g.node.extend(nodes)
    del g.value_info[:]  # tensors that became uint8 would keep a float type there
    return convs_done


def parse_size(text):
    m = re.fullmatch(r"([0-9]+)x([0-9]+)", text)
    if not m or int(m.group(1)) < 1 or int(m.group(2)) < 1:
        raise argparse.ArgumentTypeError(f"expected HxW, got {text!r}")
    return int(m.group(1)), int(m.group(2))


def main(argv):
    p = argparse.ArgumentParser(prog="make_qdq_onnx.py",
                                description="Float SceneEDNet ONNX -> QDQ int8 ONNX for ONNX "
                                            "Runtime (see the script's docstring).")
    p.add_argument("model", help="float ONNX file from tests/fixtures/gen_sceneednet.py")
    p.add_argument("-o", "--output", required=True, help="QDQ ONNX file to write")
    p.add_argument("--calibration", help="float32 .npy (N,H,W,12) or (H,W,12) network inputs")
    p.add_argument("--calibration-size", type=parse_size, default=(96, 128),
                   help="size of the seeded frames without --calibration (default 96x128)")
    p.add_argument("--calibration-frames", type=int, default=2,
                   help="frames: at most this many of --calibration, or this many seeded (2)")
    p.add_argument("--seed", type=int, default=1, help="seed of the seeded frames (default 1)")
    p.add_argument("--method", type=parse_method, default=99.99, metavar="percentile:P|minmax",
                   help="activation range: central P percent of the values (default "
                        "percentile:99.99) or minmax")
    args = p.parse_args(argv)
    if args.calibration_frames < 1:
        p.error("--calibration-frames must be >= 1")
    if not os.path.isfile(args.model):
        p.error(f"no model file {args.model!r}")

    torch.set_num_threads(max(1, min(4, os.cpu_count() or 1)))
    ranges = observe(args.model, calibration_frames(args), args.method)
    model = onnx.load(args.model)
    opset = next((o.version for o in model.opset_import if o.domain in ("", "ai.onnx")), 0)
    if opset < MIN_OPSET:
        try:
            model = version_converter.convert_version(model, MIN_OPSET)
        except Exception as exc:  # the converter raises several types
            fail(f"{args.model}: opset {opset} and onnx cannot convert it to {MIN_OPSET}: {exc}")
    convs = quantize(model, ranges)
    try:
        onnx.checker.check_model(model, full_check=True)
    except Exception as exc:  # onnx raises checker and inference errors
        fail(f"the QDQ model does not pass onnx.checker: {exc}")
    tmp = args.output + ".tmp"
    onnx.save(model, tmp)
    os.replace(tmp, args.output)
    method = "minmax" if args.method >= 100.0 else f"percentile:{args.method:g}"
    print(f"make_qdq_onnx.py: {args.output}: {convs} convolutions int8 (weights per channel), "
          f"uint8 activations; ranges ({method}): "
          + ", ".join(f"{k} {lo:.3g}..{hi:.3g}" for k, (lo, hi) in ranges.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
