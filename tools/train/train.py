#!/usr/bin/python3
"""Training reference for SceneEDNet (or SceneEDNet-U, --arch) on Scene Flow-layout data (e.g.
from `sfrt synth`).

Run with Debian's /usr/bin/python3 (python3-torch 1.13, python3-onnx, python3-numpy); CPU only.

  train.py --data DIR [DIR ...] --out RUN [--val DIR] [--arch sceneednet|sceneednet-u]
           [--batch-norm] [--width-div 8] [--recipe adam|paper]
           [--epochs N] [--batch B] [--max-minutes M] [--export --sfrt path/to/sfrt]

Recipes:
  paper  as published (docs/sceneednet.md): SGD, lr 1e-5, momentum 0.5, and a decay of
         lr/epochs applied per epoch with Keras' time-based rule lr_e = lr0 / (1 + (lr0/epochs) e).
  adam   practical: Adam, lr 1e-3, cosine decay to 0 over all iterations (after a 100-iteration
         linear warm-up); converges in far fewer iterations on small synthetic sets.
Loss: EPE, the mean over pixels of the Euclidean distance between predicted and true 3D vectors.
Input: L0,R0,L1,R1 BGR images; value = (pixel / 255 - 0.5) / 0.25 (recorded in the .sfrt).
Augmentation (--augment): random horizontal crop offsets are NOT used (they would change the
principal point); a random brightness/contrast change, the same for all four images, and with
--noise N a contrast difference of up to 5% per image and Gaussian noise of sigma up to N grey
levels (real stereo pairs differ in exposure and carry sensor noise; the renderer's do not).
Two exact geometric augmentations: --vflip mirrors half of the samples top to bottom (a rectified
rig mirrored about its horizontal plane is still rectified: rows flip, dY changes sign; needs the
principal point on the middle row, cy = (H - 1) / 2), and --static-share P replaces a share P of
the samples by a still scene (L0, R0 shown at t and t+1, true flow zero).

Files in RUN/: log.csv (one row per logged iteration and per validation), checkpoint.pt (latest:
model, optimiser, iteration; --resume continues from it), best.pt (lowest validation EPE when
--val is given), config.json; with --export: model.onnx and model.sfrt (via `sfrt export`).
"""

import argparse
import csv
import hashlib
import json
import math
import os
import subprocess
import sys
import time
import warnings

import numpy as np
import torch

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import sceneednet  # noqa: E402
import sfdata  # noqa: E402

PIXEL_SCALE = 1.0 / 255.0
PIXEL_MEAN = 0.5
PIXEL_STD = 0.25


def to_input(x_uint8):
    """uint8 (N, H, W, 12) numpy -> float32 (N, 12, H, W) tensor, normalised."""
    x = torch.from_numpy(x_uint8).permute(0, 3, 1, 2).float()
    return (x * PIXEL_SCALE - PIXEL_MEAN) / PIXEL_STD


def to_target(y):
    return torch.from_numpy(y).permute(0, 3, 1, 2).contiguous()


def mirror_rows(xb, yb, mask):
    """Mirrors the samples where `mask` is set top to bottom: images and flow flip rows, and the
    flow's Y component (camera y points down) changes sign. Exact when cy = (H - 1) / 2."""
    if not mask.any():
        return xb, yb
    m = torch.from_numpy(mask)
    xb, yb = xb.clone(), yb.clone()
    xb[m] = xb[m].flip(2)
    flipped = yb[m].flip(2)
    flipped[:, 1] = -flipped[:, 1]
    yb[m] = flipped
    return xb, yb


def still_scene(xb, yb, mask):
    """Replaces the samples where `mask` is set by (L0, R0, L0, R0) with zero flow."""
    if not mask.any():
        return xb, yb
    m = torch.from_numpy(mask)
    xb, yb = xb.clone(), yb.clone()
    xb[m, 6:12] = xb[m, 0:6]
    yb[m] = 0.0
    return xb, yb


