#!/usr/bin/python3
"""Run `sfrt bench --json` and check the JSON's structure (never its times).

usage: bench_json_check.py --sfrt BIN --model M --work DIR

Checks: the keys tools/bench/compare_ort.sh reads; per configuration, one step entry per planned
step whose mean times add up to the mean of the per-run step totals (the same timestamps, summed
two ways) and never exceed the mean wall time around Run(); shares add up to 1; by-op rows
account for every step; per-run counter arrays have one entry per run; build and cpu metadata.
"""
import argparse
import json
import math
import os
import subprocess
import sys


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--sfrt", required=True)
    p.add_argument("--model", required=True)
    p.add_argument("--work", required=True)
    args = p.parse_args()
    os.makedirs(args.work, exist_ok=True)
    out = os.path.join(args.work, "bench.json")
    if os.path.exists(out):
        os.remove(out)
    runs = 4
    cmd = [args.sfrt, "bench", "--model", args.model, "--size", "35x61", "--isa", "all",
           "--threads", "1,2", "--runs", str(runs), "--top", "3", "--peak-seconds", "0.01",
           "--json", out]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    print("$ " + " ".join(cmd))
    print(proc.stdout, end="")
    print(proc.stderr, end="", file=sys.stderr)
    failures = []

    def check(cond, what):
        if not cond:
            failures.append(what)

    check(proc.returncode == 0, f"exit code {proc.returncode}")
    if proc.returncode != 0 or not os.path.exists(out):
        print("FAIL: no JSON")
        return 1
    j = json.load(open(out))
    for key in ("height", "width", "macs", "peak_rss_mib", "peak_rss_kib", "results", "build",
                "cpu", "cpu_migrations"):
        check(key in j, f"top-level key {key}")
    for key in ("compiler", "build_type", "cxx_flags", "version", "git_describe"):
        check(key in j["build"], f"build.{key}")
    check(j["cpu"]["model"] != "", "cpu.model empty")
    check(j["peak_rss_mib"] > 0, "peak_rss_mib not positive")
    check(len(j["results"]) >= 2, "at least two configurations (threads 1,2)")
    for r in j["results"]:
        name = f'{r.get("isa")} x{r.get("threads")}'
        for key in ("isa", "threads", "median_ms", "p90_ms", "p99_ms", "p999_ms", "max_ms",
                    "stddev_ms", "gflops", "peak_gflops", "percent_of_peak", "kernels", "steps",
                    "by_op", "top_steps", "per_run", "steps_total_mean_ms"):
            check(key in r, f"{name}: key {key}")
        check(r["runs"] == runs, f"{name}: runs {r['runs']} != {runs}")
        check(r["median_ms"] <= r["p90_ms"] <= r["p99_ms"] <= r["p999_ms"] <= r["max_ms"],
              f"{name}: percentiles not ordered")
        check(r["stddev_ms"] >= 0, f"{name}: negative stddev")
        check(r["gflops"] > 0 and math.isfinite(r["gflops"]), f"{name}: gflops")
        check(r["peak_gflops"] > 0 and math.isfinite(r["peak_gflops"]), f"{name}: peak_gflops")
        check(r["percent_of_peak"] > 0, f"{name}: percent_of_peak")
        steps = r["steps"]
        check(len(steps) > 0, f"{name}: no steps")
        total = sum(s["mean_ms"] for s in steps)
        check(abs(total - r["steps_total_mean_ms"]) <= 1e-6 * max(1.0, total),
              f"{name}: step means sum {total} != steps_total_mean_ms {r['steps_total_mean_ms']}")
        check(r["steps_total_mean_ms"] <= r["mean_ms"] * (1 + 1e-9),
              f"{name}: steps total {r['steps_total_mean_ms']} > wall mean {r['mean_ms']}")
        check(abs(sum(s["share"] for s in steps) - 1) < 1e-6, f"{name}: shares do not sum to 1")
        check([s["step"] for s in steps] == list(range(len(steps))), f"{name}: not in run order")
        last = -1
        for s in steps:
            check(s["first_layer"] == last + 1, f"{name}: step {s['step']} does not follow")
            last = s["last_layer"]
            check(s["layers"] != "" and s["op"] != "" and s["kernel"] != "",
                  f"{name}: step {s['step']} unlabelled")
            check(s["median_ms"] >= 0 and s["max_ms"] >= s["median_ms"],
                  f"{name}: step {s['step']} times")
        check(sum(o["steps"] for o in r["by_op"]) == len(steps), f"{name}: by_op misses steps")
        check(abs(sum(o["mean_ms"] for o in r["by_op"]) - total) <= 1e-6 * max(1.0, total),
              f"{name}: by_op means do not add up")
        check(len(r["top_steps"]) == min(3, len(steps)), f"{name}: top_steps length")
        medians = [steps[i]["median_ms"] for i in r["top_steps"]]
        check(medians == sorted(medians, reverse=True), f"{name}: top_steps not slowest first")
        pr = r["per_run"]
        for key in ("wall_ms", "minor_faults", "major_faults", "voluntary_switches",
                    "involuntary_switches"):
            check(len(pr[key]) == runs, f"{name}: per_run.{key} length")
        if j["cpu_migrations"]["available"]:
            check(len(pr["cpu_migrations"]) == runs, f"{name}: per_run.cpu_migrations length")
        else:
            check(pr["cpu_migrations"] is None and j["cpu_migrations"]["reason"] != "",
                  f"{name}: migrations unavailable without a reason")
        check(sorted(pr["wall_ms"])[0] == r["min_ms"], f"{name}: min_ms is not the fastest run")
    for f in failures:
        print("FAIL: " + f)
    if not failures:
        print("OK")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
