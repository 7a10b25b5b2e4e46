#!/usr/bin/python3
"""Turn a replay directory into a rosbag2 bag a ROS 2 robot could have recorded, written with
implementations sfrt did not write, for testing `sfrt run --replay-bag` on rosbag2 bags.

usage: make_bag2.py --left DIR --right DIR --out PATH --storage mcap|sqlite3|mcap-file|db3-file
                    [--compression zstd|none] [--no-chunks] [--fps 30] [--skew-ms 3]
                    [--drop-right N]... [--encoding bgr8|rgb8|mono8|jpeg|png]
                    [--left-topic T] [--right-topic T] [--seed S] [--start SECONDS]
                    --node NODE --oracle tests/ros2/make_bag2.cjs

Frames and stamps as tools/ros/make_bag.py lays them out for ROS 1 (frame i at start + i / fps,
the right one a seeded skew of at most --skew-ms away; --drop-right N leaves right frame N out).
The CDR bytes of every message and the MCAP file come from make_bag2.cjs (@mcap/core and
@foxglove/rosmsg2-serialization, run by NODE with NODE_PATH set by the caller).
  mcap        PATH is a bag folder: PATH/<name>_0.mcap and metadata.yaml, as `ros2 bag record`
  sqlite3     PATH is a bag folder: PATH/<name>_0.db3 (rosbag2's sqlite3 tables, built here with
              Python's sqlite3 from the same CDR bytes) and metadata.yaml
  mcap-file   PATH is one .mcap file
  db3-file    PATH is one .db3 file

Needs Debian's python3-numpy and python3-pil.
"""
import argparse
import io
import json
import os
import random
import shutil
import sqlite3
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image as PilImage

EXTENSIONS = (".png", ".jpg", ".jpeg", ".ppm", ".pgm", ".bmp")
IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"


def frames(directory):
    names = sorted(n for n in os.listdir(directory) if n.lower().endswith(EXTENSIONS))
    if not names:
        sys.exit("make_bag2.py: no images in '%s'" % directory)
    return [os.path.join(directory, n) for n in names]


def plan_message(path, encoding, stamp_ns, topic, frame_id, blob):
    rgb = PilImage.open(path).convert("RGB")
    m = {"topic": topic, "stamp_ns": str(stamp_ns), "frame_id": frame_id, "blob": blob}
    if encoding in ("jpeg", "png"):
        buf = io.BytesIO()
        rgb.save(buf, format="JPEG" if encoding == "jpeg" else "PNG", quality=95)
        data = buf.getvalue()
        m.update(type="CompressedImage", format=encoding)
    else:
        pixels = np.asarray(rgb)
        if encoding == "bgr8":
            pixels = pixels[:, :, ::-1]
        elif encoding == "mono8":
            pixels = np.asarray(rgb.convert("L"))
        pixels = np.ascontiguousarray(pixels)
        data = pixels.tobytes()
        m.update(type="Image", encoding=encoding, height=int(pixels.shape[0]),
                 width=int(pixels.shape[1]), step=int(pixels.strides[0]))
    with open(blob, "wb") as f:
        f.write(data)
    return m


def events(a, n):
    rng = random.Random(a.seed)
    start_ns = int(round(a.start * 1e9))
    out = []
    for i in range(n):
        t = start_ns + int(round(i * 1e9 / a.fps))
        out.append((t, 0, i))
        if i not in a.drop_right:
            out.append((t + int(round(rng.uniform(-a.skew_ms, a.skew_ms) * 1e6)), 1, i))
    return sorted(out)


def write_db3(path, messages, payloads):
    """rosbag2's sqlite3 storage, schema version 4 (Iron and later), as sqlite_storage.cpp makes
    it."""
    db = sqlite3.connect(path)
    db.executescript("""
        CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
        CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL,
                              metadata TEXT NOT NULL);
        CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
                            serialization_format TEXT NOT NULL,
                            offered_qos_profiles TEXT NOT NULL,
                            type_description_hash TEXT NOT NULL);
        CREATE TABLE message_definitions(id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL,
                                         encoding TEXT NOT NULL,
                                         encoded_message_definition TEXT NOT NULL,
                                         type_description_hash TEXT NOT NULL);
        CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
                              timestamp INTEGER NOT NULL, data BLOB NOT NULL);
        CREATE INDEX timestamp_idx ON messages (timestamp ASC);
        INSERT INTO schema (schema_version, ros_distro) VALUES (4, 'jazzy');
    """)
    ids = {}
    for i, m in enumerate(messages):
        if m["topic"] not in ids:
            cur = db.execute("INSERT INTO topics (name, type, serialization_format, "
                             "offered_qos_profiles, type_description_hash) VALUES (?,?,?,?,?)",
                             (m["topic"], "sensor_msgs/msg/" + m["type"], "cdr", "", ""))
            ids[m["topic"]] = cur.lastrowid
        with open(os.path.join(payloads, "%d.cdr" % i), "rb") as f:
            db.execute("INSERT INTO messages (timestamp, topic_id, data) VALUES (?,?,?)",
                       (int(m["stamp_ns"]), ids[m["topic"]], f.read()))
    db.commit()
    db.close()


