"""Read the float32 convolution weights of an .sfrt file (to fine-tune a shipped model).

The reader follows runtime/schema/sfrt_model.fbs field by field with the FlatBuffers Python
runtime (Debian python3-flatbuffers), so no generated code is needed. Only what fine-tuning
needs is read: each Conv2D layer's name, weights (HWIO) and bias, float32 or float16 storage.
An int8 or bf16 file is refused: fine-tune from its float32 source.
"""

import flatbuffers
import numpy as np

# Field slots (declaration order in runtime/schema/sfrt_model.fbs).
_MODEL_LAYERS = 6
_LAYER_NAME, _LAYER_OP_TYPE, _LAYER_OP = 0, 1, 2
_CONV_WEIGHTS, _CONV_BIAS, _CONV_PRECISION = 10, 11, 12
_TENSOR_DTYPE, _TENSOR_SHAPE, _TENSOR_DATA = 0, 1, 2
# LayerOp union members that are a Conv2D table (Conv2D = 1, Conv2DV2: Conv2D = 10).
_CONV_OP_TYPES = (1, 10)
_DTYPES = {0: np.float32, 1: np.float16}


def _offset(table, slot):
    return table.Offset(4 + 2 * slot)


def _subtable(table, slot):
    o = _offset(table, slot)
    if o == 0:
        return None
    return flatbuffers.table.Table(table.Bytes, table.Indirect(table.Pos + o))


def _vector(table, slot):
    """(start position, length) of a vector field, or (0, 0) when absent."""
    o = _offset(table, slot)
    if o == 0:
        return 0, 0
    return table.Vector(o), table.VectorLen(o)


def _scalar(table, slot, flags, default):
    o = _offset(table, slot)
    return table.Get(flags, table.Pos + o) if o else default


def _tensor(table, what):
    if table is None:
        raise ValueError(f"{what}: absent")
    dtype = _scalar(table, _TENSOR_DTYPE, flatbuffers.number_types.Int8Flags, 0)
    if dtype not in _DTYPES:
        raise ValueError(f"{what}: data type {dtype} is not float32 or float16")
    start, n = _vector(table, _TENSOR_SHAPE)
    shape = tuple(int(v) for v in np.frombuffer(table.Bytes, "<i4", n, start))
    start, nbytes = _vector(table, _TENSOR_DATA)
    data = np.frombuffer(table.Bytes, np.dtype(_DTYPES[dtype]).newbyteorder("<"),
                         nbytes // np.dtype(_DTYPES[dtype]).itemsize, start)
    return data.astype(np.float32).reshape(shape)


def read_convolutions(path):
    """{layer name: (weights HWIO float32, bias float32)} for every Conv2D layer of `path`."""
    with open(path, "rb") as f:
        buf = bytearray(f.read())
    root = flatbuffers.table.Table(buf, flatbuffers.encode.Get(
        flatbuffers.packer.uoffset, buf, 0))
    start, n = _vector(root, _MODEL_LAYERS)
    convs = {}
    for i in range(n):
        layer = flatbuffers.table.Table(buf, root.Indirect(start + 4 * i))
        name_off = _offset(layer, _LAYER_NAME)
        name = layer.String(layer.Pos + name_off).decode() if name_off else f"layer{i}"
        op_type = _scalar(layer, _LAYER_OP_TYPE, flatbuffers.number_types.Uint8Flags, 0)
        if op_type not in _CONV_OP_TYPES:
            continue
        conv = _subtable(layer, _LAYER_OP)
        precision = _scalar(conv, _CONV_PRECISION, flatbuffers.number_types.Int8Flags, 0)
        if precision != 0:
            raise ValueError(f"{path}: layer {name} is not float32 (precision {precision}); "
                             "fine-tune from the float32 model it was exported from")
        convs[name] = (_tensor(_subtable(conv, _CONV_WEIGHTS), f"{path}: {name} weights"),
                       _tensor(_subtable(conv, _CONV_BIAS), f"{path}: {name} bias"))
    if not convs:
        raise ValueError(f"{path}: no convolution layers")
    return convs


def load_into(model, path, output_scale=1.0):
    """Copy `path`'s convolutions into the same-named nn.Conv2d modules of `model` (which has no
    batch norm: an exported file's batch norm is folded into its convolutions). The output
    convolution is multiplied by `output_scale` (train.py's --flow-scale). Every Conv2d of the
    model must get weights of its shape, and every file convolution must be used."""
    import torch

    convs = read_convolutions(path)
    modules = {n: m for n, m in model.named_modules() if isinstance(m, torch.nn.Conv2d)}
    if sorted(modules) != sorted(convs):
        raise ValueError(f"{path}: convolutions {sorted(convs)} do not match the model's "
                         f"{sorted(modules)}")
    with torch.no_grad():
        for name, module in modules.items():
            w, b = convs[name]
            w = torch.from_numpy(np.ascontiguousarray(w.transpose(3, 2, 0, 1)))  # HWIO -> OIHW
            if tuple(w.shape) != tuple(module.weight.shape) or module.bias is None or \
                    b.shape[0] != module.bias.shape[0]:
                raise ValueError(f"{path}: {name} has weights {tuple(w.shape)} and bias "
                                 f"{b.shape}, the model {tuple(module.weight.shape)}")
            scale = output_scale if name == "output" else 1.0
            module.weight.copy_(w * scale)
            module.bias.copy_(torch.from_numpy(b.copy()) * scale)
