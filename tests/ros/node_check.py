#!/usr/bin/python3
"""The sfrt_ros node end to end (issue #14): a real roscore on a free loopback port, the node, and
`rosbag play` of a bag tools/ros/make_bag.py makes from a `sfrt synth` sequence.

usage: node_check.py SCENARIO --node BIN --sfrt BIN --model M.sfrt --work DIR
                     --make-bag tools/ros/make_bag.py

Scenarios (each one ctest test named after the behaviour it checks):
  node_publishes_each_windows_flow_equal_to_sfrt_infer
      rosbag play of a 6-frame bag, raw bgr8 Images and (with ~transport compressed) PNG
      CompressedImages on the .../compressed topics: one `flow` per window (5), each equal bit for bit to
      `sfrt infer` on the window's four images; stamps (flow: pair t's left stamp, flow_t1: pair
      t+1's), seq (the window number) and frame_id (the left images') as docs/ros.md says;
      flow_vis published; /diagnostics published with per-stage latency, ISA and counters;
      SIGINT ends the node with exit 0 and its summary.json.
  node_reports_bad_model_bad_profile_wrong_encoding_and_camera_mismatch
      a model file that is not one: exit 1 with the message `sfrt inspect` gives for it; an
      invalid ~config: exit 2 with the lines `sfrt config check` prints; an ~out it cannot write
      and ~budget_ms:=nan: exit 2 before the first frame, naming them; yuv422 images: skipped,
      one warning naming the encoding (rate-limited), counted in /diagnostics; camera_info with
      another focal length and baseline than the model's: one warning naming both values.
"""
import argparse
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time

FAILED = []
ANSI = re.compile(r"\x1b\[[0-9;]*m")


def check(ok, what):
    if not ok:
        FAILED.append(what)
        print("FAIL: " + what, flush=True)
    return ok


def fresh(path):
    shutil.rmtree(path, ignore_errors=True)
    os.makedirs(path)
    return path


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(predicate, timeout, step=0.05):
    end = time.time() + timeout
    while time.time() < end:
        if predicate():
            return True
        time.sleep(step)
    return predicate()


class Master:
    """roscore on a free loopback port, with the environment every child process inherits."""

    def __init__(self, work):
        self.port = free_port()
        os.environ["ROS_MASTER_URI"] = "http://127.0.0.1:%d" % self.port
        os.environ["ROS_IP"] = "127.0.0.1"
        os.environ.pop("ROS_HOSTNAME", None)
        os.environ["ROS_HOME"] = fresh(os.path.join(work, "ros_home"))
        os.environ["ROS_LOG_DIR"] = os.path.join(work, "ros_home", "log")
        self.log = open(os.path.join(work, "roscore.log"), "w")
        self.proc = subprocess.Popen(["roscore", "-p", str(self.port)], stdout=self.log,
                                     stderr=subprocess.STDOUT, start_new_session=True)
        import rosgraph
        self.master = rosgraph.Master("/sfrt_node_check")
        if not wait_for(self.online, 60, 0.2):
            sys.exit("roscore did not come up on port %d" % self.port)

    def online(self):
        try:
            return self.master.is_online()
        except Exception:
            return False

    def subscribers(self, topic):
        _, subs, _ = self.master.getSystemState()
        for name, nodes in subs:
            if name == topic:
                return nodes
        return []

    def close(self):
        try:
            os.killpg(self.proc.pid, signal.SIGINT)
            self.proc.wait(timeout=20)
        except Exception:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        self.log.close()


class Node:
    def __init__(self, args, work, name, params):
        self.out_path = os.path.join(work, name + ".out")
        self.err_path = os.path.join(work, name + ".err")
        cmd = [args.node, "__name:=" + name] + ["_%s:=%s" % kv for kv in params.items()]
        self.proc = subprocess.Popen(cmd, stdout=open(self.out_path, "w"),
                                     stderr=open(self.err_path, "w"))
        self.name = name

    def wait(self, timeout):
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            return None

    def interrupt(self, timeout=30):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        return self.wait(timeout)

    def stdout(self):
        with open(self.out_path) as f:
            return ANSI.sub("", f.read())

    def stderr(self):
        with open(self.err_path) as f:
            return ANSI.sub("", f.read())


def run(cmd):
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          timeout=600)


def synth(a, frames=6):
    root = os.path.join(a.work, "synth")
    shutil.rmtree(root, ignore_errors=True)
    p = run([a.sfrt, "synth", "--out", root, "--frames", str(frames), "--size", "64x96",
             "--seed", "5"])
    if not check(p.returncode == 0, "sfrt synth exit %d: %s" % (p.returncode, p.stderr)):
        sys.exit(1)
    seq = os.path.join(root, "frames_cleanpass", "0000")
    left, right = os.path.join(seq, "left"), os.path.join(seq, "right")
    names = sorted(os.listdir(left))
    return [os.path.join(left, n) for n in names], [os.path.join(right, n) for n in sorted(
        os.listdir(right))], left, right


