#!/usr/bin/python3
"""`sfrt run --replay-bag` on rosbag2 bags (issue #39), made by make_bag2.py with implementations
sfrt did not write (@mcap/core, @foxglove/rosmsg2-serialization, Python's sqlite3) from a
`sfrt synth` sequence.

usage: bag2_check.py SCENARIO --sfrt BIN --model M.sfrt --work DIR --node NODE
                     --make-bag2 tests/ros2/make_bag2.py --oracle tests/ros2/make_bag2.cjs
(NODE_PATH must name the installed oracles: the ctest fixture npm.oracles sets it up.)

Scenarios (each one ctest test named after the behaviour it checks):
  rosbag2_replay_gives_the_flow_files_of_the_directory_replay
      bag folders with metadata.yaml (MCAP with zstd chunks, bgr8; sqlite3, rgb8), a single
      .mcap without chunks holding PNG CompressedImages, a single .db3 (mono8 is not lossless,
      so bgr8), and a folder whose metadata.yaml is gone: every window's flow file equals, byte
      for byte, the one `sfrt run --replay-left/--replay-right` writes from the directory the
      bag was made from; summary.json names the format and counts the messages.
  rosbag2_missing_right_frame_breaks_the_window_chain
      a bag without right frame 3: the left frame 3 is counted unpaired, no window spans the
      gap, the flow files keep the bag's message numbers (as for a ROS 1 bag).
  rosbag2_record_bag_is_read_back_by_mcap_core_and_the_ros2_codec
      --record-bag to a .mcap file and to a new folder (with --record-bag-vis): @mcap/core's
      indexed and stream readers read the file (CRCs checked), profile ros2, ros2msg schemas, cdr;
      /flow has one 32FC3 Image per window whose data equals the window's .npy flow file,
      stamped (header and log time) with pair t's stamp from windows.csv, frame_id as given;
      /flow_t1 carries pair t+1's stamp; /flow_vis one bgr8 picture each; /left/image_rect and
      /right/image_rect one bgr8 Image per stereo pair read (6), pixels equal to the frames' and
      stamped as the source bag's; the folder holds <name>_0.mcap and a metadata.yaml that counts
      each topic's messages, and replays to the same flow files; --record-bag-flow-only leaves
      the images out; no temporary file or folder is left. An existing folder, a device and a
      FIFO are refused (exit 2, no summary).
  rosbag2_bad_bags_and_topics_are_refused_naming_them
      a topic not in the bag (the error lists the bag's topics), a truncated .mcap (named, with
      an offset), a file that is neither MCAP nor sqlite3, a folder with no bag file in it, a
      metadata.yaml with another storage, and a metadata.yaml that lists a missing file: each
      exit 2 before any output, with a message naming the path.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

FAILED = []


def check(ok, what):
    if not ok:
        FAILED.append(what)
        print("FAIL: " + what, flush=True)
    return ok


def run(cmd, expect=None):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=600)
    if expect is not None and p.returncode != expect:
        print(p.stdout + p.stderr, flush=True)
    return p


def fresh(path):
    shutil.rmtree(path, ignore_errors=True)
    os.makedirs(path)
    return path


def synth(a, frames=6):
    root = os.path.join(a.work, "synth")
    if not os.path.isdir(os.path.join(root, "frames_cleanpass")):
        shutil.rmtree(root, ignore_errors=True)
        p = run([a.sfrt, "synth", "--out", root, "--frames", str(frames), "--size", "64x96",
                 "--seed", "3"], expect=0)
        if not check(p.returncode == 0, "sfrt synth exit %d" % p.returncode):
            sys.exit(1)
    seq = os.path.join(root, "frames_cleanpass", "0000")
    return os.path.join(seq, "left"), os.path.join(seq, "right")


def make_bag2(a, left, right, name, storage, extra=()):
    out = os.path.join(a.work, name)
    p = run(["/usr/bin/python3", a.make_bag2, "--left", left, "--right", right, "--out", out,
             "--storage", storage, "--node", a.node, "--oracle", a.oracle] + list(extra),
            expect=0)
    check(p.returncode == 0, "make_bag2.py %s exit %d: %s" % (name, p.returncode, p.stderr))
    return out


def sfrt_run(a, source, out, extra=(), expect=None):
    return run([a.sfrt, "run", "--model", a.model, "--out", out, "--progress", "off", "--no-png"]
               + source + list(extra), expect)


def flows(out):
    return sorted(n for n in os.listdir(out) if n.endswith(".pfm")) if os.path.isdir(out) else []


def summary(out):
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def same_files(label, got_dir, want_dir, want):
    got = flows(got_dir)
    check(got == want, "%s: flow files %s, expected %s" % (label, got, want))
    for name in want:
        if name in got:
            with open(os.path.join(got_dir, name), "rb") as f1, \
                    open(os.path.join(want_dir, name), "rb") as f2:
                check(f1.read() == f2.read(), "%s: %s differs from the directory replay's"
                      % (label, name))


def scenario_same_flow(a):
    left, right = synth(a)
    want_dir = fresh(os.path.join(a.work, "dir_out"))
    p = sfrt_run(a, ["--replay-left", left, "--replay-right", right], want_dir)
    check(p.returncode == 0, "directory replay exit %d" % p.returncode)
    want = flows(want_dir)
    check(len(want) == 5, "directory replay wrote %d flow files, expected 5" % len(want))
    cases = [  # (name, storage, extra, format in summary.json)
        ("mcap_zstd_bgr8", "mcap", ["--encoding", "bgr8"], "rosbag2 MCAP"),
        ("sqlite3_rgb8", "sqlite3", ["--encoding", "rgb8"], "rosbag2 sqlite3"),
        ("png_unchunked.mcap", "mcap-file", ["--encoding", "png", "--no-chunks",
                                             "--compression", "none"], "rosbag2 MCAP"),
        ("single_bgr8.db3", "db3-file", ["--encoding", "bgr8"], "rosbag2 sqlite3"),
    ]
    for name, storage, extra, fmt in cases:
        bag = make_bag2(a, left, right, name, storage, extra)
        out = fresh(os.path.join(a.work, "out_" + name))
        p = sfrt_run(a, ["--replay-bag", bag], out, expect=0)
        if not check(p.returncode == 0, "%s: exit %d: %s" % (name, p.returncode, p.stderr)):
            continue
        same_files(name, out, want_dir, want)
        s = summary(out)["source"]
        check(s.get("kind") == "replay-bag" and s.get("format") == fmt and s.get("pairs") == 6
              and s.get("messages") == {"left": 6, "right": 6},
              "%s: summary source %s" % (name, s))
    # A recording cut short loses its metadata.yaml: the folder's .mcap is read by name.
    bag = make_bag2(a, left, right, "no_metadata", "mcap", ["--encoding", "bgr8"])
    os.unlink(os.path.join(bag, "metadata.yaml"))
    out = fresh(os.path.join(a.work, "out_no_metadata"))
    p = sfrt_run(a, ["--replay-bag", bag], out, expect=0)
    if check(p.returncode == 0, "no metadata.yaml: exit %d: %s" % (p.returncode, p.stderr)):
        same_files("no metadata.yaml", out, want_dir, want)


def scenario_missing_right(a):
    left, right = synth(a)
    bag = make_bag2(a, left, right, "drop_right_3", "mcap", ["--drop-right", "3"])
    out = fresh(os.path.join(a.work, "out_drop"))
    p = sfrt_run(a, ["--replay-bag", bag], out, expect=0)
    if not check(p.returncode == 0, "exit %d: %s" % (p.returncode, p.stderr)):
        return
    names = flows(out)
    check(len(names) == 3, "flow files %s: expected the windows 0-1, 1-2 and 4-5" % names)
    check(names and names[-1].endswith("000004.pfm"),
          "the last flow file is %s, expected the one named by left message 4" % names[-1:])
    s = summary(out)
    check(s["source"]["unpaired_left"] == 1, "unpaired_left %s" % s["source"]["unpaired_left"])
    check(s["windows"]["broken_by_lost_frame"] == 1, "windows %s" % s["windows"])


def refused(a, label, bag, needles, extra=()):
    out = os.path.join(a.work, "out_refused")
    shutil.rmtree(out, ignore_errors=True)
    p = sfrt_run(a, ["--replay-bag", bag] + list(extra), out)
    check(p.returncode == 2, "%s: exit %d, expected 2: %s" % (label, p.returncode, p.stderr))
    for needle in needles:
        check(needle in p.stderr, "%s: stderr does not say %r: %s" % (label, needle, p.stderr))
    check(not os.path.exists(os.path.join(out, "summary.json")),
          "%s: a summary.json was written" % label)


def scenario_bad_bags(a):
    left, right = synth(a)
    good = make_bag2(a, left, right, "good.mcap", "mcap-file")
    refused(a, "missing topic", good, ["has no topic '/cam/left'", "/left/image_rect ("],
            ["--left-topic", "/cam/left"])
    with open(good, "rb") as f:
        data = f.read()
    cut = os.path.join(a.work, "cut.mcap")
    with open(cut, "wb") as f:
        f.write(data[: len(data) // 2])
    refused(a, "truncated mcap", cut, [cut])
    junk = os.path.join(a.work, "junk.db3")
    with open(junk, "wb") as f:
        f.write(b"this is not a database, nor a bag" * 100)
    refused(a, "not sqlite", junk, [junk, "not a rosbag2 sqlite3 bag"])
    empty = fresh(os.path.join(a.work, "empty_folder"))
    refused(a, "empty folder", empty, [empty, "not a rosbag2 bag"])
    folder = make_bag2(a, left, right, "other_storage", "mcap")
    meta = os.path.join(folder, "metadata.yaml")
    with open(meta) as f:
        text = f.read()
    with open(meta, "w") as f:
        f.write(text.replace("storage_identifier: mcap", "storage_identifier: foxglove"))
    refused(a, "other storage", folder, ["storage_identifier 'foxglove'"])
    with open(meta, "w") as f:
        f.write(text.replace("other_storage_0.mcap", "other_storage_7.mcap"))
    refused(a, "listed file missing", folder, ["other_storage_7.mcap", "not in the folder"])


def read_mcap(a, path):
    p = run([a.node, os.path.join(os.path.dirname(a.oracle), "read_bag2.cjs"), path])
    if not check(p.returncode == 0, "read_bag2.cjs %s: %s" % (path, p.stderr)):
        return None
    return json.loads(p.stdout)


def windows_csv(out):
    with open(os.path.join(out, "windows.csv")) as f:
        rows = [line.rstrip("\n").split(",") for line in f][1:]
    return [(r[0], int(r[4]), int(r[5])) for r in rows]


def check_recorded_inputs(label, bag, left, right, stamps):
    """The stereo pairs the run read, one bgr8 Image per frame and side, as the frames' pixels."""
    import base64
    import numpy as np
    from PIL import Image
    for side, folder in (("left", left), ("right", right)):
        topic = "/%s/image_rect" % side
        got = [m for m in bag["messages"] if m["topic"] == topic]
        files = sorted(os.listdir(folder))
        if not check(len(got) == len(files) == len(stamps),
                     "%s: %d %s messages, %d frames" % (label, len(got), topic, len(files))):
            continue
        for m, name, stamp in zip(got, files, stamps):
            im = m["message"]
            st = im["header"]["stamp"]["sec"] * 10**9 + im["header"]["stamp"]["nanosec"]
            bgr = np.asarray(Image.open(os.path.join(folder, name)).convert("RGB"))[:, :, ::-1]
            data = np.frombuffer(base64.b64decode(im["data"]["base64"]), dtype=np.uint8)
            check(im["encoding"] == "bgr8" and st == stamp and int(m["log_time"]) == stamp
                  and im["height"] == bgr.shape[0] and im["width"] == bgr.shape[1]
                  and im["step"] == bgr.shape[1] * 3,
                  "%s: %s %s: encoding %s stamp %d (pair stamp %d) %dx%d step %d" % (
                      label, topic, name, im["encoding"], st, stamp, im["height"], im["width"],
                      im["step"]))
            check(data.size == bgr.size and np.array_equal(data.reshape(bgr.shape), bgr),
                  "%s: %s %s: pixels differ from the frame's" % (label, topic, name))


