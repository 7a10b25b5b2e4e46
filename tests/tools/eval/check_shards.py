#!/usr/bin/python3
"""A sharded sfrt eval merges into exactly the single run: on a Scene Flow tree (units:
sequences) and a KITTI tree (units: scenes), `sfrt eval --shard I/N` for every I and `sfrt merge`
of their --json files (given in any order) write the single run's --json byte for byte and print
its tables. --shard auto reads a Slurm array task (SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN of
SLURM_ARRAY_TASK_COUNT) and a Kubernetes Indexed Job (JOB_COMPLETION_INDEX of --shard-count).
Each shard writes JSON.status. sfrt merge refuses a missing shard, a shard given twice, shards of
different options (naming the option) or models, each naming the file and the field, and a JSON
file that is not a shard's (without crashing). A tree whose units lack some of the files the
FlyingThings3D conventions' masks need merges into the single run too, naming the same file.

usage: check_shards.py --sfrt BIN --model M --other-model M2 --work DIR
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

SYNTH = ["--scene", "robot", "--seed", "11", "--size", "96x128", "--focal", "90", "--baseline",
         "0.12", "--objects", "3"]


def run(cmd, env=None, expect=0):
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if p.returncode != expect:
        print("FAIL: exit %d (expected %d): %s\n%s%s" % (p.returncode, expect, " ".join(cmd),
                                                        p.stdout, p.stderr))
        sys.exit(1)
    return p.stdout + p.stderr


def table(text):
    """The printed report without the lines that differ by nature (timing, file names)."""
    return [l for l in text.splitlines()
            if not l.startswith(("evaluated", "wrote", "merged", "frame "))]


def check_merge(a, root, extra, shards, failed):
    single = os.path.join(a.work, "single.json")
    single_text = run([a.sfrt, "eval", "--model", a.model, "--dataset", root, "--json", single,
                       "--quiet"] + extra)
    parts = []
    for i in range(shards):
        part = os.path.join(a.work, "shard%d.json" % i)
        run([a.sfrt, "eval", "--model", a.model, "--dataset", root, "--json", part, "--quiet",
             "--shard", "%d/%d" % (i, shards)] + extra)
        with open(part + ".status") as f:
            status = json.load(f)
        if status["state"] != "done" or status["shard"] != "%d/%d" % (i, shards):
            failed.append("%s: status %s" % (part, status))
        parts.append(part)
    merged = os.path.join(a.work, "merged.json")
    merged_text = run([a.sfrt, "merge"] + parts[::-1] + ["--json", merged])
    with open(single, "rb") as f, open(merged, "rb") as g:
        if f.read() != g.read():
            failed.append("%s: the merged --json differs from the single run's" % root)
    if table(single_text) != table(merged_text):
        failed.append("%s: sfrt merge printed other tables than sfrt eval:\n%s\n---\n%s" % (
            root, "\n".join(table(single_text)), "\n".join(table(merged_text))))
    with open(parts[0]) as f:
        units = json.load(f)["shard"]["units"]
    print("%s: %d units in %d shards merged into the single run's --json (byte for byte)" % (
        os.path.basename(root), len(units), shards))
    return parts


def main():
    ap = argparse.ArgumentParser()
    for flag in ("--sfrt", "--model", "--other-model", "--work"):
        ap.add_argument(flag, required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    flows = os.path.join(a.work, "flows")
    kitti = os.path.join(a.work, "kitti")
    run([a.sfrt, "synth", "--out", flows, "--sequences", "5", "--frames", "3"] + SYNTH)
    run([a.sfrt, "synth", "--layout", "kitti", "--out", kitti, "--sequences", "2", "--frames",
         "4"] + SYNTH)
    failed = []
    check_merge(a, kitti, ["--depth", "stereo"], 2, failed)
    parts = check_merge(a, flows, [], 3, failed)

    # The FlyingThings3D conventions when some units lack the files their masks need: unavailable
    # in every shard that met the gap, and the merge names the first such file in list order, as
    # the single run does (sequence 0000 lacks its 2D flow, 0001 its disparities).
    gaps = os.path.join(a.work, "gaps")
    shutil.copytree(flows, gaps)
    shutil.rmtree(os.path.join(gaps, "optical_flow", "0000"))
    shutil.rmtree(os.path.join(gaps, "disparity", "0001"))
    check_merge(a, gaps, [], 3, failed)
    with open(os.path.join(a.work, "merged.json")) as f:
        conventions = json.load(f)["sfrt"]["conventions"]
    reasons = {k: v.get("reason") for k, v in conventions.items()}
    expected = {
        "raft3d": "its mask needs the |2D optical flow|: no "
                  "optical_flow/0000/into_future/left/OpticalFlowIntoFuture_0000_L.pfm",
        "flownet3d": "its mask needs the depth at t: no disparity/0001/left/0000.pfm",
    }
    for key, reason in expected.items():
        if reasons.get(key) != reason:
            failed.append("gaps: %s's reason is %r, expected %r" % (key, reasons.get(key), reason))

    # --shard auto, from the scheduler's environment.
    cases = [({"SLURM_ARRAY_TASK_ID": "7", "SLURM_ARRAY_TASK_MIN": "5",
               "SLURM_ARRAY_TASK_COUNT": "3"}, [], 2),
             ({"JOB_COMPLETION_INDEX": "1"}, ["--shard-count", "3"], 1)]
    for env, extra, index in cases:
        out = os.path.join(a.work, "auto.json")
        run([a.sfrt, "eval", "--model", a.model, "--dataset", flows, "--json", out, "--quiet",
             "--shard", "auto"] + extra, env=dict(os.environ, **env))
        with open(out) as f:
            shard = json.load(f)["shard"]
        if (shard["index"], shard["count"]) != (index, 3):
            failed.append("--shard auto with %s: shard %s/%s, expected %d/3" % (
                env, shard["index"], shard["count"], index))

    # Refusals, each naming the file and the field.
    other = os.path.join(a.work, "other.json")
    run([a.sfrt, "eval", "--model", a.model, "--dataset", flows, "--json", other, "--quiet",
         "--shard", "1/3", "--thresholds", "relative"])
    model = os.path.join(a.work, "model.json")
    run([a.sfrt, "eval", "--model", a.other_model, "--dataset", flows, "--json", model, "--quiet",
         "--shard", "1/3", "--size", "96x128", "--allow-camera-mismatch"])
    broken = os.path.join(a.work, "broken.json")
    with open(parts[0]) as f:
        doc = json.load(f)
    doc["image_size"] = "96x128"  # JSON, but not what a shard writes: refused, not a crash
    with open(broken, "w") as f:
        json.dump(doc, f)
    refusals = [
        ([broken, parts[1], parts[2]], "is not what sfrt eval --shard writes"),
        ([parts[0], parts[2]], "shard 1 of 3 is missing"),
        ([parts[0], parts[1], parts[1], parts[2]], "shard 1 of 3 is given twice"),
        ([parts[0], other, parts[2]], "other.json: provenance.options.thresholds is \"relative\""),
        ([parts[0], model, parts[2]], "model.json: provenance.model_sha256 is"),
    ]
    for inputs, message in refusals:
        text = run([a.sfrt, "merge"] + inputs, expect=1)
        if message not in text:
            failed.append("sfrt merge %s: expected '%s' in:\n%s" % (
                " ".join(os.path.basename(i) for i in inputs), message, text))
    if failed:
        for f in failed:
            print("FAIL: " + f)
        sys.exit(1)
    print("PASS")


if __name__ == "__main__":
    main()
