#!/usr/bin/python3
"""Run `sfrt bench --json` and check the JSON's structure (never its times).

usage: bench_json_check.py --sfrt BIN --model M --work DIR

Checks: the keys tools/bench/compare_ort.sh reads; per configuration, one step entry per planned
step whose mean times add up to the mean of the per-run step totals (the same timestamps, summed
two ways) and never exceed the mean wall time around Run(); shares add up to 1; by-op rows
account for every step; per-run counter arrays have one entry per run; build and cpu metadata.
The int8 model runs as two --tuning variants (default, fewout=off): one result each, naming its
variant, the variant applied, the steps side by side.
The roofline (per configuration, and again on the int8 model): one entry per step, whose
multiply-accumulates add up to its total (never above the model's nominal work; below it where
phase kernels run), a unit for every step that agrees with its kernel's name, memory steps with
no MACs, achieved rates that are the step's work over its median, the roof the lower of the
unit's peak and intensity x bandwidth, the floors the work at the roofs.
"""
import argparse
import json
import math
import os
import subprocess
import sys


def run(cmd):
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    print("$ " + " ".join(cmd))
    print(proc.stdout, end="")
    print(proc.stderr, end="", file=sys.stderr)
    return proc


# The unit each kernel family runs on (profiling/roofline.cc's table, restated).
def expected_unit(kernel, macs):
    if macs == 0:
        return "memory"
    for part, unit in (("__amx_emulated", "unmeasured"), ("u8s8__avx512amx", "amx int8"),
                       ("bf16__avx512amx", "amx bf16"), ("u8s8__avx512vnni", "int8 vnni"),
                       ("bf16__avx512bf16", "bf16 avx512"), ("_f32__", "fma"),
                       ("winograd", "fma")):
        if part in kernel:
            return unit
    if kernel.startswith("ref::"):
        return "unmeasured" if ("Int8" in kernel or "Bf16" in kernel) else "fma"
    return "unmeasured"


PEAK_OF_UNIT = {"fma": "fma_gmacs", "int8 vnni": "int8_vnni_gmacs",
                "bf16 avx512": "bf16_avx512_gmacs", "amx int8": "amx_int8_gmacs",
                "amx bf16": "amx_bf16_gmacs"}


def close(a, b, rel=1e-6):
    return abs(a - b) <= rel * max(abs(a), abs(b), 1e-12)


def check_roofline(r, nominal_macs, name, check):
    roof = r.get("roofline")
    check(roof is not None, f"{name}: no roofline")
    if roof is None:
        return
    steps, points = r["steps"], roof["steps"]
    check(len(points) == len(steps), f"{name}: roofline steps {len(points)} != {len(steps)}")
    check(sum(p["macs"] for p in points) == roof["macs"], f"{name}: roofline MACs do not add up")
    check(0 < roof["macs"] <= nominal_macs, f"{name}: actual MACs {roof['macs']} vs nominal")
    if any(s["kernel"].startswith("upconv") for s in steps):
        check(roof["macs"] < nominal_macs, f"{name}: phase kernels ran but no MACs were saved")
    bandwidth = roof["peaks"]["read_gbytes"]
    check(bandwidth is not None and bandwidth > 0, f"{name}: no read bandwidth")
    floor = 0.0
    for s, p in zip(steps, points):
        what = f"{name} step {s['step']} {s['kernel']}"
        check(p["unit"] == expected_unit(s["kernel"], p["macs"]), f"{what}: unit {p['unit']}")
        moved = p["bytes_read"] + p["bytes_written"] + p["weight_bytes"]
        seconds = s["median_ms"] * 1e-3
        if seconds > 0 and p["achieved_gbytes"] is not None:
            check(close(p["achieved_gbytes"], moved / seconds * 1e-9),
                  f"{what}: achieved GB/s is not its bytes over its median")
        if p["unit"] == "memory":
            check(p["achieved_gmacs"] is None and p["bound"] == "memory", f"{what}: memory step")
            if moved == 0:  # a view
                check(p["share_of_roof"] is None and p["achieved_gbytes"] is None,
                      f"{what}: a view has no rate")
            elif seconds > 0:
                check(close(p["share_of_roof"], p["achieved_gbytes"] / bandwidth),
                      f"{what}: share is not its bandwidth over the read bandwidth")
            floor += moved / (bandwidth * 1e9) * 1e3
            continue
        check(moved > 0, f"{what}: computes on nothing")
        if p["unit"] == "unmeasured":
            check(p["roof_gmacs"] is None and p["share_of_roof"] is None, f"{what}: unmeasured")
            floor = math.nan
            continue
        peak = roof["peaks"][PEAK_OF_UNIT[p["unit"]]]
        check(peak is not None and peak > 0 and close(p["peak_gmacs"], peak),
              f"{what}: peak of its unit")
        want_roof = min(peak, p["macs"] / moved * bandwidth)
        check(close(p["roof_gmacs"], want_roof), f"{what}: roof {p['roof_gmacs']} != {want_roof}")
        check(p["bound"] == ("memory" if want_roof < peak else "compute"), f"{what}: bound")
        if seconds > 0:
            check(close(p["achieved_gmacs"], p["macs"] / seconds * 1e-9), f"{what}: achieved")
            check(close(p["share_of_roof"], p["achieved_gmacs"] / want_roof), f"{what}: share")
        floor += p["macs"] / (want_roof * 1e9) * 1e3
    if not math.isnan(floor):
        check(close(roof["floor_ms"], floor, 1e-5), f"{name}: floor {roof['floor_ms']} != {floor}")
        check(close(roof["median_over_floor"], r["median_ms"] / floor, 1e-5),
              f"{name}: median over floor")
    main_peak = roof["peaks"][PEAK_OF_UNIT.get(roof["main_unit"], "fma_gmacs")]
    if roof["main_unit"] in PEAK_OF_UNIT:
        check(roof["main_peak_gmacs"] == main_peak, f"{name}: main_peak_gmacs")
    if roof["main_unit"] in PEAK_OF_UNIT and main_peak:
        check(close(roof["main_floor_ms"], roof["macs"] / (main_peak * 1e6), 1e-9),
              f"{name}: main floor")


