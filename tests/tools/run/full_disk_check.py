#!/usr/bin/python3
"""Every file an sfrt command writes goes through the one atomic writer (issue #38, item 5): on a
full disk (ENOSPC from the LD_PRELOAD shim output_fault_preload.cc, on the output's own writes)
the command exits 1 naming the file and the system's reason, the previous file at that path is
left byte for byte, and no temporary file stays beside it. Also: an output that cannot be
written at all (its directory missing or not writable) is found before the command computes.

Writers checked: bench --json, infer -o (.npy and .pfm), run --profile (exit 1, not 0).

usage: full_disk_check.py --sfrt BIN --preload SHIM.so --model M.sfrt --images DIR --work DIR
"""
import argparse
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


def run(a, args, fault_match=None):
    env = dict(os.environ)
    if fault_match is not None:
        env["LD_PRELOAD"] = a.preload
        env["SFRT_FAULT_ERRNO"] = "ENOSPC"
        env["SFRT_FAULT_MATCH"] = fault_match
        env["SFRT_FAULT_AFTER_BYTES"] = "100"  # a cut-short write, as a real full disk gives
        env["ASAN_OPTIONS"] = env.get("ASAN_OPTIONS", "") + ":verify_asan_link_order=0"
    return subprocess.run([a.sfrt] + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True, env=env, timeout=600)


def kept_on_full_disk(a, name, args, path):
    """Runs `args` once to make `path`, then again on a full disk: the first file must stay."""
    p = run(a, args)
    if not check(p.returncode == 0 and os.path.isfile(path),
                 "%s: the first run failed (exit %d): %s" % (name, p.returncode, p.stderr)):
        return
    with open(path, "rb") as f:
        before = f.read()
    p = run(a, args, fault_match=os.path.basename(path))
    check(p.returncode == 1, "%s on a full disk: exit %d, expected 1" % (name, p.returncode))
    check("No space left on device" in p.stderr and os.path.basename(path) in p.stderr,
          "%s on a full disk: stderr names neither the file nor the reason: %r" % (name, p.stderr))
    with open(path, "rb") as f:
        check(f.read() == before, "%s on a full disk: the previous %s was changed" % (name, path))
    left = [n for n in os.listdir(os.path.dirname(path)) if ".tmp" in n]
    check(not left, "%s on a full disk: temporary files left: %s" % (name, left))


def main():
    ap = argparse.ArgumentParser()
    for flag in ("--sfrt", "--preload", "--model", "--images", "--work"):
        ap.add_argument(flag, required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    left = os.path.join(a.images, "left")
    right = os.path.join(a.images, "right")
    frames = sorted(os.listdir(left))[:2]
    images = ["--left0", os.path.join(left, frames[0]), "--right0", os.path.join(right, frames[0]),
              "--left1", os.path.join(left, frames[1]), "--right1", os.path.join(right, frames[1])]

    bench_json = os.path.join(a.work, "bench.json")
    kept_on_full_disk(a, "bench --json", ["bench", "--model", a.model, "--size", "48x64",
                                          "--runs", "1", "--warmup", "0", "--json", bench_json],
                      bench_json)
    for ext in ("npy", "pfm"):
        out = os.path.join(a.work, "flow." + ext)
        kept_on_full_disk(a, "infer -o ." + ext,
                          ["infer", "--model", a.model, "--size", "64x96", "-o", out] + images, out)

    # Found before the work: an output directory that does not exist, or refuses files.
    missing = os.path.join(a.work, "no", "such", "bench.json")
    p = run(a, ["bench", "--model", a.model, "--size", "48x64", "--runs", "1", "--json", missing])
    check(p.returncode == 1 and "does not exist" in p.stderr and "median" not in p.stdout,
          "bench --json into a missing directory: exit %d, measured anyway? %r %r"
          % (p.returncode, p.stdout[-200:], p.stderr))
    if os.geteuid() != 0:  # root writes anywhere: only a non-root run can see a refusing folder
        locked = os.path.join(a.work, "locked")
        os.makedirs(locked)
        os.chmod(locked, 0o555)
        p = run(a, ["infer", "--model", a.model, "-o", os.path.join(locked, "f.npy")] + images)
        check(p.returncode == 1 and "cannot create files" in p.stderr,
              "infer -o into a read-only directory: exit %d %r" % (p.returncode, p.stderr))

    # run --profile whose reports cannot be written: the run says so and exits 1.
    prof = os.path.join(a.work, "profile")
    out = os.path.join(a.work, "run_out")
    p = run(a, ["run", "--model", a.model, "--replay-left", left, "--replay-right", right,
                "--size", "64x96", "--out", out, "--no-png", "--progress", "off",
                "--profile", prof], fault_match="profile.json")
    check(p.returncode == 1 and "--profile" in p.stderr and "No space left" in p.stderr,
          "run --profile on a full disk: exit %d, stderr %r" % (p.returncode, p.stderr))

    if FAILED:
        print("%d check(s) failed" % len(FAILED))
        sys.exit(1)
    print("ok")


if __name__ == "__main__":
    main()
