#!/usr/bin/env python3
"""Makes tests/data/sceneflow-samples from the Scene Flow sample frames (see README.md here).

Usage: python3 tests/data/make_sceneflow_samples.py SOURCE [--out DIR]

SOURCE is a sceneflow-samples folder holding images/{Driving,Monkaa}/{left,right}/0006-0008.png
(540x960) and disparity/Driving/left/0006.pfm. Every image and the one disparity file the tests
read are cropped to the same 270x480 window: the bottom half, centred horizontally (image rows
270..539, columns 240..719). A crop keeps disparity values valid for the pixels kept; a
downscale would not. The directory layout is kept, so dataset detection sees the same tree.

PFM rows are stored bottom to top: the disparity is flipped to image order, cropped, and flipped
back before it is written; the header keeps the source's spacing (the LMB files' trailing-space
variant "Pf \\n960 540 \\n-1.0\\n"), with the new width and height. Each written file is read back
and compared with the source window.
"""
import argparse
import os
import re
import sys

import numpy as np
from PIL import Image

SOURCE_SIZE = (540, 960)  # HxW of every source file
TOP, LEFT, HEIGHT, WIDTH = 270, 240, 270, 480  # the crop window, image coordinates
SEQUENCES = ("Driving", "Monkaa")
FRAMES = ("0006", "0007", "0008")
DISPARITY = (("Driving", "0006"),)  # the disparity files the tests read


def crop_png(src, dst):
    with Image.open(src) as im:
        if (im.height, im.width) != SOURCE_SIZE or im.mode != "RGB":
            sys.exit("%s: %dx%d %s, expected %dx%d RGB" % (src, im.height, im.width, im.mode,
                                                            *SOURCE_SIZE))
        window = im.crop((LEFT, TOP, LEFT + WIDTH, TOP + HEIGHT))
        window.load()
    window.save(dst, optimize=True)
    with Image.open(dst) as back:
        if not np.array_equal(np.asarray(back), np.asarray(window)):
            sys.exit("%s: read back differs from the crop" % dst)


def split_pfm(data, path):
    """Returns (type line, dims line, scale line, raster offset) of a PFM's three header lines."""
    lines = []
    pos = 0
    for _ in range(3):
        end = data.index(b"\n", pos)
        lines.append(data[pos:end])
        pos = end + 1
    if lines[0].strip() != b"Pf":
        sys.exit("%s: type %r, expected a one-channel 'Pf' file" % (path, lines[0]))
    return lines[0], lines[1], lines[2], pos


def read_pfm_image_order(path):
    """The disparity as an HxW array in image order (top row first), and the header lines."""
    with open(path, "rb") as f:
        data = f.read()
    type_line, dims_line, scale_line, pos = split_pfm(data, path)
    width, height = (int(v) for v in dims_line.split())
    scale = float(scale_line)
    stored = np.frombuffer(data[pos:], dtype="<f4" if scale < 0 else ">f4")
    if stored.size != width * height:
        sys.exit("%s: %d values, expected %dx%d" % (path, stored.size, height, width))
    # Stored bottom row first: flip to image order.
    return np.flipud(stored.reshape(height, width)), (type_line, dims_line, scale_line)


def crop_pfm(src, dst):
    image, (type_line, dims_line, scale_line) = read_pfm_image_order(src)
    if image.shape != SOURCE_SIZE:
        sys.exit("%s: %dx%d, expected %dx%d" % (src, *image.shape, *SOURCE_SIZE))
    window = image[TOP:TOP + HEIGHT, LEFT:LEFT + WIDTH]
    # Same spacing as the source's dims line, new numbers (width first, as PFM stores them).
    numbers = iter((str(WIDTH).encode(), str(HEIGHT).encode()))
    new_dims = re.sub(rb"\d+", lambda _: next(numbers), dims_line)
    dtype = "<f4" if float(scale_line) < 0 else ">f4"
    raster = np.ascontiguousarray(np.flipud(window)).astype(dtype).tobytes()  # bottom row first
    with open(dst, "wb") as f:
        f.write(type_line + b"\n" + new_dims + b"\n" + scale_line + b"\n" + raster)
    back, _ = read_pfm_image_order(dst)
    if not np.array_equal(back, window):
        sys.exit("%s: read back differs from the crop" % dst)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source", help="the sceneflow-samples folder to crop from")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                  "sceneflow-samples"),
                    help="where to write (default: sceneflow-samples beside this script)")
    a = ap.parse_args()
    for seq in SEQUENCES:
        for side in ("left", "right"):
            os.makedirs(os.path.join(a.out, "images", seq, side), exist_ok=True)
            for frame in FRAMES:
                rel = os.path.join("images", seq, side, frame + ".png")
                crop_png(os.path.join(a.source, rel), os.path.join(a.out, rel))
    for seq, frame in DISPARITY:
        os.makedirs(os.path.join(a.out, "disparity", seq, "left"), exist_ok=True)
        rel = os.path.join("disparity", seq, "left", frame + ".pfm")
        crop_pfm(os.path.join(a.source, rel), os.path.join(a.out, rel))
    print("wrote %s (%dx%d window at row %d, column %d)" % (a.out, HEIGHT, WIDTH, TOP, LEFT))
    return 0


if __name__ == "__main__":
    sys.exit(main())
