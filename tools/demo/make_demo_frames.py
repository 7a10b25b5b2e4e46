#!/usr/bin/python3
"""Write four small procedural stereo frames for the sfrt demo.

Output (default: frames/ next to this script): left0.png, right0.png, left1.png, right1.png,
8-bit RGB PNGs of 224x128 pixels (W x H). Read with OpenCV (cv::imread) they come back in BGR
order, like the authors' training data.

The scene is a rectified stereo pair seen at two times: a far textured background (small
disparity, static) and a near textured rectangle (larger disparity) that moves right and down
and comes closer (its disparity grows) between t0 and t1. A point at column x in the left
image appears at column x - d in the right image. Output is fully deterministic; only numpy,
zlib and struct are used (the PNG encoder is below).
"""

import argparse
import os
import struct
import sys
import zlib

import numpy as np

HEIGHT, WIDTH = 128, 224
SEED = 20180709  # arXiv 1807.03464

BACKGROUND_DISPARITY = 4  # pixels, both times (static background, static camera)
# Rectangle in the LEFT image: (top, left, height, width, disparity) at t0 and t1.
RECT_T0 = (36, 72, 48, 76, 14)
RECT_T1 = (42, 84, 48, 76, 17)


# ------------------------------------------------------------------------------ textures

def _value_noise(rng, cells_y, cells_x):
    """A periodic lattice of random values in [0,1] and a sampler with bilinear smoothing."""
    grid = rng.random((cells_y, cells_x))

    def sample(y, x, cell):
        gy = y / cell
        gx = x / cell
        y0 = np.floor(gy).astype(np.int64)
        x0 = np.floor(gx).astype(np.int64)
        fy = gy - y0
        fx = gx - x0
        # Smoothstep weights for softer cell borders.
        fy = fy * fy * (3 - 2 * fy)
        fx = fx * fx * (3 - 2 * fx)
        y0m, y1m = y0 % cells_y, (y0 + 1) % cells_y
        x0m, x1m = x0 % cells_x, (x0 + 1) % cells_x
        top = grid[y0m, x0m] * (1 - fx) + grid[y0m, x1m] * fx
        bot = grid[y1m, x0m] * (1 - fx) + grid[y1m, x1m] * fx
        return top * (1 - fy) + bot * fy

    return sample


class Textures:
    def __init__(self, seed):
        rng = np.random.default_rng(seed)
        self.bg_coarse = _value_noise(rng, 16, 32)
        self.bg_fine = _value_noise(rng, 64, 64)
        self.fg_coarse = _value_noise(rng, 16, 16)
        self.fg_fine = _value_noise(rng, 64, 64)

    def background(self, y, x):
        """RGB float in 0..255 at scene coordinates (y, x) of the far plane."""
        c = self.bg_coarse(y, x, 24.0)
        f = self.bg_fine(y, x, 4.0)
        stripes = 0.5 + 0.5 * np.sin(x * 0.21 + 2.0 * np.sin(y * 0.05))
        sky = np.clip(1.2 - y / HEIGHT, 0.0, 1.0)  # lighter at the top
        r = 70 + 90 * c + 30 * f + 25 * stripes * (1 - sky)
        g = 90 + 70 * c + 30 * f + 40 * sky
        b = 110 + 50 * c + 25 * f + 60 * sky
        return np.stack([r, g, b], axis=-1)

    def rectangle(self, v, u):
        """RGB float in 0..255 at object-local coordinates (row v, column u)."""
        c = self.fg_coarse(v, u, 10.0)
        f = self.fg_fine(v, u, 3.0)
        checker = ((np.floor(v / 8) + np.floor(u / 8)) % 2)
        r = 150 + 60 * checker + 30 * c + 15 * f
        g = 60 + 50 * c + 20 * f + 20 * checker
        b = 40 + 40 * c + 15 * f
        return np.stack([r, g, b], axis=-1)


# ------------------------------------------------------------------------------ scene

