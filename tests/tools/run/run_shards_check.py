#!/usr/bin/python3
"""A sharded sfrt run merges into the single run: over a synthesised dataset of 5 sequences (one
frame missing, --on-bad-frame skip), `sfrt run --shard I/3` for every I writes its files to
OUT/shard-I-of-3/, and together the shards write exactly the single run's flow files (byte for
byte) and windows. `sfrt merge OUT --json F` gives the single run's summary.json: every counter,
list and string equal (frames, windows and their breaks, drops, pairs, images, bad frames in the
dataset's order, the last window, the source line), and every latency percentile equal to the
percentile (NumPy's linear rule, computed here) of all the shards' samples. Timing cannot equal
another run's: the latencies, wall_s and fps are checked against the shards' own samples and
wall times instead. --shard auto reads Slurm's and Kubernetes' variables; each shard's
status.json says done. Refused, each naming the file and field: a missing shard, one given twice,
shards of different options or models, a shard with no unit, a summary that is not a shard's.
With --bags: the same for a folder of 3 rosbag2 bags (recorded by sfrt run --record-bag), each
bag a unit of --replay-bags.

usage: run_shards_check.py --sfrt BIN --model M --other-model M2 --work DIR [--bags]
"""
import argparse
import glob
import json
import os
import shutil
import subprocess
import sys

import numpy as np

SYNTH = ["--scene", "robot", "--seed", "5", "--size", "96x128", "--sequences", "5", "--frames",
         "4", "--objects", "2"]
# Values that are the run's timing, not its counts: checked against the samples instead.
TIMING = ("latency_ms", "latency_attribution_ms", "fps", "wall_s")


def run(cmd, env=None, expect=0):
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if p.returncode != expect:
        print("FAIL: exit %d (expected %d): %s\n%s%s" % (p.returncode, expect, " ".join(cmd),
                                                        p.stdout, p.stderr))
        sys.exit(1)
    return p.stdout + p.stderr


def differences(single, merged, path=""):
    """Paths where the two summaries differ, timing and the merge's own records left out."""
    out = []
    if isinstance(single, dict) and isinstance(merged, dict):
        for key in sorted(set(single) | set(merged)):
            where = path + "." + key if path else key
            if where in TIMING or where in ("merged", "provenance", "outputs.dir"):
                continue
            if key not in merged or key not in single:
                out.append(where + (" missing in the merge" if key in single else " added"))
                continue
            out += differences(single[key], merged[key], where)
    elif single != merged:
        out.append("%s: single %r, merged %r" % (path, single, merged))
    return out


def percentiles(samples):
    v = np.asarray(samples, dtype=np.float64)
    return {"p50": np.percentile(v, 50), "p90": np.percentile(v, 90),
            "p99": np.percentile(v, 99), "max": v.max(), "count": len(v)}


def check_latencies(shards, merged, failed):
    """Every merged percentile is the percentile of all shards' samples."""
    def joined(group, name):
        out = []
        for s in shards:
            samples = s["latency_samples_ms"]
            out += samples[group][name] if group else samples[name]
        return out
    series = [("latency_ms." + n, joined("stages", n), merged["latency_ms"][n])
              for n in ("source", "preprocess", "infer", "output")]
    series.append(("latency_ms.end_to_end", joined(None, "end_to_end"),
                   merged["latency_ms"]["end_to_end"]))
    for name, got in merged["latency_attribution_ms"]["parts"].items():
        series.append(("latency_attribution_ms.parts." + name, joined("parts", name), got))
    for name, samples, got in series:
        want = percentiles(samples)
        for key, value in want.items():
            if abs(got[key] - value) > 1e-9 * max(1.0, abs(value)):
                failed.append("%s.%s: merged %r, the shards' samples give %r" % (
                    name, key, got[key], value))
    wall = sum(s["wall_s"] for s in shards)
    if abs(merged["wall_s"] - wall) > 1e-9 or \
            abs(merged["fps"] - merged["frames"]["written"] / wall) > 1e-6:
        failed.append("wall_s %r / fps %r: not the shards' %r s summed" % (
            merged["wall_s"], merged["fps"], wall))
    return len(series)


