#!/usr/bin/python3
"""Times a SceneEDNet ONNX file's network in PyTorch (CPU, eager) the way ort_bench.mjs times it
in ONNX Runtime: warm-up, then N runs, median / p90 / min, printed as one JSON line.

The network is tools/train/sceneednet.py's SceneEDNet (the module gen_sceneednet.py exports),
with the ONNX file's initializers (conv0.weight ... output.bias) loaded into it; the padding
mode (tf: Pad nodes, torch: Conv pads 1) and the width divisor come from the file. Only the
convolutions differ from SceneEDNet.forward: where TF 'same' padding is symmetric (every
stride-1 conv, stride-2 convs on odd sizes) the pad goes into the convolution instead of a
separate F.pad copy; the asymmetric ones keep F.pad (extra row/column at the bottom/right).
Weights and input in --dtype (default bf16), channels_last, eval, torch.inference_mode(),
torch.set_num_threads(THREADS). The input is float NCHW (1, 12, H, W) from ort_bench.mjs's
seeded LCG (the same values), then cast to --dtype.

usage: torch_bench.py [--dtype fp32|bf16] [--verbose-kernels] [--check]
                      MODEL.onnx HEIGHT WIDTH [THREADS=1] [RUNS=5] [WARMUP=1]

--verbose-kernels: one extra, untimed run with oneDNN verbose on (the same messages as
DNNL_VERBOSE=1/ONEDNN_VERBOSE=1, for that run only); prints each convolution implementation
oneDNN ran (e.g. brgconv:avx512_core_bf16) and the data types to stderr, and adds
"conv_impls" to the JSON line.
--check: also runs SceneEDNet.forward itself in float32 on the same input and weights and
prints max |difference| / max |reference| to stderr; fails above 1e-4 (fp32) or 0.1 (bf16).
peak_rss_mib is the process's peak resident memory (getrusage), loading included, as
ort_bench.mjs reports it. Run with Debian's /usr/bin/python3 (python3-torch, python3-onnx).
"""

import argparse
import collections
import ctypes
import json
import os
import resource
import sys
import tempfile
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "train"))

try:
    import numpy as np
    import onnx
    from onnx import numpy_helper
    import torch
    import torch.nn.functional as F
except ImportError as exc:  # pragma: no cover - environment problem
    sys.exit(f"torch_bench.py: cannot import {exc.name}: run this with /usr/bin/python3 "
             f"(Debian's python3-torch, python3-onnx, python3-numpy), not {sys.executable}")

import sceneednet  # noqa: E402  (tools/train/sceneednet.py: the one definition of the network)
from sceneednet import FULL_WIDTHS, IN_CHANNELS, SceneEDNet  # noqa: E402

DTYPES = {"fp32": torch.float32, "bf16": torch.bfloat16}
CHECK_TOLERANCE = {"fp32": 1e-4, "bf16": 0.1}
PROG = "torch_bench.py"  # error prefix; make_qdq_onnx.py sets its own name


def fail(msg):
    sys.exit(f"{PROG}: {msg}")


class BenchNet(SceneEDNet):
    """SceneEDNet with TF 'same' padding folded into the convolution where it is symmetric."""

    def _conv(self, conv, x):
        if self.padding == "tf":
            top, bottom = sceneednet._same_pad_amounts(x.shape[2], conv.stride[0])
            left, right = sceneednet._same_pad_amounts(x.shape[3], conv.stride[1])
            if top == bottom and left == right:
                return F.conv2d(x, conv.weight, conv.bias, conv.stride, (top, left))
            x = F.pad(x, [left, right, top, bottom])
        return conv(x)


def read_onnx(path):
    """The ONNX file's weights as a state dict, its width divisor and padding mode."""
    try:
        model = onnx.load(path)
    except Exception as exc:  # onnx raises several types for unreadable files
        fail(f"cannot read ONNX file {path!r}: {exc}")
    weights = {i.name: numpy_helper.to_array(i) for i in model.graph.initializer}
    if "conv0.weight" not in weights:
        fail(f"{path}: no initializer 'conv0.weight'; not a SceneEDNet export of "
             f"tests/fixtures/gen_sceneednet.py (initializers conv0.weight ... output.bias)")
    out0 = weights["conv0.weight"].shape[0]
    if out0 == 0 or FULL_WIDTHS[0] % out0 != 0:
        fail(f"{path}: conv0.weight has {out0} output channels; expected 64 / a divisor")
    width_div = FULL_WIDTHS[0] // out0
    ops = {n.op_type for n in model.graph.node}
    padding = "tf" if "Pad" in ops else "torch"
    del model
    state = {}
    for name, value in weights.items():
        if name.endswith(".weight") or name.endswith(".bias"):
            state[name] = torch.from_numpy(np.array(value, dtype=np.float32))  # a writable copy
    return state, width_div, padding


