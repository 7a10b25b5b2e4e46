#!/usr/bin/python3
"""Runs the default model on one window of stereo frames and shows its scene flow.

    bash tools/demo.sh                      # once: builds sfrt and writes out/demo/data
    PYTHONPATH=build/release/python python3 examples/python/show_flow.py
    ... --save flow.png                     # write the figure instead of opening a window

The figure: the left image at t, the sideways motion (hue = direction, brightness = speed) and
the motion along the optical axis (red: away from the camera, blue: towards it), in the model's
units (metres for the default model).
"""
import argparse
import os

import numpy as np
from PIL import Image

import sfrt

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")


def read_rgb(path):
    return np.asarray(Image.open(path).convert("RGB"))


def sideways_picture(flow):
    """dX, dY as colour: hue the direction, value the speed (scaled to the largest)."""
    import matplotlib.colors as colors
    speed = np.hypot(flow[..., 0], flow[..., 1])
    hue = (np.arctan2(flow[..., 1], flow[..., 0]) / (2 * np.pi)) % 1.0
    value = speed / max(float(speed.max()), 1e-12)
    return colors.hsv_to_rgb(np.stack([hue, np.ones_like(hue), value], axis=-1)), speed.max()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--model", default=os.path.join(ROOT, "models", "sceneednet-default.sfrt"))
    ap.add_argument("--frames", default=os.path.join(ROOT, "out", "demo", "data",
                                                     "frames_cleanpass", "0000"),
                    help="a folder with left/ and right/ images NNNN.png")
    ap.add_argument("--frame", type=int, default=0, help="the window's first frame number")
    ap.add_argument("--save", help="write the figure to this file instead of showing it")
    a = ap.parse_args()

    import matplotlib
    if a.save:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = [os.path.join(a.frames, side, "%04d.png" % n)
             for n in (a.frame, a.frame + 1) for side in ("left", "right")]
    model = sfrt.Model(a.model)
    session = sfrt.Session(model)  # at the size the model was trained at
    flow = session.run(*[read_rgb(p) for p in paths], color="rgb")
    units = model.info["output"]["units"] or "model units"
    print("%s: flow %dx%d, mean |dZ| %.4f %s" % (session, flow.shape[0], flow.shape[1],
                                                  float(np.abs(flow[..., 2]).mean()), units))

    sideways, top = sideways_picture(flow)
    limit = max(float(np.abs(flow[..., 2]).max()), 1e-12)
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    axes[0].imshow(read_rgb(paths[0]))
    axes[0].set_title("left image at t")
    axes[1].imshow(sideways)
    axes[1].set_title("sideways motion (hue: direction; max %.3g %s)" % (top, units))
    shown = axes[2].imshow(flow[..., 2], cmap="coolwarm", vmin=-limit, vmax=limit)
    axes[2].set_title("dZ (red: away, blue: towards)")
    fig.colorbar(shown, ax=axes[2], label=units)
    for ax in axes:
        ax.axis("off")
    fig.tight_layout()
    if a.save:
        fig.savefig(a.save, dpi=100)
        print("wrote " + a.save)
    else:
        plt.show()


if __name__ == "__main__":
    main()
