#!/usr/bin/python3
"""A network of two RGB-D frames end to end: a PyTorch network with 8 input channels exported to
ONNX goes through `sfrt export --input-kind rgbd` (colour order, pixel normalisation and depth
normalisation stated), `sfrt inspect` reports the frames, and `sfrt infer --color0 --depth0
--color1 --depth1` on PNG colour images, a 16-bit PNG depth map in millimetres and a float32 .npy
depth map in metres (both with missing depths) matches PyTorch on the input built here from the
model file's formulas, within 1e-4 of the output's largest magnitude. A depth map of another size
is refused, naming both files. A stereo-pair command line
for the RGB-D model is refused, naming the flags it needs, and `sfrt run` and `sfrt eval` (which
read stereo pairs) refuse the model, saying what reads it.

usage: rgbd_check.py --sfrt BIN --work DIR
"""
import argparse
import os
import re
import shutil
import struct
import subprocess
import sys
import zlib

import numpy as np
import torch
from torch import nn

H, W = 29, 43
SCALE, MEAN, STD = 1 / 255, (0.4, 0.5, 0.6), (0.25, 0.3, 0.2)
DEPTH_MEAN, DEPTH_STD, DEPTH_INVALID = 2.0, 1.5, -1.0


class Net(nn.Module):
    def __init__(self):
        super().__init__()
        self.conv0 = nn.Conv2d(8, 16, 3, stride=2, padding=1)
        self.conv1 = nn.Conv2d(16, 3, 3, padding=1)

    def forward(self, x):
        h, w = x.shape[2], x.shape[3]
        y = nn.functional.leaky_relu(self.conv0(x), 0.3)
        y = nn.functional.interpolate(y, scale_factor=2, mode="nearest")
        return self.conv1(y)[:, :, :h, :w]


def write_png(path, pixels):
    """uint8 (H, W, 3) as 8-bit RGB, or uint16 (H, W) as 16-bit grey, non-interlaced."""
    if pixels.dtype == np.uint8:
        color, depth, rows = 2, 8, pixels.reshape(pixels.shape[0], -1)
    else:
        color, depth, rows = 0, 16, pixels.astype(">u2").view(np.uint8)
    raw = b"".join(b"\x00" + row.tobytes() for row in rows)

    def chunk(kind, body):
        return (struct.pack(">I", len(body)) + kind + body +
                struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))

    header = struct.pack(">IIBBBBB", pixels.shape[1], pixels.shape[0], depth, color, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) +
                chunk(b"IEND", b""))