def check_tuning_variants(j, stdout, check):
    """--tuning default --tuning fewout=off: one configuration each, in that order, the variant
    applied (on AVX-512 the output layer leaves its few-output kernel) and the steps compared."""
    tunings = [r.get("tuning") for r in j["results"]]
    check(tunings == ["default", "fewout=off"], f"int8 run: tunings {tunings}")
    if len(j["results"]) != 2:
        return
    default, off = j["results"]
    check(default["isa"] == off["isa"] and default["threads"] == off["threads"],
          "int8 run: the variants differ in more than their tuning")
    if default["isa"].startswith("avx512"):
        k0, k1 = default["steps"][-1]["kernel"], off["steps"][-1]["kernel"]
        check(k0 != k1, f"int8 run: fewout=off left the output layer's kernel {k0}")
    check("steps side by side" in stdout and "(fewout=off)" in stdout,
          "int8 run: no side-by-side step table naming the variant")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--sfrt", required=True)
    p.add_argument("--model", required=True)
    p.add_argument("--work", required=True)
    p.add_argument("--int8-model", help="also check the roofline of this int8 model's run")
    args = p.parse_args()
    os.makedirs(args.work, exist_ok=True)
    out = os.path.join(args.work, "bench.json")
    if os.path.exists(out):
        os.remove(out)
    runs = 4
    cmd = [args.sfrt, "bench", "--model", args.model, "--size", "35x61", "--isa", "all",
           "--threads", "1,2", "--runs", str(runs), "--top", "3", "--peak-seconds", "0.01",
           "--json", out]
    proc = run(cmd)
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
                    "by_op", "top_steps", "per_run", "steps_total_mean_ms", "arena_bytes",
                    "packed_weight_bytes"):
            check(key in r, f"{name}: key {key}")
        check(r["runs"] == runs, f"{name}: runs {r['runs']} != {runs}")
        check(r["median_ms"] <= r["p90_ms"] <= r["p99_ms"] <= r["p999_ms"] <= r["max_ms"],
              f"{name}: percentiles not ordered")
        check(r["stddev_ms"] >= 0, f"{name}: negative stddev")
        check(r["gflops"] > 0 and math.isfinite(r["gflops"]), f"{name}: gflops")
        check(r["peak_gflops"] > 0 and math.isfinite(r["peak_gflops"]), f"{name}: peak_gflops")
        check(r["percent_of_peak"] > 0, f"{name}: percent_of_peak")
        check(r["arena_bytes"] > 0, f"{name}: arena_bytes")
        check((r["packed_weight_bytes"] == 0) == (r["isa"] == "ref"),
              f"{name}: packed_weight_bytes {r['packed_weight_bytes']} on {r['isa']}")
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
        check_roofline(r, j["macs"], name, check)
    if args.int8_model:
        out8 = os.path.join(args.work, "bench-int8.json")
        cmd = [args.sfrt, "bench", "--model", args.int8_model, "--runs", "2", "--warmup", "0",
               "--peak-seconds", "0.01", "--tuning", "default", "--tuning", "fewout=off",
               "--json", out8]
        proc = run(cmd)
        check(proc.returncode == 0, f"int8 run: exit code {proc.returncode}")
        if proc.returncode == 0:
            j8 = json.load(open(out8))
            for r in j8["results"]:
                check_roofline(r, j8["macs"], f'int8 {r["isa"]} x{r["threads"]} {r["tuning"]}',
                               check)
            check("roofline (median per step" in proc.stdout, "int8 run: no roofline table")
            check_tuning_variants(j8, proc.stdout, check)
    for f in failures:
        print("FAIL: " + f)
    if not failures:
        print("OK")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
