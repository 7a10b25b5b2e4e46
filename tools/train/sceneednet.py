"""SceneEDNet (Thakur and Mukherjee, ICARCV 2018) in PyTorch: the one definition of the network.

Used by the training reference (tools/train/train.py) and by the test fixture generator
(tests/fixtures/gen_sceneednet.py). It follows docs/sceneednet.md exactly: eleven 3x3
convolutions with bias, leaky ReLU (alpha 0.3) after all but the output conv, four stride-2
encoder convs, four nearest 2x upsamplings in the decoder and a crop that removes the excess
rows from the TOP and the excess columns from the LEFT, so the output has the input's size.
Hidden channel widths are divided by `width_div` (a divisor of 64); input stays 12 channels
(left(t), right(t), left(t+1), right(t+1)) and output 3 (dX, dY, dZ).

padding="tf" reproduces TensorFlow/Keras 'same' padding (asymmetric, extra row/column at the
bottom/right), computed from the runtime shape so an ONNX export stores it as a rule;
padding="torch" is Conv2d(padding=1).
"""

import torch
import torch.nn as nn
import torch.nn.functional as F

# Hidden conv widths conv0..conv9 (docs/sceneednet.md, Graph table); output conv is 64 -> 3.
FULL_WIDTHS = (64, 128, 256, 512, 1024, 1024, 512, 256, 128, 64)
STRIDES = (2, 2, 2, 2, 1, 1, 1, 1, 1, 1)
IN_CHANNELS = 12
OUT_CHANNELS = 3
LEAKY_ALPHA = 0.3
INPUT_NAME = "stereo_pairs"
OUTPUT_NAME = "scene_flow"
PADDING_MODES = ("tf", "torch")
WIDTH_DIVS = (1, 2, 4, 8, 16, 32, 64)


def _same_pad_amounts(size, stride, kernel=3):
    """TF/Keras 'same' padding for one axis: (before, after).

    `size` is a Python int in eager mode and a 0-d int64 tensor while tracing for ONNX export,
    so the amounts end up computed in the graph from the tensor's runtime shape.
    """
    out = (size + stride - 1) // stride  # ceil(size / stride)
    total = (out - 1) * stride + kernel - size
    if isinstance(total, torch.Tensor):
        total = torch.clamp(total, min=0)
    else:
        total = max(total, 0)
    before = total // 2
    return before, total - before


