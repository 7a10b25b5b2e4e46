#!/usr/bin/python3
"""What bf16 and int8 storage cost on a generated SceneEDNet fixture, simulated in PyTorch.

Issue 12's fixture bars (bf16 within 2e-2, int8 within 5e-2 of float32's largest output) are
measured on random-weight networks. This script simulates exact per-layer rounding on the same
network and input that tests/fixtures/gen_sceneednet.py makes (seed 0), with float64
convolutions, so that the error of the storage formats themselves can be told from any
implementation's:
  bf16        weights and each convolution's input rounded to bfloat16
  bf16-phases bf16, and the four upsample->conv layers by sfrt's exact phase shortcut as its bf16
              kernels run it: each phase's 2x2 kernel summed from the float32 3x3 weights, then
              rounded to bfloat16 (issue 12: phase weights summed before quantisation); border
              pixels direct
  int8        weights symmetric per output channel, each convolution's input quantised to uint8
              with one range per tensor (its min and max on this input)
  int8-chan   the same with one range per input channel (an ideal: integer kernels cannot
              apply a scale per input channel inside their sums)
  int8-chan-folded  one range per input channel as integer kernels would have to do it: each
              channel's scale folded into the weights, which are then quantised per output
              channel (so a wide channel coarsens the weights of all the others)
  bf16-biascorr, int8-biascorr
              bf16, int8 with each convolution's bias corrected by the mean over this input of its
              output's error against float32 (per channel, the layers before it already
              corrected): empirical bias correction, calibrated in-sample as the fixture sweep's
              int8 is
  bf16-ends, int8-ends
              bf16, int8 with the first and the output convolution kept float32 (what issue 12
              allows --precision auto to keep)
  int8-wino   int8, and the Winograd algorithm on the stride-1 convolutions as reduced-precision
              kernels would run it: conv4 and conv5 by F(2x2,3x3), the four upsample->conv
              layers by F(2x2,2x2) on each phase's 2x2 kernel (sfrt's exact phase shortcut);
              the transformed input requantised to uint8 per tile position (its min and max on
              this input), the transformed weights to int8 per tile position and output channel
  bf16-wino   bf16, and the same Winograd layers with the transformed input and weights rounded
              to bfloat16 (F(4x4,3x3) for conv4 and conv5, as float32 Winograd uses)
  bf16-wino23 the same with F(2x2,3x3) for conv4 and conv5
and PyTorch's own bf16 (the whole model cast to bfloat16) as a peer. It prints, per variant, the
largest error relative to float32's largest |output| and the relative RMS error. The Winograd
transforms are checked against direct convolution in float64 before the variants run.

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


# Winograd F(m, r) transforms (Lavin and Gray 2016): Y = A^T [(G g G^T) * (B^T d B)] A over
# tiles of m + r - 1 inputs, m outputs.
WINOGRAD = {
    (2, 2): ([[1, -1, 0], [0, 1, 0], [0, -1, 1]],
             [[1, 0], [1, 1], [0, 1]],
             [[1, 1, 0], [0, 1, 1]]),
    (2, 3): ([[1, 0, -1, 0], [0, 1, 1, 0], [0, -1, 1, 0], [0, 1, 0, -1]],
             [[1, 0, 0], [0.5, 0.5, 0.5], [0.5, -0.5, 0.5], [0, 0, 1]],
             [[1, 1, 1, 0], [0, 1, -1, -1]]),
    (4, 3): ([[4, 0, -5, 0, 1, 0], [0, -4, -4, 1, 1, 0], [0, 4, -4, -1, 1, 0],
              [0, -2, -1, 2, 1, 0], [0, 2, -1, -2, 1, 0], [0, 4, 0, -5, 0, 1]],
             [[1 / 4, 0, 0], [-1 / 6, -1 / 6, -1 / 6], [-1 / 6, 1 / 6, -1 / 6],
              [1 / 24, 1 / 12, 1 / 6], [1 / 24, -1 / 12, 1 / 6], [0, 0, 1]],
             [[1, 1, 1, 1, 1, 0], [0, 1, -1, 2, -2, 0], [0, 1, 1, 4, 4, 0], [0, 1, -1, 8, -8, 1]]),
}


def winograd_conv(d, w, m, in_domain=None, w_domain=None):
    """Valid stride-1 convolution of d (N, C, H, W) with w (O, C, r, r) by F(m x m, r x r), no
    bias; in_domain / w_domain round the transformed input (N, C, th, tw, a, a) and weights
    (O, C, a, a)."""
    r = w.shape[2]
    bt, g, at = (torch.tensor(t, dtype=torch.float64) for t in WINOGRAD[(m, r)])
    a = m + r - 1
    n, _, h, wd = d.shape
    ho, wo = h - r + 1, wd - r + 1
    th, tw = -(-ho // m), -(-wo // m)
    d = F.pad(d, [0, tw * m + r - 1 - wd, 0, th * m + r - 1 - h])
    v = torch.einsum("ia,nctuab,jb->nctuij", bt, d.unfold(2, a, m).unfold(3, a, m), bt)
    u = torch.einsum("ia,ocab,jb->ocij", g, w, g)
    if in_domain:
        v = in_domain(v)
    if w_domain:
        u = w_domain(u)
    y = torch.einsum("ia,notuab,jb->notuij", at, torch.einsum("ocij,nctuij->notuij", u, v), at)
    return y.permute(0, 1, 2, 4, 3, 5).reshape(n, -1, th * m, tw * m)[:, :, :ho, :wo]


def phase_kernels(w):
    """The 2x2 kernels of a 3x3 convolution after a nearest 2x upsampling, by (row, column)
    phase of the upsampled position: phase 0 reads low-resolution rows i - 1, i with rows
    (w0, w1 + w2), phase 1 rows i, i + 1 with (w0 + w1, w2)."""
    def rows(k, phase, dim):
        k0, k1, k2 = k.unbind(dim)
        return torch.stack((k0, k1 + k2) if phase == 0 else (k0 + k1, k2), dim)
    return {(ry, rx): rows(rows(w, ry, 2), rx, 3) for ry in (0, 1) for rx in (0, 1)}


def upsampled_conv_by_phases(low, crop, w, direct, conv2x2):
    """The 3x3 convolution (tf padding, 1 on every side) of upsample(low) cropped by `crop`
    (rows, columns from the top left), its interior from the phases' 2x2 kernels over `low`
    through conv2x2(low, kernel) (a valid convolution), its border rows and columns from
    `direct` (the whole output computed directly, as sfrt computes the border pixels)."""
    out = direct.clone()
    hc, wc = out.shape[2], out.shape[3]
    for (ry, rx), k in phase_kernels(w).items():
        z = conv2x2(low, k)  # z[i, j]: rows i, i + 1 and columns j, j + 1 of low
        ys = [y for y in range(1, hc - 1) if (y + crop[0]) & 1 == ry]
        xs = [x for x in range(1, wc - 1) if (x + crop[1]) & 1 == rx]
        if not ys or not xs:
            continue
        lo_y = torch.tensor([(y + crop[0] - 1) >> 1 for y in ys])
        lo_x = torch.tensor([(x + crop[1] - 1) >> 1 for x in xs])
        out[:, :, ys[0]:ys[-1] + 1:2, xs[0]:xs[-1] + 1:2] = z[:, :, lo_y][:, :, :, lo_x]
    return out


def uint8_per_position(v):
    """v (N, C, th, tw, a, a) quantised to uint8 with one range per tile position (a, a)."""
    lo = v.amin(dim=(0, 1, 2, 3), keepdim=True).clamp(max=0)
    hi = v.amax(dim=(0, 1, 2, 3), keepdim=True).clamp(min=0)
    scale = (hi - lo).clamp(min=1e-30) / 255
    zero = torch.round(-lo / scale)
    return ((torch.round(v / scale) + zero).clamp(0, 255) - zero) * scale


def int8_per_position(u):
    """u (O, C, a, a) quantised to int8, symmetric per output channel and tile position."""
    scale = u.abs().amax(dim=1, keepdim=True).clamp(min=1e-30) / 127
    return torch.round(u / scale).clamp(-127, 127) * scale


WINOGRAD_VARIANTS = {  # name: (F(m,3) for conv4 and conv5, in_domain, w_domain)
    "int8-wino": (2, uint8_per_position, int8_per_position),
    "bf16-wino": (4, lambda v: to_bf16(v).double(), lambda u: to_bf16(u).double()),
    "bf16-wino23": (2, lambda v: to_bf16(v).double(), lambda u: to_bf16(u).double()),
}

PHASE_VARIANTS = {  # name: how the phases' 2x2 kernels (summed in float64) are rounded
    "bf16-phases": to_bf16,
}

VARIANTS = {
    "bf16": (to_bf16, to_bf16),
    "bf16-phases": (to_bf16, to_bf16),
    "bf16-ends": (to_bf16, to_bf16),
    "bf16-biascorr": (to_bf16, to_bf16),
    "int8": (int8_weights, lambda t: uint8_activations(t, False)),
    "int8-ends": (int8_weights, lambda t: uint8_activations(t, False)),
    "int8-biascorr": (int8_weights, lambda t: uint8_activations(t, False)),
    "int8-chan": (int8_weights, lambda t: uint8_activations(t, True)),
    "int8-chan-folded": (None, None),  # folded_conv
    "int8-wino": (int8_weights, lambda t: uint8_activations(t, False)),
    "bf16-wino": (to_bf16, to_bf16),
    "bf16-wino23": (to_bf16, to_bf16),
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

    up_layers = [model.conv6, model.conv7, model.conv8, model.conv9]  # each after an upsampling
    lows = []  # the inputs of the upsamplings so far

    float_outputs = []  # each convolution's float32 output, in call order (for the bias correction)

    def run(weights=None, activations=None, folded=False, winograd=None, phases=None,
            keep_ends=False, bias_correct=False, record=None):
        seen = [] if record is None else record  # this run's convolution outputs so far

        def conv(self, c, t):
            top, bottom = sceneednet._same_pad_amounts(t.shape[2], c.stride[0])
            left, right = sceneednet._same_pad_amounts(t.shape[3], c.stride[1])
            t = F.pad(t, [left, right, top, bottom])
            if folded:
                t, w = folded_conv(t.double(), c.weight.double())
            elif keep_ends and c in (model.conv0, model.output):
                w = c.weight
            else:
                w = weights(c.weight) if weights else c.weight
                t = activations(t) if activations else t
            y = F.conv2d(t.double(), w.double(), c.bias.double(), c.stride)
            bias = c.bias.double().view(1, -1, 1, 1)
            if phases is not None and c in up_layers:
                conv2x2 = lambda d, k: F.conv2d(d, phases(k).double())  # noqa: E731
            elif winograd is None or c.stride[0] != 1 or (c not in up_layers and
                                                          c not in (model.conv4, model.conv5)):
                if bias_correct:
                    y = y - (y - float_outputs[len(seen)]).mean(dim=(0, 2, 3), keepdim=True)
                seen.append(y)
                return y.float()
            elif c not in up_layers:
                m, in_domain, w_domain = winograd
                return (winograd_conv(t.double(), c.weight.double(), m, in_domain, w_domain) +
                        bias).float()
            else:
                _, in_domain, w_domain = winograd
                conv2x2 = lambda d, k: winograd_conv(d, k, 2, in_domain, w_domain)  # noqa: E731
            # The rounded upsampled map's low-resolution pixels (the crop drops the top rows and
            # left columns: low row i is upsampled row 2i - crop, row 0 for i = 0).
            low = lows[-1]
            crop = (2 * low.shape[2] - (t.shape[2] - 2), 2 * low.shape[3] - (t.shape[3] - 2))
            iy = [max(2 * i - crop[0], 0) + 1 for i in range(low.shape[2])]  # + 1: the pad
            ix = [max(2 * i - crop[1], 0) + 1 for i in range(low.shape[3])]
            low_rounded = t.double()[:, :, iy][:, :, :, ix]
            return (upsampled_conv_by_phases(low_rounded, crop, c.weight.double(), y - bias,
                                             conv2x2) + bias).float()

        def upsample(t):
            lows.append(t)
            return F.interpolate(t, scale_factor=2, mode="nearest")

        original = sceneednet.SceneEDNet._conv, sceneednet.SceneEDNet.__dict__["_up"]
        sceneednet.SceneEDNet._conv = conv
        sceneednet.SceneEDNet._up = staticmethod(upsample)
        try:
            return model(x).double()
        finally:
            sceneednet.SceneEDNet._conv, sceneednet.SceneEDNet._up = original
            lows.clear()

    def check_transforms():
        """Every Winograd form equals direct convolution in float64, phases included."""
        g = torch.Generator().manual_seed(1)
        d = torch.randn(2, 3, 11, 14, generator=g, dtype=torch.float64)
        for m, r in WINOGRAD:
            k = torch.randn(4, 3, r, r, generator=g, dtype=torch.float64)
            err = (winograd_conv(d, k, m) - F.conv2d(d, k)).abs().max().item()
            assert err < 1e-9, f"F({m},{r}) differs from direct convolution by {err}"
        k = torch.randn(4, 3, 3, 3, generator=g, dtype=torch.float64)
        for crop in ((0, 0), (1, 0), (0, 1), (1, 1)):
            u = F.interpolate(d, scale_factor=2, mode="nearest")[:, :, crop[0]:, crop[1]:]
            direct = F.conv2d(F.pad(u, [1, 1, 1, 1]), k)
            by_phases = upsampled_conv_by_phases(d, crop, k, torch.zeros_like(direct),
                                                 lambda a, b: winograd_conv(a, b, 2))
            err = (by_phases - direct)[:, :, 1:-1, 1:-1].abs().max().item()
            assert err < 1e-9, f"the phases with crop {crop} differ by {err}"

    with torch.no_grad():
        check_transforms()
        ref = run(record=float_outputs)
        largest = ref.abs().max().item()
        rms = ref.pow(2).mean().sqrt().item()
        print(f"SceneEDNet 1/{args.width_div} width at {args.height}x{args.width}, seed 0: "
              f"largest |output| {largest:.4g}")
        outputs = {name: run(*fns, folded=name == "int8-chan-folded",
                             winograd=WINOGRAD_VARIANTS.get(name), phases=PHASE_VARIANTS.get(name),
                             keep_ends=name.endswith("-ends"),
                             bias_correct=name.endswith("-biascorr"))
                   for name, fns in VARIANTS.items()}
        for m in (2, 4):
            exact = run(winograd=(m, None, None))  # the algorithm alone, float64
            err = (exact - ref).abs().max().item() / largest
            assert err < 1e-4, f"float64 Winograd F({m}) differs from direct by {err:.3e}"
        outputs["torch-bf16"] = model.to(torch.bfloat16)(x.to(torch.bfloat16)).double()
        for name, y in outputs.items():
            d = y - ref
            print(f"{name:16s} max error {d.abs().max().item() / largest:.3e} of the largest "
                  f"output, rms {d.pow(2).mean().sqrt().item() / rms:.3e}")


if __name__ == "__main__":
    main()
