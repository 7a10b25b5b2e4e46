#!/usr/bin/python3
"""`sfrt synth` stopped by SIGINT or SIGTERM mid-generation (issue #38): it exits 1 saying it was
stopped, removes its <out>.partial-<pid> tree, and leaves --out as it was (absent here; an
earlier complete data set stays whole).

usage: interrupt_check.py --sfrt BIN --work DIR
"""
import argparse
import glob
import os
import shutil
import signal
import subprocess
import sys
import time

FAILED = []


def check(ok, what):
    if not ok:
        FAILED.append(what)
        print("FAIL: " + what, flush=True)
    return ok


def interrupt(a, sig, out):
    """Starts a long generation, sends `sig` once two frames are written, returns the result."""
    p = subprocess.Popen([a.sfrt, "synth", "--out", out, "--frames", "400", "--size", "96x128",
                          "--seed", "5", "--force"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    frames = 0
    for line in p.stdout:  # one progress line every 4 frames (400 / 100)
        if line.startswith("frame"):
            frames += 1
            if frames == 2:
                p.send_signal(sig)
                break
    try:
        _, err = p.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()
        check(False, "%s: synth did not stop within 120 s" % sig.name)
        return None, ""
    return p.returncode, err


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    for sig in (signal.SIGINT, signal.SIGTERM):
        out = os.path.join(a.work, "new_" + sig.name)
        code, err = interrupt(a, sig, out)
        check(code == 1, "%s: exit %s, expected 1; stderr %r" % (sig.name, code, err))
        check("stopped by a signal" in err and "partial data set was removed" in err,
              "%s: stderr does not say it stopped and cleaned up: %r" % (sig.name, err))
        check(not os.path.exists(out), "%s: --out %s was created" % (sig.name, out))
        left = glob.glob(out + ".partial-*")
        check(not left, "%s: partial trees left: %s" % (sig.name, left))
    # An existing complete data set is not touched by an interrupted --force replacement.
    keep = os.path.join(a.work, "keep")
    p = subprocess.run([a.sfrt, "synth", "--out", keep, "--frames", "2", "--size", "32x48"],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    check(p.returncode == 0, "the first data set: exit %d %s" % (p.returncode, p.stderr))
    before = sorted(os.path.relpath(f, keep) for f in glob.glob(keep + "/**", recursive=True))
    code, _ = interrupt(a, signal.SIGINT, keep)
    after = sorted(os.path.relpath(f, keep) for f in glob.glob(keep + "/**", recursive=True))
    check(code == 1 and before == after, "replacement interrupted: exit %s, files changed" % code)
    check(not glob.glob(keep + ".partial-*"), "replacement interrupted: partial tree left")
    if FAILED:
        print("%d check(s) failed" % len(FAILED))
        sys.exit(1)
    print("ok")


if __name__ == "__main__":
    main()
