#!/usr/bin/python3
"""Write small PNG frames for the sfrt CLI tests, and the network input they should produce.

usage: make_test_images.py --out-dir D --height H --width W [--seed S]
                           [--variant FILE.npy:ORDER:COLOR:SCALE:MEAN:STD]...

Writes D/left0.png, right0.png, left1.png, right1.png (H x W, random 8-bit colour) and
D/taller.png (H+1 x W). For each --variant (e.g. "in.npy:L0,R0,L1,R1:BGR:1:0,0,0:1,1,1") it
writes the float32 (H, W, 12) array sfrt should assemble from those images: images in ORDER,
channels in COLOR order (OpenCV reads BGR), value = (pixel * SCALE - MEAN[c]) / STD[c].
The PNG encoder is written here (zlib only) so the test needs nothing beyond numpy.
"""
import argparse
import os
import struct
import sys
import zlib

import numpy as np


def write_png(path, rgb):
    """8-bit RGB PNG (colour type 2), filter 0 on every row."""
    height, width, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[y].tobytes() for y in range(height))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    png = (b"\x89PNG\r\n\x1a\n" +
           chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) +
           chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(png)
    os.replace(tmp, path)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out-dir", required=True)
    p.add_argument("--height", type=int, required=True)
    p.add_argument("--width", type=int, required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--variant", action="append", default=[])
    args = p.parse_args()
    os.makedirs(args.out_dir, exist_ok=True)

    rng = np.random.default_rng(args.seed)
    names = ["left0", "right0", "left1", "right1"]
    images_rgb = {}
    for name in names:
        rgb = rng.integers(0, 256, size=(args.height, args.width, 3), dtype=np.uint8)
        images_rgb[name] = rgb
        write_png(os.path.join(args.out_dir, name + ".png"), rgb)
    taller = rng.integers(0, 256, size=(args.height + 1, args.width, 3), dtype=np.uint8)
    write_png(os.path.join(args.out_dir, "taller.png"), taller)

    slots = {"L0": "left0", "R0": "right0", "L1": "left1", "R1": "right1"}
    for variant in args.variant:
        file_name, order, color, scale, mean, std = variant.split(":")
        scale = np.float32(float(scale))
        mean = np.array([float(v) for v in mean.split(",")], dtype=np.float32)
        std = np.array([float(v) for v in std.split(",")], dtype=np.float32)
        groups = []
        for slot in order.split(","):
            rgb = images_rgb[slots[slot.upper()]]
            pixels = rgb if color.upper() == "RGB" else rgb[:, :, ::-1]  # PNG holds RGB
            groups.append((pixels.astype(np.float32) * scale - mean) / std)
        tensor = np.ascontiguousarray(np.concatenate(groups, axis=2).astype("<f4"))
        np.save(os.path.join(args.out_dir, file_name), tensor)
        print(f"{file_name}: {tensor.shape}, {order}, {color}, scale {scale}, mean {mean}, "
              f"std {std}")
    print(f"wrote 5 PNGs into {args.out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
