#!/usr/bin/python3
"""Synthesises a held-out sequence with exact ground truth, scores the model on it beside the
zero-flow and classical baselines, and replays it window by window.

    PYTHONPATH=build/release/python python3 examples/python/evaluate_synthetic.py

The sequence comes from `sfrt synth` (the command; the package has no synthesiser), seed 4242, at
the default model's training camera (f 90 px at 96x128, baseline 0.12 m).
"""
import argparse
import os
import subprocess
import tempfile

import numpy as np

import sfrt

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--model", default=os.path.join(ROOT, "models", "sceneednet-default.sfrt"))
    ap.add_argument("--sfrt", default=os.path.join(ROOT, "build", "release", "bin", "sfrt"),
                    help="the sfrt command, for `sfrt synth`")
    ap.add_argument("--frames", type=int, default=6)
    a = ap.parse_args()

    model = sfrt.Model(a.model)
    with tempfile.TemporaryDirectory() as work:
        data = os.path.join(work, "data")
        subprocess.run([a.sfrt, "synth", "--out", data, "--scene", "robot", "--seed", "4242",
                        "--sequences", "1", "--frames", str(a.frames), "--size", "96x128",
                        "--focal", "90", "--baseline", "0.12", "--objects", "4"],
                       check=True, stdout=subprocess.DEVNULL)
        scores = sfrt.evaluate(model, data)
        print("mean 3D end-point error over %d frames (%s):" % (scores["sfrt"]["frames"],
                                                                  scores["thresholds"]))
        for method in ("sfrt", "zero_flow", "classical"):
            print("  %-10s %.4f" % (method, scores[method]["epe3d"]))
        ratio = scores["sfrt"]["epe3d"] / scores["zero_flow"]["epe3d"]
        print("  the model's error is %.2fx zero flow's" % ratio)

        print("windows as `sfrt run` makes them:")
        with sfrt.replay(model, dataset=data) as windows:
            for w in windows:
                print("  %s  frames %d-%d  mean |flow| %.4f" % (
                    w.name, w.sources["frame0"], w.sources["frame1"],
                    float(np.linalg.norm(w.flow, axis=-1).mean())))
            print("%d windows at %.1f a second" % (windows.summary["frames"]["written"],
                                                   windows.summary["fps"]))


if __name__ == "__main__":
    main()
