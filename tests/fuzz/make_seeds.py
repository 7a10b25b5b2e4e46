#!/usr/bin/python3
"""Generate the seed corpora of the fuzz targets from valid files.

Writes OUT_DIR/<target>/ for every target of tests/fuzz:
  model_load, model_session  .sfrt files from sfrt_fuzz_make_model_seeds (SceneEDNet at 1/16 and
                             1/64 width, fp16 weights, an explicit-padding/crop chain,
                             SceneEDNet-U at 1/64 width with a residual Add: a graph)
  onnx_import                SceneEDNet ONNX at 1/64 width, 16x16, from
                             tests/fixtures/gen_sceneednet.py (tf and torch padding, opset 11
                             without constant folding)
  keras_import               Keras 2 .h5 files from tests/fixtures/gen_keras_h5.py (the 1/16-width
                             ones and the Sequential one; the malformed bad_*.h5 ones too)
  pfm, npy                   small images/arrays in every accepted variant
  calibration                ROS camera_info pair, Kalibr camchain, OpenCV FileStorage YAML/XML,
                             each behind its reader-selector byte (calibration_fuzzer.cc)
  image                      small PNG (8-bit RGB, grey, 16-bit, palette, RGBA), PPM and PGM
                             frames behind the selector byte of image_fuzzer.cc
  profile                    the shipped deployment profiles firmware-cfg/*.yaml
Run with Debian's /usr/bin/python3 (torch, onnx, numpy, h5py).
Usage: make_seeds.py --out-dir DIR --model-seeds BIN [--work-dir DIR]
"""

import argparse
import io
import os
import shutil
import struct
import subprocess
import sys
import zlib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
FIXTURES = os.path.join(HERE, "..", "fixtures")
SPLIT = b"\n---8<---\n"


def write(path, data):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "wb") as f:
        f.write(data)


def npy_bytes(array, version=(1, 0)):
    header = "{'descr': '<f4', 'fortran_order': False, 'shape': %s, }" % (repr(tuple(array.shape)),)
    prefix = 10 if version == (1, 0) else 12
    pad = (64 - (prefix + len(header) + 1) % 64) % 64
    header = header + " " * pad + "\n"
    length = struct.pack("<H", len(header)) if version == (1, 0) else struct.pack("<I", len(header))
    return (b"\x93NUMPY" + bytes(version) + length + header.encode("latin1") +
            array.astype("<f4").tobytes())


def pfm_bytes(image, big_endian=False, header_style="plain"):
    h, w = image.shape[:2]
    channels = 1 if image.ndim == 2 else image.shape[2]
    tag = "PF" if channels == 3 else "Pf"
    scale = "1.0" if big_endian else "-1.0"
    if header_style == "sceneflow":
        header = f"{tag} \n{w} {h} \n{scale}\n"
    else:
        header = f"{tag}\n{w} {h}\n{scale}\n"
    rows = np.ascontiguousarray(image[::-1]).astype(">f4" if big_endian else "<f4")
    return header.encode("ascii") + rows.tobytes()


def ros_yaml(k, d, r, p, name):
    def lst(v):
        return "[" + ", ".join(repr(float(x)) for x in v) + "]"
    return (f"image_width: 64\nimage_height: 48\ncamera_name: {name}\n"
            f"camera_matrix:\n  rows: 3\n  cols: 3\n  data: {lst(k)}\n"
            f"distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n"
            f"  data: {lst(d)}\n"
            f"rectification_matrix:\n  rows: 3\n  cols: 3\n  data: {lst(r)}\n"
            f"projection_matrix:\n  rows: 3\n  cols: 4\n  data: {lst(p)}\n").encode()