def render(tex, rect, right_view):
    """One view of the scene as uint8 (H, W, 3) RGB."""
    top, left, h, w, disp = rect
    ys, xs = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float64)
    # A right-image pixel at column x sees the scene point at left-image column x + d.
    bg_shift = BACKGROUND_DISPARITY if right_view else 0
    img = tex.background(ys, xs + bg_shift)

    rect_left = left - disp if right_view else left
    inside = (ys >= top) & (ys < top + h) & (xs >= rect_left) & (xs < rect_left + w)
    v = ys - top
    u = xs - rect_left
    fg = tex.rectangle(v, u)
    border = inside & ((v < 2) | (v >= h - 2) | (u < 2) | (u >= w - 2))
    fg[border] = (30.0, 25.0, 20.0)
    img = np.where(inside[..., None], fg, img)

    # Mild shading shared by both views (a vignette), so the images are not flat-lit.
    cy, cx = (HEIGHT - 1) / 2.0, (WIDTH - 1) / 2.0
    vign = 1.0 - 0.25 * (((ys - cy) / HEIGHT) ** 2 + ((xs - cx) / WIDTH) ** 2) * 2.0
    img = img * vign[..., None]
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


# ------------------------------------------------------------------------------ PNG

def _chunk(kind, data):
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)


def _filter_rows(img):
    """PNG filtering (types 0..4), choosing per row the minimum sum of |signed bytes|."""
    h = img.shape[0]
    bpp = img.shape[2]
    rows = img.reshape(h, -1).astype(np.int16)
    out = bytearray()
    prev = np.zeros_like(rows[0])
    for r in range(h):
        cur = rows[r]
        a = np.concatenate([np.zeros(bpp, np.int16), cur[:-bpp]])
        b = prev
        c = np.concatenate([np.zeros(bpp, np.int16), prev[:-bpp]])
        p = a + b - c
        pa, pb, pc = np.abs(p - a), np.abs(p - b), np.abs(p - c)
        paeth = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))
        candidates = (cur, cur - a, cur - b, cur - ((a + b) // 2), cur - paeth)
        best_type, best_bytes, best_cost = 0, None, None
        for ftype, cand in enumerate(candidates):
            data = (cand % 256).astype(np.uint8)
            cost = int(np.abs(data.astype(np.int8).astype(np.int32)).sum())
            if best_cost is None or cost < best_cost:
                best_type, best_bytes, best_cost = ftype, data, cost
        out.append(best_type)
        out += best_bytes.tobytes()
        prev = cur
    return bytes(out)


def write_png(path, img):
    """Write a uint8 (H, W, 3) RGB image as an 8-bit truecolor, non-interlaced PNG."""
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
        raise ValueError("write_png expects a uint8 (H, W, 3) array")
    h, w, _ = img.shape
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    idat = zlib.compress(_filter_rows(img), 9)
    data = b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", idat) + \
        _chunk(b"IEND", b"")
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(data)
    os.replace(tmp, path)
    return len(data)


# ------------------------------------------------------------------------------ main

def main(argv=None):
    default_out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "frames")
    p = argparse.ArgumentParser(description="Write the demo's four procedural stereo frames "
                                "(left0/right0/left1/right1.png, 224x128 RGB PNG).")
    p.add_argument("--out-dir", default=default_out,
                   help=f"output directory (default {default_out})")
    args = p.parse_args(argv)
    try:
        os.makedirs(args.out_dir, exist_ok=True)
    except OSError as exc:
        sys.exit(f"make_demo_frames.py: cannot create {args.out_dir!r}: {exc}")

    tex = Textures(SEED)
    for t, rect in ((0, RECT_T0), (1, RECT_T1)):
        for side in ("left", "right"):
            img = render(tex, rect, right_view=(side == "right"))
            path = os.path.join(args.out_dir, f"{side}{t}.png")
            size = write_png(path, img)
            print(f"{path}: {WIDTH}x{HEIGHT}, {size} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
