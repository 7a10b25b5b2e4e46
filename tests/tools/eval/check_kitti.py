#!/usr/bin/python3
"""The KITTI Scene Flow 2015 path end to end, against an independent scorer written here.

1. `sfrt synth --layout kitti` and `--layout scene-flow` with the same options: the KITTI files,
   decoded with pypng (pure Python, neither OpenCV nor libpng), hold the Scene Flow layout's
   ground truth within the encodings' quantisation (disparity 1/256 px, flow 1/64 px), with the
   devkit's conventions (uint16 d*256, 0 = none; RGB u, v at 2^15 + 64 x, B = valid; disp_1 on the
   grid of t; obj_map 0 = background).
2. `sfrt eval --dataset KITTI --write-submission`: each method's "kitti" object; with the oracle
   depth the model's and zero flow's D1 is 0 (the ground truth's own disparity); the counts are
   the independent scorer's (the devkit's rule: > 3 px AND > 5%; SF where all three ground truths
   have a value, an outlier where any is) on the written submission, pixel and outlier counts
   exactly (sfrt scores the estimate as the submission holds it, quantised by the encodings, as
   the devkit reads it).
3. The ground truth scored as a submission has no outlier (the hand-worked counts of known
   perturbations are kitti_test.cc's).

usage: check_kitti.py --sfrt BIN --model M --work DIR
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import png

SYNTH = ["--scene", "robot", "--seed", "4242", "--sequences", "1", "--frames", "5", "--size",
         "96x128", "--focal", "90", "--baseline", "0.12", "--objects", "4"]


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        print("FAIL: exit %d: %s\n%s%s" % (p.returncode, " ".join(cmd), p.stdout, p.stderr))
        sys.exit(1)
    return p.stdout


def read_png(path):
    """uint16 (H, W) or (H, W, 3) in the file's own channel order (RGB), via pypng."""
    w, h, rows, info = png.Reader(filename=path).asDirect()
    a = np.vstack([np.asarray(r, dtype=np.uint32) for r in rows])
    planes = info["planes"]
    return a.reshape(h, w, planes) if planes > 1 else a.reshape(h, w)


def disparity(path):
    v = read_png(path).astype(np.float64)
    return np.where(v > 0, v / 256.0, np.nan)


def flow(path):
    rgb = read_png(path).astype(np.float64)
    valid = rgb[..., 2] > 0
    u = np.where(valid, (rgb[..., 0] - 32768) / 64.0, np.nan)
    v = np.where(valid, (rgb[..., 1] - 32768) / 64.0, np.nan)
    return u, v


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    channels = 3 if kind == b"PF" else 1
    return np.flipud(data.reshape(h, w, channels)).squeeze()


def outlier(err, mag):
    with np.errstate(divide="ignore", invalid="ignore"):
        return (err > 3.0) & (err / mag > 0.05)


def score(gt_dir, sub_dir, scenes):
    """The devkit's counts: {map: [[pixels bg, fg], [outliers bg, fg]]}."""
    counts = {m: np.zeros((2, 2), dtype=np.int64) for m in ("d1", "d2", "fl", "sf")}
    for name in scenes:
        png_name = name + "_10.png"
        g0 = disparity(os.path.join(gt_dir, "disp_occ_0", png_name))
        g1 = disparity(os.path.join(gt_dir, "disp_occ_1", png_name))
        gu, gv = flow(os.path.join(gt_dir, "flow_occ", png_name))
        obj = read_png(os.path.join(gt_dir, "obj_map", png_name)) > 0
        e0 = disparity(os.path.join(sub_dir, "disp_0", png_name))
        e1 = disparity(os.path.join(sub_dir, "disp_1", png_name))
        eu, ev = flow(os.path.join(sub_dir, "flow", png_name))
        has = {"d1": ~np.isnan(g0), "d2": ~np.isnan(g1), "fl": ~np.isnan(gu)}
        bad = {"d1": outlier(np.abs(e0 - g0), np.abs(g0)),
               "d2": outlier(np.abs(e1 - g1), np.abs(g1)),
               "fl": outlier(np.hypot(eu - gu, ev - gv), np.hypot(gu, gv))}
        has["sf"] = has["d1"] & has["d2"] & has["fl"]
        bad["sf"] = bad["d1"] | bad["d2"] | bad["fl"]
        for m in counts:
            for r, region in enumerate((~obj, obj)):
                counts[m][0, r] += int((has[m] & region).sum())
                counts[m][1, r] += int((has[m] & bad[m] & region).sum())
    return counts