def calibration_seeds(out):
    k1 = [50, 0, 32, 0, 51, 24, 0, 0, 1]
    k2 = [52, 0, 31, 0, 52, 23, 0, 0, 1]
    d = [-0.1, 0.02, 0.001, -0.002, 0.0]
    eye = [1, 0, 0, 0, 1, 0, 0, 0, 1]
    p1 = [50, 0, 32, 0, 0, 50, 24, 0, 0, 0, 1, 0]
    p2 = [50, 0, 32, -6, 0, 50, 24, 0, 0, 0, 1, 0]
    left = ros_yaml(k1, d, eye, p1, "left")
    right = ros_yaml(k2, d, eye, p2, "right")
    write(os.path.join(out, "ros_pair"), bytes([0]) + left + SPLIT + right)
    write(os.path.join(out, "detect_ros_pair"), bytes([6]) + left + SPLIT + right)
    kalibr = b"""cam0:
  camera_model: pinhole
  intrinsics: [50.0, 51.0, 32.0, 24.0]
  distortion_model: radtan
  distortion_coeffs: [-0.1, 0.02, 0.001, -0.002]
  resolution: [64, 48]
cam1:
  T_cn_cnm1:
  - [1.0, 0.0, 0.0, -0.12]
  - [0.0, 1.0, 0.0, 0.0]
  - [0.0, 0.0, 1.0, 0.0]
  - [0.0, 0.0, 0.0, 1.0]
  camera_model: pinhole
  intrinsics: [52.0, 52.0, 31.0, 23.0]
  distortion_model: radtan
  distortion_coeffs: [-0.1, 0.02, 0.001, -0.002]
  resolution: [64, 48]
"""
    write(os.path.join(out, "kalibr"), bytes([1]) + kalibr)
    write(os.path.join(out, "detect_kalibr"), bytes([5]) + kalibr)

    def mat(name, rows, cols, values):
        data = ", ".join(repr(float(v)) for v in values)
        return (f"{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n"
                f"   data: [ {data} ]\n").encode()
    intr = (b"%YAML:1.0\n---\n" + mat("M1", 3, 3, k1) + mat("D1", 1, 5, d) +
            mat("M2", 3, 3, k2) + mat("D2", 1, 5, d))
    extr = (b"%YAML:1.0\n---\n" + mat("R", 3, 3, eye) + mat("T", 3, 1, [-0.12, 0, 0]) +
            b"image_size: [ 64, 48 ]\n")
    one = intr + extr[len(b"%YAML:1.0\n---\n"):]
    write(os.path.join(out, "opencv_yaml"), bytes([2]) + one)
    write(os.path.join(out, "opencv_two_files"), bytes([4]) + intr + SPLIT + extr)
    write(os.path.join(out, "detect_opencv_yaml"), bytes([5]) + one)
    rvec = one.replace(mat("R", 3, 3, eye), mat("R", 3, 1, [0.01, -0.02, 0.005]))
    write(os.path.join(out, "opencv_rodrigues"), bytes([2]) + rvec)

    def xmat(name, rows, cols, values):
        data = " ".join(repr(float(v)) for v in values)
        return (f'<{name} type_id="opencv-matrix"><rows>{rows}</rows><cols>{cols}</cols>'
                f"<dt>d</dt><data>{data}</data></{name}>\n").encode()
    xml = (b'<?xml version="1.0"?>\n<opencv_storage>\n' + xmat("K1", 3, 3, k1) +
           xmat("D1", 1, 5, d) + xmat("K2", 3, 3, k2) + xmat("D2", 1, 5, d) +
           xmat("R", 3, 3, eye) + xmat("T", 3, 1, [-0.12, 0, 0]) +
           b"<image_width>64</image_width><image_height>48</image_height>\n</opencv_storage>\n")
    write(os.path.join(out, "opencv_xml"), bytes([3]) + xml)


def png_bytes(width, height, color_type, bit_depth, pixels, palette=None):
    """A PNG with one IDAT; pixels: bytes of the filtered-free scanlines (filter 0 added)."""
    def chunk(tag, body):
        return (struct.pack(">I", len(body)) + tag + body +
                struct.pack(">I", zlib.crc32(tag + body) & 0xFFFFFFFF))
    channels = {0: 1, 2: 3, 3: 1, 6: 4}[color_type]
    stride = (width * channels * bit_depth + 7) // 8
    raw = b"".join(b"\0" + pixels[y * stride:(y + 1) * stride] for y in range(height))
    out = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, bit_depth,
                                                             color_type, 0, 0, 0))
    if palette is not None:
        out += chunk(b"PLTE", palette)
    return out + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def image_seeds(out):
    # Selector byte (image_fuzzer.cc): bits 0-1 extension (.png .ppm .pgm .jpg), bit 2 stop
    # policy, bit 3 glob. The right frame there is 4x4, so the 4x4 seeds decode into pairs.
    rng = np.random.default_rng(1)
    rgb = rng.integers(0, 256, (4, 4, 3), dtype=np.uint8).tobytes()
    grey = rng.integers(0, 256, (4, 4), dtype=np.uint8).tobytes()
    write(os.path.join(out, "png_rgb8"), bytes([0]) + png_bytes(4, 4, 2, 8, rgb))
    write(os.path.join(out, "png_grey8_glob_stop"), bytes([12]) + png_bytes(4, 4, 0, 8, grey))
    write(os.path.join(out, "png_rgb16"), bytes([0]) + png_bytes(4, 4, 2, 16, rgb + rgb))
    write(os.path.join(out, "png_rgba8_5x3"), bytes([4]) + png_bytes(5, 3, 6, 8, rgb + rgb[:12]))
    write(os.path.join(out, "png_palette"),
          bytes([8]) + png_bytes(4, 4, 3, 8, bytes(i % 4 for i in range(16)), rgb[:12]))
    write(os.path.join(out, "ppm_p6"), bytes([1]) + b"P6\n4 4\n255\n" + rgb)
    write(os.path.join(out, "ppm_p3_comment"), bytes([9]) + b"P3\n# c\n2 2\n255\n" +
          " ".join(str(v) for v in rgb[:12]).encode() + b"\n")
    write(os.path.join(out, "pgm_p5"), bytes([2]) + b"P5\n4 4\n255\n" + grey)
    write(os.path.join(out, "ppm_p6_16bit"), bytes([5]) + b"P6\n2 2\n65535\n" + rgb[:24])
    from PIL import Image  # Debian python3-pil
    buf = io.BytesIO()
    Image.frombytes("RGB", (4, 4), rgb).save(buf, format="JPEG", quality=90)
    write(os.path.join(out, "jpeg_baseline"), bytes([3]) + buf.getvalue())


