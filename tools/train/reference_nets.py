"""Reference encoder-decoder networks beyond SceneEDNet (issue 16), written here from the papers.

DispNetS (Mayer et al., "A Large Dataset to Train Convolutional Networks for Disparity, Optical
Flow, and Scene Flow Estimation", CVPR 2016) is below FlowNetS: the same contracting part, and
an expanding part whose every level convolves its stack once more (iconv, 3x3) before
predicting, down to half the input's resolution.

FlowNetS (Dosovitskiy et al., "FlowNet: Learning Optical Flow with Convolutional Networks",
ICCV 2015), adapted to scene flow: the same 12-channel input as SceneEDNet (two stereo pairs)
and 3-channel predictions. Its contracting part is ten convolutions (7x7/2, 5x5/2, 5x5/2, then
3x3 with strides 1 and 2 alternating); its expanding part, at each of four levels, stacks the
encoder tensor of that resolution, a 4x4/2 transposed convolution of the level below (leaky
ReLU) and the level below's prediction upsampled by its own 4x4/2 transposed convolution, and
predicts from the stack with a 3x3 convolution. The network's output is the finest prediction,
at a quarter of the input's resolution, as the paper's (which a bilinear upsampling outside the
network brings to full size). Odd input sizes make a transposed convolution's output one row or
column larger than the encoder tensor beside it: it is cut to that size (x[..., :h, :w]). With
batch_norm, every encoder convolution and every feature transposed convolution is followed by a
BatchNorm2d before its leaky ReLU (the paper's FlowNetS has none; FlowNet 2.0's variants do).
Leaky ReLU slope 0.1, as the paper's implementation.
"""

import torch
import torch.nn as nn
import torch.nn.functional as F

IN_CHANNELS = 12
OUT_CHANNELS = 3
LEAKY = 0.1
# (name, kernel, stride, width) of the contracting part at full width.
FLOWNETS_ENCODER = (("conv1", 7, 2, 64), ("conv2", 5, 2, 128), ("conv3", 5, 2, 256),
                    ("conv3_1", 3, 1, 256), ("conv4", 3, 2, 512), ("conv4_1", 3, 1, 512),
                    ("conv5", 3, 2, 512), ("conv5_1", 3, 1, 512), ("conv6", 3, 2, 1024),
                    ("conv6_1", 3, 1, 1024))
# (level, encoder tensor it stacks with, width of its feature transposed convolution)
FLOWNETS_DECODER = ((5, "conv5_1", 512), (4, "conv4_1", 256), (3, "conv3_1", 128),
                    (2, "conv2", 64))
WIDTH_DIVS = (1, 2, 4, 8, 16, 32, 64)