def outputs(folder):
    """Flow files (name -> bytes) and windows.csv lines (without the header) of a run."""
    flows = {}
    for path in glob.glob(os.path.join(folder, "*.pfm")):
        with open(path, "rb") as f:
            flows[os.path.basename(path)] = f.read()
    with open(os.path.join(folder, "windows.csv")) as f:
        lines = f.read().splitlines()[1:]
    return flows, lines


def check_files(single_dir, shard_dirs, failed):
    flows, lines = outputs(single_dir)
    got_flows, got_lines = {}, []
    for d in shard_dirs:
        f, l = outputs(d)
        for name in f:
            if name in got_flows:
                failed.append("%s written by two shards" % name)
        got_flows.update(f)
        got_lines += l
    if sorted(flows) != sorted(got_flows):
        failed.append("the shards wrote %s, the single run %s" % (sorted(got_flows),
                                                                  sorted(flows)))
    for name, data in flows.items():
        if got_flows.get(name) != data:
            failed.append("%s differs from the single run's" % name)
    if sorted(lines) != sorted(got_lines):
        failed.append("windows.csv of the shards differ from the single run's")
    return len(flows)


def check_sharded(a, base, work, count, failed):
    """The single run and `count` shards of `base` (an sfrt run command line without --out):
    the merged summary and the shards' files against the single run's. Returns the shards'
    summaries."""
    single_dir = os.path.join(work, "single")
    single_text = run(base + ["--out", single_dir])
    out = os.path.join(work, "sharded")
    for i in reversed(range(count)):
        run(base + ["--out", out, "--shard", "%d/%d" % (i, count)])
    shard_dirs = [os.path.join(out, "shard-%d-of-%d" % (i, count)) for i in range(count)]
    shards = []
    for i, d in enumerate(shard_dirs):
        with open(os.path.join(d, "status.json")) as f:
            status = json.load(f)
        if status["state"] != "done" or status["shard"] != "%d/%d" % (i, count):
            failed.append("%s: status %s" % (d, status))
        with open(os.path.join(d, "summary.json")) as f:
            shards.append(json.load(f))
    merged_path = os.path.join(work, "merged.json")
    merged_text = run([a.sfrt, "merge", out, "--json", merged_path])
    with open(os.path.join(single_dir, "summary.json")) as f:
        single = json.load(f)
    with open(merged_path) as f:
        merged = json.load(f)
    failed += differences(single, merged)
    series = check_latencies(shards, merged, failed)
    files = check_files(single_dir, shard_dirs, failed)
    if merged["frames"]["written"] != sum(s["frames"]["written"] for s in shards):
        failed.append("merged frames are not the shards' sum")
    first = [l for l in single_text.splitlines() if l.startswith(("source", "frames"))]
    again = [l for l in merged_text.splitlines() if l.startswith(("source", "frames"))]
    if first != again:
        failed.append("sfrt merge printed %s, sfrt run %s" % (again, first))
    print("%d units in %d shards: %d flow files as the single run's, summary equal but for "
          "timing, %d latency series the percentiles of the shards' %d samples" % (
              len(shards[0]["shard"]["units"]), count, files, series,
              merged["latency_ms"]["end_to_end"]["count"]))
    return single, shards, shard_dirs


def check_bags(a, data, failed):
    """Three bags recorded from the dataset's sequences, replayed as --replay-bags units."""
    work = os.path.join(a.work, "bags")
    folder = os.path.join(work, "drives")
    os.makedirs(folder)
    for seq in ("0000", "0001", "0002"):
        frames = os.path.join(data, "frames_cleanpass", seq)
        run([a.sfrt, "run", "--model", a.model, "--replay-left", os.path.join(frames, "left"),
             "--replay-right", os.path.join(frames, "right"), "--out",
             os.path.join(work, "rec" + seq), "--flow-format", "none", "--no-png",
             "--progress", "off", "--record-bag", os.path.join(folder, "drive_%s.mcap" % seq)])
    bags = sorted(os.listdir(folder))
    with open(os.path.join(folder, "README.txt"), "w") as f:  # not a bag: passed over
        f.write("drives of 2026-12-06\n")
    base = [a.sfrt, "run", "--model", a.model, "--replay-bags", folder, "--threads", "1",
            "--progress", "off"]
    single, _, _ = check_sharded(a, base, work, 2, failed)
    if [u["sequence"] for u in single["source"]["units"]] != bags:
        failed.append("--replay-bags units %s" % single["source"]["units"])