def profile_seeds(out):
    cfg = os.path.join(HERE, "..", "..", "firmware-cfg")
    for name in sorted(os.listdir(cfg)):
        if name.endswith(".yaml"):
            write(os.path.join(out, name), open(os.path.join(cfg, name), "rb").read())


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out-dir", required=True)
    p.add_argument("--model-seeds", required=True, help="the sfrt_fuzz_make_model_seeds program")
    p.add_argument("--work-dir", default=None, help="where fixture generators write (default "
                   "OUT_DIR/.work; kept between runs, generators skip up-to-date files)")
    args = p.parse_args()
    out = args.out_dir
    work = args.work_dir or os.path.join(out, ".work")
    os.makedirs(work, exist_ok=True)

    # Model files.
    models = os.path.join(work, "sfrt")
    subprocess.run([args.model_seeds, models], check=True, stdout=subprocess.DEVNULL)
    for target in ("model_load", "model_session"):
        for name in sorted(os.listdir(models)):
            write(os.path.join(out, target, name), open(os.path.join(models, name), "rb").read())

    # ONNX.
    onnx_dir = os.path.join(work, "onnx")
    cases = [("w64_tf", []), ("w64_torch", ["--padding", "torch"]),
             ("w64_nofold11", ["--no-constant-folding", "--opset", "11"])]
    for name, extra in cases:
        subprocess.run([sys.executable, os.path.join(FIXTURES, "gen_sceneednet.py"), "--out-dir",
                        onnx_dir, "--width-div", "64", "--height", "16", "--width", "16",
                        "--name", name] + extra, check=True, stdout=subprocess.DEVNULL)
        os.makedirs(os.path.join(out, "onnx_import"), exist_ok=True)
        shutil.copy(os.path.join(onnx_dir, name + ".onnx"),
                    os.path.join(out, "onnx_import", name + ".onnx"))

    # Keras HDF5.
    h5_dir = os.path.join(work, "h5")
    subprocess.run([sys.executable, os.path.join(FIXTURES, "gen_keras_h5.py"), "--out-dir",
                    h5_dir], check=True, stdout=subprocess.DEVNULL)
    os.makedirs(os.path.join(out, "keras_import"), exist_ok=True)
    for name in sorted(os.listdir(h5_dir)):
        if name.endswith(".h5") and os.path.getsize(os.path.join(h5_dir, name)) < 1_000_000:
            shutil.copy(os.path.join(h5_dir, name), os.path.join(out, "keras_import", name))

    # PFM and NPY.
    rng = np.random.default_rng(0)
    img3 = rng.standard_normal((5, 7, 3)).astype(np.float32)
    img1 = rng.standard_normal((4, 3)).astype(np.float32)
    write(os.path.join(out, "pfm", "rgb_le.pfm"), pfm_bytes(img3))
    write(os.path.join(out, "pfm", "gray_le.pfm"), pfm_bytes(img1))
    write(os.path.join(out, "pfm", "rgb_be.pfm"), pfm_bytes(img3, big_endian=True))
    write(os.path.join(out, "pfm", "gray_sceneflow.pfm"), pfm_bytes(img1, header_style="sceneflow"))
    write(os.path.join(out, "npy", "hwc_v1.npy"), npy_bytes(img3))
    write(os.path.join(out, "npy", "hwc_v2.npy"), npy_bytes(img3, (2, 0)))
    write(os.path.join(out, "npy", "scalar.npy"), npy_bytes(np.array(1.5, dtype=np.float32)))
    write(os.path.join(out, "npy", "empty.npy"), npy_bytes(np.zeros((0, 4), dtype=np.float32)))
    buf = io.BytesIO()
    np.save(buf, rng.standard_normal((2, 3, 4, 1)).astype(np.float32))
    write(os.path.join(out, "npy", "numpy_save.npy"), buf.getvalue())

    calibration_seeds(os.path.join(out, "calibration"))
    image_seeds(os.path.join(out, "image"))
    profile_seeds(os.path.join(out, "profile"))
    for target in sorted(os.listdir(out)):
        if target.startswith("."):
            continue
        files = os.listdir(os.path.join(out, target))
        size = sum(os.path.getsize(os.path.join(out, target, f)) for f in files)
        print(f"{target}: {len(files)} seeds, {size} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
