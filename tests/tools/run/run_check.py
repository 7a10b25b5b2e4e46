#!/usr/bin/env python3
"""Runs `sfrt run` end to end in one scenario and checks what it wrote.

Scenarios:
  camera     under the LD_PRELOAD fake camera pair (drop knob on the right camera): flow files,
             a summary whose drop counts match the knob.
  replay     --replay on the Scene Flow samples in tests/data/sceneflow-samples (Driving and
             Monkaa, 3 frames each -> 2 windows each, 270x480): flow files, PNGs, a video and
             the summary.
  corrupt    the samples copied with one PNG truncated: reported by path; --on-bad-frame skip
             goes on, stop exits 1.
  sigterm    a longer replay killed with SIGTERM: only complete files, no temporary files, a
             summary saying how far it got.
Exit 0 when every check passes; otherwise prints what failed and exits 1.
"""
import argparse
import glob
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np

FAILURES = []


def check(cond, what):
    if not cond:
        FAILURES.append(what)
        print("FAIL: " + what)
    return cond


def parse_pfm(path):
    with open(path, "rb") as f:
        data = f.read()
    fields = []
    pos = 0
    while len(fields) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        start = pos
        while pos < len(data) and not data[pos:pos + 1].isspace():
            pos += 1
        fields.append(data[start:pos].decode("ascii"))
    pos += 1
    kind, width, height, scale = fields[0], int(fields[1]), int(fields[2]), float(fields[3])
    channels = {"PF": 3, "Pf": 1}[kind]
    expected = width * height * channels * 4
    if len(data) - pos != expected:
        raise ValueError("%s: %d data bytes, expected %d" % (path, len(data) - pos, expected))
    arr = np.frombuffer(data[pos:], dtype="<f4" if scale < 0 else ">f4")
    return np.flipud(arr.reshape(height, width, channels))


def check_outputs(out, expect_frames, size, ext="pfm"):
    """Every flow file parses, has the size, is finite; PNG beside it; no temp files."""
    temps = [p for p in os.listdir(out) if ".tmp." in p]
    check(not temps, "temporary files left in %s: %s" % (out, temps))
    flows = sorted(glob.glob(os.path.join(out, "*." + ext)))
    if expect_frames is not None:
        check(len(flows) == expect_frames,
              "%d .%s files in %s, expected %d" % (len(flows), ext, out, expect_frames))
    for f in flows:
        try:
            flow = parse_pfm(f)
        except Exception as e:  # noqa: BLE001 - report any parse failure
            check(False, "flow file %s does not parse: %s" % (f, e))
            continue
        check(flow.shape == (size[0], size[1], 3), "%s: shape %s" % (f, flow.shape))
        check(np.isfinite(flow).all(), "%s: non-finite values" % f)
        png = f[:-len(ext)] + "png"
        check(os.path.isfile(png), "no visualisation %s" % png)
        if os.path.isfile(png):
            with open(png, "rb") as p:
                check(p.read(8) == b"\x89PNG\r\n\x1a\n", "%s is not a PNG" % png)
    return flows


def load_summary(out):
    path = os.path.join(out, "summary.json")
    if not check(os.path.isfile(path), "no summary %s" % path):
        return None
    with open(path) as f:
        return json.load(f)


def run(cmd, env=None):
    print("+ " + " ".join(cmd), flush=True)
    p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       timeout=600)
    print(p.stdout)
    print(p.stderr, file=sys.stderr)
    return p


def samples_dir(samples):
    images = os.path.join(samples, "images")
    if not os.path.isdir(os.path.join(images, "Driving")) or not os.path.isdir(
            os.path.join(images, "Monkaa")):
        print("FAIL: the Scene Flow samples are missing: %s (Driving/ and Monkaa/ needed; "
              "they are committed in tests/data/sceneflow-samples)" % images)
        sys.exit(1)
    return images


def fresh(path):
    shutil.rmtree(path, ignore_errors=True)
    os.makedirs(path)
    return path


