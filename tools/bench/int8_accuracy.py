#!/usr/bin/python3
"""sfrt's int8 and bf16 error against its peers' on the same network, calibration and input
(issue 43, item 5): the bar is "no worse than the best peer", measured, not a fixed number.

usage: int8_accuracy.py MODEL.onnx [MODEL.onnx ...] --sfrt BIN [--calibration CAL.npy]
                        [--size HxW] [--inputs N] [--threads N] [--peers LIST] [--engine E]
                        [--json FILE] [--keep DIR]

MODEL.onnx: a float SceneEDNet export (tests/fixtures/gen_sceneednet.py, any width divisor);
several: the same measurement on each network (gen_sceneednet.py --seed S makes one network per
seed), and the verdicts pooled over the networks (below).
Every engine runs the same --inputs inputs (default 8): ort_bench.mjs's seeded values in [0, 255)
from seeds 1..N at --size (default the ONNX file's fixed size, else 96x128), NCHW (1, 12, H, W)
(torch_bench.lcg_input). The error of each engine on each input is
  max_rel = max |out - ref| / max |ref|   and   rms_rel = RMS(out - ref) / RMS(ref)
against the float32 network: PyTorch's SceneEDNet.forward on the ONNX file's weights (sfrt
int8, sfrt bf16, torch-int8, torch-bf16), or ONNX Runtime's float32 run of the same file for
ort-int8 (ort_bench.mjs --reference: ORT's own float32, which agrees with PyTorch's to ~1e-6).

Engines:
- sfrt int8: `sfrt export --precision int8 --calibration CAL` (int8 weights per output
  channel, uint8 activations), `sfrt infer --input-npy`; sfrt bf16: `--precision bf16`.
- torch-int8: PyTorch's post-training static quantisation in eager mode on --engine (default
  onednn where this PyTorch has it, else x86/fbgemm): int8 weights per output channel
  (get_default_qconfig(engine)), uint8 activations observed over the same calibration frames,
  quantised convolutions, LeakyReLU, pads, upsamplings and the crop on the quantised tensors.
- ort-int8: make_qdq_onnx.py's QDQ model (int8 weights per channel, uint8 activations from the
  same frames) in ONNX Runtime (npm onnxruntime-node; installed on first use as
  compare_peers.sh does), QLinearConv.
- torch-bf16: the network and input in bfloat16, channels_last, in PyTorch (oneDNN), as
  compare_peers.sh times it (torch_bench.py's network).
--peers: any of torch-int8, ort-int8, torch-bf16 (default all three).
--calibration: float32 .npy (N,H,W,12), as `sfrt export --calibration` reads it; default 2
seeded frames of integers 0..255 at 96x128 (compare_peers.sh's).
Prints a table (each engine's errors on the first input and their means over all) and the
verdicts: sfrt int8's max_rel against the best int8 peer's (the lowest mean), sfrt bf16's against
torch-bf16's. One input is one draw of where the roundings fall: two engines rounding at
different points differ by 10-20% on one input and swap places on the next, so the verdict is
paired over the inputs: sfrt is WORSE when its mean max_rel exceeds the peer's by more than twice
the standard error of the per-input differences (with one input: when it exceeds it at all).
The inputs share one network, and so one draw of where the weights' roundings fall: on the
full-width fixture (seed 0) sfrt bf16 is x1.07 torch-bf16 over 8 inputs, on the network of seed 1
x0.85. With several networks the verdict is paired over the networks instead: each network's
mean difference over its inputs, WORSE when their mean exceeds twice their standard error.
Exit 0 when both hold (or have no peer to hold against), 3 when one does not, 1 on an error.
--json: the same as a document (one entry per network in "models"), with every input's errors.
Needs Debian's /usr/bin/python3 with python3-torch, python3-onnx, python3-numpy; node for
ort-int8.
"""

import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402
import torch_bench  # noqa: E402  (read_onnx, lcg_input; imports torch and sceneednet)
import torch  # noqa: E402
import torch.ao.quantization as tq  # noqa: E402
from sceneednet import SceneEDNet  # noqa: E402

