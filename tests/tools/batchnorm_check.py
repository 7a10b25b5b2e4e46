#!/usr/bin/python3
"""A PyTorch network with batch normalisation, exported to ONNX with its BatchNormalization nodes
kept (model.eval(), training=TrainingMode.PRESERVE), goes through `sfrt export` with each one
folded into the Conv before it, and `sfrt infer` matches PyTorch within 1e-4 of the output's
largest magnitude at an odd size.

usage: batchnorm_check.py --sfrt BIN --work DIR

The network: Conv 12->8 3x3/2 + BatchNorm + LeakyReLU(0.3), Conv 8->8 3x3 + BatchNorm + ReLU,
nearest 2x upsampling, Conv 8->3 3x3 + BatchNorm, crop to the input size. The batch-norm running
statistics and affine parameters are seeded random values far from the identity, so a missing or
wrong fold shows.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import torch
from torch import nn


class Net(nn.Module):
    def __init__(self):
        super().__init__()
        self.conv0 = nn.Conv2d(12, 8, 3, stride=2, padding=1)
        self.bn0 = nn.BatchNorm2d(8, eps=1e-3)
        self.conv1 = nn.Conv2d(8, 8, 3, padding=1)
        self.bn1 = nn.BatchNorm2d(8)
        self.conv2 = nn.Conv2d(8, 3, 3, padding=1, bias=False)
        self.bn2 = nn.BatchNorm2d(3)

    def forward(self, x):
        h, w = x.shape[2], x.shape[3]
        y = nn.functional.leaky_relu(self.bn0(self.conv0(x)), 0.3)
        y = torch.relu(self.bn1(self.conv1(y)))
        y = nn.functional.interpolate(y, scale_factor=2, mode="nearest")
        y = self.bn2(self.conv2(y))
        return y[:, :, :h, :w]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    torch.manual_seed(11)
    net = Net()
    with torch.no_grad():
        for bn in (net.bn0, net.bn1, net.bn2):
            n = bn.num_features
            bn.running_mean.copy_(torch.randn(n) * 0.5)
            bn.running_var.copy_(torch.rand(n) * 3 + 0.2)
            bn.weight.copy_(torch.randn(n) * 0.8 + 1)
            bn.bias.copy_(torch.randn(n) * 0.3)
    net.eval()
    h, w = 37, 53
    x = torch.rand(1, 12, h, w) * 2 - 1
    onnx_path = os.path.join(a.work, "bn.onnx")
    torch.onnx.export(net, x, onnx_path, opset_version=13, input_names=["input"],
                      output_names=["flow"], training=torch.onnx.TrainingMode.PRESERVE,
                      do_constant_folding=False)
    import onnx
    ops = [n.op_type for n in onnx.load(onnx_path).graph.node]
    failed = []
    if ops.count("BatchNormalization") != 3:
        failed.append("the ONNX file has %d BatchNormalization nodes, expected 3 (ops %s)"
                      % (ops.count("BatchNormalization"), ops))
    model = os.path.join(a.work, "bn.sfrt")
    p = subprocess.run([a.sfrt, "export", onnx_path, "-o", model], capture_output=True, text=True)
    if p.returncode != 0:
        print(p.stdout + p.stderr)
        sys.exit("sfrt export failed (exit %d)" % p.returncode)
    p = subprocess.run([a.sfrt, "inspect", model], capture_output=True, text=True)
    layers = [line for line in p.stdout.splitlines() if re.match(r"^\s+\d+\s+\S+\s", line)]
    conv_lines = [line for line in layers if " conv " in line]
    if len(conv_lines) != 3 or any("norm" in line.lower() for line in layers):
        failed.append("sfrt inspect shows %d convolutions (expected 3, batch norm folded):\n%s"
                      % (len(conv_lines), p.stdout))
    xin = os.path.join(a.work, "x.npy")
    np.save(xin, x[0].permute(1, 2, 0).numpy().astype(np.float32))
    out = os.path.join(a.work, "y.npy")
    p = subprocess.run([a.sfrt, "infer", "--model", model, "--input-npy", xin, "-o", out],
                       capture_output=True, text=True)
    if p.returncode != 0:
        print(p.stdout + p.stderr)
        sys.exit("sfrt infer failed (exit %d)" % p.returncode)
    with torch.no_grad():
        want = net(x)[0].permute(1, 2, 0).numpy()
    got = np.load(out)
    if got.shape != want.shape:
        failed.append("output shape %s, PyTorch %s" % (got.shape, want.shape))
    else:
        err = float(np.abs(got - want).max())
        scale = float(np.abs(want).max())
        print("max |sfrt - torch| = %.3g, max |torch| = %.3g, ratio %.3g" % (err, scale,
                                                                           err / scale))
        if not err <= 1e-4 * scale:
            failed.append("max |sfrt - torch| %.3g over 1e-4 x %.3g" % (err, scale))
    for f in failed:
        print("FAIL: " + f)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
