#!/usr/bin/python3
"""Run `sfrt bench --peak --json` and check the JSON's structure (never its rates).

usage: bench_peak_json_check.py --sfrt BIN --work DIR

Checks: one fp32 row per ISA and thread count; peak_int8, peak_int16, peak_bf16 and the AMX types
have one row per thread count with positive rates, GMAC/s = half the ops and the instruction
named, or none and a reason in peak_unavailable;
peak_unavailable names amx with a reason unless AMX could run; peak_read_bandwidth has one row
per thread count with a positive rate over a buffer of at least 256 MiB; build and cpu metadata.
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
    p.add_argument("--work", required=True)
    args = p.parse_args()
    os.makedirs(args.work, exist_ok=True)
    out = os.path.join(args.work, "peak.json")
    if os.path.exists(out):
        os.remove(out)
    cmd = [args.sfrt, "bench", "--peak", "--isa", "ref", "--threads", "1,2", "--peak-seconds",
           "0.01", "--json", out]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
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
    for key in ("peak", "peak_int8", "peak_int16", "peak_bf16", "peak_amx_int8", "peak_amx_bf16",
                "peak_unavailable", "build", "cpu"):
        check(key in j, f"top-level key {key}")
    if failures:
        print("FAIL: " + "; ".join(failures))
        return 1
    check([(r["isa"], r["threads"]) for r in j["peak"]] == [("ref", 1), ("ref", 2)],
          "peak: one ref row per thread count")
    unavailable = j["peak_unavailable"]
    for name, ops, instruction in (("int8", "gops", "vpdpbusd"), ("int16", "gops", "vpdpwssd"),
                                   ("bf16", "gflops", "vdpbf16ps"),
                                   ("amx_int8", "gops", "tdpbusd"),
                                   ("amx_bf16", "gflops", "tdpbf16ps")):
        rows = j["peak_" + name]
        if name in unavailable:
            check(rows == [], f"peak_{name}: rows although unavailable")
            check(unavailable[name] != "", f"peak_unavailable.{name}: empty reason")
            check(f"peak {name} dot-product throughput: not available ("
                  + unavailable[name] + ")" in proc.stdout, f"{name}: reason not printed")
            continue
        check([r["threads"] for r in rows] == [1, 2], f"peak_{name}: one row per thread count")
        for r in rows:
            for key in ("threads", ops, "gmacs", ops + "_per_thread", "kernel"):
                check(key in r, f"peak_{name}: key {key}")
            if ops not in r or "gmacs" not in r:
                continue
            check(r[ops] > 0 and math.isfinite(r[ops]), f"peak_{name}: {ops} not positive")
            check(math.isclose(r["gmacs"], r[ops] / 2), f"peak_{name}: gmacs != {ops} / 2")
            check(instruction in r.get("kernel", ""), f"peak_{name}: kernel names {instruction}")
    if "amx" in unavailable:
        check("amx: not available (" + unavailable["amx"] + ")" in proc.stdout,
              "amx: reason not printed")
    else:
        check("amx: available" in proc.stdout, "amx: neither available nor a reason")
    # The read bandwidth: one row per thread count, a positive rate over the whole buffer.
    bandwidth = j.get("peak_read_bandwidth", [])
    check([r["threads"] for r in bandwidth] == [1, 2], "peak_read_bandwidth: a row per thread count")
    for r in bandwidth:
        check(r["gbytes_per_second"] > 0 and math.isfinite(r["gbytes_per_second"]),
              "peak_read_bandwidth: rate not positive")
        check(math.isclose(r["gbytes_per_second_per_thread"], r["gbytes_per_second"] / r["threads"]),
              "peak_read_bandwidth: per thread != rate / threads")
        check(r["buffer_mib"] >= 256, "peak_read_bandwidth: buffer below 256 MiB")
    check("peak read bandwidth" in proc.stdout, "read bandwidth table not printed")
    check(j["cpu"]["model"] != "", "cpu.model empty")
    for f in failures:
        print("FAIL: " + f)
    if failures:
        return 1
    print("OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