def scenario_camera(a):
    out = fresh(os.path.join(a.work, "camera_out"))
    env = dict(os.environ)
    env["LD_PRELOAD"] = a.preload
    env["SFRT_FAKE_V4L2"] = ("/dev/video0:side=0;/dev/video1:side=1,phase_ms=2,drop_every=%d"
                             % a.drop_every)
    env["ASAN_OPTIONS"] = env.get("ASAN_OPTIONS", "") + ":verify_asan_link_order=0"
    frames = 12
    p = run([a.sfrt, "run", "--model", a.model, "--camera", "/dev/video0,/dev/video1",
             "--camera-size", "120x160", "--format", "GREY", "--fps", "30", "--out", out,
             "--max-frames", str(frames), "--budget-ms", "1000", "--progress", "lines"], env)
    check(p.returncode == 0, "sfrt run --camera exited %d" % p.returncode)
    check_outputs(out, frames, (120, 160))
    s = load_summary(out)
    if s is None:
        return
    check(s["frames"]["written"] == frames, "summary frames.written %s" % s["frames"]["written"])
    check(s["stopped_by"] == "max-frames", "stopped_by %s" % s["stopped_by"])
    check(s["queue_policy"] == "newest-wins", "queue policy %s" % s["queue_policy"])
    devs = {d["role"]: d for d in s["source"]["devices"]}
    left, right = devs["left"], devs["right"]
    check(left["sequence_drops"] == 0, "left camera drops %d, expected 0" % left["sequence_drops"])
    # Knob: every drop_every-th frame slot of the right camera is dropped, so over the span of
    # sequence numbers it delivered, floor or ceil of span / drop_every numbers are missing, and
    # every missing number is a counted drop.
    span = right["last_sequence"] - right["first_sequence"] + 1
    lo, hi = span // a.drop_every, -(-span // a.drop_every)
    check(lo <= right["sequence_drops"] <= hi,
          "right camera drops %d for %d sequence numbers with drop_every=%d (expected %d..%d)"
          % (right["sequence_drops"], span, a.drop_every, lo, hi))
    check(right["sequence_drops"] == span - right["frames_dequeued"],
          "right camera: %d drops but %d of %d sequence numbers dequeued"
          % (right["sequence_drops"], right["frames_dequeued"], span))
    check(right["sequence_drops"] >= 2, "too few right-camera frames to see the knob")
    expect_source = (left["sequence_drops"] + left["stale_dropped"] + right["sequence_drops"] +
                     right["stale_dropped"] + s["source"]["unpaired_left"] +
                     s["source"]["unpaired_right"])
    check(s["drops"]["source"] == expect_source,
          "drops.source %d, expected %d" % (s["drops"]["source"], expect_source))
    check(s["deadline"]["budget_ms"] == 1000, "budget recorded")
    for st in ("source", "preprocess", "infer", "output", "end_to_end"):
        check(s["latency_ms"][st]["count"] == frames, "latency count for %s" % st)
    # A dropped right frame leaves its left frame unpaired, and no window spans the gap it makes:
    # every window is two consecutive left sequence numbers, one frame interval apart.
    w = s["windows"]
    check(w["broken_by_lost_frame"] >= 1 and w["formed"] >= frames,
          "summary windows %s: the right camera's drops should break the chain" % w)
    with open(os.path.join(out, "windows.csv")) as f:
        rows = [line.rstrip("\n").split(",") for line in f][1:]
    check(len(rows) == frames, "windows.csv has %d windows, expected %d" % (len(rows), frames))
    for r in rows:
        check(int(r[3]) == int(r[2]) + 1,
              "window %s spans left sequence numbers %s..%s" % (r[0], r[2], r[3]))


def scenario_replay(a):
    images = samples_dir(a.samples)
    out = fresh(os.path.join(a.work, "replay_out"))
    video = os.path.join(out, "vis.avi")
    p = run([a.sfrt, "run", "--model", a.model, "--replay", images, "--out", out, "--size",
             "135x240", "--video", video, "--progress", "lines"])
    check(p.returncode == 0, "sfrt run --replay exited %d" % p.returncode)
    flows = check_outputs(out, 4, (135, 240))
    names = sorted(os.path.basename(f) for f in flows)
    check(names == ["Driving_000006.pfm", "Driving_000007.pfm", "Monkaa_000006.pfm",
                    "Monkaa_000007.pfm"], "flow files %s" % names)
    check(os.path.isfile(video) and os.path.getsize(video) > 0, "no video %s" % video)
    if os.path.isfile(video):
        with open(video, "rb") as f:
            head = f.read(12)
        check(head[:4] == b"RIFF" and head[8:12] == b"AVI ", "%s is not an AVI" % video)
    s = load_summary(out)
    if s is None:
        return
    check(s["frames"] == {"written": 4, "read": 4, "total": 4}, "frames %s" % s["frames"])
    check(s["completed"] is True and s["stopped_by"] == "end of source", "completed")
    check(s["bad_frames"] == [], "bad frames %s" % s["bad_frames"])
    check(s["model"]["input_size"] == [135, 240], "input size %s" % s["model"]["input_size"])
    check(s["source"]["frame_size"] == [270, 480], "frame size %s" % s["source"]["frame_size"])
    check(s["queue_policy"] == "block", "replays block")
    check(all(v == 0 for v in s["drops"].values()), "replay drops %s" % s["drops"])
    check("4/4 frames" in p.stderr, "progress line '4/4 frames' on stderr")
    # Two sequences of three pairs: 12 image files, each decoded once (pair t+1 of a window is
    # pair t of the next), for the 4 windows.
    listed, decoded = s["source"].get("images_listed"), s["source"].get("images_decoded")
    check(listed == 12, "images listed %s" % listed)
    check(decoded == 12, "images decoded %s, expected each of the 12 once" % decoded)
    parts = s.get("latency_attribution_ms", {}).get("parts", {})
    check(len(parts) == 10 and all(parts[k]["count"] == 4 for k in parts),
          "latency attribution parts %s" % sorted(parts))


