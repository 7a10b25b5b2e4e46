#!/usr/bin/python3
"""Compare an sfrt output with a reference array.

usage: compare_npy.py ACTUAL EXPECTED [--rel-tol 1e-4]

ACTUAL and EXPECTED are .npy (float32) or .pfm files (PFM rows are flipped to top-to-bottom).
Prints the maximum absolute error and that error relative to the reference's largest |value|;
exits 1 if the shapes differ, ACTUAL has non-finite values, or the relative error exceeds the
tolerance.
"""
import argparse
import sys

import numpy as np


def load(path):
    if path.lower().endswith(".pfm"):
        with open(path, "rb") as f:
            kind = f.readline().strip()
            width, height = (int(v) for v in f.readline().split())
            scale = float(f.readline().strip())
            data = np.fromfile(f, dtype="<f4" if scale < 0 else ">f4")
        channels = 3 if kind == b"PF" else 1
        image = data.reshape(height, width, channels)[::-1]
        return image if channels == 3 else image[:, :, 0]
    return np.load(path)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("actual")
    p.add_argument("expected")
    p.add_argument("--rel-tol", type=float, default=1e-4)
    args = p.parse_args()

    actual = load(args.actual)
    expected = load(args.expected)
    print(f"actual   {args.actual}: shape {actual.shape} dtype {actual.dtype}")
    print(f"expected {args.expected}: shape {expected.shape} dtype {expected.dtype}")
    if actual.shape != expected.shape:
        print(f"FAIL: shapes differ: {actual.shape} vs {expected.shape}")
        return 1
    if not np.isfinite(actual).all():
        print(f"FAIL: actual has {np.size(actual) - np.isfinite(actual).sum()} non-finite values")
        return 1
    a = actual.astype(np.float64)
    e = expected.astype(np.float64)
    max_abs = float(np.max(np.abs(a - e))) if a.size else 0.0
    ref_scale = float(np.max(np.abs(e))) if e.size else 0.0
    rel = max_abs / ref_scale if ref_scale > 0 else max_abs
    print(f"max abs error {max_abs:.3e}, reference max |value| {ref_scale:.6g}, "
          f"max error relative to it {rel:.3e} (tolerance {args.rel_tol:.1e})")
    if rel > args.rel_tol:
        worst = np.unravel_index(np.argmax(np.abs(a - e)), a.shape)
        print(f"FAIL: worst at index {tuple(int(i) for i in worst)}: "
              f"actual {a[worst]:.8g}, expected {e[worst]:.8g}")
        return 1
    print("OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
