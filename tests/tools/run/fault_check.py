#!/usr/bin/python3
"""Faults during `sfrt run` (issue #8), end to end on the sfrt binary and generated frames.

usage: fault_check.py SCENARIO --sfrt BIN --model M.sfrt --work DIR [--preload SHIM.so]
                      [--camera-preload FAKE_V4L2.so] [--trials N] [--seed S]

Scenarios (each is one ctest test named after the behaviour it checks):
  full_disk_stops_the_run_naming_the_file_and_errno
      ENOSPC part-way through a window's flow file, and part-way through its PNG after its flow
      file was written (output_fault_preload.cc): exit 1, the error names the file and says
      "No space left on device", only the earlier windows' files remain, each complete (the
      failed window's flow file is removed), no temporary file, summary.json says so.
  full_disk_with_skip_drops_the_window_and_goes_on
      --on-output-error skip with one window's writes failing: exit 0, every other window
      written, the skipped one listed in summary.json and warned about on stderr.
  read_only_directory_stops_the_run_naming_the_file
      every file creation fails with EROFS: exit 1, the error names the first flow file and says
      "Read-only file system", nothing is left in the directory, the missing summary is warned
      about.
  full_disk_everywhere_leaves_only_complete_files
      ENOSPC for every file including summary.json after a few windows: exit 1, only complete
      windows, no temporary file.
  signals_at_random_moments_leave_only_complete_files
      SIGINT or SIGTERM (seeded random choice) after a seeded random delay, --trials times:
      exit 0, the printed "frames N (stopped by SIG...)" and summary.json agree with the N
      complete windows on disk, no temporary file.
  stalled_camera_is_reported_naming_the_device_and_sigterm_still_stops
      two fake cameras (--camera-preload), the right one never delivers a frame: the watchdog
      is logged naming it, the run does not end by itself, SIGTERM ends it within 5 s with
      exit 0, 0 frames, timeouts counted in summary.json.
  camera_missing_at_start_is_an_error_naming_the_device
      the right camera is not there at the start: exit 1 with an error naming it, no hang.
  camera_unplugged_mid_run_is_reported_naming_the_device_and_leaves_only_complete_files
      the right camera unplugs itself after 20 frames (shim knob unplug_after_frames) and does
      not come back: the disconnect and the failing reopen attempts are logged naming it, the
      run does not end by itself, SIGTERM ends it with exit 0, "frames N (stopped by SIGTERM)"
      and summary.json agree with the N complete windows on disk (all from before the unplug),
      the disconnect is counted for /dev/video1 only, no temporary file.
  camera_replugged_mid_run_resumes_and_counts_the_reconnect
      the right camera unplugs itself after 20 frames and comes back 500 ms later
      (replug_after_ms): the run reconnects it and goes on to --max-frames 40 (more windows than
      the frames before the unplug allow), exit 0, one disconnect and one reopen counted for
      /dev/video1, only complete files.
"""
import argparse
import glob
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import threading
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from make_test_images import write_png  # noqa: E402  (zlib-only PNG writer)

import numpy as np  # noqa: E402

H, W = 64, 96
FAILURES = []


def check(cond, what):
    if not cond:
        FAILURES.append(what)
        print("FAIL: " + what, flush=True)
    return cond


def make_frames(root, count, seed=8):
    """<root>/seq/{left,right}/NNNN.png: `count` stereo pairs of seeded noise, H x W."""
    if os.path.isdir(root) and len(glob.glob(os.path.join(root, "seq", "left", "*.png"))) == count:
        return root
    shutil.rmtree(root, ignore_errors=True)
    rng = np.random.default_rng(seed)
    for side in ("left", "right"):
        os.makedirs(os.path.join(root, "seq", side))
    for i in range(count):
        for side in ("left", "right"):
            img = rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8)
            write_png(os.path.join(root, "seq", side, "%04d.png" % i), img)
    return root