def copy_samples(a, name):
    images = samples_dir(a.samples)
    root = os.path.join(a.work, name)
    shutil.rmtree(root, ignore_errors=True)
    shutil.copytree(images, root)
    return root


def scenario_corrupt(a):
    root = copy_samples(a, "corrupt_frames")
    bad = os.path.join(root, "Monkaa", "left", "0007.png")
    with open(bad, "r+b") as f:
        f.truncate(100)  # a PNG signature and part of a header, no image data
    for policy in ("skip", "stop"):
        out = fresh(os.path.join(a.work, "corrupt_out_" + policy))
        p = run([a.sfrt, "run", "--model", a.model, "--replay", root, "--out", out, "--size",
                 "135x240", "--on-bad-frame", policy, "--progress", "off"])
        s = load_summary(out)
        if policy == "skip":
            check(p.returncode == 0, "skip: exit %d" % p.returncode)
            # Driving: 2 windows; Monkaa: 0006 | bad 0007 | 0008 -> no window.
            check_outputs(out, 2, (135, 240))
            if s:
                check(s["completed"] is True, "skip: completed")
        else:
            check(p.returncode == 1, "stop: exit %d, expected 1" % p.returncode)
            check(bad in p.stderr and "--on-bad-frame stop" in p.stderr,
                  "stop: stderr names the bad file: %r" % p.stderr)
            check_outputs(out, 2, (135, 240))  # Driving's windows came before it
            if s:
                check(s["stopped_by"] == "error" and bad in (s["error"] or ""),
                      "stop: summary error %r" % s.get("error"))
        if s:
            paths = [b["path"] for b in s["bad_frames"]]
            check(paths == [bad], "%s: bad frames %s, expected [%s]" % (policy, paths, bad))
            check(s["frames"]["written"] == 2, "%s: written %s" % (policy, s["frames"]["written"]))


def scenario_sigterm(a):
    images = samples_dir(a.samples)
    root = os.path.join(a.work, "long_replay", "seq")
    shutil.rmtree(os.path.dirname(root), ignore_errors=True)
    frames = 40
    for side in ("left", "right"):
        os.makedirs(os.path.join(root, side))
        sources = sorted(glob.glob(os.path.join(images, "Driving", side, "*.png")))
        for i in range(frames):
            shutil.copy(sources[i % len(sources)], os.path.join(root, side, "%04d.png" % i))
    out = fresh(os.path.join(a.work, "sigterm_out"))
    cmd = [a.sfrt, "run", "--model", a.model, "--replay", os.path.dirname(root), "--out", out,
           "--size", "135x240", "--progress", "off"]
    print("+ " + " ".join(cmd), flush=True)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if len(glob.glob(os.path.join(out, "*.pfm"))) >= 2:
            break
        time.sleep(0.02)
    check(proc.poll() is None, "sfrt run ended before it could be signalled")
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=300)
    print(stdout)
    print(stderr, file=sys.stderr)
    check(proc.returncode == 0, "exit %d after SIGTERM, expected 0" % proc.returncode)
    flows = check_outputs(out, None, (135, 240))
    s = load_summary(out)
    if s:
        check(s["stopped_by"] == "SIGTERM", "stopped_by %s" % s["stopped_by"])
        check(s["completed"] is False, "completed should be false")
        check(s["frames"]["written"] == len(flows),
              "summary says %d written, %d flow files" % (s["frames"]["written"], len(flows)))
        check(2 <= s["frames"]["written"] < frames - 1,
              "written %d (expected a partial run)" % s["frames"]["written"])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", choices=["camera", "replay", "corrupt", "sigterm"])
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--model", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--samples", default="",
                    help="the sceneflow-samples folder (images/, disparity/)")
    ap.add_argument("--preload", default="")
    ap.add_argument("--drop-every", type=int, default=4)
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    {"camera": scenario_camera, "replay": scenario_replay, "corrupt": scenario_corrupt,
     "sigterm": scenario_sigterm}[a.scenario](a)
    if FAILURES:
        print("%d check(s) failed" % len(FAILURES))
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
