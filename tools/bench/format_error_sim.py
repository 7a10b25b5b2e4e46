#!/usr/bin/python3
"""What bf16 and int8 storage cost on a generated SceneEDNet fixture, simulated in PyTorch.

Issue 12's fixture bars (bf16 within 2e-2, int8 within 5e-2 of float32's largest output) are
measured on random-weight networks. This script simulates exact per-layer rounding on the same
network and input that tests/fixtures/gen_sceneednet.py makes (seed 0), with float64
convolutions, so that the error of the storage formats themselves can be told from any
implementation's:
  bf16        weights and each convolution's input rounded to bfloat16
  int8        weights symmetric per output channel, each convolution's input quantised to uint8
              with one range per tensor (its min and max on this input)
  int8-chan   the same with one range per input channel (an ideal: integer kernels cannot
              apply a scale per input channel inside their sums)
  int8-chan-folded  one range per input channel as integer kernels would have to do it: each
              channel's scale folded into the weights, which are then quantised per output
              channel (so a wide channel coarsens the weights of all the others)
and PyTorch's own bf16 (the whole model cast to bfloat16) as a peer. It prints, per variant, the
largest error relative to float32's largest |output| and the relative RMS error.

Run with Debian's /usr/bin/python3 (python3-torch, python3-numpy):
  /usr/bin/python3 tools/bench/format_error_sim.py --width-div 8 --height 270 --width 480
"""
import argparse
import os
import sys

import torch
import torch.nn.functional as F

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "tests", "fixtures"))
sys.path.insert(0, os.path.join(ROOT, "tools", "train"))
import gen_sceneednet  # noqa: E402
import sceneednet  # noqa: E402


def to_bf16(t):
    return t.to(torch.bfloat16).to(torch.float32)


def int8_weights(w):
    scale = w.abs().amax(dim=(1, 2, 3), keepdim=True).clamp(min=1e-30) / 127
    return torch.round(w / scale).clamp(-127, 127) * scale


def uint8_levels(t, per_channel):
    """(integer levels minus the zero point, scale) of t quantised to uint8."""
    dims = (0, 2, 3) if per_channel else (0, 1, 2, 3)
    lo = t.amin(dim=dims, keepdim=True).clamp(max=0)
    hi = t.amax(dim=dims, keepdim=True).clamp(min=0)
    scale = (hi - lo).clamp(min=1e-30) / 255
    zero = torch.round(-lo / scale)
    return (torch.round(t / scale) + zero).clamp(0, 255).sub(zero), scale


def uint8_activations(t, per_channel):
    levels, scale = uint8_levels(t, per_channel)
    return levels * scale


def folded_conv(t, w):
    """(input, weights) of a convolution on per-channel uint8 levels, scales in the weights."""
    levels, scale = uint8_levels(t, True)  # scale: (1, C, 1, 1)
    return levels, int8_weights(w * scale.view(1, -1, 1, 1))


VARIANTS = {
    "bf16": (to_bf16, to_bf16),
    "int8": (int8_weights, lambda t: uint8_activations(t, False)),
    "int8-chan": (int8_weights, lambda t: uint8_activations(t, True)),
    "int8-chan-folded": (None, None),  # folded_conv
}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--width-div", type=int, default=8, help="as gen_sceneednet.py (default 8)")
    p.add_argument("--height", type=int, default=270)
    p.add_argument("--width", type=int, default=480)
    args = p.parse_args()
    if args.width_div not in sceneednet.WIDTH_DIVS:
        p.error(f"--width-div must be one of {sceneednet.WIDTH_DIVS}")
    if args.height < 16 or args.width < 16:
        p.error("--height and --width must be at least 16")

    torch.manual_seed(0)
    model = sceneednet.SceneEDNet(args.width_div, "tf")
    gen_sceneednet.init_weights(model, 0)
    model.eval()
    x = torch.from_numpy(gen_sceneednet.make_input(args.height, args.width, 0))

    def run(weights=None, activations=None, folded=False):
        def conv(self, c, t):
            top, bottom = sceneednet._same_pad_amounts(t.shape[2], c.stride[0])
            left, right = sceneednet._same_pad_amounts(t.shape[3], c.stride[1])
            t = F.pad(t, [left, right, top, bottom])
            if folded:
                t, w = folded_conv(t.double(), c.weight.double())
            else:
                w = weights(c.weight) if weights else c.weight
                t = activations(t) if activations else t
            return F.conv2d(t.double(), w.double(), c.bias.double(), c.stride).float()

        original = sceneednet.SceneEDNet._conv
        sceneednet.SceneEDNet._conv = conv
        try:
            return model(x).double()
        finally:
            sceneednet.SceneEDNet._conv = original

    with torch.no_grad():
        ref = run()
        largest = ref.abs().max().item()
        rms = ref.pow(2).mean().sqrt().item()
        print(f"SceneEDNet 1/{args.width_div} width at {args.height}x{args.width}, seed 0: "
              f"largest |output| {largest:.4g}")
        outputs = {name: run(*fns, folded=name == "int8-chan-folded")
                   for name, fns in VARIANTS.items()}
        outputs["torch-bf16"] = model.to(torch.bfloat16)(x.to(torch.bfloat16)).double()
        for name, y in outputs.items():
            d = y - ref
            print(f"{name:16s} max error {d.abs().max().item() / largest:.3e} of the largest "
                  f"output, rms {d.pow(2).mean().sqrt().item() / rms:.3e}")


if __name__ == "__main__":
    main()
