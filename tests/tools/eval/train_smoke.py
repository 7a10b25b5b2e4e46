#!/usr/bin/python3
"""Smoke test of tools/train/train.py: synthesise a 3-frame tree at 64x96 with `sfrt synth`,
train width/16 for 12 Adam iterations on its 2 samples (the loss must decrease), export to
ONNX and .sfrt, and check the .sfrt loads (`sfrt inspect`) and runs (`sfrt eval`) with
PyTorch's validation EPE. Extra arguments after the options go to train.py (e.g. --arch
sceneednet-u --batch-norm)."""
import argparse
import csv
import json
import os
import shutil
import subprocess
import sys


def run(cmd):
    print("+ " + " ".join(cmd), flush=True)
    rc = subprocess.call(cmd)
    if rc != 0:
        sys.exit(f"train_smoke.py: command failed with exit code {rc}: {' '.join(cmd)}")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--sfrt", required=True)
    p.add_argument("--train-dir", required=True)
    p.add_argument("--work", required=True)
    args, train_extra = p.parse_known_args()
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    tree = os.path.join(args.work, "tree")
    run([args.sfrt, "synth", "--out", tree, "--seed", "5", "--frames", "3", "--size", "64x96",
         "--threads", "1"])
    out = os.path.join(args.work, "run")
    run([sys.executable, os.path.join(args.train_dir, "train.py"), "--data", tree, "--val", tree,
         "--out", out, "--width-div", "16", "--recipe", "adam", "--lr", "2e-3", "--batch", "2",
         "--max-iters", "12", "--log-every", "1", "--val-every", "6", "--export",
         "--export-from", "last", "--sfrt", args.sfrt, "--name", "smoke",
         "--require-decrease"] + train_extra)
    for name in ("log.csv", "checkpoint.pt", "best.pt", "config.json", "model.onnx",
                 "model.sfrt"):
        if not os.path.isfile(os.path.join(out, name)):
            sys.exit(f"train_smoke.py: {name} was not written to {out}")
    run([args.sfrt, "inspect", os.path.join(out, "model.sfrt"), "--size", "64x96"])
    # The runtime on the exported file must score what PyTorch scored on the same frames
    # (train.py's last validation, on the same tree, of the same last weights).
    eval_json = os.path.join(args.work, "eval.json")
    run([args.sfrt, "eval", "--model", os.path.join(out, "model.sfrt"), "--dataset", tree,
         "--quiet", "--no-classical", "--json", eval_json])
    with open(os.path.join(out, "log.csv"), newline="", encoding="utf-8") as f:
        torch_epe = [float(r["val_epe"]) for r in csv.DictReader(f) if r["val_epe"]][-1]
    with open(eval_json, encoding="utf-8") as f:
        sfrt_epe = json.load(f)["sfrt"]["epe3d"]
    print(f"EPE     PyTorch {torch_epe:.6f}, sfrt eval {sfrt_epe:.6f}")
    if abs(torch_epe - sfrt_epe) > 1e-3 * max(torch_epe, 1e-6):
        sys.exit("train_smoke.py: sfrt eval's EPE differs from PyTorch's by more than 0.1%")
    print("ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