def check_recorded(label, bag, out, left=None, right=None):
    import base64
    import numpy as np
    if bag is None:
        return
    check(bag["profile"] == "ros2", "%s: profile %r" % (label, bag["profile"]))
    windows = windows_csv(out)
    flow = [m for m in bag["messages"] if m["topic"] == "/flow"]
    t1 = [m for m in bag["messages"] if m["topic"] == "/flow_t1"]
    vis = [m for m in bag["messages"] if m["topic"] == "/flow_vis"]
    check(len(flow) == len(windows) == 5 and len(t1) == 5 and len(vis) == 5,
          "%s: %d /flow, %d /flow_t1, %d /flow_vis for %d windows"
          % (label, len(flow), len(t1), len(vis), len(windows)))
    for (name, t0, t1_ns), f, h, v in zip(windows, flow, t1, vis):
        m = f["message"]
        stamp = m["header"]["stamp"]["sec"] * 10**9 + m["header"]["stamp"]["nanosec"]
        check(f["schema"] == "sensor_msgs/msg/Image" and f["schema_encoding"] == "ros2msg"
              and f["message_encoding"] == "cdr", "%s: /flow schema %s" % (label, f))
        check(m["encoding"] == "32FC3" and m["header"]["frame_id"] == "stereo_left",
              "%s: /flow %s: encoding %s frame_id %s" % (label, name, m["encoding"],
                                                         m["header"]["frame_id"]))
        check(stamp == t0 and int(f["log_time"]) == t0,
              "%s: /flow %s stamped %d (log time %s), pair t is %d" % (label, name, stamp,
                                                                      f["log_time"], t0))
        data = np.frombuffer(base64.b64decode(m["data"]["base64"]), dtype="<f4")
        want = np.load(os.path.join(out, name + ".npy"))
        check(data.size == want.size and np.array_equal(data.reshape(want.shape), want),
              "%s: /flow %s differs from %s.npy" % (label, name, name))
        hs = h["message"]["stamp"]
        check(hs["sec"] * 10**9 + hs["nanosec"] == t1_ns and h["schema"] == "std_msgs/msg/Header",
              "%s: /flow_t1 of %s: %s, pair t+1 is %d" % (label, name, h, t1_ns))
        check(v["message"]["encoding"] == "bgr8", "%s: /flow_vis %s" % (label, v["message"]))
    images = [m for m in bag["messages"] if m["topic"].endswith("/image_rect")]
    if left is None:
        check(not images, "%s: --record-bag-flow-only recorded %d images" % (label, len(images)))
    else:
        check_recorded_inputs(label, bag, left, right, [w[1] for w in windows] + [windows[-1][2]])


