#!/usr/bin/python3
"""`sfrt run --replay-bag` end to end (issue #14), on bags made by tools/ros/make_bag.py from a
`sfrt synth` sequence.

usage: bag_check.py SCENARIO --sfrt BIN --model M.sfrt --work DIR --make-bag tools/ros/make_bag.py

Scenarios (each one ctest test named after the behaviour it checks):
  bag_replay_gives_the_flow_files_of_the_directory_replay
      a bag of raw bgr8 frames and one of rgb8, and one of PNG CompressedImages (lossless): every
      window's flow file equals, byte for byte, the one `sfrt run --replay-left/--replay-right`
      writes from the directory the bag was made from; each pair rectified once.
  missing_right_frame_breaks_the_window_chain
      a bag without right frame 3: the left frame 3 is counted unpaired (summary.json
      source.unpaired_left, drops.source), no window spans the gap (windows 0-1, 1-2, 4-5; the
      pair 4 opens none: windows.broken_by_lost_frame 1), and the flow files and windows.csv
      name each window by the bag's message numbers, so the files after the gap keep theirs.
  record_bag_holds_each_windows_flow_with_the_input_stamps
      --record-bag (with --record-bag-vis) on a bag replay: /flow has one 32FC3 message per window
      equal to that window's .npy flow file, stamped with the left stamp of pair t, seq = window,
      frame_id as given; /flow_t1 carries pair t+1's stamp; /flow_vis one bgr8 picture each;
      /left/image_rect and /right/image_rect hold the bag's 6 bgr8 images again (same bytes,
      each pair stamped with its left image's stamp); no temporary file is left. A --record-bag that is a character device or a FIFO is refused
      (exit 2, no summary.json) before the
      first frame, naming it.
  bad_bags_and_topics_are_refused_naming_them
      a topic not in the bag (the error lists the bag's topics), a file that is not a bag, a
      truncated bag, and an image encoding the reader does not convert (--on-bad-frame stop names
      the topic, message and encoding; skip goes on and lists it).
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


def make_bag(a, left, right, name, extra=()):
    out = os.path.join(a.work, name)
    p = run(["/usr/bin/python3", a.make_bag, "--left", left, "--right", right, "--out", out]
            + list(extra), expect=0)
    check(p.returncode == 0, "make_bag.py %s exit %d: %s" % (name, p.returncode, p.stderr))
    return out


def sfrt_run(a, source, out, extra=(), expect=None):
    return run([a.sfrt, "run", "--model", a.model, "--out", out, "--progress", "off", "--no-png"]
               + source + list(extra), expect)


def flows(out):
    return sorted(n for n in os.listdir(out) if n.endswith(".pfm"))


def summary(out):
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def scenario_same_flow(a):
    left, right = synth(a)
    want_dir = fresh(os.path.join(a.work, "dir_out"))
    p = sfrt_run(a, ["--replay-left", left, "--replay-right", right], want_dir)
    check(p.returncode == 0, "directory replay exit %d" % p.returncode)
    want = flows(want_dir)
    check(len(want) == 5, "directory replay wrote %d flow files, expected 5" % len(want))
    for encoding in ("bgr8", "rgb8", "png"):
        bag = make_bag(a, left, right, "frames_%s.bag" % encoding, ["--encoding", encoding])
        out = fresh(os.path.join(a.work, "bag_out_" + encoding))
        p = sfrt_run(a, ["--replay-bag", bag], out, expect=0)
        if not check(p.returncode == 0, "%s: exit %d: %s" % (encoding, p.returncode, p.stderr)):
            continue
        got = flows(out)
        check(got == want, "%s: flow files %s, expected %s" % (encoding, got, want))
        for name in want:
            if name in got:
                with open(os.path.join(out, name), "rb") as f1, \
                        open(os.path.join(want_dir, name), "rb") as f2:
                    check(f1.read() == f2.read(), "%s: %s differs from the directory replay's"
                          % (encoding, name))
        s = summary(out)
        check(s["source"]["kind"] == "replay-bag" and s["source"]["pairs"] == 6,
              "%s: summary source %s" % (encoding, s["source"]))
        check(s["preprocess"] == {"pairs_rectified": 6, "pairs_reused": 4},
              "%s: summary preprocess %s" % (encoding, s["preprocess"]))


def scenario_missing_right(a):
    left, right = synth(a)
    bag = make_bag(a, left, right, "drop3.bag", ["--drop-right", "3"])
    out = fresh(os.path.join(a.work, "drop_out"))
    p = sfrt_run(a, ["--replay-bag", bag], out, expect=0)
    check(p.returncode == 0, "exit %d" % p.returncode)
    s = summary(out)
    src = s["source"]
    check(src["unpaired_left"] == 1 and src["unpaired_right"] == 0,
          "unpaired left/right %s/%s, expected 1/0" % (src["unpaired_left"], src["unpaired_right"]))
    check(src["messages_read"] == {"left": 6, "right": 5}, "messages read %s" % src["messages_read"])
    check(s["drops"]["source"] == 1, "drops.source %s" % s["drops"]["source"])
    check(s["frames"]["written"] == 3, "written %d, expected 3" % s["frames"]["written"])
    check(s["windows"] == {"formed": 3, "broken_by_lost_frame": 1, "skipped_for_gap": 0,
                           "stream_restarts": 0}, "summary windows %s" % s["windows"])
    got = flows(out)
    want = ["frame_000000.pfm", "frame_000001.pfm", "frame_000004.pfm"]
    check(got == want, "flow files %s, expected %s" % (got, want))
    with open(os.path.join(out, "windows.csv")) as f:
        rows = [line.rstrip("\n").split(",") for line in f]
    check(rows[0][:4] == ["file", "sequence", "frame_t", "frame_t1"], "windows.csv header %s"
          % rows[0])
    check([r[2:4] for r in rows[1:]] == [["0", "1"], ["1", "2"], ["4", "5"]],
          "windows.csv frames %s" % rows[1:])
    stamps = [(int(r[4]), int(r[5])) for r in rows[1:]]
    steps = [t1 - t0 for t0, t1 in stamps]  # 30 fps in whole ns: 33333333 or 33333334
    check(min(steps) > 0 and max(steps) - min(steps) <= 1,
          "windows.csv stamps %s: one time step expected" % stamps)
    check("pair(s) opened no window (lost frame 1" in p.stdout,
          "the console does not count the broken chain: %r" % p.stdout)


def scenario_bad(a):
    left, right = synth(a)
    bag = make_bag(a, left, right, "frames_bgr8.bag")
    out = fresh(os.path.join(a.work, "bad_out"))
    p = sfrt_run(a, ["--replay-bag", bag, "--left-topic", "/camera/left"], out)
    check(p.returncode == 2 and "has no topic '/camera/left' (it has " in p.stderr
          and "/left/image_rect (sensor_msgs/Image)" in p.stderr,
          "missing topic: exit %d, stderr %r" % (p.returncode, p.stderr))
    not_bag = os.path.join(a.work, "not_a.bag")
    with open(not_bag, "w") as f:
        f.write("hello\n")
    p = sfrt_run(a, ["--replay-bag", not_bag], out)
    check(p.returncode == 2 and ("cannot read '%s' as a ROS bag" % not_bag) in p.stderr,
          "not a bag: exit %d, stderr %r" % (p.returncode, p.stderr))
    truncated = os.path.join(a.work, "truncated.bag")
    with open(bag, "rb") as f:
        data = f.read()
    with open(truncated, "wb") as f:
        f.write(data[:len(data) // 2])
    p = sfrt_run(a, ["--replay-bag", truncated], out)
    check(p.returncode != 0 and truncated in p.stderr and "Traceback" not in p.stderr,
          "truncated: exit %d, stderr %r" % (p.returncode, p.stderr))
    # An encoding the reader does not convert: yuv422 on the right from message 2 on.
    odd = os.path.join(a.work, "yuv.bag")
    code = (
        "import rosbag\n"
        "with rosbag.Bag(%r) as src, rosbag.Bag(%r, 'w') as dst:\n"
        "    for topic, msg, t in src.read_messages():\n"
        "        if topic == '/right/image_rect' and msg.header.seq >= 2:\n"
        "            msg.encoding = 'yuv422'\n"
        "        dst.write(topic, msg, t)\n" % (bag, odd))
    p = run(["/usr/bin/python3", "-c", code], expect=0)
    check(p.returncode == 0, "making the yuv422 bag: %s" % p.stderr)
    p = sfrt_run(a, ["--replay-bag", odd], fresh(out))
    check(p.returncode == 1 and "/right/image_rect message 2" in p.stderr
          and "encoding 'yuv422'" in p.stderr,
          "bad encoding, stop: exit %d, stderr %r" % (p.returncode, p.stderr))
    p = sfrt_run(a, ["--replay-bag", odd, "--on-bad-frame", "skip"], fresh(out))
    check(p.returncode == 0 and "bad frame skipped" in p.stderr,
          "bad encoding, skip: exit %d, stderr %r" % (p.returncode, p.stderr))
    if p.returncode == 0:
        s = summary(out)
        check(len(s["bad_frames"]) == 4 and "yuv422" in s["bad_frames"][0]["reason"],
              "bad encoding, skip: bad_frames %s" % s["bad_frames"])


def scenario_record(a):
    left, right = synth(a)
    bag = make_bag(a, left, right, "frames_bgr8.bag")
    out = fresh(os.path.join(a.work, "record_out"))
    recorded = os.path.join(out, "flow.bag")
    p = sfrt_run(a, ["--replay-bag", bag], out,
                 ["--flow-format", "npy", "--record-bag", recorded, "--record-bag-vis",
                  "--record-bag-frame-id", "stereo_left"], expect=0)
    if not check(p.returncode == 0, "exit %d" % p.returncode):
        return
    check(not os.path.exists(recorded + ".tmp.bag"), "the temporary bag is left behind")
    code = r"""
