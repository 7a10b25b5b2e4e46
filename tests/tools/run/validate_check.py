#!/usr/bin/python3
"""`sfrt run` input that is checked before the first frame (issue 15), on generated frames.

usage: validate_check.py SCENARIO --sfrt BIN --model M.sfrt --work DIR

Every rejection scenario asserts: exit 2, exactly one stderr line "sfrt run: <message>" with
the expected words, nothing on stdout (no statistics table), and nothing written: the --out
directory is not created (or stays empty), no summary.json, no frame files.

Scenarios (one ctest test each, named after the behaviour):
  RunRejectsAnUnwritableOutDirBeforeOpeningTheSource
      --out under a regular file, with a replay folder that does not exist: the --out error is
      the one reported (so it was checked before the source was opened).
  RunRejectsAnIsaThisCpuCannotRunBeforeStarting
      an ISA the CPU lacks, found at test time from `sfrt bench --peak --isa all`.
  RunRejectsLeftAndRightReplayFoldersWithDifferentFrameCounts
      --replay-left with 4 frames, --replay-right with 3.
  RunRejectsAnEmptyReplayFolder
      --replay-left and --replay-right that hold no image.
  RunRejectsASizeOutsideTheLimitsBeforeStarting
      --size 100000x100000.
  RunLoopProgressCountsEveryPass
      --loop 3 over 4 frames (3 windows): progress ends at 9/9 frames.
  RunNamesTheCorruptFileOnTheConsoleWhenSkipping
      a truncated PNG under --on-bad-frame skip: a stderr line names its path.
  RunNotesAGrayscaleInputOnce
      grayscale PNG frames: one note on stderr, whatever the number of frames.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from make_test_images import write_png  # noqa: E402  (zlib-only PNG writer)

import numpy as np  # noqa: E402

H, W = 32, 48
FAILURES = []


def check(cond, what):
    if not cond:
        FAILURES.append(what)
        print("FAIL: " + what, flush=True)
    return cond


def frames(root, count, grey=False, seed=3):
    """root/{left,right}/NNNN.png, `count` pairs of seeded noise."""
    shutil.rmtree(root, ignore_errors=True)
    rng = np.random.default_rng(seed)
    for side in ("left", "right"):
        os.makedirs(os.path.join(root, side))
        for i in range(count):
            img = rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8)
            path = os.path.join(root, side, "%04d.png" % i)
            if grey:
                from PIL import Image  # grayscale PNG (colour type 0)
                Image.fromarray(img[:, :, 0], "L").save(path)
            else:
                write_png(path, img)
    return root


def run(a, args, env=None):
    quiet = [] if "--progress" in args else ["--progress", "off"]
    cmd = [a.sfrt, "run", "--model", a.model] + quiet + args
    print("+ %s%s" % ("".join("%s=%s " % kv for kv in (env or {}).items()), " ".join(cmd)),
          flush=True)
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=300,
                       env=dict(os.environ, **env) if env else None)
    print("--- exit %d; stdout:\n%s--- stderr:\n%s---" % (p.returncode, p.stdout, p.stderr))
    return p


def expect_rejected(a, args, out, patterns, env=None):
    p = run(a, args + ["--out", out], env)
    check(p.returncode == 2, "exit %d, expected 2" % p.returncode)
    lines = p.stderr.splitlines()
    check(len(lines) == 1 and lines[0].startswith("sfrt run: "),
          "stderr is not one line 'sfrt run: ...': %r" % p.stderr)
    for pat in patterns:
        check(re.search(pat, p.stderr), "stderr does not match %r" % pat)
    check(p.stdout == "", "something on stdout (a statistics table?): %r" % p.stdout)
    if os.path.isdir(out):
        check(os.listdir(out) == [], "files written into %s: %s" % (out, os.listdir(out)))
    else:
        check(not os.path.exists(out) or os.path.isfile(out), "%s was created" % out)
    return p


def fresh(path):
    shutil.rmtree(path, ignore_errors=True)
    return path


def scenario_unwritable_out(a):
    blocker = os.path.join(a.work, "a_file")
    with open(blocker, "w") as f:
        f.write("not a directory\n")
    out = os.path.join(blocker, "out")
    expect_rejected(a, ["--replay-left", os.path.join(a.work, "nothere", "left"),
                        "--replay-right", os.path.join(a.work, "nothere", "right")],
                    out, [r"--out '.*a_file/out': '.*a_file' exists and is not a directory"])


def missing_isa(a):
    """An ISA name this CPU cannot run, from `sfrt bench --peak --isa all`."""
    p = subprocess.run([a.sfrt, "bench", "--peak", "--isa", "all", "--peak-seconds", "0.01"],
                       capture_output=True, text=True, timeout=120)
    runs = set(re.findall(r"^(ref|avx2|avx512amx|avx512|neon)\s", p.stdout, re.MULTILINE))
    check(p.returncode == 0 and "ref" in runs, "bench --peak --isa all: %r" % p.stdout)
    for isa in ("avx512amx", "avx512", "avx2", "neon"):
        if isa not in runs:
            return isa, True
    return None, False


def scenario_isa(a):
    root = frames(os.path.join(a.work, "frames"), 3)
    isa, known = missing_isa(a)
    out = fresh(os.path.join(a.work, "out"))
    args = ["--replay-left", root + "/left", "--replay-right", root + "/right"]
    if known:
        print("this CPU cannot run %s" % isa)
        expect_rejected(a, args + ["--isa", isa], out,
                        [r"--isa %s: this CPU \(or this build\) cannot run it; it runs ref" % isa])
        # The same ISA through SFRT_ISA: refused before the run too, as a usage error.
        expect_rejected(a, args, fresh(out), [
            r"ISA %s \(from --isa, the profile or SFRT_ISA\): this CPU \(or this build\) "
            r"cannot run it; it runs ref" % isa], env={"SFRT_ISA": isa})
    else:  # a CPU with every ISA: a name the build does not know is refused the same way
        print("this CPU runs every ISA; testing an unknown ISA name instead")
        expect_rejected(a, args + ["--isa", "sve9"], out, [r"--isa: 'sve9' is not one of"])


def scenario_counts(a):
    root = frames(os.path.join(a.work, "frames"), 4)
    os.remove(os.path.join(root, "right", "0003.png"))
    out = fresh(os.path.join(a.work, "out"))
    expect_rejected(a, ["--replay-left", root + "/left", "--replay-right", root + "/right",
                        "--on-bad-frame", "skip"], out,
                    [r"--replay-left/--replay-right: left frames '.*left' has 4 images but "
                     r"right frames '.*right' has 3; .*counts must match"])


def scenario_empty(a):
    root = os.path.join(a.work, "empty")
    shutil.rmtree(root, ignore_errors=True)
    for side in ("left", "right"):
        os.makedirs(os.path.join(root, side))
    out = fresh(os.path.join(a.work, "out"))
    expect_rejected(a, ["--replay-left", root + "/left", "--replay-right", root + "/right"], out,
                    [r"--replay-left/--replay-right: left frames: .*left: no image files"])


def scenario_size(a):
    root = frames(os.path.join(a.work, "frames"), 3)
    out = fresh(os.path.join(a.work, "out"))
    expect_rejected(a, ["--replay-left", root + "/left", "--replay-right", root + "/right",
                        "--size", "100000x100000"], out,
                    [r"--size: 100000x100000 \(HxW\) is outside the input size limits "
                     r"16\.\.4096 pixels per side"])


def scenario_loop(a):
    root = frames(os.path.join(a.work, "frames"), 4)
    out = fresh(os.path.join(a.work, "out"))
    p = run(a, ["--replay-left", root + "/left", "--replay-right", root + "/right", "--out", out,
                "--loop", "3", "--progress", "lines", "--progress-every", "1"])
    check(p.returncode == 0, "exit %d" % p.returncode)
    totals = re.findall(r"sfrt run: (\d+)/(\d+) frames", p.stderr)
    check(totals and totals[-1] == ("9", "9"), "last progress %s, expected 9/9" % totals[-1:])
    check(all(int(n) <= int(t) for n, t in totals), "progress beyond its total: %s" % totals)


def scenario_corrupt(a):
    root = frames(os.path.join(a.work, "frames"), 5)
    bad = os.path.join(root, "left", "0002.png")
    with open(bad, "r+b") as f:
        f.truncate(60)
    out = fresh(os.path.join(a.work, "out"))
    p = run(a, ["--replay-left", root + "/left", "--replay-right", root + "/right", "--out", out,
                "--on-bad-frame", "skip"])
    check(p.returncode == 0, "exit %d" % p.returncode)
    check(re.search(r"^sfrt run: warning: bad frame skipped: '%s': " % re.escape(bad), p.stderr,
                    re.MULTILINE), "no console line names %s" % bad)


def scenario_grey(a):
    root = frames(os.path.join(a.work, "frames"), 4, grey=True)
    out = fresh(os.path.join(a.work, "out"))
    p = run(a, ["--replay-left", root + "/left", "--replay-right", root + "/right", "--out", out])
    check(p.returncode == 0, "exit %d" % p.returncode)
    notes = [l for l in p.stderr.splitlines() if "grayscale" in l]
    check(len(notes) == 1, "grayscale notes: %s, expected one" % notes)
    check(notes and os.path.join(root, "left", "0000.png") in notes[0],
          "the note names the first grayscale file: %s" % notes)


SCENARIOS = {
    "RunRejectsAnUnwritableOutDirBeforeOpeningTheSource": scenario_unwritable_out,
    "RunRejectsAnIsaThisCpuCannotRunBeforeStarting": scenario_isa,
    "RunRejectsLeftAndRightReplayFoldersWithDifferentFrameCounts": scenario_counts,
    "RunRejectsAnEmptyReplayFolder": scenario_empty,
    "RunRejectsASizeOutsideTheLimitsBeforeStarting": scenario_size,
    "RunLoopProgressCountsEveryPass": scenario_loop,
    "RunNamesTheCorruptFileOnTheConsoleWhenSkipping": scenario_corrupt,
    "RunNotesAGrayscaleInputOnce": scenario_grey,
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", choices=sorted(SCENARIOS))
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--model", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    a.work = os.path.abspath(a.work)
    fresh(a.work)
    os.makedirs(a.work)
    SCENARIOS[a.scenario](a)
    print("FAILED: %d check(s)" % len(FAILURES) if FAILURES else "OK")
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main())