def downsample(x, y, cam, factor):
    """Area-averages images (rounded to uint8, as cv::resize INTER_AREA does for an integer
    factor) and ground truth (3D vectors: averaged, not rescaled) by `factor`; the camera's
    focal length and principal point follow the pixel grid."""
    if factor == 1:
        return x, y, cam
    n, h, w = x.shape[:3]
    h2, w2 = h // factor, w // factor
    xb = x[:, :h2 * factor, :w2 * factor].reshape(n, h2, factor, w2, factor, -1)
    x = np.floor(xb.mean(axis=(2, 4), dtype=np.float64) + 0.5).astype(np.uint8)
    yb = y[:, :h2 * factor, :w2 * factor].reshape(n, h2, factor, w2, factor, -1)
    y = yb.mean(axis=(2, 4), dtype=np.float64).astype(np.float32)
    cam = {"focal": cam["focal"] / factor, "baseline": cam["baseline"],
           "cx": (cam["cx"] + 0.5) / factor - 0.5, "cy": (cam["cy"] + 0.5) / factor - 0.5}
    return x, y, cam


def tree_signature(root):
    """Changes whenever a file of the tree is added, removed, resized or rewritten."""
    entries = []
    for dirpath, _, names in os.walk(root):
        for n in names:
            st = os.stat(os.path.join(dirpath, n))
            entries.append((os.path.relpath(os.path.join(dirpath, n), root), st.st_size,
                            st.st_mtime_ns))
    entries.sort()
    return hashlib.sha256(repr(entries).encode()).hexdigest()[:16]


def load_tree_cached(root, factor, cache_dir):
    """load_tree + downsample; with cache_dir, the arrays are kept there as .npy files keyed by
    the tree's path, the factor and its signature, so a second run skips decoding the PNGs."""
    cam = sfdata.read_camera(root)
    if not cache_dir:
        x, y = sfdata.load_tree(root)
        return downsample(x, y, cam, factor)
    key = hashlib.sha256(f"{os.path.abspath(root)}|{factor}|{tree_signature(root)}"
                         .encode()).hexdigest()[:20]
    base = os.path.join(cache_dir, key)
    if os.path.isfile(base + ".done"):
        x = np.load(base + "-x.npy", mmap_mode="r")
        y = np.load(base + "-y.npy", mmap_mode="r")
        with open(base + ".done", encoding="utf-8") as f:
            cam = json.load(f)
        return np.ascontiguousarray(x), np.ascontiguousarray(y), cam
    x, y = sfdata.load_tree(root)
    x, y, cam = downsample(x, y, cam, factor)
    os.makedirs(cache_dir, exist_ok=True)
    np.save(base + "-x.npy", x)
    np.save(base + "-y.npy", y)
    with open(base + ".done.tmp", "w", encoding="utf-8") as f:  # marker last: no half cache
        json.dump(cam, f)
    os.replace(base + ".done.tmp", base + ".done")
    return x, y, cam


def load_sets(dirs, factor=1, cache_dir=""):
    xs, ys, cams = [], [], []
    for d in dirs:
        x, y, cam = load_tree_cached(d, factor, cache_dir)
        xs.append(x)
        ys.append(y)
        cams.append(cam)
        print(f"data    {d}: {x.shape[0]} samples, {x.shape[1]}x{x.shape[2]}", flush=True)
    shapes = {x.shape[1:3] for x in xs}
    if len(shapes) != 1:
        raise SystemExit(f"train.py: all data sets must have one image size, got {sorted(shapes)}")
    for d, c in zip(dirs[1:], cams[1:]):
        if c != cams[0]:
            raise SystemExit(f"train.py: {d}/camera.json {c} differs from {dirs[0]}: {cams[0]} "
                             f"(one training camera per model)")
    return np.concatenate(xs), np.concatenate(ys), cams[0]


def evaluate(model, x, y, batch, flow_scale=1.0):
    """(model EPE, zero-flow EPE) over all samples, in the data's units."""
    model.eval()
    total, zero, n = 0.0, 0.0, 0
    with torch.no_grad():
        for i in range(0, x.shape[0], batch):
            xb, yb = to_input(x[i:i + batch]), to_target(y[i:i + batch])
            pred = model(xb) / flow_scale
            total += float(torch.norm(pred - yb, dim=1).sum())
            zero += float(torch.norm(yb, dim=1).sum())
            n += yb.shape[0] * yb.shape[2] * yb.shape[3]
    model.train()
    return total / n, zero / n