import json, sys
import numpy as np
import rosbag
src, rec, out = sys.argv[1:4]
left = [m.header.stamp.to_nsec() for _, m, _ in rosbag.Bag(src).read_messages(topics=['/left/image_rect'])]
res = {"flow": [], "t1": [], "vis": [], "inputs": {}}
sides = ('/left/image_rect', '/right/image_rect')
def images(path):
    with rosbag.Bag(path) as b:
        return {t: [(m.header.stamp.to_nsec(), m.encoding, m.height, m.width, m.step, bytes(m.data))
                    for _, m, _ in b.read_messages(topics=[t])] for t in sides}
src_images, rec_images = images(src), images(rec)
# Each pair is recorded with the pair's stamp, the left image's (the bag's right stamps are a few
# milliseconds off them).
for t in sides:
    want = [(l[0],) + r[1:] for l, r in zip(src_images[sides[0]], src_images[t])]
    res["inputs"][t] = [len(src_images[t]), len(rec_images[t]), want == rec_images[t]]
with rosbag.Bag(rec) as b:
    for topic, m, t in b.read_messages():
        if topic == '/flow':
            a = np.frombuffer(m.data, dtype='<f4').reshape(m.height, m.width, 3)
            ref = np.load('%s/frame_%06d.npy' % (out, m.header.seq))
            res["flow"].append([m.encoding, m.header.seq, m.header.frame_id,
                                m.header.stamp.to_nsec() == left[m.header.seq],
                                bool(np.array_equal(a, ref)), t.to_nsec() == m.header.stamp.to_nsec()])
        elif topic == '/flow_t1':
            res["t1"].append(m.stamp.to_nsec() == left[m.seq + 1])
        elif topic == '/flow_vis':
            res["vis"].append(m.encoding)