def write_metadata(folder, storage, file_name, messages):
    """metadata.yaml as rosbag2_storage's metadata_io writes it (version 9)."""
    counts = {}
    types = {}
    for m in messages:
        counts[m["topic"]] = counts.get(m["topic"], 0) + 1
        types[m["topic"]] = "sensor_msgs/msg/" + m["type"]
    stamps = [int(m["stamp_ns"]) for m in messages]
    lines = ["rosbag2_bagfile_information:", "  version: 9",
             "  storage_identifier: %s" % storage,
             "  duration:", "    nanoseconds: %d" % (max(stamps) - min(stamps)),
             "  starting_time:", "    nanoseconds_since_epoch: %d" % min(stamps),
             "  message_count: %d" % len(messages), "  topics_with_message_count:"]
    for topic in counts:
        lines += ["    - topic_metadata:", "        name: %s" % topic,
                  "        type: %s" % types[topic], "        serialization_format: cdr",
                  "        offered_qos_profiles: []", "        type_description_hash: \"\"",
                  "      message_count: %d" % counts[topic]]
    lines += ["  compression_format: \"\"", "  compression_mode: \"\"",
              "  relative_file_paths:", "    - %s" % file_name, "  files:",
              "    - path: %s" % file_name, "      starting_time:",
              "        nanoseconds_since_epoch: %d" % min(stamps), "      duration:",
              "        nanoseconds: %d" % (max(stamps) - min(stamps)),
              "      message_count: %d" % len(messages), "  custom_data: ~",
              "  ros_distro: jazzy", ""]
    with open(os.path.join(folder, "metadata.yaml"), "w") as f:
        f.write("\n".join(lines))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    for name in ("--left", "--right", "--out", "--node", "--oracle"):
        ap.add_argument(name, required=True)
    ap.add_argument("--storage", required=True,
                    choices=["mcap", "sqlite3", "mcap-file", "db3-file"])
    ap.add_argument("--compression", default="zstd", choices=["zstd", "none"])
    ap.add_argument("--no-chunks", action="store_true")
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
        sys.exit("make_bag2.py: %d left and %d right images" % (len(left), len(right)))
    work = tempfile.mkdtemp(prefix="make_bag2_")
    try:
        messages = []
        for n, (stamp, side, i) in enumerate(events(a, len(left))):
            messages.append(plan_message((left if side == 0 else right)[i], a.encoding, stamp,
                                         a.left_topic if side == 0 else a.right_topic,
                                         "left_camera" if side == 0 else "right_camera",
                                         os.path.join(work, "blob_%d" % n)))
        with open(os.path.join(work, "plan.json"), "w") as f:
            json.dump({"messages": messages}, f)
        mcap = os.path.join(work, "bag.mcap")
        payloads = os.path.join(work, "cdr")
        cmd = [a.node, a.oracle, os.path.join(work, "plan.json"), mcap, "--compression",
               a.compression, "--payloads", payloads] + (["--no-chunks"] if a.no_chunks else [])
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if p.returncode != 0:
            sys.exit("make_bag2.py: %s failed: %s" % (a.oracle, p.stderr))
        name = os.path.basename(a.out.rstrip("/"))
        if os.path.exists(a.out):
            shutil.rmtree(a.out) if os.path.isdir(a.out) else os.unlink(a.out)
        if a.storage == "mcap-file":
            shutil.move(mcap, a.out)
        elif a.storage == "db3-file":
            write_db3(a.out, messages, payloads)
        else:
            os.makedirs(a.out)
            ext = ".mcap" if a.storage == "mcap" else ".db3"
            file_name = name + "_0" + ext
            if a.storage == "mcap":
                shutil.move(mcap, os.path.join(a.out, file_name))
            else:
                write_db3(os.path.join(a.out, file_name), messages, payloads)
            write_metadata(a.out, a.storage, file_name, messages)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print("make_bag2.py: %s (%s, %s): %d messages" % (a.out, a.storage, a.encoding, len(messages)))


if __name__ == "__main__":
    main()
