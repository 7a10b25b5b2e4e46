#!/usr/bin/python3
"""Outputs to special files and on a full disk (issue 15), end to end on the sfrt binary.

usage: special_file_check.py SCENARIO --sfrt BIN --work DIR [--model M.sfrt] [--onnx N.onnx]
                             [--preload output_fault_preload.so]

The character device that fails every write with ENOSPC is a private node of /dev/full's device
(1, 7) in the work folder when this process may create one (root), so a regression can only
replace that node; otherwise /dev/full itself, whose directory an unprivileged process cannot
write into, so cannot replace.

Scenarios (each is one ctest test named after the behaviour it checks):
  export_to_a_character_device_writes_in_place_and_reports_enospc
      sfrt export -o FULL: exit 1, "cannot write 'FULL' (write): No space left on device", FULL
      is still a character device.
  eval_json_to_a_full_device_exits_1_with_enospc
      sfrt eval --json FULL: exit 1, the same message, FULL still a character device.
  eval_json_to_a_fifo_writes_in_place
      sfrt eval --json FIFO with a reader: exit 0, the reader gets the JSON, FIFO still a FIFO.
  run_video_to_a_character_device_is_refused_before_starting
      sfrt run --video FULL: exit 2 before the first frame, naming FULL and saying the AVI
      writer needs a regular file; FULL still a character device, no summary.json written.
  video_on_a_full_disk_fails_the_run_and_replaces_nothing
      sfrt run --video LINK (a symbolic link to an earlier video) under the shim's ENOSPC after
      20 kB of .avi: exit 1, "the video 'LINK' was not written (nothing replaced it)" (OpenCV's
      VideoWriter reports no write errors; the finished file's index is read back), the earlier
      video is unchanged, no temporary file; then without the fault: exit 0, the link is kept
      and names the new AVI.
  latency_log_to_a_full_device_stops_the_run_naming_the_file
      sfrt run --latency-log FULL: exit 1, "the latency log: cannot write 'FULL' (write): No
      space left on device", FULL still a character device.
  latency_log_on_a_full_disk_mid_run_stops_or_warns_by_policy
      --latency-log on a regular file that hits ENOSPC after a few lines (write-fault shim):
      --on-output-error stop exits 1 naming the log; skip exits 0, writes every window and warns
      naming the log once.
  latency_log_to_a_fifo_is_written_in_place
      sfrt run --latency-log FIFO with a reader: exit 0, the reader gets the header and a line
      per window, the FIFO is still a FIFO.
  synth_on_a_full_disk_leaves_no_dataset_behind
      sfrt synth under the shim's ENOSPC after some frames: exit 1 naming the file and errno,
      nothing at --out and no "<out>.partial-*" left; with --force over an earlier complete data
      set, that data set is left as it was.
"""
import argparse
import glob
import json
import os
import shutil
import stat
import subprocess
import sys
import threading

FAILURES = []


def check(cond, what):
    if not cond:
        FAILURES.append(what)
        print("FAIL: " + what, flush=True)
    return cond


def fresh(path):
    shutil.rmtree(path, ignore_errors=True)
    os.makedirs(path)
    return path


def full_device(work):
    node = os.path.join(work, "full")
    try:
        if os.path.lexists(node):
            os.unlink(node)
        os.mknod(node, 0o666 | stat.S_IFCHR, os.makedev(1, 7))
        os.close(os.open(node, os.O_WRONLY))  # fails on a nodev mount
        return node
    except OSError:
        if os.path.lexists(node):
            os.unlink(node)
        return "/dev/full"


def is_char_device(path):
    return stat.S_ISCHR(os.lstat(path).st_mode)


def sfrt(a, args, env_extra=None):
    cmd = [a.sfrt] + args
    env = dict(os.environ)
    if env_extra:
        env.update(env_extra)
    print("+ %s%s" % ("".join("%s=%s " % kv for kv in (env_extra or {}).items()), " ".join(cmd)),
          flush=True)
    # errors="replace": OpenCV's AVI reader prints raw bytes of a damaged file.
    p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       errors="replace", timeout=300)
    print(p.stdout + p.stderr, flush=True)
    return p


def dataset(a, name="data", frames=4):
    """A small sfrt synth tree (64x96), generated once per work folder."""
    root = os.path.join(a.work, name)
    if not os.path.exists(os.path.join(root, "camera.json")):
        shutil.rmtree(root, ignore_errors=True)
        p = sfrt(a, ["synth", "--out", root, "--seed", "3", "--frames", str(frames),
                     "--size", "64x96", "--objects", "2", "--threads", "1"])
        check(p.returncode == 0, "synth exit %d" % p.returncode)
    return root


def read_fifo(path, into):
    with open(path, "rb") as f:
        into.append(f.read())


def expect_enospc(p, path, prefix=""):
    want = "%scannot write '%s' (write): No space left on device" % (prefix, path)
    check(p.returncode == 1, "exit %d, expected 1" % p.returncode)
    check(want in p.stderr, "stderr does not say: " + want)
    check(is_char_device(path), path + " is no longer a character device")