torch_bench.PROG = "int8_accuracy.py"
fail = torch_bench.fail
PEERS = ("torch-int8", "ort-int8", "torch-bf16")
EXIT_BAR_MISSED = 3


def errors(out, ref):
    """max |out - ref| / max |ref| and RMS(out - ref) / RMS(ref), in float64."""
    out = np.asarray(out, np.float64)
    ref = np.asarray(ref, np.float64)
    diff = out - ref
    return {"max_rel": float(np.abs(diff).max() / np.abs(ref).max()),
            "rms_rel": float(np.sqrt((diff ** 2).mean() / (ref ** 2).mean()))}


def run(cmd, what, **kwargs):
    proc = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout[-2000:] + proc.stderr[-2000:])
        fail(f"{what} failed (exit {proc.returncode}): {' '.join(cmd)}")
    return proc


def sfrt_export(args, onnx_path, work, precision):
    """The model exported in `precision`: its path."""
    model = os.path.join(work, f"model-{precision}.sfrt")
    cmd = [args.sfrt, "export", onnx_path, "-o", model, "--precision", precision]
    if precision == "int8":
        cmd += ["--calibration", args.calibration]
    run(cmd, f"sfrt export --precision {precision}")
    return model


def sfrt_output(args, work, model, precision, index, x_nhwc_path, height, width):
    """sfrt's output (1, 3, H, W) for the exported `model` on input `index`."""
    out = os.path.join(work, f"out-{precision}-{index}.npy")
    run([args.sfrt, "infer", "--model", model, "--input-npy", x_nhwc_path, "-o", out],
        f"sfrt infer ({precision})")
    y = np.load(out)
    if y.shape != (height, width, 3):
        fail(f"sfrt infer ({precision}) wrote {y.shape}, expected ({height}, {width}, 3)")
    return y.transpose(2, 0, 1)[None]


class QuantNet(SceneEDNet):
    """SceneEDNet between a quantise and a dequantise stub (PyTorch's eager-mode quantisation
    replaces every nn.Conv2d by its quantised form; the rest runs on quantised tensors)."""

    def __init__(self, width_div, padding):
        super().__init__(width_div, padding)
        self.quant = tq.QuantStub()
        self.dequant = tq.DeQuantStub()

    def forward(self, x):
        return self.dequant(SceneEDNet.forward(self, self.quant(x)))


def torch_int8_net(state, width_div, padding, engine, frames):
    """PyTorch's quantised network, calibrated on `frames`, and what it is (engine, observers)."""
    torch.backends.quantized.engine = engine
    net = QuantNet(width_div, padding)
    net.load_state_dict(state, strict=True)
    net.eval()
    net.qconfig = tq.get_default_qconfig(engine)
    observers = {"activation": type(net.qconfig.activation()).__name__,
                 "weight": type(net.qconfig.weight()).__name__}
    tq.prepare(net, inplace=True)
    with torch.inference_mode():
        for frame in frames:
            net(frame)
    tq.convert(net, inplace=True)
    convs = [m for m in net.modules() if isinstance(m, torch.ao.nn.quantized.Conv2d)]
    if len(convs) != 11:
        fail(f"torch-int8: {len(convs)} quantised convolutions, expected 11")
    per_channel = all(c.weight().qscheme() == torch.per_channel_symmetric
                      or c.weight().qscheme() == torch.per_channel_affine for c in convs)
    return net, {"engine": engine, "weights_per_channel": per_channel, "observers": observers}


