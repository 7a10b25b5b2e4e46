"""Readers for the Scene Flow dataset layout (as `sfrt synth` writes it), in pure Python + numpy.

No OpenCV in Debian's Python here, so PNG and PFM are decoded by the small readers below
(zlib + numpy; 8-bit greyscale/RGB/RGBA, non-interlaced, as OpenCV's imwrite writes them).

Layout (tools/synth/dataset.h):
  DIR/camera.json                                       focal, baseline, cx, cy
  DIR/frames_cleanpass/<seq>/{left,right}/NNNN.png      8-bit images
  DIR/scene_flow/<seq>/into_future/left/NNNN.pfm        dX, dY, dZ ground truth (scene units)
A sample is frame t of a sequence whose frame t+1 images exist: input left(t), right(t),
left(t+1), right(t+1) (BGR, as OpenCV reads them), target the scene flow of frame t.
"""

import json
import os
import struct
import zlib

import numpy as np

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _unfilter(raw, height, width, bpp):
    """Undoes PNG's per-row filters; returns uint8 (height, width * bpp)."""
    stride = width * bpp
    out = np.zeros((height, stride), dtype=np.uint8)
    prev = np.zeros(stride, dtype=np.int32)
    pos = 0
    for y in range(height):
        ftype = raw[pos]
        line = np.frombuffer(raw, dtype=np.uint8, count=stride, offset=pos + 1).astype(np.int32)
        pos += 1 + stride
        if ftype == 0:  # None
            cur = line
        elif ftype == 1:  # Sub: cumulative sum per channel, modulo 256
            cur = np.cumsum(line.reshape(width, bpp), axis=0).reshape(-1) & 0xFF
        elif ftype == 2:  # Up
            cur = (line + prev) & 0xFF
        elif ftype in (3, 4):  # Average, Paeth: sequential along the row
            cur_list = [0] * stride
            ln = line.tolist()
            pv = prev.tolist()
            for i in range(stride):
                a = cur_list[i - bpp] if i >= bpp else 0
                b = pv[i]
                if ftype == 3:
                    cur_list[i] = (ln[i] + ((a + b) >> 1)) & 0xFF
                else:
                    c = pv[i - bpp] if i >= bpp else 0
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pred = a if (pa <= pb and pa <= pc) else (b if pb <= pc else c)
                    cur_list[i] = (ln[i] + pred) & 0xFF
            cur = np.array(cur_list, dtype=np.int32)
        else:
            raise ValueError(f"PNG row {y}: unknown filter type {ftype}")
        out[y] = cur
        prev = cur
    return out


def read_png(path):
    """8-bit PNG -> uint8 array (H, W, C) in the file's channel order (RGB/RGBA/grey)."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != _PNG_SIGNATURE:
        raise ValueError(f"{path}: not a PNG file (bad signature)")
    pos = 8
    idat = []
    header = None
    while pos < len(data):
        length, ctype = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if ctype == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif ctype == b"IDAT":
            idat.append(body)
        elif ctype == b"IEND":
            break
    if header is None:
        raise ValueError(f"{path}: no IHDR chunk")
    width, height, depth, color, _, _, interlace = header
    channels = {0: 1, 2: 3, 6: 4}.get(color)
    if depth != 8 or channels is None or interlace != 0:
        raise ValueError(f"{path}: unsupported PNG (bit depth {depth}, color type {color}, "
                         f"interlace {interlace}); 8-bit grey/RGB/RGBA, non-interlaced only")
    raw = zlib.decompress(b"".join(idat))
    if len(raw) != height * (1 + width * channels):
        raise ValueError(f"{path}: image data has {len(raw)} bytes, expected "
                         f"{height * (1 + width * channels)}")
    return _unfilter(raw, height, width, channels).reshape(height, width, channels)


def read_image_bgr(path):
    """uint8 (H, W, 3) in BGR order, as OpenCV's imread(IMREAD_COLOR) gives it."""
    img = read_png(path)
    if img.shape[2] == 1:
        img = np.repeat(img, 3, axis=2)
    return np.ascontiguousarray(img[:, :, 2::-1])