class Collector:
    """Subscribes with rospy and keeps every message of the given topics."""

    def __init__(self, topics):
        import rospy
        self.lock = threading.Lock()
        self.msgs = {t: [] for t, _ in topics}
        self.subs = [rospy.Subscriber(t, cls, self._cb, callback_args=t, queue_size=100)
                     for t, cls in topics]

    def _cb(self, msg, topic):
        with self.lock:
            self.msgs[topic].append(msg)

    def get(self, topic):
        with self.lock:
            return list(self.msgs[topic])

    def connected(self):
        return all(s.get_num_connections() > 0 for s in self.subs)


def diag_values(status):
    return {kv.key: kv.value for kv in status.values}


def scenario_flow(a):
    import rospy

    lefts, rights, left_dir, right_dir = synth(a)
    master = Master(a.work)
    try:
        rospy.init_node("sfrt_node_check", disable_signals=True)
        want = []
        for k in range(len(lefts) - 1):
            path = os.path.join(a.work, "infer_%d.npy" % k)
            p = run([a.sfrt, "infer", "--model", a.model, "--left0", lefts[k], "--right0",
                     rights[k], "--left1", lefts[k + 1], "--right1", rights[k + 1], "-o", path])
            check(p.returncode == 0, "sfrt infer %d: %s" % (k, p.stderr))
            want.append(path)
        # Raw bgr8 through image_transport, and lossless PNG CompressedImages on the
        # .../compressed topics.
        for transport, extra in (("raw", []), ("compressed", [
                "--encoding", "png", "--left-topic", "/left/image_rect/compressed",
                "--right-topic", "/right/image_rect/compressed"])):
            flow_through_the_node(a, master, transport, extra, left_dir, right_dir, want)
    finally:
        master.close()


