#!/usr/bin/python3
"""train.py --init FILE.sfrt: a shipped model's weights go back into PyTorch for fine-tuning.

A seeded SceneEDNet-U (width/16) with batch norm, its running statistics far from the identity,
is exported the way train.py exports (ONNX, then `sfrt export`, which folds the norms). Loading
the .sfrt into the same network without batch norm (tools/train/sfrt_weights.py) must give
PyTorch's output within 1e-5 of its largest magnitude, with the output convolution scaled by
--flow-scale; a bf16 file and a network of other convolutions are refused, naming the file.

usage: train_init_sfrt_test.py --sfrt BIN --train-dir tools/train --work DIR
"""
import argparse
import os
import shutil
import subprocess
import sys
import warnings

import torch


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--sfrt", required=True)
    p.add_argument("--train-dir", required=True)
    p.add_argument("--work", required=True)
    args = p.parse_args()
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    sys.path.insert(0, args.train_dir)
    import sfrt_weights
    import train

    torch.manual_seed(3)
    net = train.build_model("sceneednet-u", 16, True)
    with torch.no_grad():
        for m in net.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.copy_(torch.randn(m.num_features) * 0.3)
                m.running_var.copy_(torch.rand(m.num_features) * 2 + 0.3)
                m.weight.copy_(torch.randn(m.num_features) * 0.5 + 1)
                m.bias.copy_(torch.randn(m.num_features) * 0.2)
    net.eval()
    onnx_path = os.path.join(args.work, "u.onnx")
    x = torch.rand(1, 12, 40, 56) * 4 - 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(net, (x,), onnx_path, opset_version=13,
                          training=torch.onnx.TrainingMode.EVAL)
    sfrt_path = os.path.join(args.work, "u.sfrt")
    subprocess.run([args.sfrt, "export", onnx_path, "-o", sfrt_path], check=True,
                   stdout=subprocess.DEVNULL)

    failed = []
    with torch.no_grad():
        want = net(x)
        for scale in (1.0, 10.0):
            plain = train.build_model("sceneednet-u", 16, False)
            sfrt_weights.load_into(plain, sfrt_path, output_scale=scale)
            got = plain(x) / scale
            err = float((got - want).abs().max())
            top = float(want.abs().max())
            print(f"output scale {scale:g}: max |loaded - original| {err:.3g} of {top:.3g}")
            if not err <= 1e-5 * top:
                failed.append(f"output scale {scale:g}: error {err:.3g} over 1e-5 x {top:.3g}")

    bf16_path = os.path.join(args.work, "u-bf16.sfrt")
    subprocess.run([args.sfrt, "export", sfrt_path, "-o", bf16_path, "--precision", "bf16"],
                   check=True, stdout=subprocess.DEVNULL)
    for path, arch, want_text in ((bf16_path, "sceneednet-u", "is not float32"),
                                  (sfrt_path, "sceneednet", "has weights")):
        try:
            sfrt_weights.load_into(train.build_model(arch, 16, False), path)
            failed.append(f"{path} loaded into {arch}; it should be refused")
        except ValueError as e:
            if want_text not in str(e) or path not in str(e):
                failed.append(f"{path} into {arch}: unexpected message: {e}")
    for f in failed:
        print("FAIL: " + f)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