def main():
    ap = argparse.ArgumentParser()
    for flag in ("--sfrt", "--model", "--other-model", "--work"):
        ap.add_argument(flag, required=True)
    ap.add_argument("--bags", action="store_true", help="also shard a folder of bags")
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    data = os.path.join(a.work, "data")
    run([a.sfrt, "synth", "--out", data] + SYNTH)
    # A lost frame in the middle of sequence 0003: a bad frame, and a break in its windows.
    lost = glob.glob(os.path.join(data, "frames_cleanpass", "0003", "right", "0001.*"))[0]
    os.remove(lost)
    base = [a.sfrt, "run", "--model", a.model, "--replay", data, "--threads", "1",
            "--progress", "off", "--on-bad-frame", "skip"]
    failed = []
    single, shards, shard_dirs = check_sharded(a, base, a.work, 3, failed)
    if not single["bad_frames"] or single["windows"]["broken_by_lost_frame"] < 1:
        failed.append("the lost frame made no bad frame or break: %s" % single["bad_frames"])
    if a.bags:
        check_bags(a, data, failed)

    # --shard auto, from the scheduler's environment.
    cases = [({"SLURM_ARRAY_TASK_ID": "6", "SLURM_ARRAY_TASK_MIN": "5",
               "SLURM_ARRAY_TASK_COUNT": "3"}, [], 1),
             ({"JOB_COMPLETION_INDEX": "2"}, ["--shard-count", "3"], 2)]
    for env, extra, index in cases:
        auto = os.path.join(a.work, "auto")
        shutil.rmtree(auto, ignore_errors=True)
        run(base + ["--out", auto, "--shard", "auto"] + extra, env=dict(os.environ, **env))
        with open(os.path.join(auto, "shard-%d-of-3" % index, "summary.json")) as f:
            shard = json.load(f)["shard"]
        if (shard["index"], shard["count"], shard["mine"]) != (index, 3,
                                                               shards[index]["shard"]["mine"]):
            failed.append("--shard auto with %s: shard %s" % (env, shard))

    # Refusals, each naming the file and the field.
    other = os.path.join(a.work, "other")
    run(base + ["--out", other, "--shard", "1/3", "--flow-format", "npy"])
    model = os.path.join(a.work, "model")
    run(base[:2] + ["--model", a.other_model] + base[4:] +
        ["--out", model, "--shard", "1/3", "--size", "96x128"])
    broken = os.path.join(a.work, "broken.json")
    doc = dict(shards[0])
    doc["frames"] = "many"  # JSON, but not what a shard writes: refused, not a crash
    with open(broken, "w") as f:
        json.dump(doc, f)
    d0, d1, d2 = shard_dirs
    refusals = [
        ([d0, d2], "shard 1 of 3 is missing"),
        ([d0, d1, d1, d2], "shard 1 of 3 is given twice"),
        ([d0, os.path.join(other, "shard-1-of-3"), d2],
         "shard-1-of-3/summary.json: outputs.flow_format is \"npy\""),
        ([d0, os.path.join(model, "shard-1-of-3"), d2], "model."),
        ([broken, d1, d2], "frames"),
        ([os.path.join(a.work, "single")], "not the summary of sfrt run --shard"),
    ]
    for inputs, message in refusals:
        text = run([a.sfrt, "merge"] + inputs, expect=1)
        if message not in text:
            failed.append("sfrt merge %s: expected '%s' in:\n%s" % (" ".join(inputs), message,
                                                                     text))
    text = run(base + ["--out", os.path.join(a.work, "none"), "--shard", "5/6"], expect=2)
    if "shard 5/6 has no unit" not in text:
        failed.append("a shard without a unit: %s" % text)
    text = run([a.sfrt, "run", "--model", a.model, "--replay-video", lost,
                "--out", os.path.join(a.work, "none"), "--shard", "0/2"], expect=2)
    if "--shard splits a dataset" not in text:
        failed.append("--shard without --replay: %s" % text)
    if failed:
        for f in failed:
            print("FAIL: " + f)
        sys.exit(1)
    print("PASS")


if __name__ == "__main__":
    main()
