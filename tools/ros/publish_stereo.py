#!/usr/bin/python3
"""Publish a replay directory's stereo frames as a live camera driver would, for measuring
sfrt_ros without a robot: sensor_msgs/Image bgr8 on left/image_rect and right/image_rect, stamped
with the time of publication (the right image --skew-ms later), at --fps, looping over the
frames until --seconds have passed.

usage: publish_stereo.py --left DIR --right DIR [--fps 30] [--seconds 20] [--skew-ms 0]
                         [--frame-id-left left_camera] [--frame-id-right right_camera]
                         [--wait-subscribers 30]

The images are read and converted once, before the first message, so the publisher's own cost
per frame is the serialisation. It waits (up to --wait-subscribers seconds) for a subscriber on
both topics before it starts, and prints how many pairs it published and how late its schedule
ran (p50/max), so a measurement can tell a slow publisher from a slow node.

Needs Debian's python3-rospy, python3-sensor-msgs, python3-numpy and python3-pil, and a master
(ROS_MASTER_URI).
"""
import argparse
import os
import sys
import time

import numpy as np
from PIL import Image as PilImage

import rospy
from sensor_msgs.msg import Image

EXTENSIONS = (".png", ".jpg", ".jpeg", ".ppm", ".bmp")


def load(directory):
    names = sorted(n for n in os.listdir(directory) if n.lower().endswith(EXTENSIONS))
    if not names:
        sys.exit("publish_stereo.py: no images in '%s'" % directory)
    out = []
    for n in names:
        rgb = np.asarray(PilImage.open(os.path.join(directory, n)).convert("RGB"))
        out.append((rgb.shape[0], rgb.shape[1], np.ascontiguousarray(rgb[:, :, ::-1]).tobytes()))
    return out


def message(frame, stamp, seq, frame_id):
    h, w, data = frame
    m = Image()
    m.header.stamp = stamp
    m.header.seq = seq
    m.header.frame_id = frame_id
    m.height, m.width, m.encoding, m.is_bigendian, m.step = h, w, "bgr8", 0, w * 3
    m.data = data
    return m


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--left", required=True)
    ap.add_argument("--right", required=True)
    ap.add_argument("--fps", type=float, default=30)
    ap.add_argument("--seconds", type=float, default=20)
    ap.add_argument("--skew-ms", type=float, default=0)
    ap.add_argument("--frame-id-left", default="left_camera")
    ap.add_argument("--frame-id-right", default="right_camera")
    ap.add_argument("--wait-subscribers", type=float, default=30)
    a = ap.parse_args()
    left, right = load(a.left), load(a.right)
    n = min(len(left), len(right))
    rospy.init_node("publish_stereo", anonymous=True, disable_signals=True)
    pub_l = rospy.Publisher("left/image_rect", Image, queue_size=2)
    pub_r = rospy.Publisher("right/image_rect", Image, queue_size=2)
    end = time.time() + a.wait_subscribers
    while (pub_l.get_num_connections() == 0 or pub_r.get_num_connections() == 0) \
            and time.time() < end:
        time.sleep(0.05)
    if pub_l.get_num_connections() == 0 or pub_r.get_num_connections() == 0:
        sys.exit("publish_stereo.py: no subscriber on left/image_rect and right/image_rect "
                 "after %g s" % a.wait_subscribers)
    time.sleep(0.5)  # let the connections settle
    period = 1.0 / a.fps
    start = time.monotonic()
    late = []
    i = 0
    while True:
        due = start + i * period
        if due - start >= a.seconds:
            break
        now = time.monotonic()
        if now < due:
            time.sleep(due - now)
        late.append(time.monotonic() - due)
        stamp = rospy.Time.now()
        pub_l.publish(message(left[i % n], stamp, i, a.frame_id_left))
        pub_r.publish(message(right[i % n], stamp + rospy.Duration.from_sec(a.skew_ms / 1e3), i,
                              a.frame_id_right))
        i += 1
    late.sort()
    print("publish_stereo.py: %d pairs at %g fps; schedule late p50 %.2f ms, max %.2f ms"
          % (i, a.fps, 1e3 * late[len(late) // 2], 1e3 * late[-1]))


if __name__ == "__main__":
    main()
