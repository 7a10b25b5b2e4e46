#!/usr/bin/python3
"""Write the calibration inputs the `sfrt export --precision` CLI tests read.

usage: make_calibration_npy.py OUTDIR

Writes float32 .npy files of network inputs (values as the models' preprocessing gives them,
smooth seeded images in -2..2) and the broken ones each error test needs, and an empty
directory (no stereo pairs).
"""
import os
import sys

import numpy as np


def frames(n, h, w, c, seed):
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    out = np.empty((n, h, w, c), np.float32)
    for i in range(n):
        for k in range(c):
            fy, fx, phase = rng.uniform(0.05, 0.3, 2).tolist() + [rng.uniform(0, 6.28)]
            out[i, :, :, k] = 1.8 * np.sin(fx * x + fy * y + phase)
    out += rng.uniform(-0.1, 0.1, out.shape).astype(np.float32)
    return np.clip(out, -2.0, 2.0)


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    os.makedirs(os.path.join(out, "no_pairs"), exist_ok=True)
    np.save(os.path.join(out, "cal_4x48x64.npy"), frames(4, 48, 64, 12, 1234))
    np.save(os.path.join(out, "one_48x64.npy"), frames(1, 48, 64, 12, 77)[0])
    nan = frames(2, 48, 64, 12, 5)
    nan[1, 5, 7, 3] = np.nan
    np.save(os.path.join(out, "nan.npy"), nan)
    np.save(os.path.join(out, "channels3.npy"), frames(2, 48, 64, 3, 6))
    np.save(os.path.join(out, "rank2.npy"), frames(1, 48, 64, 1, 7)[0, :, :, 0])
    np.save(os.path.join(out, "constant.npy"), np.full((2, 48, 64, 12), 0.5, np.float32))
    np.save(os.path.join(out, "empty.npy"), np.zeros((0, 48, 64, 12), np.float32))
    np.save(os.path.join(out, "tiny.npy"), frames(1, 3, 5, 12, 8))
    return 0


if __name__ == "__main__":
    sys.exit(main())
