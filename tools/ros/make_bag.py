#!/usr/bin/python3
"""Turn a replay directory into a ROS 1 bag a robot could have recorded, for testing
`sfrt run --replay-bag` (and, later, the ROS node) without a robot.

usage: make_bag.py --left DIR --right DIR --out FILE.bag [--fps 30] [--skew-ms 3]
                   [--drop-right N]... [--encoding bgr8|rgb8|mono8|jpeg|png]
                   [--left-topic T] [--right-topic T] [--seed S] [--start SECONDS]

Frames are the images of DIR sorted by name (PNG, JPEG, PPM: anything Pillow reads), left and
right in step. Frame i is stamped start + i / fps on the left, and the right one a seeded random
skew of at most --skew-ms later or earlier, as two free-running cameras would be; messages are
written in stamp order. --drop-right N leaves out right frame N (a frame the robot lost).
sensor_msgs/Image for bgr8/rgb8/mono8, sensor_msgs/CompressedImage for jpeg/png; header.seq is
the frame number, header.frame_id "left_camera" / "right_camera". The bag is written to a
temporary name beside FILE.bag and renamed when complete.

Needs Debian's python3-rosbag, python3-sensor-msgs, python3-numpy and python3-pil.
"""
import argparse
import io
import os
import random
import sys

import numpy as np
from PIL import Image as PilImage

import genpy
import rosbag
from sensor_msgs.msg import CompressedImage, Image

EXTENSIONS = (".png", ".jpg", ".jpeg", ".ppm", ".pgm", ".bmp", ".webp", ".tif", ".tiff")


def frames(directory):
    names = sorted(n for n in os.listdir(directory) if n.lower().endswith(EXTENSIONS))
    if not names:
        sys.exit("make_bag.py: no images in '%s'" % directory)
    return [os.path.join(directory, n) for n in names]


def message(path, encoding, stamp, seq, frame_id):
    rgb = PilImage.open(path).convert("RGB")
    if encoding in ("jpeg", "png"):
        buf = io.BytesIO()
        rgb.save(buf, format="JPEG" if encoding == "jpeg" else "PNG", quality=95)
        msg = CompressedImage()
        msg.format = encoding
        msg.data = buf.getvalue()
    else:
        pixels = np.asarray(rgb)
        if encoding == "bgr8":
            pixels = pixels[:, :, ::-1]
        elif encoding == "mono8":
            pixels = np.asarray(rgb.convert("L"))
        pixels = np.ascontiguousarray(pixels)
        msg = Image()
        msg.height, msg.width = pixels.shape[0], pixels.shape[1]
        msg.encoding = encoding
        msg.is_bigendian = 0
        msg.step = pixels.strides[0]
        msg.data = pixels.tobytes()
    msg.header.stamp = stamp
    msg.header.seq = seq
    msg.header.frame_id = frame_id
    return msg


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--left", required=True)
    ap.add_argument("--right", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--skew-ms", type=float, default=3.0)
    ap.add_argument("--drop-right", type=int, action="append", default=[])
    ap.add_argument("--encoding", default="bgr8", choices=["bgr8", "rgb8", "mono8", "jpeg", "png"])
    ap.add_argument("--left-topic", default="/left/image_rect")
    ap.add_argument("--right-topic", default="/right/image_rect")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--start", type=float, default=1700000000.0)
    a = ap.parse_args()
    left, right = frames(a.left), frames(a.right)
    if len(left) != len(right):
        sys.exit("make_bag.py: %d left and %d right images" % (len(left), len(right)))
    if a.fps <= 0:
        sys.exit("make_bag.py: --fps must be positive")
    rng = random.Random(a.seed)
    start_ns = int(round(a.start * 1e9))
    period_ns = 1e9 / a.fps
    events = []  # (stamp_ns, side, frame)
    for i in range(len(left)):
        t = start_ns + int(round(i * period_ns))
        events.append((t, 0, i))
        if i not in a.drop_right:
            events.append((t + int(round(rng.uniform(-a.skew_ms, a.skew_ms) * 1e6)), 1, i))
    events.sort()
    tmp = a.out + ".tmp.bag"
    try:
        with rosbag.Bag(tmp, "w") as bag:
            for stamp_ns, side, i in events:
                stamp = genpy.Time(stamp_ns // 1000000000, stamp_ns % 1000000000)
                path = (left if side == 0 else right)[i]
                msg = message(path, a.encoding, stamp, i, "left_camera" if side == 0 else
                              "right_camera")
                bag.write(a.left_topic if side == 0 else a.right_topic, msg, stamp)
        os.replace(tmp, a.out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    print("make_bag.py: %s: %d left, %d right frames at %g fps (%s)" % (
        a.out, len(left), len(left) - len(set(a.drop_right) & set(range(len(left)))), a.fps,
        a.encoding))


if __name__ == "__main__":
    main()