def scenario_export(a):
    full = full_device(a.work)
    p = sfrt(a, ["export", a.onnx, "-o", full])
    expect_enospc(p, full)


def scenario_eval_full(a):
    root = dataset(a)
    full = full_device(a.work)
    p = sfrt(a, ["eval", "--model", a.model, "--dataset", root, "--no-classical", "--quiet",
                 "--allow-camera-mismatch",
                 "--json", full])
    expect_enospc(p, full)


def scenario_eval_fifo(a):
    root = dataset(a)
    fifo = os.path.join(a.work, "results.fifo")
    if os.path.lexists(fifo):
        os.unlink(fifo)
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=read_fifo, args=(fifo, got), daemon=True)
    reader.start()
    p = sfrt(a, ["eval", "--model", a.model, "--dataset", root, "--no-classical", "--quiet",
                 "--allow-camera-mismatch",
                 "--json", fifo])
    reader.join(60)
    check(p.returncode == 0, "exit %d, expected 0" % p.returncode)
    check(got and "zero_flow" in json.loads(got[0].decode()), "the reader got no results JSON")
    check(stat.S_ISFIFO(os.lstat(fifo).st_mode), fifo + " is no longer a FIFO")


def scenario_video(a):
    root = dataset(a)
    full = full_device(a.work)
    out = fresh(os.path.join(a.work, "out"))
    p = sfrt(a, ["run", "--model", a.model, "--replay", root, "--out", out, "--progress", "off",
                 "--video", full])
    check(p.returncode == 2, "exit %d, expected 2" % p.returncode)
    want = "--video '%s' is a character device: the MJPG/AVI writer seeks back" % full
    check(want in p.stderr, "stderr does not say: " + want)
    check(is_char_device(full), full + " is no longer a character device")
    check(os.listdir(out) == [], "files written before the refusal: %s" % os.listdir(out))


def scenario_video_full_disk(a):
    root = dataset(a)
    video = os.path.join(a.work, "v.avi")
    link = os.path.join(a.work, "latest.avi")
    for p in (video, link):
        if os.path.lexists(p):
            os.unlink(p)
    with open(video, "w") as f:
        f.write("the previous video")
    os.symlink("v.avi", link)
    fault = {"LD_PRELOAD": a.preload, "SFRT_FAULT_ERRNO": "ENOSPC", "SFRT_FAULT_MATCH": ".avi",
             "SFRT_FAULT_AFTER_BYTES": "20000"}
    args = ["run", "--model", a.model, "--replay", root, "--progress", "off", "--video", link]
    p = sfrt(a, args + ["--out", fresh(os.path.join(a.work, "out_full"))], fault)
    check(p.returncode == 1, "full disk: exit %d, expected 1" % p.returncode)
    want = "the video '%s' was not written (nothing replaced it)" % link
    check(want in p.stderr, "full disk: stderr does not say: " + want)
    with open(video) as f:
        check(f.read() == "the previous video", "full disk: the previous video was replaced")
    check(not glob.glob(os.path.join(a.work, "*.tmp.avi")), "full disk: temporary video left")
    p = sfrt(a, args + ["--out", fresh(os.path.join(a.work, "out_clean"))])
    check(p.returncode == 0, "clean: exit %d, expected 0" % p.returncode)
    check(os.path.islink(link) and os.readlink(link) == "v.avi", "clean: the link was replaced")
    with open(video, "rb") as f:
        check(f.read(4) == b"RIFF", "clean: the link's target is not the new AVI")


def scenario_latency_full(a):
    root = dataset(a)
    full = full_device(a.work)
    out = fresh(os.path.join(a.work, "out"))
    p = sfrt(a, ["run", "--model", a.model, "--replay", root, "--out", out, "--progress", "off",
                 "--latency-log", full])
    expect_enospc(p, full, "the latency log: ")


def scenario_latency_mid_run(a):
    root = dataset(a, frames=8)
    log = os.path.join(a.work, "latency.csv")
    # The header is about 110 bytes and a line about 60: room for the header and two lines.
    fault = {"LD_PRELOAD": a.preload, "SFRT_FAULT_ERRNO": "ENOSPC",
             "SFRT_FAULT_MATCH": "latency.csv", "SFRT_FAULT_AFTER_BYTES": "230"}
    want = "the latency log: cannot write '%s' (write): No space left on device" % log
    out = fresh(os.path.join(a.work, "out_stop"))
    p = sfrt(a, ["run", "--model", a.model, "--replay", root, "--out", out, "--progress", "off",
                 "--latency-log", log], fault)
    check(p.returncode == 1, "stop: exit %d, expected 1" % p.returncode)
    check(want in p.stderr, "stop: stderr does not say: " + want)
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    check(s["stopped_by"] == "error", "stop: stopped_by %s" % s["stopped_by"])
    out = fresh(os.path.join(a.work, "out_skip"))
    p = sfrt(a, ["run", "--model", a.model, "--replay", root, "--out", out, "--progress", "off",
                 "--latency-log", log, "--on-output-error", "skip"], fault)
    check(p.returncode == 0, "skip: exit %d, expected 0" % p.returncode)
    check(p.stderr.count(want) == 1, "skip: the warning naming the log is not there exactly once")
    check(len(glob.glob(os.path.join(out, "*.pfm"))) == 7, "skip: not every window written")
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    check(any(want in w for w in s["warnings"]), "skip: summary.json warnings: %s" % s["warnings"])