def _add_encoder(module, width_div):
    """Adds FlowNetS's contracting part to `module`; returns each layer's width by name, in
    order."""
    widths = {}
    cin = IN_CHANNELS
    for name, k, s, w in FLOWNETS_ENCODER:
        w //= width_div
        setattr(module, name, nn.Conv2d(cin, w, k, stride=s, padding=(k - 1) // 2))
        widths[name] = w
        cin = w
    return widths


def _encode(module, x):
    """Runs the contracting part (module._act(i, .) after layer i); returns the last tensor and
    every layer's output by name."""
    enc = {}
    for i, (name, *_) in enumerate(FLOWNETS_ENCODER):
        x = module._act(i, getattr(module, name)(x))
        enc[name] = x
    return x, enc


class FlowNetS(nn.Module):
    """FlowNetS-style scene flow network with widths divided by `width_div`."""

    def __init__(self, width_div=1, batch_norm=False):
        super().__init__()
        if width_div not in WIDTH_DIVS:
            raise ValueError(f"width_div must be one of {WIDTH_DIVS}, got {width_div!r}")
        self.batch_norm = batch_norm
        widths = _add_encoder(self, width_div)
        norms = list(widths.values())
        cin = norms[-1]
        below = cin  # channels of the level below (conv6_1, then each concat)
        self.flow6 = nn.Conv2d(below, OUT_CHANNELS, 3, padding=1)
        for level, skip, w in FLOWNETS_DECODER:
            w //= width_div
            setattr(self, f"deconv{level}", nn.ConvTranspose2d(below, w, 4, stride=2, padding=1))
            setattr(self, f"up_flow{level + 1}",
                    nn.ConvTranspose2d(OUT_CHANNELS, OUT_CHANNELS, 4, stride=2, padding=1,
                                       bias=False))
            norms.append(w)
            below = widths[skip] + w + OUT_CHANNELS
            setattr(self, f"flow{level}", nn.Conv2d(below, OUT_CHANNELS, 3, padding=1))
        if batch_norm:
            self.norms = nn.ModuleList(nn.BatchNorm2d(c) for c in norms)
        self.output = self.flow2

    def hidden_convs(self):
        """Every convolution but the output one, in the order the fixture initialises them."""
        convs = [getattr(self, name) for name, *_ in FLOWNETS_ENCODER] + [self.flow6]
        for level, _, _ in FLOWNETS_DECODER:
            convs += [getattr(self, f"deconv{level}"), getattr(self, f"up_flow{level + 1}")]
            if level != 2:
                convs.append(getattr(self, f"flow{level}"))
        return convs

    def _act(self, i, y):
        if self.batch_norm:
            y = self.norms[i](y)
        return F.leaky_relu(y, negative_slope=LEAKY)

    @staticmethod
    def _cut(x, like):
        return x[:, :, :like.shape[2], :like.shape[3]]

    def forward(self, x):
        x, enc = _encode(self, x)
        flow = self.flow6(x)
        for j, (level, skip, _) in enumerate(FLOWNETS_DECODER):
            s = enc[skip]
            feat = self._act(len(FLOWNETS_ENCODER) + j, getattr(self, f"deconv{level}")(x))
            up = getattr(self, f"up_flow{level + 1}")(flow)
            x = torch.cat([s, self._cut(feat, s), self._cut(up, s)], dim=1)
            flow = getattr(self, f"flow{level}")(x)
        return flow

    @staticmethod
    def output_size(height, width):
        """The finest prediction's size: conv1 and conv2 each halve, rounding up."""
        for _ in range(2):
            height, width = (height + 1) // 2, (width + 1) // 2
        return height, width


class PoolNet(nn.Module):
    """An encoder that downsamples by pooling, as U-Net encoders do, for operator coverage:
    max pooling with padding, average pooling in ceil mode with and without the pads counted,
    and a max pooling in ceil mode, each after a 3x3 convolution (leaky ReLU); a 1x1
    convolution predicts 3 channels at an eighth of the input's size (rounded up).
    """

    def __init__(self, width_div=16, batch_norm=False):
        super().__init__()
        if width_div not in WIDTH_DIVS:
            raise ValueError(f"width_div must be one of {WIDTH_DIVS}, got {width_div!r}")
        w = [c // width_div for c in (64, 128, 256, 512)]
        self.batch_norm = batch_norm
        self.conv0 = nn.Conv2d(IN_CHANNELS, w[0], 3, padding=1)
        self.pool0 = nn.MaxPool2d(3, stride=2, padding=1)
        self.conv1 = nn.Conv2d(w[0], w[1], 3, padding=1)
        self.pool1 = nn.AvgPool2d(2, stride=2, ceil_mode=True, count_include_pad=False)
        self.conv2 = nn.Conv2d(w[1], w[2], 3, padding=1)
        self.pool2 = nn.AvgPool2d(3, stride=2, padding=1, ceil_mode=True, count_include_pad=True)
        self.conv3 = nn.Conv2d(w[2], w[3], 3, padding=1)
        self.pool3 = nn.MaxPool2d(2, stride=1, ceil_mode=True)
        self.output = nn.Conv2d(w[3], OUT_CHANNELS, 1)
        if batch_norm:
            self.norms = nn.ModuleList(nn.BatchNorm2d(c) for c in w)

    def hidden_convs(self):
        return [self.conv0, self.conv1, self.conv2, self.conv3]

    def forward(self, x):
        for i, (conv, pool) in enumerate(((self.conv0, self.pool0), (self.conv1, self.pool1),
                                          (self.conv2, self.pool2), (self.conv3, self.pool3))):
            y = conv(x)
            if self.batch_norm:
                y = self.norms[i](y)
            x = pool(F.leaky_relu(y, negative_slope=LEAKY))
        return self.output(x)


class SeparableNet(nn.Module):
    """A depthwise-separable network (MobileNet-style blocks) for operator coverage: a 3x3
    stride-2 convolution, then three blocks of a depthwise 3x3 convolution (the second dilated by
    2, the third with stride 2 and two outputs per input) and a pointwise 1x1 convolution, each
    followed by ReLU6 (a Clip in ONNX); a 1x1 convolution predicts 3 channels, squashed to -1..1
    by sigmoid(x) * 2 - 1 (a Sigmoid, a Mul and a Sub in ONNX). The output is at a quarter of
    the input's size (rounded up). With batch_norm, a BatchNorm2d before every ReLU6.
    """

    def __init__(self, width_div=16, batch_norm=False):
        super().__init__()
        if width_div not in WIDTH_DIVS:
            raise ValueError(f"width_div must be one of {WIDTH_DIVS}, got {width_div!r}")
        w = [c // width_div for c in (64, 128, 256)]
        self.batch_norm = batch_norm
        self.conv0 = nn.Conv2d(IN_CHANNELS, w[0], 3, stride=2, padding=1)
        self.dw1 = nn.Conv2d(w[0], w[0], 3, padding=1, groups=w[0])
        self.pw1 = nn.Conv2d(w[0], w[1], 1)
        self.dw2 = nn.Conv2d(w[1], w[1], 3, padding=2, dilation=2, groups=w[1])
        self.pw2 = nn.Conv2d(w[1], w[1], 1)
        self.dw3 = nn.Conv2d(w[1], 2 * w[1], 3, stride=2, padding=1, groups=w[1])
        self.pw3 = nn.Conv2d(2 * w[1], w[2], 1)
        self.output = nn.Conv2d(w[2], OUT_CHANNELS, 1)
        if batch_norm:
            self.norms = nn.ModuleList(nn.BatchNorm2d(conv.out_channels)
                                       for conv in self.hidden_convs())

    def hidden_convs(self):
        return [self.conv0, self.dw1, self.pw1, self.dw2, self.pw2, self.dw3, self.pw3]

    def forward(self, x):
        for i, conv in enumerate(self.hidden_convs()):
            x = conv(x)
            if self.batch_norm:
                x = self.norms[i](x)
            x = F.relu6(x)
        return torch.sigmoid(self.output(x)) * 2 - 1


# (level, encoder tensor it stacks with, width of its upconvolution and iconv) at full width.
DISPNETS_DECODER = ((5, "conv5_1", 512), (4, "conv4_1", 256), (3, "conv3_1", 128),
                    (2, "conv2", 64), (1, "conv1", 32))


class DispNetS(nn.Module):
    """DispNetS-style network (scene flow: 12 channels in, 3-channel predictions) with widths
    divided by `width_div`. The encoder is FlowNetS's; each decoder level stacks the encoder
    tensor of its resolution, a 4x4/2 transposed convolution of the level below (leaky ReLU) and
    the level below's prediction upsampled by a 4x4/2 transposed convolution, convolves the stack
    (iconv, 3x3, leaky ReLU) and predicts from that (3x3). The output is the finest prediction,
    pr1, at half the input's resolution (rounded up). Odd sizes cut the transposed convolutions'
    outputs to the encoder tensor's size. With batch_norm, a BatchNorm2d before every leaky ReLU
    of the encoder, the upconvolutions and the iconvs.
    """

    def __init__(self, width_div=1, batch_norm=False):
        super().__init__()
        if width_div not in WIDTH_DIVS:
            raise ValueError(f"width_div must be one of {WIDTH_DIVS}, got {width_div!r}")
        self.batch_norm = batch_norm
        widths = _add_encoder(self, width_div)
        norms = list(widths.values())
        cin = norms[-1]
        self.pr6 = nn.Conv2d(cin, OUT_CHANNELS, 3, padding=1)
        below = cin
        for level, skip, w in DISPNETS_DECODER:
            w = max(w // width_div, 1)
            setattr(self, f"upconv{level}", nn.ConvTranspose2d(below, w, 4, stride=2, padding=1))
            setattr(self, f"up_pr{level + 1}",
                    nn.ConvTranspose2d(OUT_CHANNELS, OUT_CHANNELS, 4, stride=2, padding=1,
                                       bias=False))
            setattr(self, f"iconv{level}",
                    nn.Conv2d(w + OUT_CHANNELS + widths[skip], w, 3, padding=1))
            setattr(self, f"pr{level}", nn.Conv2d(w, OUT_CHANNELS, 3, padding=1))
            norms += [w, w]
            below = w
        if batch_norm:
            self.norms = nn.ModuleList(nn.BatchNorm2d(c) for c in norms)
        self.output = self.pr1

    def hidden_convs(self):
        """Every convolution but the output one, in the order the fixture initialises them."""
        convs = [getattr(self, name) for name, *_ in FLOWNETS_ENCODER] + [self.pr6]
        for level, _, _ in DISPNETS_DECODER:
            convs += [getattr(self, f"upconv{level}"), getattr(self, f"up_pr{level + 1}"),
                      getattr(self, f"iconv{level}")]
            if level != 1:
                convs.append(getattr(self, f"pr{level}"))
        return convs

    def _act(self, i, y):
        if self.batch_norm:
            y = self.norms[i](y)
        return F.leaky_relu(y, negative_slope=LEAKY)

    def forward(self, x):
        x, enc = _encode(self, x)
        pr = self.pr6(x)
        n = len(FLOWNETS_ENCODER)
        for j, (level, skip, _) in enumerate(DISPNETS_DECODER):
            s = enc[skip]
            up = self._act(n + 2 * j, getattr(self, f"upconv{level}")(x))
            up_pr = getattr(self, f"up_pr{level + 1}")(pr)
            x = torch.cat([FlowNetS._cut(up, s), FlowNetS._cut(up_pr, s), s], dim=1)
            x = self._act(n + 2 * j + 1, getattr(self, f"iconv{level}")(x))
            pr = getattr(self, f"pr{level}")(x)
        return pr