def flow_through_the_node(a, master, transport, bag_args, left_dir, right_dir, want):
    import json
    import numpy as np
    import rosbag
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import Image
    from std_msgs.msg import Header

    bag = os.path.join(a.work, "frames_%s.bag" % transport)
    p = run(["/usr/bin/python3", a.make_bag, "--left", left_dir, "--right", right_dir,
             "--out", bag] + bag_args)
    if not check(p.returncode == 0, "make_bag.py exit %d: %s" % (p.returncode, p.stderr)):
        return
    left_topic = "/left/image_rect" + ("/compressed" if transport == "compressed" else "")
    left_stamps = [m.header.stamp.to_nsec() for _, m, _ in
                   rosbag.Bag(bag).read_messages(topics=[left_topic])]
    col = Collector([("/flow", Image), ("/flow_t1", Header), ("/flow_vis", Image),
                     ("/diagnostics", DiagnosticArray)])
    out = fresh(os.path.join(a.work, "node_out_" + transport))
    node = Node(a, a.work, "sfrt_ros", {
        "model": a.model, "out": out, "queue_policy": "block", "input_queue": 16,
        "publish_vis": "true", "diagnostics_period": 0.2, "transport": transport})
    suffix = "/compressed" if transport == "compressed" else ""
    ready = wait_for(lambda: node.proc.poll() is None and col.connected()
                     and len(master.subscribers("/left/image_rect" + suffix)) > 0
                     and len(master.subscribers("/right/image_rect" + suffix)) > 0, 60)
    what = transport + ": "
    if not check(ready, what + "the node did not subscribe and advertise within 60 s: %s"
                 % node.stderr()):
        node.interrupt()
        return
    # Half speed: the header stamps keep their 30 fps spacing. -d 3: after advertising, rosbag
    # waits 3 s before the first message, so the node's subscriptions (listed by the master
    # above) have connected to it; with its default 0.2 s a loaded machine lost the first pairs.
    p = run(["rosbag", "play", "-q", "-d", "3", "-r", "0.5", bag])
    check(p.returncode == 0, what + "rosbag play exit %d: %s" % (p.returncode, p.stderr))
    wait_for(lambda: len(col.get("/flow")) >= 5 and len(col.get("/flow_vis")) >= 5, 120)
    time.sleep(0.5)  # nothing more should come
    code = node.interrupt()
    check(code == 0, what + "SIGINT: exit %s, stderr %r" % (code, node.stderr()))
    check("5 windows published, stopped by SIGINT" in node.stdout(),
          what + "the node's last line: %r" % node.stdout()[-400:])
    flows, t1s, vis = col.get("/flow"), col.get("/flow_t1"), col.get("/flow_vis")
    for sub in col.subs:
        sub.unregister()
    check(len(flows) == 5, what + "%d flow messages, expected 5 (one per window)" % len(flows))
    check(len(t1s) == len(flows) and len(vis) == len(flows),
          what + "%d flow_t1 and %d flow_vis messages for %d flows" % (len(t1s), len(vis),
                                                                      len(flows)))
    for k, m in enumerate(flows):
        if not check(m.header.seq == k, what + "flow %d: seq %d" % (k, m.header.seq)):
            continue
        check(m.encoding == "32FC3" and m.height == 64 and m.width == 96
              and m.step == 96 * 12 and m.is_bigendian == 0,
              what + "flow %d: %s %dx%d step %d" % (k, m.encoding, m.height, m.width, m.step))
        check(m.header.frame_id == "left_camera",
              what + "flow %d: frame_id %r" % (k, m.header.frame_id))
        check(m.header.stamp.to_nsec() == left_stamps[k],
              what + "flow %d: stamp %d, expected pair t's left stamp %d"
              % (k, m.header.stamp.to_nsec(), left_stamps[k]))
        if k < len(t1s):
            check(t1s[k].seq == k and t1s[k].stamp.to_nsec() == left_stamps[k + 1]
                  and t1s[k].frame_id == "left_camera",
                  what + "flow_t1 %d: seq %d stamp %d, expected pair t+1's %d"
                  % (k, t1s[k].seq, t1s[k].stamp.to_nsec(), left_stamps[k + 1]))
        if k < len(vis):
            check(vis[k].encoding == "bgr8" and vis[k].header.seq == k,
                  what + "flow_vis %d: %s seq %d" % (k, vis[k].encoding, vis[k].header.seq))
        if k < len(want) and os.path.exists(want[k]):
            ref = np.load(want[k]).astype("<f4")
            got = np.frombuffer(m.data, dtype="<f4").reshape(m.height, m.width, 3)
            check(ref.shape == got.shape and ref.tobytes() == got.tobytes(),
                  what + "flow %d differs from sfrt infer on its four images (max |diff| %s)"
                  % (k, np.abs(ref - got).max() if ref.shape == got.shape else "shape"))
    statuses = [s for arr in col.get("/diagnostics") for s in arr.status
                if s.name == "sfrt_ros: scene flow"]
    check(len(statuses) > 0, what + "no /diagnostics status named 'sfrt_ros: scene flow'")
    check(any(diag_values(s).get("windows published") == "5" for s in statuses),
          what + "no /diagnostics status counts the 5 windows: %s"
          % [diag_values(s).get("windows published") for s in statuses])
    # The statuses the output stage publishes while windows complete carry the latencies; the
    # ones after the bag ended say that no window came (WARN) and carry the counters.
    full = [s for s in statuses if "infer p50 ms" in diag_values(s)]
    if check(len(full) > 0, what + "no /diagnostics status with latencies"):
        v = diag_values(full[-1])
        for key in ("source p50 ms", "preprocess p99 ms", "infer p50 ms", "infer p99 ms",
                    "output p99 ms", "end_to_end p50 ms", "end_to_end p99 ms", "fps", "isa",
                    "precision", "deadline misses", "pairs dropped at the source (newest wins)",
                    "windows dropped in the pipeline (newest wins)", "windows published"):
            check(key in v, what + "/diagnostics has no %r (it has %s)" % (key, sorted(v)))
        check(v.get("deadline misses") == "0" and v.get("precision") == "fp32"
              and full[-1].level == 0 and float(v.get("infer p50 ms", "0")) > 0,
              what + "/diagnostics values %s, level %d" % (v, full[-1].level))
    summary_path = os.path.join(out, "summary.json")
    if check(os.path.exists(summary_path), what + "no summary.json in ~out"):
        with open(summary_path) as f:
            s = json.load(f)
        check(s["frames"]["written"] == 5 and s["source"]["kind"] == "ros-topics"
              and s["source"]["pairs"] == 6 and s["stopped_by"] == "SIGINT",
              what + "summary frames %s source %s stopped_by %s"
              % (s["frames"], s["source"], s.get("stopped_by")))