def parse_pfm(path):
    """(height, width, channels) of a complete PFM, or None."""
    with open(path, "rb") as f:
        data = f.read()
    m = re.match(rb"(PF|Pf)\n(\d+) (\d+)\n(-?[0-9.]+)\n", data)
    if not m:
        return None
    channels = 3 if m.group(1) == b"PF" else 1
    w, h = int(m.group(2)), int(m.group(3))
    if len(data) - m.end() != w * h * channels * 4:
        return None
    return (h, w, channels)


def png_complete(path):
    with open(path, "rb") as f:
        data = f.read()
    return data.startswith(b"\x89PNG\r\n\x1a\n") and data.endswith(b"IEND\xaeB`\x82")


def pictures_dropped(out):
    """The pictures the run's summary says its queued pictures sink dropped to keep up (by
    design: newest-wins), 0 without a summary."""
    path = os.path.join(out, "summary.json")
    if not os.path.exists(path):
        return 0
    with open(path) as f:
        sinks = json.load(f).get("sinks", [])
    return sum(s.get("dropped", 0) for s in sinks if s.get("name") == "pictures")


def inspect_out(out):
    """Stems with a complete pfm and png; fails on temporary, incomplete or half-present windows.
    A window without its png counts as complete only as often as the summary says the pictures
    sink dropped one to keep up."""
    names = os.listdir(out)
    temps = [n for n in names if ".tmp." in n]
    check(not temps, "temporary files left: %s" % temps)
    stems = sorted({n.rsplit(".", 1)[0] for n in names if n.endswith((".pfm", ".png"))})
    complete = []
    dropped_left = pictures_dropped(out)
    for stem in stems:
        pfm, png = os.path.join(out, stem + ".pfm"), os.path.join(out, stem + ".png")
        picture_dropped = os.path.exists(pfm) and not os.path.exists(png) and dropped_left > 0
        if picture_dropped:
            dropped_left -= 1
        ok = check(os.path.exists(pfm) and (os.path.exists(png) or picture_dropped),
                   "window %s has only some of its files" % stem)
        ok = ok and check(parse_pfm(pfm) == (H, W, 3), "%s is not a complete PFM" % pfm)
        ok = ok and check(picture_dropped or png_complete(png), "%s is not a complete PNG" % png)
        if ok:
            complete.append(stem)
    return complete


def load_summary(out):
    path = os.path.join(out, "summary.json")
    if not check(os.path.exists(path), "no summary.json in " + out):
        return None
    with open(path) as f:
        return json.load(f)


def fresh(path):
    shutil.rmtree(path, ignore_errors=True)
    os.makedirs(path)
    return path


def sfrt_run(a, root, out, extra=(), fault=None):
    cmd = [a.sfrt, "run", "--model", a.model, "--replay", root, "--out", out,
           "--progress", "off"] + list(extra)
    env = dict(os.environ)
    if fault is not None:
        env["LD_PRELOAD"] = a.preload
        env.update(fault)
    print("+ %s%s" % ("".join("%s=%s " % kv for kv in (fault or {}).items()), " ".join(cmd)),
          flush=True)
    p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       timeout=600)
    print(p.stdout + p.stderr, flush=True)
    return p


def baseline(a, frames):
    """A clean run: the stems in order and the size of each file."""
    root = make_frames(os.path.join(a.work, "frames%d" % frames), frames)
    out = fresh(os.path.join(a.work, "clean"))
    p = sfrt_run(a, root, out)
    check(p.returncode == 0, "clean run exit %d" % p.returncode)
    stems = inspect_out(out)
    check(len(stems) == frames - 1, "clean run wrote %d windows, expected %d"
          % (len(stems), frames - 1))
    sizes = {s: (os.path.getsize(os.path.join(out, s + ".pfm")),
                 os.path.getsize(os.path.join(out, s + ".png"))) for s in stems}
    return root, stems, sizes