def scenario_record(a):
    import yaml
    left, right = synth(a)
    source = make_bag2(a, left, right, "record_source", "mcap")
    for label, name in (("mcap file", "flow.mcap"), ("bag folder", "flow_bag")):
        out = fresh(os.path.join(a.work, "record_out_" + name))
        recorded = os.path.join(out, name)
        p = sfrt_run(a, ["--replay-bag", source], out,
                     ["--flow-format", "npy", "--record-bag", recorded, "--record-bag-vis",
                      "--record-bag-frame-id", "stereo_left"], expect=0)
        if not check(p.returncode == 0, "%s: exit %d" % (label, p.returncode)):
            continue
        left_over = [n for n in os.listdir(out) if ".tmp." in n or ".partial-" in n]
        check(not left_over, "%s: temporary files left: %s" % (label, left_over))
        if name.endswith(".mcap"):
            check_recorded(label, read_mcap(a, recorded), out, left, right)
            continue
        names = sorted(os.listdir(recorded))
        check(names == ["flow_bag_0.mcap", "metadata.yaml"], "%s: holds %s" % (label, names))
        check_recorded(label, read_mcap(a, os.path.join(recorded, "flow_bag_0.mcap")), out, left,
                       right)
        with open(os.path.join(recorded, "metadata.yaml")) as f:
            info = yaml.safe_load(f)["rosbag2_bagfile_information"]
        counts = {t["topic_metadata"]["name"]: t["message_count"]
                  for t in info["topics_with_message_count"]}
        check(info["storage_identifier"] == "mcap" and info["message_count"] == 27
              and counts == {"/flow": 5, "/flow_t1": 5, "/flow_vis": 5, "/left/image_rect": 6,
                             "/right/image_rect": 6}
              and info["relative_file_paths"] == ["flow_bag_0.mcap"],
              "%s: metadata.yaml %s" % (label, info))
        # The folder it wrote is a bag that replays: the same flow, file for file.
        again = fresh(os.path.join(a.work, "record_replayed"))
        p = sfrt_run(a, ["--replay-bag", recorded], again, ["--flow-format", "npy"], expect=0)
        if check(p.returncode == 0, "replaying the recorded folder: exit %d" % p.returncode):
            got = sorted(n for n in os.listdir(again) if n.endswith(".npy"))
            want = sorted(n for n in os.listdir(out) if n.endswith(".npy"))
            check(got == want and len(want) == 5, "the recorded folder replays to %s, not %s"
                  % (got, want))
            for n in set(got) & set(want):
                with open(os.path.join(again, n), "rb") as f1, \
                        open(os.path.join(out, n), "rb") as f2:
                    check(f1.read() == f2.read(), "the recorded folder's replay: %s differs" % n)
        # Recording again onto the folder: refused before the run.
        refused(a, "existing folder", source, ["--record-bag '%s' exists" % recorded],
                ["--record-bag", recorded])
    out = fresh(os.path.join(a.work, "record_out_flow_only"))
    p = sfrt_run(a, ["--replay-bag", source], out,
                 ["--flow-format", "npy", "--record-bag", os.path.join(out, "flow.mcap"),
                  "--record-bag-vis", "--record-bag-frame-id", "stereo_left",
                  "--record-bag-flow-only"], expect=0)
    if check(p.returncode == 0, "--record-bag-flow-only: exit %d" % p.returncode):
        check_recorded("flow only", read_mcap(a, os.path.join(out, "flow.mcap")), out)
    fifo = os.path.join(a.work, "bag2.fifo")
    if not os.path.exists(fifo):
        os.mkfifo(fifo)
    refused(a, "a FIFO", source, ["--record-bag '%s'" % fifo], ["--record-bag", fifo])
    refused(a, "a device", source, ["--record-bag '/dev/null'"], ["--record-bag", "/dev/null"])


SCENARIOS = {
    "rosbag2_record_bag_is_read_back_by_mcap_core_and_the_ros2_codec": scenario_record,
    "rosbag2_replay_gives_the_flow_files_of_the_directory_replay": scenario_same_flow,
    "rosbag2_missing_right_frame_breaks_the_window_chain": scenario_missing_right,
    "rosbag2_bad_bags_and_topics_are_refused_naming_them": scenario_bad_bags,
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", choices=sorted(SCENARIOS))
    for name in ("--sfrt", "--model", "--work", "--node", "--make-bag2", "--oracle"):
        ap.add_argument(name, required=True)
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    SCENARIOS[a.scenario](a)
    if FAILED:
        print("%d check(s) failed" % len(FAILED))
        sys.exit(1)
    print("ok")


if __name__ == "__main__":
    main()