def ort_int8_errors(args, onnx_path, work, height, width):
    """make_qdq_onnx.py's QDQ model in ONNX Runtime: its errors against ORT's float32 run on each
    input (seeds 1..--inputs), or None and why it could not run."""
    if shutil.which("node") is None:
        return None, "node not found (apt-get install nodejs npm)"
    if not os.path.isdir(os.path.join(HERE, "node_modules", "onnxruntime-node")):
        print("int8_accuracy.py: installing onnxruntime-node (npm) as compare_peers.sh does",
              file=sys.stderr)
        env = dict(os.environ, ONNXRUNTIME_NODE_INSTALL="skip")
        proc = subprocess.run(["npm", "install", "--no-audit", "--no-fund"], cwd=HERE, env=env,
                              capture_output=True, text=True)
        if proc.returncode != 0:
            return None, f"npm install onnxruntime-node failed: {proc.stderr.strip()[-300:]}"
    qdq = os.path.join(work, "model-qdq.onnx")
    run([sys.executable, os.path.join(HERE, "make_qdq_onnx.py"), onnx_path, "-o", qdq,
         "--calibration", args.calibration], "make_qdq_onnx.py")
    per_input = []
    for seed in range(1, args.inputs + 1):
        # The profile (first input only) shows which kernels ran.
        profile = [f"--profile={os.path.join(work, 'ort-profile')}"] if seed == 1 else []
        proc = run(["node", os.path.join(HERE, "ort_bench.mjs"), f"--reference={onnx_path}",
                    f"--seed={seed}", *profile, qdq, str(height), str(width), str(args.threads),
                    "1", "0"], "ort_bench.mjs")
        line = json.loads(proc.stdout.strip().splitlines()[-1])
        if seed == 1:
            float_convs = [op for op in line.get("ops", {}) if op in ("Conv", "FusedConv")]
            if float_convs or "QLinearConv" not in line.get("ops", {}):
                fail(f"ort-int8: ONNX Runtime ran {', '.join(float_convs) or 'no QLinearConv'}")
        ref = line["vs_reference"]
        per_input.append({"max_rel": ref["max_rel"], "rms_rel": ref["rms_rel"]})
    return per_input, ""


def onnx_input_size(path):
    """(H, W) of the ONNX file's input when both are fixed, else None."""
    import onnx  # noqa: PLC0415  (torch_bench imported it already)
    dims = onnx.load(path, load_external_data=False).graph.input[0].type.tensor_type.shape.dim
    if len(dims) == 4 and all(d.HasField("dim_value") for d in dims[2:]):
        return dims[2].dim_value, dims[3].dim_value
    return None


def parse_args(argv):
    p = argparse.ArgumentParser(prog="int8_accuracy.py",
                                description="sfrt int8/bf16 error against its peers'.")
    p.add_argument("models", nargs="+", metavar="MODEL.onnx",
                   help="one or more float SceneEDNet ONNX files")
    p.add_argument("--sfrt", required=True, help="the sfrt binary")
    p.add_argument("--calibration", help="float32 .npy (N,H,W,12) calibration frames")
    p.add_argument("--size", help="input HxW (default: the ONNX file's, when fixed; else "
                   "96x128)")
    p.add_argument("--inputs", type=int, default=8,
                   help="inputs every engine runs (seeds 1..N; default 8)")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--peers", default=",".join(PEERS), help="any of " + ", ".join(PEERS))
    p.add_argument("--engine", help="PyTorch quantised engine (default onednn, else x86)")
    p.add_argument("--json", help="also write the results here")
    p.add_argument("--keep", help="keep the exported models and outputs in this folder")
    args = p.parse_args(argv)
    for path in args.models + [args.sfrt]:
        if not os.path.isfile(path):
            p.error(f"{'--sfrt' if path == args.sfrt else 'MODEL'}: no file {path!r}")
    if len(set(args.models)) != len(args.models):
        p.error("MODEL: a file is given twice (the verdict pairs distinct networks)")
    args.sizes = [model_size(p, args.size, path) for path in args.models]
    if args.inputs < 1:
        p.error(f"--inputs: at least 1, got {args.inputs}")
    args.peer_list = [q for q in args.peers.split(",") if q]
    for q in args.peer_list:
        if q not in PEERS:
            p.error(f"--peers: unknown peer {q!r} (known: {', '.join(PEERS)})")
    engines = torch.backends.quantized.supported_engines
    if args.engine is None:
        args.engine = next((e for e in ("onednn", "x86", "fbgemm") if e in engines), None)
    if "torch-int8" in args.peer_list and args.engine not in engines:
        p.error(f"--engine: {args.engine!r} is not one of this PyTorch's {engines}")
    return args