def read_pfm(path):
    """PFM -> float32 (H, W, C), rows top to bottom. Accepts any whitespace in the header."""
    with open(path, "rb") as f:
        data = f.read()
    fields = []
    pos = 0
    while len(fields) < 4:
        while pos < len(data) and data[pos:pos + 1].isspace():
            pos += 1
        start = pos
        while pos < len(data) and not data[pos:pos + 1].isspace():
            pos += 1
        if start == pos:
            raise ValueError(f"{path}: truncated PFM header")
        fields.append(data[start:pos].decode("ascii"))
    # The scale line ends with a newline, after which the pixels start.
    while pos < len(data) and data[pos:pos + 1] != b"\n":
        pos += 1
    pos += 1
    kind, width, height, scale = fields[0], int(fields[1]), int(fields[2]), float(fields[3])
    channels = {"PF": 3, "Pf": 1}.get(kind)
    if channels is None:
        raise ValueError(f"{path}: PFM type '{kind}' is neither PF nor Pf")
    dtype = "<f4" if scale < 0 else ">f4"
    count = width * height * channels
    arr = np.frombuffer(data, dtype=dtype, count=count, offset=pos)
    return np.ascontiguousarray(arr.reshape(height, width, channels)[::-1]).astype(np.float32)


def read_camera(root):
    """focal, baseline, cx, cy from DIR/camera.json."""
    with open(os.path.join(root, "camera.json"), "r", encoding="utf-8") as f:
        cam = json.load(f)
    return {k: float(cam[k]) for k in ("focal", "baseline", "cx", "cy")}


def list_samples(root):
    """[(seq, frame)] with both images at t and t+1 and the scene flow of t present."""
    frames_dir = os.path.join(root, "frames_cleanpass")
    if not os.path.isdir(frames_dir):
        raise FileNotFoundError(f"{root}: no 'frames_cleanpass' directory")
    samples = []
    for seq in sorted(os.listdir(frames_dir)):
        left = os.path.join(frames_dir, seq, "left")
        if not os.path.isdir(left):
            continue
        names = sorted(n for n in os.listdir(left) if n.endswith(".png"))
        have = set(names)
        for n in names:
            stem = n[:-4]
            if not stem.isdigit():
                continue
            nxt = f"{int(stem) + 1:0{len(stem)}d}.png"
            flow = os.path.join(root, "scene_flow", seq, "into_future", "left", stem + ".pfm")
            if nxt in have and os.path.isfile(flow):
                samples.append((seq, stem))
    return samples


def load_sample(root, seq, stem, cache=None):
    """(input uint8 (H, W, 12) as L0,R0,L1,R1 BGR, target float32 (H, W, 3))."""
    nxt = f"{int(stem) + 1:0{len(stem)}d}"

    def img(side, frame):
        path = os.path.join(root, "frames_cleanpass", seq, side, frame + ".png")
        if cache is None:
            return read_image_bgr(path)
        if path not in cache:
            cache[path] = read_image_bgr(path)
        return cache[path]

    x = np.concatenate([img("left", stem), img("right", stem), img("left", nxt),
                        img("right", nxt)], axis=2)
    y = read_pfm(os.path.join(root, "scene_flow", seq, "into_future", "left", stem + ".pfm"))
    if y.shape[:2] != x.shape[:2] or y.shape[2] != 3:
        raise ValueError(f"{root}/{seq}/{stem}: scene flow shape {y.shape} does not match the "
                         f"images {x.shape}")
    return x, y


def load_tree(root):
    """All samples of one tree: (inputs uint8 (N, H, W, 12), targets float32 (N, H, W, 3))."""
    samples = list_samples(root)
    if not samples:
        raise ValueError(f"{root}: no frame has images at t and t+1 and scene_flow at t")
    cache = {}
    xs, ys = [], []
    for seq, stem in samples:
        x, y = load_sample(root, seq, stem, cache)
        # Images of frame t are reused as the t+1 images of the previous sample only.
        for key in [k for k in cache if os.sep + stem + ".png" in k]:
            del cache[key]
        xs.append(x)
        ys.append(y)
    return np.stack(xs), np.stack(ys)