def check_encodings(kitti, flows, failed):
    """Scene k of the KITTI layout is frame k of the Scene Flow layout's sequence 0000."""
    for k in range(4):
        name = "%06d_10.png" % k
        d0 = read_pfm(os.path.join(flows, "disparity", "0000", "left", "%04d.pfm" % k))
        dc = read_pfm(os.path.join(flows, "disparity_change", "0000", "into_future", "left",
                                   "%04d.pfm" % k))
        of = read_pfm(os.path.join(flows, "optical_flow", "0000", "into_future", "left",
                                   "OpticalFlowIntoFuture_%04d_L.pfm" % k))
        k0 = disparity(os.path.join(kitti, "disp_occ_0", name))
        k1 = disparity(os.path.join(kitti, "disp_occ_1", name))
        ku, kv = flow(os.path.join(kitti, "flow_occ", name))
        h, w = d0.shape
        ys, xs = np.mgrid[0:h, 0:w]
        inside = ((xs + of[..., 0] >= 0) & (xs + of[..., 0] <= w - 1) &
                  (ys + of[..., 1] >= 0) & (ys + of[..., 1] <= h - 1))
        checks = [("disp_occ_0", k0, d0, np.ones_like(inside), 1 / 256.0),
                  ("disp_occ_1", k1, d0 + dc, inside, 1 / 256.0),
                  ("flow_occ u", ku, of[..., 0], inside, 1 / 64.0),
                  ("flow_occ v", kv, of[..., 1], inside, 1 / 64.0)]
        for label, got, want, valid, q in checks:
            if not np.array_equal(~np.isnan(got), valid):
                failed.append("%s %s: values where the point stays in view, none elsewhere" %
                              (label, name))
                continue
            err = np.abs(got[valid] - want[valid]).max() if valid.any() else 0.0
            if err > q + 1e-6:
                failed.append("%s %s: off by %.6f, more than the encoding's %.6f" %
                              (label, name, err, q))
    return 4


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--model", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    kitti_root = os.path.join(a.work, "kitti")
    flows = os.path.join(a.work, "flows")
    run([a.sfrt, "synth", "--layout", "kitti", "--out", kitti_root] + SYNTH)
    run([a.sfrt, "synth", "--out", flows] + SYNTH)
    kitti = os.path.join(kitti_root, "training")
    scenes = sorted(f[:6] for f in os.listdir(os.path.join(kitti, "image_2"))
                    if f.endswith("_10.png"))
    failed = []
    if scenes != ["%06d" % k for k in range(4)]:
        failed.append("synth --layout kitti wrote scenes %s; expected 000000..000003" % scenes)
    check_encodings(kitti, flows, failed)

    out = os.path.join(a.work, "eval.json")
    sub = os.path.join(a.work, "submission")
    text = run([a.sfrt, "eval", "--dataset", kitti_root, "--model", a.model, "--size", "96x128",
                "--json", out, "--write-submission", sub, "--quiet"])
    with open(out) as f:
        report = json.load(f)
    if report.get("layout") != "kitti":
        failed.append("eval.json's layout is %r, not 'kitti'" % report.get("layout"))
    for method, depth in (("sfrt", "gt (oracle)"), ("zero_flow", "gt (oracle)"),
                          ("classical", "stereo (its own)")):
        k = report[method]["kitti"]
        if k["depth"] != depth:
            failed.append("%s: depth %r, expected %r" % (method, k["depth"], depth))
        if method != "classical" and k["d1"]["all"] != 0:
            failed.append("%s: D1 %.3f%% with the oracle depth; expected 0" % (method,
                                                                               k["d1"]["all"]))
    if "D1-all" not in text or "gt (oracle)" not in text:
        failed.append("the table does not show D1-all and the oracle depth:\n" + text)

    # The JSON's counts against the independent scorer on the written submission.
    mine = score(kitti, sub, scenes)
    theirs = report["sfrt"]["kitti"]["counts"]
    for m in ("d1", "d2", "fl", "sf"):
        pixels = np.array(theirs[m]["pixels"])
        outliers = np.array(theirs[m]["outliers"])
        if not np.array_equal(pixels, mine[m][0]):
            failed.append("%s pixels: sfrt %s, independent %s" % (m, pixels, mine[m][0]))
        if not np.array_equal(outliers, mine[m][1]):
            failed.append("%s outliers: sfrt %s, independent %s" % (m, outliers, mine[m][1]))
        print("%s: pixels %s, outliers sfrt %s / independent %s" % (
            m, pixels.tolist(), outliers.tolist(), mine[m][1].tolist()))

    # The ground truth as a submission: no outlier. A foreground disparity 4 px off: counted.
    gt_sub = os.path.join(a.work, "gt_submission")
    for src, dst in (("disp_occ_0", "disp_0"), ("disp_occ_1", "disp_1"), ("flow_occ", "flow")):
        shutil.copytree(os.path.join(kitti, src), os.path.join(gt_sub, dst))
    exact = score(kitti, gt_sub, scenes)
    if any(exact[m][1].sum() for m in exact):
        failed.append("the ground truth as a submission has outliers: %s" % exact)
    if failed:
        for f in failed:
            print("FAIL: " + f)
        sys.exit(1)
    print("PASS: %d scenes; sfrt D1/D2/Fl/SF all %.2f/%.2f/%.2f/%.2f%% (oracle depth)" % (
        len(scenes), *(report["sfrt"]["kitti"][m]["all"] for m in ("d1", "d2", "fl", "sf"))))


if __name__ == "__main__":
    main()
