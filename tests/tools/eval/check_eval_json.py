#!/usr/bin/python3
"""Checks the schema of `sfrt eval --json` output: one object per method with the metrics; with
--max-ratio R also that the model's EPE3D is at most R times zero flow's (a trained model's
accuracy, so a broken export or kernel shows)."""
import argparse
import json
import math
import sys

KEYS = ("epe3d", "epe_x", "epe_y", "epe_z", "acc05", "acc10", "outliers", "valid_pixels",
        "frames", "sequences")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("json")
    p.add_argument("--methods", nargs="+", required=True)
    p.add_argument("--frames", type=int, required=True)
    p.add_argument("--max-ratio", type=float, default=None,
                   help="fail unless sfrt's EPE3D / zero_flow's EPE3D is at most this")
    args = p.parse_args()
    with open(args.json, encoding="utf-8") as f:
        doc = json.load(f)
    problems = []
    for top in ("dataset", "camera", "frames", "definitions"):
        if top not in doc:
            problems.append(f"missing top-level key {top!r}")
    if doc.get("frames") != args.frames:
        problems.append(f"frames is {doc.get('frames')}, expected {args.frames}")
    for method in args.methods:
        m = doc.get(method)
        if not isinstance(m, dict):
            problems.append(f"missing method object {method!r}")
            continue
        for key in KEYS:
            if key not in m:
                problems.append(f"{method}: missing {key!r}")
        for key in ("epe3d", "acc05", "acc10", "outliers"):
            v = m.get(key)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                problems.append(f"{method}.{key} = {v!r} is not a finite number >= 0")
        for key in ("acc05", "acc10", "outliers"):
            v = m.get(key, 0)
            if isinstance(v, (int, float)) and v > 1:
                problems.append(f"{method}.{key} = {v} is a share and must be <= 1")
        seqs = m.get("sequences", {})
        if not seqs or any("epe3d" not in s for s in seqs.values()):
            problems.append(f"{method}: sequences missing or without epe3d")
    if args.max_ratio is not None and not problems:
        ratio = doc["sfrt"]["epe3d"] / doc["zero_flow"]["epe3d"]
        print(f"sfrt EPE3D {doc['sfrt']['epe3d']:.5f} / zero flow {doc['zero_flow']['epe3d']:.5f}"
              f" = {ratio:.3f} (at most {args.max_ratio:g})")
        if not ratio <= args.max_ratio:
            problems.append(f"sfrt / zero flow = {ratio:.3f} is above {args.max_ratio:g}")
    for line in problems:
        print(line)
    print("ok" if not problems else f"{len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