def lcg_input(height, width, seed=1):
    """ort_bench.mjs's input (its --seed): seed = seed * 1103515245 + 12345 mod 2^32 from `seed`,
    each value seed / 2^32 * 255 in double, stored as float32; NCHW (1, 12, H, W)."""
    n = IN_CHANNELS * height * width
    a, c, mask = 1103515245, 12345, 0xFFFFFFFF
    k = 4096  # values per row; each row is the previous one advanced k steps at once
    first = np.empty(k, np.uint64)
    for i in range(k):
        seed = (seed * a + c) & mask
        first[i] = seed
    ak, ck = 1, 0
    for _ in range(k):
        ak, ck = (ak * a) & mask, (ck * a + c) & mask
    rows = -(-n // k)
    vals = np.empty((rows, k), np.uint64)
    vals[0] = first
    ak64, ck64 = np.uint64(ak), np.uint64(ck)
    for r in range(1, rows):
        # Both factors < 2^32, so the product fits in 64 bits before the mask.
        vals[r] = (vals[r - 1] * ak64 + ck64) & np.uint64(mask)
    x = (vals.reshape(-1)[:n].astype(np.float64) / 4294967296.0 * 255.0).astype(np.float32)
    return torch.from_numpy(x.reshape(1, IN_CHANNELS, height, width))


def percentile(sorted_ms, q):
    """Linear interpolation, as ort_bench.mjs's pct()."""
    pos = q * (len(sorted_ms) - 1)
    lo = int(pos)
    hi = min(lo + 1, len(sorted_ms) - 1)
    return sorted_ms[lo] + (sorted_ms[hi] - sorted_ms[lo]) * (pos - lo)


def conv_impls(net, x):
    """One run with oneDNN verbose on; returns {(impl, data types): executions} of convolutions."""
    libc = ctypes.CDLL(None)
    sys.stdout.flush()
    saved = os.dup(1)
    with tempfile.TemporaryFile(mode="w+") as log:
        os.dup2(log.fileno(), 1)  # oneDNN prints to the C stdout
        try:
            with torch.backends.mkldnn.verbose(torch.backends.mkldnn.VERBOSE_ON):
                net(x)
        finally:
            libc.fflush(None)
            os.dup2(saved, 1)
            os.close(saved)
        log.seek(0)
        lines = log.read().splitlines()
    found = collections.Counter()
    for line in lines:
        f = line.split(",")
        # onednn_verbose,exec,cpu,convolution,IMPL,PROP,MEMORY DESCRIPTORS,...
        if len(f) > 6 and f[1] == "exec" and f[3] == "convolution":
            types = " ".join(d.split(":")[0] for d in f[6].split() if not d.endswith("undef"))
            found[(f[4], types)] += 1
    return found


def main(argv):
    p = argparse.ArgumentParser(prog="torch_bench.py",
                                description="Time a SceneEDNet ONNX file's network in PyTorch.")
    p.add_argument("model")
    p.add_argument("height", type=int)
    p.add_argument("width", type=int)
    p.add_argument("threads", type=int, nargs="?", default=1)
    p.add_argument("runs", type=int, nargs="?", default=5)
    p.add_argument("warmup", type=int, nargs="?", default=1)
    p.add_argument("--dtype", choices=sorted(DTYPES), default="bf16",
                   help="weights, activations and arithmetic (default bf16)")
    p.add_argument("--verbose-kernels", action="store_true",
                   help="print the oneDNN convolution implementations (one extra untimed run)")
    p.add_argument("--check", action="store_true",
                   help="compare with SceneEDNet.forward in float32 on the same input")
    args = p.parse_args(argv)
    if args.height < 1 or args.width < 1:
        p.error(f"HEIGHT and WIDTH must be >= 1 (got {args.height}x{args.width})")
    if args.threads < 1 or args.runs < 1 or args.warmup < 0:
        p.error("THREADS and RUNS must be >= 1, WARMUP >= 0")
    if not os.path.isfile(args.model):
        p.error(f"no model file {args.model!r}")

    torch.set_num_threads(args.threads)
    dtype = DTYPES[args.dtype]
    state, width_div, padding = read_onnx(args.model)
    net = BenchNet(width_div, padding)
    try:
        net.load_state_dict(state, strict=True)
    except RuntimeError as exc:
        fail(f"{args.model}: its initializers do not match SceneEDNet at 1/{width_div} width: "
             f"{exc}")
    net.eval()
    x32 = lcg_input(args.height, args.width)

    reference = None
    if args.check:
        with torch.inference_mode():
            reference = SceneEDNet.forward(net, x32)  # the unmodified definition, float32
    del state

    net = net.to(dtype=dtype, memory_format=torch.channels_last)
    x = x32.to(dtype=dtype).contiguous(memory_format=torch.channels_last)
    del x32

    impls = None
    ms = []
    with torch.inference_mode():
        for _ in range(args.warmup):
            net(x)
        if args.verbose_kernels:
            impls = conv_impls(net, x)
            if not impls:
                print("torch_bench.py: oneDNN reported no convolution (not run through oneDNN)",
                      file=sys.stderr)
            for (impl, types), count in sorted(impls.items()):
                print(f"torch_bench.py: oneDNN convolution {impl} ({types}): {count} "
                      f"execution(s) per run", file=sys.stderr)
        for _ in range(args.runs):
            t0 = time.perf_counter()
            y = net(x)
            ms.append((time.perf_counter() - t0) * 1e3)
        if reference is not None:
            err = float((y.float() - reference).abs().max() / reference.abs().max())
            print(f"torch_bench.py: check: max |{args.dtype} - float32 SceneEDNet.forward| / "
                  f"max |float32| = {err:.3g}", file=sys.stderr)
            if not err <= CHECK_TOLERANCE[args.dtype]:
                fail(f"check failed: {err:.3g} > {CHECK_TOLERANCE[args.dtype]}")
    if tuple(y.shape) != (1, 3, args.height, args.width):
        fail(f"output shape {tuple(y.shape)}, expected (1, 3, {args.height}, {args.width})")

    ms.sort()
    result = {
        "peer": "torch", "version": torch.__version__, "model": args.model,
        "height": args.height, "width": args.width, "threads": args.threads, "runs": args.runs,
        "dtype": args.dtype, "median_ms": percentile(ms, 0.5), "p90_ms": percentile(ms, 0.9),
        "min_ms": ms[0], "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }
    if impls is not None:
        result["conv_impls"] = {f"{impl} ({types})": n for (impl, types), n in impls.items()}
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