def model_size(p, size, path):
    """(H, W) the engines run `path` at: --size, else its fixed input size, else 96x128."""
    fixed = onnx_input_size(path)
    if size is None:
        size = f"{fixed[0]}x{fixed[1]}" if fixed else "96x128"
    try:
        height, width = (int(v) for v in size.lower().split("x"))
    except ValueError:
        p.error(f"--size: expected HxW, got {size!r}")
    if fixed and (height, width) != fixed:
        p.error(f"--size: {path} takes a fixed {fixed[0]}x{fixed[1]} input (ONNX Runtime runs "
                f"it at no other size), not {size}")
    if height < 8 or width < 8:
        p.error(f"--size: {size} is too small (at least 8x8)")
    return height, width


def mean_of(per_input, key):
    return sum(e[key] for e in per_input) / len(per_input)


def paired_difference(d):
    """The mean of the differences d (sfrt's minus the peer's), twice its standard error (None
    for one difference), and how many are below 0."""
    two_se = 2 * statistics.stdev(d) / math.sqrt(len(d)) if len(d) > 1 else None
    return sum(d) / len(d), two_se, sum(x < 0 for x in d)


def verdicts(measured):
    """sfrt int8 against the best int8 peer, sfrt bf16 against torch-bf16 (the best: the lowest
    mean max_rel over every network's inputs), paired over the inputs of one network or over the
    networks: (lines, all held)."""
    lines, held = [], True
    for precision, peers in (("int8", ("torch-int8", "ort-int8")), ("bf16", ("torch-bf16",))):
        ours = f"sfrt-{precision}"
        pooled = {q: [e for m in measured for e in m["results"].get(q, [])]
                  for q in (ours,) + peers}
        candidates = [(mean_of(pooled[q], "max_rel"), q) for q in peers
                      if all(q in m["results"] for m in measured)]
        if not pooled[ours] or not candidates:
            lines.append(f"sfrt {precision}: no peer measured, no verdict")
            continue
        best, name = min(candidates)
        # Per input of the one network, or per network (the mean over its inputs).
        per_unit = [[a["max_rel"] - b["max_rel"]
                     for a, b in zip(m["results"][ours], m["results"][name])] for m in measured]
        units = per_unit[0] if len(measured) == 1 else [sum(d) / len(d) for d in per_unit]
        unit = "inputs" if len(measured) == 1 else "networks"
        diff, two_se, lower = paired_difference(units)
        ok = diff <= (two_se if two_se is not None else 0.0)
        held = held and ok
        word = ("no worse" if diff <= 0 else f"no worse within the {unit}' spread" if ok
                else "WORSE")
        spread = f", 2 s.e. {two_se:.2e}" if two_se is not None else ""
        mean = mean_of(pooled[ours], "max_rel")
        lines.append(f"sfrt {precision}: mean max_rel {mean:.3e} against best peer {name} "
                     f"{best:.3e} (x{mean / best:.3f}; sfrt lower on {lower} of {len(units)} "
                     f"{unit}; difference {diff:+.2e}{spread}): {word}")
    return lines, held


def run_engines(args, onnx_path, work, frames_nchw, height, width):
    """Every engine on every input of one network: {model, height, width, width_div, padding,
    results: {engine: [errors per input]}, notes: {engine: notes}}."""
    state, width_div, padding = torch_bench.read_onnx(onnx_path)
    inputs = [torch_bench.lcg_input(height, width, seed) for seed in range(1, args.inputs + 1)]
    reference_net = SceneEDNet(width_div, padding)
    reference_net.load_state_dict(state, strict=True)
    reference_net.eval()
    with torch.inference_mode():
        refs = [reference_net(x).numpy() for x in inputs]
    x_paths = [os.path.join(work, f"input-{i + 1}.npy") for i in range(len(inputs))]
    for x, x_path in zip(inputs, x_paths):
        np.save(x_path, x.numpy()[0].transpose(1, 2, 0))  # NHWC, as sfrt infer reads it
    results, notes = {}, {}
    for precision in ("int8", "bf16"):
        model = sfrt_export(args, onnx_path, work, precision)
        results[f"sfrt-{precision}"] = [
            errors(sfrt_output(args, work, model, precision, i + 1, x_path, height, width), ref)
            for i, (x_path, ref) in enumerate(zip(x_paths, refs))]
    if "torch-int8" in args.peer_list:
        net, notes["torch-int8"] = torch_int8_net(state, width_div, padding, args.engine,
                                                  frames_nchw)
        with torch.inference_mode():
            results["torch-int8"] = [errors(net(x).numpy(), ref) for x, ref in zip(inputs, refs)]
    if "ort-int8" in args.peer_list:
        per_input, why = ort_int8_errors(args, onnx_path, work, height, width)
        if per_input is None:
            notes["ort-int8"] = {"unavailable": why}
            print(f"int8_accuracy.py: ort-int8 not measured: {why}", file=sys.stderr)
        else:
            results["ort-int8"] = per_input
    if "torch-bf16" in args.peer_list:  # as compare_peers.sh times it (torch_bench.py)
        net = torch_bench.BenchNet(width_div, padding)
        net.load_state_dict(state, strict=True)
        net = net.eval().to(dtype=torch.bfloat16, memory_format=torch.channels_last)
        with torch.inference_mode():
            results["torch-bf16"] = [
                errors(net(x.to(torch.bfloat16).contiguous(memory_format=torch.channels_last))
                       .float().numpy(), ref) for x, ref in zip(inputs, refs)]
    return {"model": onnx_path, "height": height, "width": width, "width_div": width_div,
            "padding": padding, "results": results, "notes": notes}