def scenario_errors(a):
    import rospy
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import CameraInfo, Image

    master = Master(a.work)
    try:
        # A model file that is not one: the loader's message, exit 1.
        junk = os.path.join(a.work, "junk.sfrt")
        with open(junk, "wb") as f:
            f.write(b"not a model\n")
        want = run([a.sfrt, "inspect", junk]).stderr.strip()
        want = want[len("sfrt inspect: "):] if want.startswith("sfrt inspect: ") else want
        node = Node(a, a.work, "bad_model", {"model": junk})
        code = node.wait(60)
        check(code == 1 and want and want in node.stderr(),
              "bad model: exit %s, stderr %r, expected %r" % (code, node.stderr(), want))
        # An invalid deployment profile: the lines `sfrt config check` prints, exit 2.
        profile = os.path.join(a.work, "bad.yaml")
        with open(profile, "w") as f:
            f.write("version: 1\nlatency:\n  budget_ms: -5\n")
        want = [line for line in run([a.sfrt, "config", "check", profile]).stderr.splitlines()
                if line.startswith(profile + ":")]
        node = Node(a, a.work, "bad_config", {"config": profile})
        code = node.wait(60)
        err = node.stderr()
        check(code == 2 and want and all(line in err for line in want),
              "bad profile: exit %s, stderr %r, expected the lines %r" % (code, err, want))

        # An ~out it could never write summary.json into: refused before the first frame
        # (exit 2 naming it), not found out at shutdown. NaN is no budget: refused too.
        node = Node(a, a.work, "bad_out", {"model": a.model, "out": "/proc/sfrt-nonexistent/dir"})
        code = node.wait(60)
        check(code == 2 and "~out '/proc/sfrt-nonexistent/dir'" in node.stderr(),
              "unwritable ~out: exit %s, stderr %r" % (code, node.stderr()))
        node = Node(a, a.work, "nan_budget", {"model": a.model, "budget_ms": "nan"})
        code = node.wait(60)
        check(code == 2 and "must be a finite number" in node.stderr(),
              "~budget_ms nan: exit %s, stderr %r" % (code, node.stderr()))

        # Images it cannot convert and a camera that is not the model's.
        rospy.init_node("sfrt_node_check", disable_signals=True)
        col = Collector([("/diagnostics", DiagnosticArray)])
        pubs = {t: rospy.Publisher(t, cls, queue_size=20) for t, cls in (
            ("/left/image_rect", Image), ("/right/image_rect", Image),
            ("/left/camera_info", CameraInfo), ("/right/camera_info", CameraInfo))}
        node = Node(a, a.work, "sfrt_ros", {"model": a.model, "diagnostics_period": 0.2})
        ready = wait_for(lambda: node.proc.poll() is None and col.connected()
                         and all(p.get_num_connections() > 0 for p in pubs.values()), 60)
        if not check(ready, "the node did not connect within 60 s: %s" % node.stderr()):
            node.interrupt()
            return
        for side, tx in (("left", 0.0), ("right", -500.0 * 0.3)):
            info = CameraInfo()
            info.header.frame_id = side + "_camera"
            info.width, info.height = 96, 64
            info.P = [500.0, 0, 48, tx, 0, 500.0, 32, 0, 0, 0, 1, 0]
            pubs["/%s/camera_info" % side].publish(info)
        start = rospy.Time.now()
        for i in range(6):
            stamp = start + rospy.Duration(0, i * 33333333)
            for side in ("left", "right"):
                im = Image()
                im.header.stamp = stamp
                im.header.frame_id = side + "_camera"
                im.height, im.width, im.encoding, im.step = 64, 96, "yuv422", 192
                im.data = bytes(64 * 192)
                pubs["/%s/image_rect" % side].publish(im)
            time.sleep(0.05)

        def skipped():
            for arr in col.get("/diagnostics"):
                for s in arr.status:
                    if diag_values(s).get("pairs skipped (bad image)") == "6":
                        return s
            return None

        status = None
        if wait_for(lambda: skipped() is not None, 30):
            status = skipped()
        check(status is not None and status.level == 1 and "waiting" in status.message,
              "/diagnostics never counted the 6 skipped pairs (WARN, waiting): %s"
              % (status.message if status else [diag_values(s) for arr in col.get(
                  "/diagnostics") for s in arr.status][-1:]))
        code = node.interrupt()
        err = node.stderr()
        check(code == 0, "SIGINT before any window: exit %s, stderr %r" % (code, err))
        check(err.count("encoding 'yuv422'") == 1 and "skipped 1 stereo pair(s)" in err,
              "one rate-limited warning naming yuv422 expected: %r" % err)
        check(err.count("camera_info: focal length 500.00 px") == 1
              and "differs from the model's training camera (1050.00 px)" in err,
              "focal length warning naming 500 and 1050 px expected: %r" % err)
        check(err.count("camera_info: baseline 0.3000") == 1
              and "training camera (1.0000)" in err,
              "baseline warning naming 0.3 and 1 expected: %r" % err)
    finally:
        master.close()


SCENARIOS = {
    "node_publishes_each_windows_flow_equal_to_sfrt_infer": scenario_flow,
    "node_reports_bad_model_bad_profile_wrong_encoding_and_camera_mismatch": scenario_errors,
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", choices=sorted(SCENARIOS))
    ap.add_argument("--node", required=True)
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--model", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--make-bag", required=True)
    a = ap.parse_args()
    a.work = os.path.abspath(fresh(a.work))
    SCENARIOS[a.scenario](a)
    if FAILED:
        print("%d check(s) failed" % len(FAILED))
        sys.exit(1)
    print("ok")


if __name__ == "__main__":
    main()
