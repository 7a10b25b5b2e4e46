#!/usr/bin/python3
"""Issue 43's speed acceptance in one run: the paper's network in int8 and bf16 against its floor.

usage: roofline_acceptance.py [--sfrt BIN] [--sizes 540x960,270x480] [--width-div 1]
                              [--threads 2] [--runs 5] [--precisions int8,bf16] [--bar 2.0]
                              [--top 8] [--against TUNING] [--json FILE] [--keep DIR]

For each precision and size: SceneEDNet with seeded random weights
(tests/fixtures/gen_sceneednet.py, 1/--width-div width, tf padding), exported with `sfrt export
--precision int8 --calibration` (2 seeded frames of integers 0..255 at 96x128) or `--precision
bf16`, timed by `sfrt bench --threads T --runs R --json` (int8 from its uint8 input,
--quantized-input, as `sfrt run` feeds it). From that JSON's roofline (`sfrt bench --help`):
the floor = the actual multiply-accumulates (the phase shortcut at 4/9) at the peak of the unit
doing most of them, both measured in that process; the verdict: median / floor <= --bar (2.0),
the issue's bar for AMX int8 and AMX bf16. Where the main unit is not AMX (a CPU without it)
the ratio is printed and the verdict says the bar is AMX's. Then each run's slowest --top steps
with their share of their roof.

--against TUNING (an `sfrt bench --tuning` variant, e.g. amx_pairs=off): every bench call also
times that variant in the same process, rounds alternating (`--tuning default --tuning TUNING`);
the verdict stays the default's, and each run prints the variant's median over the default's and
the same ratio for the slowest steps (above 1: the default is faster). On an AMX CPU,
`--against amx_pairs=off` is issue 43's A/B of the 2 x 2 tile blocking.

Full width at 540x960 takes seconds a run on an AMX Xeon (and minutes where int8 falls back to
the scalar kernels: CPUs without VNNI). --keep DIR keeps the models and JSON; --json FILE writes
every figure and verdict. No step can beat the peak of its unit: where one runs faster than
1.1x the peak measured in its process (a host that took a core away while the peak was timed),
that run's verdict is "peak disturbed" and holds nothing. Exit 0 when every verdict holds (or has
no AMX to hold on), 3 when one does not, 4 when none misses but a peak was disturbed (rerun), 1
when a step failed, 2 on a usage error. Needs Debian's /usr/bin/python3 with
python3-torch, python3-onnx and numpy (the fixture generator).
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
PROG = "roofline_acceptance.py"
EXIT_BAR_MISSED = 3
EXIT_PEAK_DISTURBED = 4
# A compute step faster than this share of its unit's peak (measured in the same process) shows
# that the peak's measurement was disturbed.
PEAK_SLACK = 1.1
AMX_UNIT = {"int8": "amx int8", "bf16": "amx bf16"}


def fail(msg):
    sys.exit(f"{PROG}: {msg}")


def run(cmd, what):
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout[-2000:] + proc.stderr[-2000:])
        fail(f"{what} failed (exit {proc.returncode}): {' '.join(cmd)}")
    return proc


def parse_size(text):
    try:
        h, w = (int(v) for v in text.lower().split("x"))
    except ValueError:
        return None
    return (h, w) if h >= 16 and w >= 16 else None


def parse_args(argv):
    p = argparse.ArgumentParser(prog=PROG, description="Issue 43's roofline acceptance.")
    p.add_argument("--sfrt", default=os.path.join(ROOT, "build", "release", "bin", "sfrt"))
    p.add_argument("--sizes", default="540x960,270x480")
    p.add_argument("--width-div", type=int, default=1)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--precisions", default="int8,bf16")
    p.add_argument("--bar", type=float, default=2.0, help="median / floor at most (default 2.0)")
    p.add_argument("--top", type=int, default=8, help="slowest steps shown per run (default 8)")
    p.add_argument("--against", metavar="TUNING",
                   help="also time this sfrt bench --tuning variant, alternating (e.g. amx_pairs=off)")
    p.add_argument("--json")
    p.add_argument("--keep")
    args = p.parse_args(argv)
    args.size_list = [parse_size(s) for s in args.sizes.split(",") if s]
    if not args.size_list or None in args.size_list:
        p.error(f"--sizes: expected HxW[,HxW...] of at least 16x16, got {args.sizes!r}")
    args.precision_list = [q for q in args.precisions.split(",") if q]
    for q in args.precision_list:
        if q not in AMX_UNIT:
            p.error(f"--precisions: unknown precision {q!r} (known: int8, bf16)")
    if args.width_div not in (1, 2, 4, 8, 16, 32, 64):
        p.error(f"--width-div: {args.width_div} is not a divisor of 64")
    if args.threads < 1 or args.runs < 1 or not args.bar > 0:
        p.error("--threads and --runs must be >= 1, --bar > 0")
    if not os.path.isfile(args.sfrt):
        p.error(f"--sfrt: no file {args.sfrt!r} (build it: cmake --build --preset release)")
    return args


def make_models(args, work):
    """The ONNX network and its int8 and bf16 .sfrt exports: {precision: path}."""
    h, w = args.size_list[0]
    name = f"sceneednet_w{args.width_div}"
    run(["/usr/bin/python3", os.path.join(ROOT, "tests", "fixtures", "gen_sceneednet.py"),
         "--out-dir", work, "--name", name, "--height", str(h), "--width", str(w),
         "--width-div", str(args.width_div), "--threads", str(args.threads)],
        "gen_sceneednet.py")
    onnx_path = os.path.join(work, name + ".onnx")
    calibration = os.path.join(work, "calibration.npy")
    run(["/usr/bin/python3", "-c",
         "import sys, numpy as np; rng = np.random.default_rng(20240601); "
         "np.save(sys.argv[1], rng.integers(0, 256, size=(2, 96, 128, 12)).astype(np.float32))",
         calibration], "the calibration frames")
    models = {}
    for q in args.precision_list:
        out = os.path.join(work, f"{name}-{q}.sfrt")
        cmd = [args.sfrt, "export", onnx_path, "-o", out, "--precision", q]
        if q == "int8":
            cmd += ["--calibration", calibration]
        run(cmd, f"sfrt export --precision {q}")
        models[q] = out
    return models


def bench(args, work, model, precision, size):
    """The default tuning's result, and --against's (None without it)."""
    h, w = size
    out = os.path.join(work, f"bench-{precision}-{h}x{w}.json")
    cmd = [args.sfrt, "bench", "--model", model, "--size", f"{h}x{w}", "--threads",
           str(args.threads), "--runs", str(args.runs), "--json", out]
    if precision == "int8":
        cmd.append("--quantized-input")
    if args.against:
        cmd += ["--tuning", "default", "--tuning", args.against]
    print(f"$ {' '.join(cmd)}", flush=True)
    run(cmd, "sfrt bench")
    with open(out) as f:
        results = json.load(f)["results"]
    return results[0], (results[1] if args.against else None)


def print_against(default, other, top):
    """The variant's median over the default's, overall and for the default's slowest steps."""
    ratio = other["median_ms"] / default["median_ms"]
    print(f"  {other['tuning']}: median {other['median_ms']:.2f} ms, {ratio:.3f}x the default's "
          f"{default['median_ms']:.2f} ms (above 1: the default is faster)")
    theirs = {s["layers"]: s for s in other["steps"]}
    order = sorted(default["steps"], key=lambda s: -s["median_ms"])[:top]
    print(f"    {'step':<30} {'default ms':>10} {'variant ms':>10} {'ratio':>7}  variant kernel")
    for s in order:
        o = theirs.get(s["layers"])
        if o is None:
            print(f"    {s['layers'][:30]:<30} {s['median_ms']:>10.3f} {'-':>10} {'-':>7}")
            continue
        r = o["median_ms"] / s["median_ms"] if s["median_ms"] > 0 else float("nan")
        print(f"    {s['layers'][:30]:<30} {s['median_ms']:>10.3f} {o['median_ms']:>10.3f} "
              f"{r:>7.3f}  {o['kernel']}")
    return ratio