print(json.dumps(res))
"""
    p = run(["/usr/bin/python3", "-c", code, bag, recorded, out], expect=0)
    if not check(p.returncode == 0, "reading the recorded bag: %s" % p.stderr):
        return
    res = json.loads(p.stdout)
    check(len(res["flow"]) == 5, "%d /flow messages, expected 5" % len(res["flow"]))
    for i, (enc, seq, frame, stamp_ok, data_ok, time_ok) in enumerate(res["flow"]):
        check(enc == "32FC3" and seq == i and frame == "stereo_left",
              "/flow %d: encoding %s seq %s frame_id %s" % (i, enc, seq, frame))
        check(stamp_ok and time_ok, "/flow %d: not stamped with pair t's left stamp" % i)
        check(data_ok, "/flow %d: differs from frame_%06d.npy" % (i, i))
    check(res["t1"] == [True] * 5, "/flow_t1 stamps %s" % res["t1"])
    check(res["vis"] == ["bgr8"] * 5, "/flow_vis %s" % res["vis"])
    for topic, (n_src, n_rec, same) in sorted(res["inputs"].items()):
        check(n_src == n_rec == 6 and same, "%s: %d images recorded of the bag's %d (equal: %s)"
              % (topic, n_rec, n_src, same))
    # A device or a FIFO: a usage error before anything is written (no summary.json either).
    fifo = os.path.join(a.work, "bag.fifo")
    if not os.path.exists(fifo):
        os.mkfifo(fifo)
    for target in ("/dev/null", fifo):
        refused = os.path.join(a.work, "refused_out")
        shutil.rmtree(refused, ignore_errors=True)
        p = sfrt_run(a, ["--replay-bag", bag], refused, ["--record-bag", target])
        check(p.returncode == 2 and ("--record-bag '%s'" % target) in p.stderr,
              "--record-bag %s: exit %d, stderr %r" % (target, p.returncode, p.stderr))
        check(not os.path.exists(os.path.join(refused, "summary.json")),
              "--record-bag %s: a summary.json was written" % target)
    check(not os.path.exists("/dev/null.tmp.bag"), "a temporary bag beside /dev/null")


SCENARIOS = {
    "record_bag_holds_each_windows_flow_with_the_input_stamps": scenario_record,
    "bag_replay_gives_the_flow_files_of_the_directory_replay": scenario_same_flow,
    "missing_right_frame_breaks_the_window_chain": scenario_missing_right,
    "bad_bags_and_topics_are_refused_naming_them": scenario_bad,
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", choices=sorted(SCENARIOS))
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--model", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--make-bag", required=True)
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    SCENARIOS[a.scenario](a)
    if FAILED:
        print("%d check(s) failed" % len(FAILED))
        return 1
    print("PASS " + a.scenario)
    return 0


if __name__ == "__main__":
    sys.exit(main())