def print_table(m, frames, inputs):
    print(f"model {m['model']} (1/{m['width_div']} width, {m['padding']} padding) at "
          f"{m['height']}x{m['width']}, calibration {frames.shape[0]} frame(s) "
          f"{frames.shape[1]}x{frames.shape[2]}, {inputs} input(s)")
    print(f"{'engine':<12} {'max_rel':>10} {'rms_rel':>10} {'mean max':>10} {'mean rms':>10}  "
          f"against")
    for name, per_input in m["results"].items():
        against = "ONNX Runtime float32" if name == "ort-int8" else "PyTorch float32"
        print(f"{name:<12} {per_input[0]['max_rel']:>10.3e} {per_input[0]['rms_rel']:>10.3e} "
              f"{mean_of(per_input, 'max_rel'):>10.3e} {mean_of(per_input, 'rms_rel'):>10.3e}  "
              f"{against}")
    print("(max_rel, rms_rel: the first input, seed 1; mean: over the inputs)")
    for name, facts in m["notes"].items():
        print(f"{name}: {facts}")


def main(argv):
    args = parse_args(argv)
    torch.set_num_threads(args.threads)
    work = args.keep or tempfile.mkdtemp(prefix="sfrt-int8-accuracy-")
    os.makedirs(work, exist_ok=True)
    measured = []
    try:
        if args.calibration is None:
            args.calibration = os.path.join(work, "calibration.npy")
            rng = np.random.default_rng(20240601)
            np.save(args.calibration,
                    rng.integers(0, 256, size=(2, 96, 128, 12)).astype(np.float32))
        frames = np.load(args.calibration).astype(np.float32)
        if frames.ndim == 3:
            frames = frames[None]
        frames_nchw = [torch.from_numpy(np.ascontiguousarray(f.transpose(2, 0, 1)))[None]
                       for f in frames]
        for i, (path, (height, width)) in enumerate(zip(args.models, args.sizes)):
            net_work = os.path.join(work, f"network-{i + 1}")
            os.makedirs(net_work, exist_ok=True)
            measured.append(run_engines(args, path, net_work, frames_nchw, height, width))
            print_table(measured[-1], frames, args.inputs)  # one network at a time: progress
            if len(args.models) > 1:
                print(f"({i + 1} of {len(args.models)} networks)\n", flush=True)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)

    lines, held = verdicts(measured)
    for line in lines:
        print(line)
    if args.json:
        for m in measured:
            m["results"] = {name: {"max_rel": e[0]["max_rel"], "rms_rel": e[0]["rms_rel"],
                                   "mean_max_rel": mean_of(e, "max_rel"),
                                   "mean_rms_rel": mean_of(e, "rms_rel"), "per_input": e}
                            for name, e in m["results"].items()}
        with open(args.json, "w") as f:
            json.dump({"models": measured, "calibration": args.calibration,
                       "inputs": args.inputs, "verdicts": lines, "held": held}, f, indent=2)
    return 0 if held else EXIT_BAR_MISSED


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
