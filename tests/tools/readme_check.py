#!/usr/bin/python3
"""The README's shell examples, run in order on this build (issue #38, item 14), so the front door
cannot drift from the product: every ```sh block of README.md (and then of each further document
given, docs/features.md) is read, its commands are run one by one in a scratch directory that looks like the repository root (models/, tools/ and build/
linked, firmware-cfg/ copied so a profile's relative outputs land here), with `sfrt` meaning this
build's bin/sfrt as the README says, and each must exit 0. Variables a block sets (M=..., F=...)
carry on to its later lines.

Commands it does not run, each with its reason (SKIPS below), are listed in its output; a README
command that matches no rule and fails fails the test. A SKIPS rule that matches no README line
fails it too, so the list cannot go stale.

usage: readme_check.py --readme README.md [--readme docs/features.md ...] --repo ROOT
                       --build BUILD_DIR --work DIR
"""
import argparse
import os
import re
import shutil
import subprocess
import sys

# (pattern matched at the start of a command, why it is not run here)
SKIPS = [
    (r"bash tools/demo\.sh", "the main job: it configures and builds the tree this test runs "
     "from; CI and the session notes run it"),
    (r"bash tools/test\.sh", "the test suite this test is part of"),
    (r"bash tools/install-deps\.sh", "installs Debian packages (changes the machine); "
     "tools/test.sh runs it first"),
    (r"cmake --preset release && cmake --build", "the build this test runs from"),
    (r"ctest --preset release", "the test suite this test is part of"),
    (r"roscore &", "needs a stereo driver publishing images; tests/ros/node_check.py runs the "
     "node against a real roscore"),
    (r"build/release/bin/sfrt_ros ", "the node needs roscore and a stereo driver (see above)"),
    (r"build/release/bin/sfrt_ros2 ", "the node needs a stereo driver on DDS; "
     "tests/ros2/node2_check.py runs it against Cyclone DDS and Fast DDS participants"),
    (r"sfrt export (model\.onnx|old\.sfrt|model\.sfrt|rgbd\.onnx)", "needs the user's own "
     "model files"),
    (r"sfrt infer --model (model|rgbd)\.sfrt", "needs the user's own model and inputs"),
    (r"sfrt report compare a/", "needs two earlier profiles of the user's"),
    (r"sfrt annotate DATASET_ROOT", "needs a Scene Flow dataset (tests/tools/synth runs annotate)"),
]


def commands(readmes):
    """(block number, command) of every ```sh block of the documents in order, continuation lines
    joined, comments kept; blocks are numbered across the documents."""
    out, block, inside, pending = [], 0, False, ""
    for line in (text for readme in readmes for text in open(readme)):
        if line.startswith("```"):
            inside = line.strip() == "```sh" if not inside else False
            block += inside
            continue
        if not inside:
            continue
        text = line.rstrip("\n")
        if text.rstrip().endswith("\\"):
            pending += text.rstrip()[:-1] + " "
            continue
        text = pending + text
        pending = ""
        if text.strip() and not text.lstrip().startswith("#"):
            out.append((block, text.strip()))
    return out


def skip_reason(command):
    for i, (pattern, reason) in enumerate(SKIPS):
        if re.match(pattern, command):
            return i, reason
    return None, None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--readme", required=True, action="append")
    for flag in ("--repo", "--build", "--work"):
        ap.add_argument(flag, required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(os.path.join(a.work, "build"))
    os.makedirs(os.path.join(a.work, "bin"))
    for name in ("models", "tools"):
        os.symlink(os.path.join(a.repo, name), os.path.join(a.work, name))
    shutil.copytree(os.path.join(a.repo, "firmware-cfg"), os.path.join(a.work, "firmware-cfg"))
    os.symlink(os.path.abspath(a.build), os.path.join(a.work, "build", "release"))
    os.symlink(os.path.join(os.path.abspath(a.build), "bin", "sfrt"),
               os.path.join(a.work, "bin", "sfrt"))
    env = dict(os.environ)
    env["PATH"] = os.path.join(a.work, "bin") + os.pathsep + env["PATH"]

    failed, used, ran, skipped = [], set(), 0, []
    blocks = {}
    for block, command in commands(a.readme):
        blocks.setdefault(block, []).append(command)
    for block in sorted(blocks):
        assignments = []  # M=..., F=...: kept for the block's later commands
        for command in blocks[block]:
            rule, reason = skip_reason(command)
            if rule is not None:
                used.add(rule)
                skipped.append("%s  -- %s" % (command.split("#")[0].strip(), reason))
                continue
            if re.match(r"^[A-Za-z_][A-Za-z0-9_]*=\S+$", command.split("#")[0].strip()):
                assignments.append(command.split("#")[0].strip())
                continue
            script = "set -e\n" + "\n".join(assignments) + "\n" + command + "\n"
            p = subprocess.run(["bash", "-c", script], cwd=a.work, env=env, text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=900)
            ran += 1
            status = "ok" if p.returncode == 0 else "FAILED (exit %d)" % p.returncode
            print("[block %d] %s: %s" % (block, status, command.split("#")[0].strip()), flush=True)
            if p.returncode != 0:
                failed.append(command)
                print(p.stdout[-2000:] + p.stderr[-2000:], flush=True)
    print("\nnot run here:")
    for line in skipped:
        print("  " + line)
    stale = [SKIPS[i][0] for i in range(len(SKIPS)) if i not in used]
    if stale:
        print("FAIL: skip rules that match no README command (remove them): %s" % stale)
    if failed or stale or ran == 0:
        print("%d of %d README commands failed" % (len(failed), ran))
        sys.exit(1)
    print("\nall %d README commands that run here exited 0" % ran)


if __name__ == "__main__":
    main()