class SceneEDNet(nn.Module):
    """SceneEDNet (Thakur and Mukherjee 2018) with hidden widths divided by `width_div`."""

    def __init__(self, width_div=1, padding="tf"):
        super().__init__()
        if padding not in PADDING_MODES:
            raise ValueError(f"padding must be one of {PADDING_MODES}, got {padding!r}")
        if width_div not in WIDTH_DIVS:
            raise ValueError(f"width_div must be one of {WIDTH_DIVS}, got {width_div!r}")
        self.padding = padding
        self.widths = tuple(c // width_div for c in FULL_WIDTHS)
        conv_pad = 0 if padding == "tf" else 1
        cin = IN_CHANNELS
        for i, (cout, stride) in enumerate(zip(self.widths, STRIDES)):
            setattr(self, f"conv{i}", nn.Conv2d(cin, cout, 3, stride=stride, padding=conv_pad,
                                                bias=True))
            cin = cout
        self.output = nn.Conv2d(cin, OUT_CHANNELS, 3, stride=1, padding=conv_pad, bias=True)

    def hidden_convs(self):
        return [getattr(self, f"conv{i}") for i in range(len(FULL_WIDTHS))]

    def _conv(self, conv, x):
        if self.padding == "tf":
            top, bottom = _same_pad_amounts(x.shape[2], conv.stride[0])
            left, right = _same_pad_amounts(x.shape[3], conv.stride[1])
            x = F.pad(x, [left, right, top, bottom])
        return conv(x)

    def _conv_act(self, conv, x):
        return F.leaky_relu(self._conv(conv, x), negative_slope=LEAKY_ALPHA)

    @staticmethod
    def _up(x):
        return F.interpolate(x, scale_factor=2, mode="nearest")

    def forward(self, x):
        in_h, in_w = x.shape[2], x.shape[3]
        c = self.hidden_convs()
        for i in range(6):  # conv0..conv3 (stride 2), conv4, conv5
            x = self._conv_act(c[i], x)
        x = self._conv_act(c[6], self._up(x))  # up1, conv6
        x = self._conv_act(c[7], self._up(x))  # up2, conv7
        x = self._conv_act(c[8], self._up(x))  # up3, conv8
        x = self._up(x)  # up4
        # Crop: drop the excess rows from the top and the excess columns from the left.
        excess_h = x.shape[2] - in_h
        excess_w = x.shape[3] - in_w
        x = x[:, :, excess_h:, excess_w:]
        x = self._conv_act(c[9], x)  # conv9
        return self._conv(self.output, x)  # output, linear


class SceneEDNetU(SceneEDNet):
    """SceneEDNet with U-Net skip connections (issue 16's SceneEDNet-U).

    The encoder is SceneEDNet's. conv3's output is stacked behind conv5's (both at 1/16 of the
    input), and every decoder level stacks the encoder output of its resolution behind the
    upsampled tensor: conv6 reads [up(conv5, conv3) cut to conv2's size, conv2], conv7
    [up(conv6) cut to conv1's size, conv1], conv8 [up(conv7) cut to conv0's size, conv0]. An
    upsampled tensor is cut to its skip's size by dropping the excess rows and columns at the
    bottom and right (x[..., :h, :w]), which odd input sizes need; the last upsampling is cropped
    to the input as in SceneEDNet. With batch_norm, every hidden convolution is followed by a
    BatchNorm2d before its leaky ReLU (the exporter folds it into the convolution).
    """

    def __init__(self, width_div=1, padding="tf", batch_norm=False):
        super().__init__(width_div, padding)
        w = self.widths
        conv_pad = 0 if padding == "tf" else 1
        # Input channels of each hidden conv: the encoder as SceneEDNet, the decoder wider.
        ins = (IN_CHANNELS, w[0], w[1], w[2], w[3], w[4], w[5] + w[3] + w[2], w[6] + w[1],
               w[7] + w[0], w[8])
        for i, (cin, cout, stride) in enumerate(zip(ins, w, STRIDES)):
            setattr(self, f"conv{i}", nn.Conv2d(cin, cout, 3, stride=stride, padding=conv_pad,
                                                bias=True))
        self.batch_norm = batch_norm
        if batch_norm:
            self.norms = nn.ModuleList(nn.BatchNorm2d(c) for c in w)

    def _conv_act_at(self, i, x):
        y = self._conv(self.hidden_convs()[i], x)
        if self.batch_norm:
            y = self.norms[i](y)
        return F.leaky_relu(y, negative_slope=LEAKY_ALPHA)

    @staticmethod
    def _up_to(x, skip):
        x = SceneEDNet._up(x)
        return torch.cat([x[:, :, :skip.shape[2], :skip.shape[3]], skip], dim=1)

    def forward(self, x):
        in_h, in_w = x.shape[2], x.shape[3]
        enc = []
        for i in range(4):  # conv0..conv3 (stride 2)
            x = self._conv_act_at(i, x)
            enc.append(x)
        x = self._conv_act_at(4, x)
        x = self._conv_act_at(5, x)
        x = torch.cat([x, enc[3]], dim=1)
        x = self._conv_act_at(6, self._up_to(x, enc[2]))
        x = self._conv_act_at(7, self._up_to(x, enc[1]))
        x = self._conv_act_at(8, self._up_to(x, enc[0]))
        x = self._up(x)
        excess_h = x.shape[2] - in_h
        excess_w = x.shape[3] - in_w
        x = x[:, :, excess_h:, excess_w:]
        x = self._conv_act_at(9, x)
        return self._conv(self.output, x)


ARCHITECTURES = {"sceneednet": SceneEDNet, "sceneednet-u": SceneEDNetU}


def epe_loss(pred, target, valid=None):
    """Mean over (valid) pixels of the Euclidean distance between predicted and true 3D vectors.

    pred, target: (N, 3, H, W). valid: optional (N, 1, H, W) or (N, H, W) bool/0-1 mask.
    """
    dist = torch.sqrt(torch.sum((pred - target) ** 2, dim=1) + 1e-12)  # (N, H, W)
    if valid is None:
        return dist.mean()
    if valid.dim() == 4:
        valid = valid[:, 0]
    valid = valid.to(dist.dtype)
    return (dist * valid).sum() / valid.sum().clamp(min=1.0)