def fastest_step(result):
    """The compute step with the largest share of its unit's peak: (layers, share) or None."""
    points = [(s["layers"], p["share_of_roof"])
              for s, p in zip(result["steps"], result["roofline"]["steps"])
              if p["unit"] != "memory" and p["share_of_roof"] is not None]
    return max(points, key=lambda point: point[1], default=None)


def verdict(precision, result, bar):
    """(status, text): status "held", "missed", "no-amx" or "disturbed"."""
    roof = result["roofline"]
    ratio = roof["median_over_main_floor"]
    fastest = fastest_step(result)
    if fastest is not None and fastest[1] > PEAK_SLACK:
        return "disturbed", (f"peak disturbed: {fastest[0]} ran at {100 * fastest[1]:.0f}% of "
                             f"its unit's peak as measured in this process; rerun")
    amx = AMX_UNIT[precision]
    if roof["main_unit"] != amx:
        against = (f"median / floor {ratio:.2f}x against {roof['main_unit']}" if ratio
                   else f"its main unit ({roof['main_unit']}) has no measured peak")
        return "no-amx", f"no AMX here: the bar is {amx}'s; {against}"
    held = ratio is not None and ratio <= bar
    text = f"median / floor {ratio:.2f}x {'<=' if held else '>'} {bar:.2f}x"
    return ("held" if held else "missed"), text