def scenario_latency_fifo(a):
    root = dataset(a)
    fifo = os.path.join(a.work, "latency.fifo")
    if os.path.lexists(fifo):
        os.unlink(fifo)
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=read_fifo, args=(fifo, got), daemon=True)
    reader.start()
    out = fresh(os.path.join(a.work, "out"))
    p = sfrt(a, ["run", "--model", a.model, "--replay", root, "--out", out, "--progress", "off",
                 "--latency-log", fifo])
    reader.join(60)
    check(p.returncode == 0, "exit %d, expected 0" % p.returncode)
    lines = got[0].decode().splitlines() if got else []
    check(lines and lines[0].startswith("window,source_ms"), "no header from the FIFO")
    check(len(lines) == 1 + 3, "the FIFO gave %d lines, expected a header and 3" % len(lines))
    check(stat.S_ISFIFO(os.lstat(fifo).st_mode), fifo + " is no longer a FIFO")


def scenario_synth_full_disk(a):
    out = os.path.join(a.work, "tree")
    shutil.rmtree(out, ignore_errors=True)
    args = ["synth", "--out", out, "--seed", "5", "--frames", "4", "--size", "64x96",
            "--objects", "2", "--threads", "1"]
    # 40 kB: camera_data.txt and the first frames' files, not the whole tree (about 400 kB).
    fault = {"LD_PRELOAD": a.preload, "SFRT_FAULT_ERRNO": "ENOSPC",
             "SFRT_FAULT_MATCH": "tree", "SFRT_FAULT_AFTER_BYTES": "40000"}

    def leftovers():
        return glob.glob(out + ".partial-*") + glob.glob(out + ".old-*")

    p = sfrt(a, args, fault)
    check(p.returncode == 1, "exit %d, expected 1" % p.returncode)
    check("No space left on device" in p.stderr and ".partial-" in p.stderr,
          "stderr does not name the file and the errno")
    check("the partial data set was removed" in p.stderr, "stderr does not say it cleaned up")
    check(not os.path.exists(out), "a data set was left at " + out)
    check(not leftovers(), "temporary trees left: %s" % leftovers())

    p = sfrt(a, args)  # a complete data set, then --force over it on a full disk
    check(p.returncode == 0, "clean synth exit %d" % p.returncode)
    before = sorted(os.path.relpath(f, out) for f in glob.glob(out + "/**", recursive=True))
    with open(os.path.join(out, "camera.json")) as f:
        camera = f.read()
    check('"complete": true' in camera, "camera.json has no completion marker")
    p = sfrt(a, args[:6] + ["6"] + args[7:] + ["--force"], fault)
    check(p.returncode == 1, "--force on a full disk: exit %d, expected 1" % p.returncode)
    after = sorted(os.path.relpath(f, out) for f in glob.glob(out + "/**", recursive=True))
    check(before == after, "the earlier data set changed under a failed --force")
    with open(os.path.join(out, "camera.json")) as f:
        check(f.read() == camera, "the earlier camera.json changed under a failed --force")
    check(not leftovers(), "temporary trees left: %s" % leftovers())


SCENARIOS = {
    "export_to_a_character_device_writes_in_place_and_reports_enospc": scenario_export,
    "eval_json_to_a_full_device_exits_1_with_enospc": scenario_eval_full,
    "eval_json_to_a_fifo_writes_in_place": scenario_eval_fifo,
    "run_video_to_a_character_device_is_refused_before_starting": scenario_video,
    "video_on_a_full_disk_fails_the_run_and_replaces_nothing": scenario_video_full_disk,
    "latency_log_to_a_full_device_stops_the_run_naming_the_file": scenario_latency_full,
    "latency_log_on_a_full_disk_mid_run_stops_or_warns_by_policy": scenario_latency_mid_run,
    "latency_log_to_a_fifo_is_written_in_place": scenario_latency_fifo,
    "synth_on_a_full_disk_leaves_no_dataset_behind": scenario_synth_full_disk,
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", choices=sorted(SCENARIOS))
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--model", default="")
    ap.add_argument("--onnx", default="")
    ap.add_argument("--preload", default="", help="output_fault_preload shim")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    SCENARIOS[a.scenario](a)
    if FAILURES:
        print("%d check(s) failed" % len(FAILURES))
        return 1
    print("ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