def run(args, want_exit=0):
    p = subprocess.run(args, capture_output=True, text=True)
    if p.returncode != want_exit:
        print(p.stdout + p.stderr)
        sys.exit("%s exited %d, expected %d" % (" ".join(args[:2]), p.returncode, want_exit))
    return p


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    torch.manual_seed(5)
    rng = np.random.default_rng(5)
    net = Net().eval()
    onnx_path = os.path.join(a.work, "rgbd.onnx")
    torch.onnx.export(net, torch.zeros(1, 8, H, W), onnx_path, opset_version=13,
                      input_names=["rgbd_frames"], output_names=["flow"])
    model = os.path.join(a.work, "rgbd.sfrt")
    run([a.sfrt, "export", onnx_path, "-o", model, "--input-kind", "rgbd", "--color-order", "RGB",
         "--scale", repr(SCALE), "--mean", ",".join(map(str, MEAN)), "--std",
         ",".join(map(str, STD)), "--depth-mean", str(DEPTH_MEAN), "--depth-std", str(DEPTH_STD),
         "--depth-invalid", str(DEPTH_INVALID)])
    failed = []
    shown = run([a.sfrt, "inspect", model]).stdout
    for want in (r"kind +RGB-D frames", r"image order +color0,depth0,color1,depth1",
                 r"depth value +\(metres - 2\) / 1\.5, missing depth \(0\) as -1"):
        if not re.search(want, shown):
            failed.append("sfrt inspect does not show /%s/:\n%s" % (want, shown))

    # Two frames: BGR colour (as OpenCV reads it), depth0 in millimetres as 16-bit PNG, depth1 in
    # metres as float32 .npy; both with missing depths.
    bgr = [rng.integers(0, 256, (H, W, 3), dtype=np.uint8) for _ in range(2)]
    depth_mm = rng.integers(300, 9000, (H, W)).astype(np.uint16)
    depth_mm[::5, ::3] = 0
    depth_m = rng.uniform(0.3, 9.0, (H, W)).astype(np.float32)
    depth_m[1::4, ::5] = 0.0
    depth_m[2, 7] = np.nan
    depth_m[3, 8] = -2.0
    files = {}
    for i, img in enumerate(bgr):
        files["color%d" % i] = os.path.join(a.work, "color%d.png" % i)
        write_png(files["color%d" % i], img[:, :, ::-1])  # PNG stores RGB
    files["depth0"] = os.path.join(a.work, "depth0.png")
    write_png(files["depth0"], depth_mm)
    files["depth1"] = os.path.join(a.work, "depth1.npy")
    np.save(files["depth1"], depth_m)
    out = os.path.join(a.work, "flow.npy")
    p = run([a.sfrt, "infer", "--model", model, "--color0", files["color0"], "--depth0",
             files["depth0"], "--color1", files["color1"], "--depth1", files["depth1"],
             "--depth-units", "1000", "-o", out])
    if "2 RGB-D frames as color0,depth0,color1,depth1" not in p.stdout:
        failed.append("sfrt infer does not report the RGB-D input:\n" + p.stdout)

    # The input as the model file prescribes, computed here in float64.
    def colour(img):
        rgb = img[:, :, ::-1].astype(np.float64)
        return (rgb * SCALE - np.array(MEAN)) / np.array(STD)

    def depth(metres):
        ok = np.isfinite(metres) & (metres > 0)
        return np.where(ok, (np.nan_to_num(metres) - DEPTH_MEAN) / DEPTH_STD, DEPTH_INVALID)

    x = np.concatenate([colour(bgr[0]), depth(depth_mm / 1000.0)[:, :, None], colour(bgr[1]),
                        depth(depth_m.astype(np.float64))[:, :, None]], axis=2)
    with torch.no_grad():
        want = net.double()(torch.from_numpy(x).permute(2, 0, 1)[None])[0].permute(1, 2, 0)
    want = want.numpy()
    got = np.load(out)
    if got.shape != want.shape:
        failed.append("output shape %s, PyTorch %s" % (got.shape, want.shape))
    else:
        err = float(np.abs(got - want).max())
        scale = float(np.abs(want).max())
        print("max |sfrt - torch| = %.3g, max |torch| = %.3g, ratio %.3g" % (err, scale,
                                                                           err / scale))
        if not err <= 1e-4 * scale:
            failed.append("max |sfrt - torch| %.3g over 1e-4 x %.3g" % (err, scale))

    # Stereo images for an RGB-D model: refused before anything is read.
    p = run([a.sfrt, "infer", "--model", model, "--left0", files["color0"], "--right0",
             files["color0"], "--left1", files["color1"], "--right1", files["color1"], "-o", out],
            want_exit=2)
    if "reads two RGB-D frames: give --color0 --depth0 --color1 --depth1" not in p.stderr:
        failed.append("the stereo command line was not refused as expected:\n" + p.stderr)
    # A depth map of another size than the colour images: refused, naming both files.
    small = os.path.join(a.work, "small-depth.npy")
    np.save(small, depth_m[:-1])
    p = run([a.sfrt, "infer", "--model", model, "--color0", files["color0"], "--depth0",
             files["depth0"], "--color1", files["color1"], "--depth1", small, "-o", out],
            want_exit=1)
    if not re.search(r"--depth1 '.*small-depth\.npy' is %dx%d but --color0 '.*color0\.png' is "
                     r"%dx%d \(both frames' colour and depth must have the same size\)"
                     % (H - 1, W, H, W), p.stderr):
        failed.append("a depth map of another size was not refused as expected:\n" + p.stderr)

    # sfrt run and sfrt eval read stereo pairs: they refuse the model, saying what reads it.
    stereo = os.path.join(a.work, "stereo")
    run([a.sfrt, "synth", "--out", stereo, "--frames", "2", "--size", "32x48"])
    for command in (["run", "--model", model, "--replay", stereo, "--out",
                     os.path.join(a.work, "run")],
                    ["eval", "--model", model, "--dataset", stereo]):
        p = run([a.sfrt] + command, want_exit=1)
        if "reads two RGB-D frames" not in p.stderr or "sfrt infer --color0" not in p.stderr:
            failed.append("sfrt %s did not refuse the RGB-D model as expected:\n%s"
                          % (command[0], p.stderr))
    for f in failed:
        print("FAIL: " + f)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
