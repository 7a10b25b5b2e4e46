#!/usr/bin/python3
"""What the Python package costs over the C++ it wraps (issue #41), measured in one run with
alternating rounds:

  1. Session.run_tensor against `sfrt bench` (the median of Session::Run in C++) on the same
     model, size and thread count: the Python call's overhead (argument checks, the finiteness
     check `sfrt infer --input-npy` also makes, the output array, the GIL hand-off);
  2. sfrt.replay over a synthesised dataset against `sfrt run` with no file outputs: frames per
     second, each as the pipeline's summary measures it (frames / wall time);
  3. two Sessions on two Python threads against one Session on one: the GIL is released, so on
     a machine with two free cores the two threads' work takes about as long as one thread's.

usage: PYTHONPATH=build/release/python /usr/bin/python3 tools/bench/python_bench.py \\
         [--sfrt build/release/bin/sfrt] [--model models/sceneednet-default.sfrt] [--size 96x128]
         [--rounds 5] [--runs 300] [--json OUT]
"""
import argparse
import json
import os
import re
import subprocess
import tempfile
import threading
import time

import numpy as np

import sfrt

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")


def sfrt_bench_median(a, work):
    out = os.path.join(work, "bench.json")
    subprocess.run([a.sfrt, "bench", "--model", a.model, "--size", a.size, "--threads",
                    str(a.threads), "--warmup", "20", "--runs", str(a.runs), "--peak-seconds", "0",
                    "--json", out], check=True, stdout=subprocess.DEVNULL)
    with open(out) as f:
        doc = json.load(f)
    return doc["results"][0]["median_ms"]


def python_median(session, x, out, runs):
    for _ in range(20):
        session.run_tensor(x, out=out)
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        session.run_tensor(x, out=out)
        times.append(time.perf_counter() - start)
    return float(np.median(times)) * 1e3


def sfrt_run_fps(a, data, work):
    done = subprocess.run([a.sfrt, "run", "--model", a.model, "--replay", data, "--size", a.size,
                           "--threads", str(a.threads), "--out", os.path.join(work, "run"),
                           "--flow-format", "none", "--no-png", "--no-summary", "--progress",
                           "off"], check=True, capture_output=True, text=True)
    return float(re.search(r"^throughput\s+([0-9.]+) fps", done.stdout, re.M).group(1))


def replay_fps(model, a, data, size):
    with sfrt.replay(model, dataset=data, size=size, threads=a.threads) as windows:
        count = sum(1 for _ in windows)
        return windows.summary["fps"], count


def parallel_ratio(model, size, x, runs):
    """Wall time of two threads each doing `runs` on its own Session / one thread doing `runs`."""
    def work(session):
        for _ in range(runs):
            session.run_tensor(x)

    solo = sfrt.Session(model, size=size)
    work(solo)
    start = time.perf_counter()
    work(solo)
    one = time.perf_counter() - start
    sessions = [sfrt.Session(model, size=size) for _ in range(2)]
    threads = [threading.Thread(target=work, args=(s,)) for s in sessions]
    start = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    two = time.perf_counter() - start
    return two / one, one, two


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sfrt", default=os.path.join(ROOT, "build", "release", "bin", "sfrt"))
    ap.add_argument("--model", default=os.path.join(ROOT, "models", "sceneednet-default.sfrt"))
    ap.add_argument("--size", default="96x128")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--runs", type=int, default=300)
    ap.add_argument("--frames", type=int, default=400, help="frames of the replay dataset")
    ap.add_argument("--json", help="also write the figures here")
    a = ap.parse_args()
    size = tuple(int(v) for v in a.size.split("x"))
    model = sfrt.Model(a.model)
    session = sfrt.Session(model, size=size, threads=a.threads)
    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, size + (model.info["input"]["channels"],)).astype(np.float32)
    out = np.empty(size + (model.info["output"]["channels"],), np.float32)
    print("sfrt %s, %s, %s, %d thread(s); %d rounds, alternating" % (
        sfrt.__version__, os.path.basename(a.model), a.size, a.threads, a.rounds))
    rows = []
    with tempfile.TemporaryDirectory() as work:
        data = os.path.join(work, "data")
        subprocess.run([a.sfrt, "synth", "--out", data, "--scene", "robot", "--seed", "7",
                        "--sequences", "1", "--frames", str(a.frames), "--size", a.size,
                        "--focal", "90", "--baseline", "0.12", "--objects", "4"],
                       check=True, stdout=subprocess.DEVNULL)
        for r in range(a.rounds):
            # Alternate which side goes first.
            order = [("cpp", None), ("py", None)] if r % 2 == 0 else [("py", None), ("cpp", None)]
            row = {"round": r}
            for side, _ in order:
                if side == "cpp":
                    row["bench_ms"] = sfrt_bench_median(a, work)
                    row["run_fps"] = sfrt_run_fps(a, data, work)
                else:
                    row["run_tensor_ms"] = python_median(session, x, None, a.runs)
                    row["run_tensor_out_ms"] = python_median(session, x, out, a.runs)
                    row["replay_fps"], row["windows"] = replay_fps(model, a, data, size)
            rows.append(row)
            print("round %d: sfrt bench %.3f ms | run_tensor %.3f ms (%.3fx), with out= %.3f ms "
                  "(%.3fx) | sfrt run %.1f fps | replay %.1f fps (%.3fx)" % (
                      r, row["bench_ms"], row["run_tensor_ms"],
                      row["run_tensor_ms"] / row["bench_ms"], row["run_tensor_out_ms"],
                      row["run_tensor_out_ms"] / row["bench_ms"], row["run_fps"],
                      row["replay_fps"], row["replay_fps"] / row["run_fps"]))
        ratio, one, two = parallel_ratio(model, size, x, a.runs * 2)
    summary = {
        "bench_ms": float(np.median([r["bench_ms"] for r in rows])),
        "run_tensor_ms": float(np.median([r["run_tensor_ms"] for r in rows])),
        "run_tensor_out_ms": float(np.median([r["run_tensor_out_ms"] for r in rows])),
        "run_fps": float(np.median([r["run_fps"] for r in rows])),
        "replay_fps": float(np.median([r["replay_fps"] for r in rows])),
        "two_threads_over_one": ratio,
        "cpus": os.cpu_count(),
    }
    # The median of the rounds' ratios (each round's two sides ran back to back).
    summary["run_tensor_over_bench"] = float(np.median(
        [r["run_tensor_ms"] / r["bench_ms"] for r in rows]))
    summary["run_tensor_out_over_bench"] = float(np.median(
        [r["run_tensor_out_ms"] / r["bench_ms"] for r in rows]))
    summary["replay_over_run"] = float(np.median([r["replay_fps"] / r["run_fps"] for r in rows]))
    print("median of the rounds' ratios: run_tensor %.3fx sfrt bench (with out= %.3fx); replay "
          "%.3fx sfrt run's fps" % (summary["run_tensor_over_bench"],
                                     summary["run_tensor_out_over_bench"],
                                     summary["replay_over_run"]))
    print("two Sessions on two threads: %.2fx one thread's time for the same work per thread "
          "(%.2f s vs %.2f s; 1.0 = fully parallel, 2.0 = serialised; %d CPUs)" % (
              ratio, two, one, os.cpu_count()))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"rounds": rows, "summary": summary}, f, indent=1)


if __name__ == "__main__":
    main()