def learning_rate(args, it, total_iters, epoch):
    if args.recipe == "paper":
        return args.lr / (1.0 + (args.lr / args.epochs) * epoch)
    warm = min(100, max(1, total_iters // 10))
    if it < warm:
        return args.lr * (it + 1) / warm
    t = (it - warm) / max(1, total_iters - warm)
    return 0.5 * args.lr * (1.0 + math.cos(math.pi * min(1.0, t)))


def unscaled(model, flow_scale):
    """A copy of `model` whose output is in the data's units: the network was trained to predict
    flow * flow_scale, so the linear output conv's weights and bias are divided by it."""
    import copy
    model = copy.deepcopy(model)
    if flow_scale != 1.0:
        with torch.no_grad():
            model.output.weight.div_(flow_scale)
            model.output.bias.div_(flow_scale)
    return model


def export(model, args, cam, height, width):
    onnx_path = os.path.join(args.out, "model.onnx")
    model = unscaled(model, args.flow_scale)
    model.eval()
    x = torch.zeros(1, sceneednet.IN_CHANNELS, height, width)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # tracing the 'same' padding arithmetic is intended
        with torch.no_grad():
            torch.onnx.export(model, (x,), onnx_path, export_params=True, opset_version=13,
                              do_constant_folding=True, input_names=[sceneednet.INPUT_NAME],
                              output_names=[sceneednet.OUTPUT_NAME],
                              training=torch.onnx.TrainingMode.EVAL)
    print(f"onnx    {onnx_path}", flush=True)
    if not args.sfrt:
        return
    sfrt_path = os.path.join(args.out, "model.sfrt")
    cmd = [args.sfrt, "export", onnx_path, "-o", sfrt_path, "--name", args.name,
           "--scale", repr(PIXEL_SCALE), "--mean", f"{PIXEL_MEAN},{PIXEL_MEAN},{PIXEL_MEAN}",
           "--std", f"{PIXEL_STD},{PIXEL_STD},{PIXEL_STD}",
           "--focal", repr(cam["focal"]), "--baseline", repr(cam["baseline"]),
           "--cx", repr(cam["cx"]), "--cy", repr(cam["cy"]), "--training-state", "trained"]
    if args.units:
        cmd += ["--units", args.units]
    print("export  " + " ".join(cmd), flush=True)
    rc = subprocess.call(cmd)
    if rc != 0:
        raise SystemExit(f"train.py: sfrt export failed with exit code {rc}")


def build_model(arch, width_div, batch_norm):
    """The network to train: SceneEDNet as published or SceneEDNet-U (skip connections), TF
    'same' padding. Batch norm (SceneEDNet-U only) is folded into the convolutions at export."""
    if arch == "sceneednet":
        if batch_norm:
            raise SystemExit("train.py: --batch-norm needs --arch sceneednet-u")
        return sceneednet.SceneEDNet(width_div, "tf")
    return sceneednet.SceneEDNetU(width_div, "tf", batch_norm=batch_norm)


def export_only(args):
    with open(os.path.join(args.out, "config.json"), encoding="utf-8") as f:
        config = json.load(f)
    # Runs from before --arch trained the published chain.
    model = build_model(config.get("arch", "sceneednet"), config["width_div"],
                        config.get("batch_norm", False))
    name = "best.pt" if args.export_from == "best" else "checkpoint.pt"
    state = torch.load(os.path.join(args.out, name))
    model.load_state_dict(state["model"])
    print(f"export  weights of {name} (iteration {state['iteration']}"
          + (f", validation EPE {state['val_epe']:.4f})" if "val_epe" in state else ")"),
          flush=True)
    args.flow_scale = config.get("flow_scale", 1.0)
    export(model, args, config["camera"], config["height"], config["width"])
    return 0


def parse_args(argv):
    p = argparse.ArgumentParser(prog="train.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--data", nargs="+", default=[], help="training data set roots")
    p.add_argument("--val", nargs="*", default=[], help="validation data set roots")
    p.add_argument("--out", required=True, help="run directory (created)")
    p.add_argument("--arch", choices=tuple(sceneednet.ARCHITECTURES), default="sceneednet",
                   help="sceneednet: the published chain; sceneednet-u: with skip connections "
                        "from conv0..conv3 to the decoder (default sceneednet)")
    p.add_argument("--batch-norm", action="store_true",
                   help="sceneednet-u: a BatchNorm2d after every hidden convolution (folded "
                        "into the convolutions at export)")
    p.add_argument("--width-div", type=int, default=8, choices=sceneednet.WIDTH_DIVS)
    p.add_argument("--downsample", type=int, default=1,
                   help="train at 1/N of the data's resolution (area average; the recorded "
                        "camera is scaled to match)")
    p.add_argument("--recipe", choices=("adam", "paper"), default="adam")
    p.add_argument("--lr", type=float, default=None,
                   help="initial learning rate (default 1e-3 adam, 1e-5 paper)")
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--batch", type=int, default=4)
    p.add_argument("--max-iters", type=int, default=0, help="stop after this many iterations")
    p.add_argument("--max-minutes", type=float, default=0,
                   help="stop after this much wall time; the cosine schedule is then laid "
                        "over the estimated number of iterations that fit")
    p.add_argument("--augment", action="store_true",
                   help="random brightness/contrast (all four images), a small gain difference "
                        "per image and Gaussian pixel noise (--noise)")
    p.add_argument("--noise", type=float, default=0.0,
                   help="with --augment: the largest noise sigma in 8-bit grey levels; each "
                        "sample draws its sigma from [0, NOISE] (default 0: none)")
    p.add_argument("--vflip", action="store_true",
                   help="mirror half of the samples top to bottom (dY changes sign); exact for "
                        "a rectified rig with cy = (H - 1) / 2, refused otherwise")
    p.add_argument("--static-share", type=float, default=0.0,
                   help="replace this share of the samples (0..1) by a still scene: the t "
                        "images again at t+1, zero flow (default 0)")
    p.add_argument("--init", default="",
                   help="start from these weights (a best.pt or checkpoint.pt, or a float32 "
                        ".sfrt file such as models/sceneednet-default.sfrt: its batch norm is folded, "
                        "so train it without --batch-norm), not from random ones; the "
                        "optimiser and iteration count start fresh")
    p.add_argument("--cache-dir", default="",
                   help="keep decoded, downsampled data sets here as .npy (faster restarts)")
    p.add_argument("--flow-scale", type=float, default=1.0,
                   help="train the network to predict flow * S (e.g. 10 for metric data: "
                        "decimetres, targets near 1); the export divides the output conv by S, "
                        "so the model file predicts the data's units")
    p.add_argument("--threads", type=int, default=1, help="torch threads")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--log-every", type=int, default=10)
    p.add_argument("--val-every", type=int, default=0,
                   help="validate every N iterations (default: once per epoch)")
    p.add_argument("--resume", action="store_true", help="continue from RUN/checkpoint.pt")
    p.add_argument("--export", action="store_true", help="write model.onnx (and model.sfrt)")
    p.add_argument("--export-only", action="store_true",
                   help="no training: export RUN/best.pt (or checkpoint.pt with --export-from "
                        "last) as written by an earlier, possibly interrupted, run")
    p.add_argument("--export-from", choices=("last", "best"), default="best",
                   help="weights to export (best: lowest validation EPE, if --val was given)")
    p.add_argument("--sfrt", default="", help="sfrt binary, for the .sfrt export")
    p.add_argument("--name", default="sceneednet", help="model name stored in the .sfrt")
    p.add_argument("--units", default="",
                   help="units of the data's scene flow, stored in the .sfrt (e.g. metres for "
                        "sfrt synth --scene robot); default: unknown")
    p.add_argument("--require-decrease", action="store_true",
                   help="exit 1 unless the mean loss of the last 3 logged iterations is below "
                        "the first iteration's loss (smoke tests)")
    args = p.parse_args(argv)
    if not args.data and not args.export_only:
        p.error("--data is required (unless --export-only)")
    if not 0.0 <= args.static_share <= 1.0:
        p.error(f"--static-share {args.static_share:g}: must be within 0..1")
    if args.lr is None:
        args.lr = 1e-3 if args.recipe == "adam" else 1e-5
    return args


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    gen = torch.Generator().manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    os.makedirs(args.out, exist_ok=True)

    if args.export_only:
        return export_only(args)
    x, y, cam = load_sets(args.data, args.downsample, args.cache_dir)
    vx = vy = None
    if args.val:
        vx, vy, vcam = load_sets(args.val, args.downsample, args.cache_dir)
        if vcam != cam:
            print(f"warning validation camera {vcam} differs from training camera {cam}")
    n, height, width = x.shape[0], x.shape[1], x.shape[2]
    if args.vflip and abs(cam["cy"] - (height - 1) / 2) > 1e-3:
        sys.exit(f"train.py: --vflip needs the principal point on the middle row, but the "
                 f"training camera has cy {cam['cy']:g} for {height} rows (middle "
                 f"{(height - 1) / 2:g}); mirroring would move it")

    model = build_model(args.arch, args.width_div, args.batch_norm)
    if args.recipe == "paper":
        opt = torch.optim.SGD(model.parameters(), lr=args.lr, momentum=0.5)
    else:
        opt = torch.optim.Adam(model.parameters(), lr=args.lr)
    ckpt_path = os.path.join(args.out, "checkpoint.pt")
    best_path = os.path.join(args.out, "best.pt")
    it, best = 0, float("inf")
    spent = 0.0
    if args.init and not (args.resume and os.path.isfile(ckpt_path)):
        if args.init.endswith(".sfrt"):
            import sfrt_weights  # needs python3-flatbuffers

            sfrt_weights.load_into(model, args.init, output_scale=args.flow_scale)
        else:
            model.load_state_dict(torch.load(args.init)["model"])
        print(f"init    weights of {args.init}", flush=True)
    if args.resume and os.path.isfile(ckpt_path):
        state = torch.load(ckpt_path)
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        it, best, spent = state["iteration"], state["best_val"], state.get("seconds", 0.0)
        print(f"resume  iteration {it}, best validation EPE {best:.4f}", flush=True)

    iters_per_epoch = max(1, n // args.batch)
    total_iters = args.epochs * iters_per_epoch
    if args.max_iters:
        total_iters = min(total_iters, args.max_iters)
    with open(os.path.join(args.out, "config.json"), "w", encoding="utf-8") as f:
        json.dump({**vars(args), "samples": n, "height": height, "width": width, "camera": cam,
                   "pixel_scale": PIXEL_SCALE, "pixel_mean": PIXEL_MEAN,
                   "pixel_std": PIXEL_STD, "torch": torch.__version__}, f, indent=2)
    params = sum(p.numel() for p in model.parameters())
    print(f"model   {args.arch} width/{args.width_div}"
          f"{' with batch norm' if args.batch_norm else ''}, {params:,} parameters; {n} samples "
          f"{height}x{width}, batch {args.batch}, recipe {args.recipe}, lr {args.lr:g}",
          flush=True)

    log_path = os.path.join(args.out, "log.csv")
    new_log = not (args.resume and os.path.isfile(log_path))
    log_file = open(log_path, "a" if not new_log else "w", newline="", encoding="utf-8")
    log = csv.writer(log_file)
    if new_log:
        log.writerow(["iteration", "epoch", "seconds", "lr", "train_epe", "val_epe",
                      "val_zero_flow_epe"])

    def validate(epoch):
        nonlocal best
        if vx is None:
            return
        v, z = evaluate(model, vx, vy, args.batch, args.flow_scale)
        log.writerow([it, epoch, f"{spent + time.monotonic() - t0:.1f}", "", "", f"{v:.6f}",
                      f"{z:.6f}"])
        log_file.flush()
        print(f"val     iteration {it}: EPE {v:.4f} (zero flow {z:.4f}, ratio {v / z:.3f})",
              flush=True)
        if v < best:
            best = v
            torch.save({"model": model.state_dict(), "iteration": it, "val_epe": v}, best_path)

    def save():
        torch.save({"model": model.state_dict(), "optimizer": opt.state_dict(), "iteration": it,
                    "best_val": best, "seconds": spent + time.monotonic() - t0}, ckpt_path)

    t0 = time.monotonic()
    losses = []
    model.train()
    order = rng.permutation(n)
    pos = 0
    while it < total_iters:
        if args.max_minutes and spent + time.monotonic() - t0 > 60 * args.max_minutes:
            print(f"stop    time limit reached at iteration {it}", flush=True)
            break
        if pos + args.batch > n:
            order, pos = rng.permutation(n), 0
        idx = np.sort(order[pos:pos + args.batch])
        pos += args.batch
        epoch = it // iters_per_epoch
        xb, yb = to_input(x[idx]), to_target(y[idx])
        if args.vflip:
            xb, yb = mirror_rows(xb, yb, rng.random(len(idx)) < 0.5)
        if args.static_share > 0:
            xb, yb = still_scene(xb, yb, rng.random(len(idx)) < args.static_share)
        if args.augment:
            gain = torch.from_numpy(rng.uniform(0.8, 1.2, size=(len(idx), 1, 1, 1))).float()
            bias = torch.from_numpy(rng.uniform(-0.3, 0.3, size=(len(idx), 1, 1, 1))).float()
            xb = xb * gain + bias
            if args.noise > 0:
                # Real stereo pairs differ slightly in exposure and carry sensor noise; the
                # renderer's images do not.
                per_image = torch.from_numpy(
                    rng.uniform(0.95, 1.05, size=(len(idx), 4, 1, 1, 1))).float()
                sigma = torch.from_numpy(
                    rng.uniform(0.0, args.noise, size=(len(idx), 1, 1, 1))).float()
                sigma = sigma * PIXEL_SCALE / PIXEL_STD
                shape = xb.shape
                xb = (xb.view(shape[0], 4, 3, shape[2], shape[3]) * per_image).view(shape)
                xb = xb + sigma * torch.randn(shape, generator=gen)
        # With --max-minutes the cosine runs over the iterations estimated to fit the budget.
        sched_total = total_iters
        if args.max_minutes and it >= 20:
            rate = it / max(1e-6, spent + time.monotonic() - t0)
            sched_total = min(total_iters, int(rate * 60 * args.max_minutes))
        lr = learning_rate(args, it, max(sched_total, it + 1), epoch)
        for g in opt.param_groups:
            g["lr"] = lr
        loss = sceneednet.epe_loss(model(xb), yb * args.flow_scale) / args.flow_scale
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss))
        it += 1
        if it % args.log_every == 0 or it == 1 or it == total_iters:
            elapsed = spent + time.monotonic() - t0
            log.writerow([it, epoch, f"{elapsed:.1f}", f"{lr:.3g}", f"{float(loss):.6f}", "", ""])
            log_file.flush()
            recent = np.mean(losses[-args.log_every:])
            print(f"iter    {it}/{total_iters} epoch {epoch} loss {recent:.4f} lr {lr:.3g} "
                  f"({elapsed:.0f} s, {it / max(elapsed, 1e-6):.2f} it/s)", flush=True)
        if (args.val_every and it % args.val_every == 0) or \
                (not args.val_every and it % iters_per_epoch == 0):
            validate(epoch)
            save()
    if vx is not None and (not losses or it % max(1, args.val_every or iters_per_epoch) != 0):
        validate(it // iters_per_epoch)
    save()
    log_file.close()
    print(f"done    {it} iterations in {spent + time.monotonic() - t0:.0f} s", flush=True)

    if args.export:
        if args.export_from == "best" and os.path.isfile(best_path):
            model.load_state_dict(torch.load(best_path)["model"])
            print(f"export  weights of best.pt (validation EPE {best:.4f})", flush=True)
        export(model, args, cam, height, width)

    if args.require_decrease:
        if len(losses) < 4:
            raise SystemExit("train.py: --require-decrease needs at least 4 iterations")
        first, last = losses[0], float(np.mean(losses[-3:]))
        print(f"loss    first {first:.6f}, mean of last 3 {last:.6f}", flush=True)
        if not last < first:
            raise SystemExit("train.py: the loss did not decrease")
    return 0


if __name__ == "__main__":
    sys.exit(main())