def scenario_full_disk_stop(a):
    root, stems, sizes = baseline(a, 10)
    before = sum(sizes[s][0] + sizes[s][1] for s in stems[:3])
    victim = stems[3]
    cases = [("in the flow file", before + sizes[victim][0] // 2),
             ("in the PNG, after the flow file", before + sizes[victim][0] + sizes[victim][1] // 2)]
    for where, budget in cases:
        print("--- ENOSPC %s of %s" % (where, victim), flush=True)
        out = fresh(os.path.join(a.work, "full_disk_stop"))
        p = sfrt_run(a, root, out, fault={"SFRT_FAULT_ERRNO": "ENOSPC", "SFRT_FAULT_MATCH": "seq_",
                                          "SFRT_FAULT_AFTER_BYTES": str(budget)})
        check(p.returncode == 1, "exit %d, expected 1" % p.returncode)
        ext = "pfm" if where == "in the flow file" else "png"
        want = "cannot write '%s' (write): No space left on device" % os.path.join(
            out, victim + "." + ext)
        check(want in p.stderr, "stderr does not say: " + want)
        check(p.stderr.count("\n") <= 3, "more than a few lines on stderr")
        done = inspect_out(out)
        check(done == stems[:3], "complete windows %s, expected %s" % (done, stems[:3]))
        s = load_summary(out)
        if s:
            check(s["stopped_by"] == "error", "stopped_by %s" % s["stopped_by"])
            check(s["frames"]["written"] == 3, "summary says %d written" % s["frames"]["written"])
            check("No space left on device" in (s["error"] or ""), "summary error: %s" % s["error"])
            check(s["output_errors"]["count"] == 1 and s["output_errors"]["policy"] == "stop",
                  "summary output_errors: %s" % s["output_errors"])


def scenario_full_disk_skip(a):
    root, stems, _ = baseline(a, 10)
    victim = stems[4]
    out = fresh(os.path.join(a.work, "full_disk_skip"))
    p = sfrt_run(a, root, out, extra=["--on-output-error", "skip"],
                 fault={"SFRT_FAULT_ERRNO": "ENOSPC", "SFRT_FAULT_MATCH": victim})
    check(p.returncode == 0, "exit %d, expected 0" % p.returncode)
    check("warning: window %s skipped: cannot write '%s.pfm' (write): No space left on device"
          % (victim, os.path.join(out, victim)) in p.stderr, "no warning naming the window")
    done = inspect_out(out)
    check(done == [s for s in stems if s != victim],
          "complete windows %s, expected all but %s" % (done, victim))
    s = load_summary(out)
    if s:
        check(s["stopped_by"] == "end of source", "stopped_by %s" % s["stopped_by"])
        check(s["frames"]["written"] == len(stems) - 1, "written %d" % s["frames"]["written"])
        oe = s["output_errors"]
        check(oe["policy"] == "skip" and oe["count"] == 1 and len(oe["skipped"]) == 1
              and oe["skipped"][0]["window"] == victim
              and "No space left on device" in oe["skipped"][0]["error"],
              "summary output_errors: %s" % oe)


def scenario_read_only(a):
    root, stems, _ = baseline(a, 4)
    out = fresh(os.path.join(a.work, "read_only"))
    # Only the output files' temporary names fail: a directory where nothing at all can be
    # created is refused before the run starts (exit 2, validate_check.py), so this one becomes
    # read-only after that check, as a remount during a run would.
    p = sfrt_run(a, root, out, fault={"SFRT_FAULT_OP": "create", "SFRT_FAULT_ERRNO": "EROFS",
                                      "SFRT_FAULT_MATCH": ".tmp."})
    check(p.returncode == 1, "exit %d, expected 1" % p.returncode)
    want = "cannot create a temporary file beside '%s': Read-only file system" % os.path.join(
        out, stems[0] + ".pfm")
    check(want in p.stderr, "stderr does not say: " + want)
    check("warning: no summary: cannot create a temporary file beside '%s'"
          % os.path.join(out, "summary.json") in p.stderr, "no warning about the summary")
    check(os.listdir(out) == [], "files left: %s" % os.listdir(out))


def scenario_full_disk_everywhere(a):
    root, stems, sizes = baseline(a, 8)
    budget = sum(sizes[s][0] + sizes[s][1] for s in stems[:2]) + sizes[stems[2]][0] // 3
    out = fresh(os.path.join(a.work, "full_disk_everywhere"))
    p = sfrt_run(a, root, out, fault={"SFRT_FAULT_ERRNO": "ENOSPC",
                                      "SFRT_FAULT_AFTER_BYTES": str(budget)})
    check(p.returncode == 1, "exit %d, expected 1" % p.returncode)
    check("No space left on device" in p.stderr, "stderr does not name the errno")
    done = inspect_out(out)
    check(done == stems[:2], "complete windows %s, expected %s" % (done, stems[:2]))
    check(not os.path.exists(os.path.join(out, "summary.json")), "a summary.json on a full disk?")


def scenario_signals(a):
    frames = 160
    root = make_frames(os.path.join(a.work, "frames%d" % frames), frames)
    rng = random.Random(a.seed)

    def start(out):
        cmd = [a.sfrt, "run", "--model", a.model, "--replay", root, "--out", out,
               "--progress", "off"]
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # The handlers are installed when the pipeline starts (before, a signal ends the process
        # with its default action and nothing is written): wait for the first file.
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline and not glob.glob(
                os.path.join(out, "*.p??")):
            time.sleep(0.002)
        return proc

    # The signal must land while frames are still being written, whatever this machine's speed:
    # time one undisturbed run from its first file to its exit and draw delays inside that span.
    proc = start(fresh(os.path.join(a.work, "signals")))
    t0 = time.monotonic()
    proc.communicate(timeout=300)
    span = time.monotonic() - t0
    print("undisturbed run: %.3f s from the first file to exit" % span, flush=True)
    stopped = 0
    for trial in range(a.trials):
        sig = rng.choice([signal.SIGINT, signal.SIGTERM])
        delay = rng.uniform(0.0, 0.6 * span)
        out = fresh(os.path.join(a.work, "signals"))
        proc = start(out)
        time.sleep(delay)
        if proc.poll() is None:
            proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=300)
        m = re.search(r"^frames\s+(\d+) \(stopped by ([^)]*)\)", stdout, re.M)
        done = inspect_out(out)
        s = load_summary(out)
        print("trial %d: %s after %.3f s: exit %d, %s, %d complete windows on disk"
              % (trial, signal.Signals(sig).name, delay, proc.returncode,
                 m.group(0) if m else "no summary line", len(done)), flush=True)
        if not check(proc.returncode == 0 and m, "trial %d: exit %d, stdout %r stderr %r"
                     % (trial, proc.returncode, stdout, stderr)):
            continue
        n, by = int(m.group(1)), m.group(2)
        check(by in (signal.Signals(sig).name, "end of source"), "trial %d: stopped by %s"
              % (trial, by))
        stopped += by != "end of source"
        check(n == len(done), "trial %d: summary line says %d frames, %d complete on disk"
              % (trial, n, len(done)))
        if s:
            check(s["frames"]["written"] == n and s["stopped_by"] == by,
                  "trial %d: summary.json says %s by %s" % (trial, s["frames"]["written"],
                                                            s["stopped_by"]))
            check(s["completed"] == (by == "end of source"), "trial %d: completed flag" % trial)
    check(stopped * 2 >= a.trials, "only %d of %d trials were stopped by the signal"
          % (stopped, a.trials))


def camera_run(a, cams, out, extra=()):
    env = dict(os.environ)
    env["LD_PRELOAD"] = a.camera_preload
    env["SFRT_FAKE_V4L2"] = cams
    cmd = [a.sfrt, "run", "--model", a.model, "--camera", "/dev/video0,/dev/video1",
           "--camera-size", "64x96", "--format", "GREY", "--fps", "30", "--out", out,
           "--progress", "off"] + list(extra)
    print("+ SFRT_FAKE_V4L2='%s' %s" % (cams, " ".join(cmd)), flush=True)
    return subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def scenario_camera_stall(a):
    out = fresh(os.path.join(a.work, "camera_stall"))
    proc = camera_run(a, "/dev/video0:side=0;/dev/video1:side=1,stalled=1", out,
                      ["--camera-timeout-ms", "200"])
    time.sleep(2.0)
    check(proc.poll() is None, "sfrt run ended on its own with a stalled camera")
    sent = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    try:
        stdout, stderr = proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        stdout, stderr = proc.communicate()
        check(False, "sfrt run did not end within 10 s of SIGTERM with a stalled camera")
    took = time.monotonic() - sent
    print(stdout + stderr, flush=True)
    print("ended %.2f s after SIGTERM" % took, flush=True)
    check(proc.returncode == 0, "exit %d after SIGTERM, expected 0" % proc.returncode)
    check(took < 5, "took %.2f s to stop after SIGTERM" % took)
    lines = [l for l in stderr.splitlines() if l.startswith("sfrt run: camera: ")]
    check(any("/dev/video1" in l for l in lines),
          "no camera line on stderr naming the stalled /dev/video1: %r" % lines)
    check(re.search(r"^frames\s+0 \(stopped by SIGTERM\)", stdout, re.M) is not None,
          "summary line: %r" % stdout)
    s = load_summary(out)
    if s:
        check(s["source"]["timeouts"] >= 1, "summary timeouts %s" % s["source"]["timeouts"])
        check(s["frames"]["written"] == 0, "written %d" % s["frames"]["written"])
    check(inspect_out(out) == [], "outputs from a stalled camera")


def scenario_camera_missing(a):
    out = fresh(os.path.join(a.work, "camera_missing"))
    # Only /dev/video0 is served; /dev/video1 is not there (unplugged before the start).
    proc = camera_run(a, "/dev/video0:side=0", out)
    try:
        stdout, stderr = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        stdout, stderr = proc.communicate()
        check(False, "sfrt run hangs when a camera is missing at the start")
    print(stdout + stderr, flush=True)
    check(proc.returncode == 1, "exit %d, expected 1" % proc.returncode)
    last = stderr.strip().splitlines()[-1] if stderr.strip() else ""
    check(last.startswith("sfrt run: ") and "/dev/video1" in last,
          "the error does not name /dev/video1: %r" % last)


class Lines:
    """Collects the lines of a process's pipe on a thread, so a test can wait for one to appear
    (the only reader of that pipe: do not also call communicate())."""

    def __init__(self, stream):
        self.lines = []
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream):
        for line in stream:
            with self._cond:
                self.lines.append(line.rstrip("\n"))
                self._cond.notify_all()
        with self._cond:
            self.lines.append(None)  # end of stream
            self._cond.notify_all()

    def wait_for(self, pattern, timeout):
        """The first line matching `pattern`, or None after `timeout` s or at end of stream."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for line in self.lines:
                    if line is not None and re.search(pattern, line):
                        return line
                left = deadline - time.monotonic()
                if (self.lines and self.lines[-1] is None) or left <= 0:
                    return None
                self._cond.wait(left)

    def text(self):
        self._thread.join(timeout=30)
        with self._cond:
            return "\n".join(l for l in self.lines if l is not None)


def finish(proc, timeout):
    """Waits for `proc` (its pipes read by Lines); kills it and returns False on timeout."""
    try:
        proc.wait(timeout=timeout)
        return True
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return False


def device_stats(summary, device):
    for d in summary["source"].get("devices", []):
        if d["device"] == device:
            return d
    check(False, "summary.json has no entry for %s: %s" % (device, summary["source"]))
    return None


UNPLUG_AFTER = 20  # frames /dev/video1 delivers before it unplugs itself


def scenario_camera_unplug(a):
    out = fresh(os.path.join(a.work, "camera_unplug"))
    proc = camera_run(a, "/dev/video0:side=0;/dev/video1:side=1,unplug_after_frames=%d"
                      % UNPLUG_AFTER, out)
    out_lines, err = Lines(proc.stdout), Lines(proc.stderr)
    gone = err.wait_for(r"^sfrt run: camera: /dev/video1: .*the device was removed", 120)
    check(gone is not None, "no line on stderr saying /dev/video1 was removed")
    print("seen: %s" % gone, flush=True)
    # Each reopen attempt sleeps the back-off first (100, 200, 400 ms, ...): three failures.
    third = err.wait_for(r"^sfrt run: camera: reopen attempt 3 failed: /dev/video1: ", 60)
    check(third is not None, "no third failed reopen attempt naming /dev/video1 on stderr")
    check(proc.poll() is None, "sfrt run ended on its own after the unplug")
    sent = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    check(finish(proc, 30), "sfrt run did not end within 30 s of SIGTERM with an unplugged camera")
    took = time.monotonic() - sent
    stdout, stderr = out_lines.text(), err.text()
    print(stdout + "\n" + stderr, flush=True)
    print("ended %.2f s after SIGTERM" % took, flush=True)
    check(proc.returncode == 0, "exit %d after SIGTERM, expected 0" % proc.returncode)
    # The back-off sleep (at most 2 s) is not cut short by the signal; a generous margin.
    check(took < 10, "took %.2f s to stop after SIGTERM" % took)
    lines = [l for l in stderr.splitlines() if l.startswith("sfrt run: camera: ")]
    check(all("/dev/video1" in l for l in lines) and lines,
          "camera lines on stderr that do not name /dev/video1: %r" % lines)
    check(any("ENODEV" in l for l in lines), "no camera line names ENODEV: %r" % lines)
    retries = [l for l in lines if "reopen attempt" in l]
    check(retries and all("ENOENT" in l for l in retries),
          "reopen attempts do not say ENOENT: %r" % retries)
    m = re.search(r"^frames\s+(\d+) \(stopped by ([^)]*)\)", stdout, re.M)
    done = inspect_out(out)
    if check(m is not None, "no summary line on stdout: %r" % stdout):
        n = int(m.group(1))
        check(m.group(2) == "SIGTERM", "stopped by %s" % m.group(2))
        check(n == len(done), "summary line says %d frames, %d complete on disk" % (n, len(done)))
        check(1 <= n < UNPLUG_AFTER, "%d windows, expected 1 to %d (from the frames before the "
              "unplug)" % (n, UNPLUG_AFTER - 1))
    s = load_summary(out)
    if s:
        check(s["stopped_by"] == "SIGTERM" and not s["completed"],
              "summary stopped_by %s completed %s" % (s["stopped_by"], s["completed"]))
        check(s["frames"]["written"] == len(done), "summary written %d, %d on disk"
              % (s["frames"]["written"], len(done)))
        check(s["source"]["disconnects"] == 1, "source.disconnects %s, expected 1"
              % s["source"]["disconnects"])
        check(s["source"]["reopen_failures"] == len(retries),
              "source.reopen_failures %s, %d lines on stderr"
              % (s["source"].get("reopen_failures"), len(retries)))
        right, left = device_stats(s, "/dev/video1"), device_stats(s, "/dev/video0")
        if right and left:
            print("summary: stopped_by %s, written %d, source.disconnects %d, /dev/video1 %s"
                  % (s["stopped_by"], s["frames"]["written"], s["source"]["disconnects"],
                     {k: right[k] for k in ("disconnects", "reopens", "frames_dequeued")}),
                  flush=True)
            check(right["disconnects"] == 1 and right["reopens"] == 0,
                  "/dev/video1 disconnects %d reopens %d" % (right["disconnects"],
                                                             right["reopens"]))
            check(right["frames_dequeued"] == UNPLUG_AFTER, "/dev/video1 dequeued %d frames"
                  % right["frames_dequeued"])
            check(left["disconnects"] == 0, "/dev/video0 disconnects %d" % left["disconnects"])


def scenario_camera_replug(a):
    out = fresh(os.path.join(a.work, "camera_replug"))
    want = 2 * UNPLUG_AFTER
    proc = camera_run(a, "/dev/video0:side=0;/dev/video1:side=1,unplug_after_frames=%d,"
                      "replug_after_ms=500" % UNPLUG_AFTER, out, ["--max-frames", str(want)])
    try:
        stdout, stderr = proc.communicate(timeout=300)
    except subprocess.TimeoutExpired:
        proc.kill()
        stdout, stderr = proc.communicate()
        check(False, "sfrt run did not reach --max-frames %d after the camera came back" % want)
    print(stdout + stderr, flush=True)
    check(proc.returncode == 0, "exit %d, expected 0" % proc.returncode)
    lines = [l for l in stderr.splitlines() if l.startswith("sfrt run: camera: ")]
    check(any("/dev/video1" in l and "the device was removed" in l for l in lines),
          "no line saying /dev/video1 was removed: %r" % lines)
    check(any(re.match(r"sfrt run: camera: /dev/video1: reconnected at reopen attempt \d+$",
                       l) for l in lines), "no line saying /dev/video1 reconnected: %r" % lines)
    m = re.search(r"^frames\s+(\d+) \(stopped by ([^)]*)\)", stdout, re.M)
    check(m is not None and int(m.group(1)) == want and m.group(2) == "max-frames",
          "summary line: %r" % (m.group(0) if m else stdout))
    done = inspect_out(out)
    check(len(done) == want, "%d complete windows on disk, expected %d" % (len(done), want))
    s = load_summary(out)
    if s:
        check(s["stopped_by"] == "max-frames" and s["frames"]["written"] == want,
              "summary stopped_by %s written %d" % (s["stopped_by"], s["frames"]["written"]))
        check(s["source"]["disconnects"] == 1, "source.disconnects %s, expected 1"
              % s["source"]["disconnects"])
        right, left = device_stats(s, "/dev/video1"), device_stats(s, "/dev/video0")
        if right and left:
            print("summary: stopped_by %s, written %d, source.disconnects %d, "
                  "source.reopen_failures %d, /dev/video1 %s"
                  % (s["stopped_by"], s["frames"]["written"], s["source"]["disconnects"],
                     s["source"]["reopen_failures"],
                     {k: right[k] for k in ("disconnects", "reopens", "reopen_attempts",
                                            "frames_dequeued")}), flush=True)
            check(right["disconnects"] == 1 and right["reopens"] == 1,
                  "/dev/video1 disconnects %d reopens %d" % (right["disconnects"],
                                                             right["reopens"]))
            check(right["frames_dequeued"] > UNPLUG_AFTER,
                  "/dev/video1 dequeued only %d frames" % right["frames_dequeued"])
            check(left["disconnects"] == 0, "/dev/video0 disconnects %d" % left["disconnects"])


SCENARIOS = {
    "full_disk_stops_the_run_naming_the_file_and_errno": scenario_full_disk_stop,
    "full_disk_with_skip_drops_the_window_and_goes_on": scenario_full_disk_skip,
    "read_only_directory_stops_the_run_naming_the_file": scenario_read_only,
    "full_disk_everywhere_leaves_only_complete_files": scenario_full_disk_everywhere,
    "signals_at_random_moments_leave_only_complete_files": scenario_signals,
    "stalled_camera_is_reported_naming_the_device_and_sigterm_still_stops": scenario_camera_stall,
    "camera_missing_at_start_is_an_error_naming_the_device": scenario_camera_missing,
    "camera_unplugged_mid_run_is_reported_naming_the_device_and_leaves_only_complete_files":
        scenario_camera_unplug,
    "camera_replugged_mid_run_resumes_and_counts_the_reconnect": scenario_camera_replug,
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", choices=sorted(SCENARIOS))
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--model", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--preload", default="", help="output_fault_preload shim")
    ap.add_argument("--camera-preload", default="", help="fake V4L2 preload shim")
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--seed", type=int, default=8)
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    SCENARIOS[a.scenario](a)
    if FAILURES:
        print("%d check(s) failed" % len(FAILURES))
        return 1
    print("ok: " + a.scenario)
    return 0


if __name__ == "__main__":
    sys.exit(main())