def exit_code(statuses):
    if "missed" in statuses:
        return EXIT_BAR_MISSED
    return EXIT_PEAK_DISTURBED if "disturbed" in statuses else 0


def print_steps(result, top):
    steps = result["steps"]
    points = result["roofline"]["steps"]
    order = sorted(range(len(steps)), key=lambda k: -steps[k]["median_ms"])[:top]
    print(f"    {'step':<30} {'unit':<11} {'GMAC':>8} {'ms':>8} {'% roof':>7}  bound")
    for k in order:
        s, p = steps[k], points[k]
        share = "-" if p["share_of_roof"] is None else f"{100 * p['share_of_roof']:.1f}"
        gmac = "-" if p["unit"] == "memory" else f"{p['macs'] / 1e9:.3f}"
        print(f"    {s['layers'][:30]:<30} {p['unit']:<11} {gmac:>8} {s['median_ms']:>8.3f} "
              f"{share:>7}  {p['bound']}")


def main(argv):
    args = parse_args(argv)
    work = args.keep or tempfile.mkdtemp(prefix="sfrt-roofline-")
    os.makedirs(work, exist_ok=True)
    rows = []
    try:
        models = make_models(args, work)
        for q in args.precision_list:
            for size in args.size_list:
                r, other = bench(args, work, models[q], q, size)
                roof = r["roofline"]
                status, text = verdict(q, r, args.bar)
                held = {"held": True, "missed": False}.get(status)
                rows.append({"precision": q, "size": f"{size[0]}x{size[1]}",
                             "median_ms": r["median_ms"], "main_unit": roof["main_unit"],
                             "main_peak_gmacs": roof["main_peak_gmacs"],
                             "gmacs": roof["macs"] / 1e9, "floor_ms": roof["main_floor_ms"],
                             "ratio": roof["median_over_main_floor"],
                             "roof_floor_ms": roof["floor_ms"], "held": held, "status": status,
                             "verdict": text})
                print(f"{q} {size[0]}x{size[1]}: median {r['median_ms']:.2f} ms; {text}")
                print_steps(r, args.top)
                if other is not None:
                    rows[-1]["against"] = {"tuning": other["tuning"],
                                           "median_ms": other["median_ms"],
                                           "ratio": print_against(r, other, args.top)}
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    print(f"\n{'precision':<9} {'size':<9} {'median ms':>10} {'GMAC':>8} {'main unit':<11} "
          f"{'peak GMAC/s':>11} {'floor ms':>9} {'ratio':>6}  verdict")
    for row in rows:
        peak = "-" if row["main_peak_gmacs"] is None else f"{row['main_peak_gmacs']:.1f}"
        floor = "-" if row["floor_ms"] is None else f"{row['floor_ms']:.2f}"
        ratio = "-" if row["ratio"] is None else f"{row['ratio']:.2f}"
        print(f"{row['precision']:<9} {row['size']:<9} {row['median_ms']:>10.2f} "
              f"{row['gmacs']:>8.3g} {row['main_unit']:<11} {peak:>11} {floor:>9} {ratio:>6}  "
              f"{row['verdict']}")
    for row in rows:
        if "against" in row:
            a = row["against"]
            print(f"{row['precision']} {row['size']}: {a['tuning']} {a['median_ms']:.2f} ms = "
                  f"{a['ratio']:.3f}x the default's {row['median_ms']:.2f} ms")
    code = exit_code([row["status"] for row in rows])
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"width_div": args.width_div, "threads": args.threads, "bar": args.bar,
                       "rows": rows, "held": code == 0}, f, indent=2)
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
