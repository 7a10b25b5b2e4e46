#!/usr/bin/python3
"""Checks train.py's exact geometric augmentations on a real synthetic sample: --vflip mirrors
rows of all twelve image channels and of the flow with dY negated (and nothing else), twice is
the identity, and train.py refuses it when the principal point is off the middle row;
--static-share shows the t images again at t+1 with zero flow."""
import argparse
import os
import shutil
import subprocess
import sys

import numpy as np


def fail(msg):
    sys.exit(f"train_augment_test.py: {msg}")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--sfrt", required=True)
    p.add_argument("--train-dir", required=True)
    p.add_argument("--work", required=True)
    args = p.parse_args()
    sys.dont_write_bytecode = True
    sys.path.insert(0, args.train_dir)
    import torch  # noqa: E402
    import train  # noqa: E402
    import sfdata  # noqa: E402

    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    tree = os.path.join(args.work, "tree")
    subprocess.check_call([args.sfrt, "synth", "--out", tree, "--seed", "9", "--frames", "3",
                           "--size", "32x48", "--threads", "1"], stdout=subprocess.DEVNULL)
    x, y = sfdata.load_tree(tree)
    xb, yb = train.to_input(x), train.to_target(y)
    if xb.shape[0] != 2 or xb.shape[1] != 12:
        fail(f"expected 2 samples of 12 channels, got {tuple(xb.shape)}")
    if float(yb[:, 1].abs().max()) == 0.0:
        fail("the sample has no vertical motion, so a missing sign change would go unseen")

    mask = np.array([True, False])
    mx, my = train.mirror_rows(xb, yb, mask)
    height = xb.shape[2]
    for r in range(height):
        if not torch.equal(mx[0, :, r], xb[0, :, height - 1 - r]):
            fail(f"mirrored image row {r} is not source row {height - 1 - r}")
        for c, sign in ((0, 1.0), (1, -1.0), (2, 1.0)):
            if not torch.equal(my[0, c, r], sign * yb[0, c, height - 1 - r]):
                fail(f"mirrored flow channel {c} row {r}: expected {sign:+g} x source row "
                     f"{height - 1 - r}")
    if not (torch.equal(mx[1], xb[1]) and torch.equal(my[1], yb[1])):
        fail("the unmasked sample changed")
    back_x, back_y = train.mirror_rows(mx, my, mask)
    if not (torch.equal(back_x, xb) and torch.equal(back_y, yb)):
        fail("mirroring twice is not the identity")

    sx, sy = train.still_scene(xb, yb, np.array([False, True]))
    if not (torch.equal(sx[1, 6:12], xb[1, 0:6]) and torch.equal(sx[1, 0:6], xb[1, 0:6])):
        fail("the still sample does not show L0, R0 at t+1")
    if float(sy[1].abs().max()) != 0.0:
        fail("the still sample's flow is not zero")
    if not (torch.equal(sx[0], xb[0]) and torch.equal(sy[0], yb[0])):
        fail("the sample outside the mask changed")

    off = os.path.join(args.work, "off_centre")
    subprocess.check_call([args.sfrt, "synth", "--out", off, "--seed", "9", "--frames", "2",
                           "--size", "32x48", "--cy", "10", "--threads", "1"],
                          stdout=subprocess.DEVNULL)
    res = subprocess.run([sys.executable, os.path.join(args.train_dir, "train.py"), "--data",
                          off, "--out", os.path.join(args.work, "run"), "--vflip",
                          "--max-iters", "1", "--width-div", "16"],
                         capture_output=True, text=True)
    want = "--vflip needs the principal point on the middle row"
    if res.returncode == 0 or want not in res.stderr:
        fail(f"train.py --vflip with cy 10 of 32 rows: exit {res.returncode}, stderr "
             f"{res.stderr.strip()!r}; expected a refusal containing {want!r}")
    print("ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
