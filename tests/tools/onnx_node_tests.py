#!/usr/bin/python3
"""ONNX's own operator tests through `sfrt export` and `sfrt infer`.

usage: onnx_node_tests.py --sfrt BIN --work DIR [--isa ref,avx2,...] [--case NAME...]

1. Writes onnx's node test cases with `python3 -m onnx.backend.test.cmd_tools generate-data`
   into DIR/data (generated here, never committed). Debian's python3-onnx 1.12 still calls numpy
   aliases that numpy 1.24 removed (np.float, np.int, ...); they are restored first.
2. Picks every 4-D case of the operators in OPERATORS: the graph's first input and its outputs
   are 4-D float tensors. Cases of the element-wise activations (ACTIVATIONS) whose data is 3-D
   run as one image of (1, C, H, W): the same values, so the same expected output. A case written
   at an opset below 11 (sfrt reads 11-17) is labelled 11 when each of its operators is defined
   the same at 11 (its version in force at 11 dates from the case's opset or before).
3. Prepares each: inputs after the first that the case feeds (weights, scales, sizes) become
   initializers holding the case's values; a batch of N is run as N one-image runs of a batch-1
   model (sfrt runs one image at a time).
4. `sfrt export --input-kind tensor` (once per graph output, with `--onnx-output`, when there
   are several: MaxPool's values and Indices), then `sfrt infer --input-npy` for each batch item
   on each ISA of --isa (default: every ISA `sfrt infer` accepts on this CPU), compared with the
   case's expected output: |sfrt - expected| <= 1e-4 * max(1, max |expected|). MaxPool's INT64
   Indices are compared as the float32 values sfrt writes (exact below 2^24). A case of 8- or 16-bit
   integers (MaxPool, Clip) is exported as it is (sfrt computes it in float32, which holds
   every such value) and fed and compared as float32 values.

Every picked case is listed in EXPECTED: "pass", or the reason sfrt cannot run it yet. The run
fails when a case expected to pass does not, when a listed gap starts passing (move it to
"pass"), and when onnx offers a case the table does not list.
"""
import argparse
import os
import shutil
import subprocess
import sys

import numpy as np

OPERATORS = {
    "Conv", "ConvTranspose", "Resize", "MaxPool", "AveragePool", "BatchNormalization", "Concat",
    "Add", "Sub", "Mul", "Div", "Relu", "LeakyRelu", "Elu", "Sigmoid", "Tanh", "Clip",
}
# Nodes a case may hold besides those operators.
HELPERS = {"Constant"}
# Element-wise on every value: a 3-D case is run with a leading batch dimension of 1.
ACTIVATIONS = {"Relu", "LeakyRelu", "Elu", "Sigmoid", "Tanh", "Clip"}

PASS = "pass"
EXPECTED = {
    # Conv (weights given as graph inputs).
    "test_basic_conv_with_padding": PASS,
    "test_basic_conv_without_padding": PASS,
    "test_conv_with_strides_padding": PASS,
    "test_conv_with_strides_no_padding": PASS,
    "test_conv_with_strides_and_asymmetric_padding": PASS,
    "test_conv_with_autopad_same": PASS,
    # ConvTranspose.
    "test_convtranspose": PASS,
    "test_convtranspose_pads": PASS,
    "test_convtranspose_kernel_shape": PASS,
    "test_convtranspose_output_shape": PASS,
    "test_convtranspose_pad": PASS,
    "test_convtranspose_autopad_same": PASS,
    "test_convtranspose_dilations": PASS,
    # MaxPool.
    "test_maxpool_2d_default": PASS,
    "test_maxpool_2d_ceil": PASS,
    "test_maxpool_2d_pads": PASS,
    "test_maxpool_2d_precomputed_pads": PASS,
    "test_maxpool_2d_precomputed_same_upper": PASS,
    "test_maxpool_2d_precomputed_strides": PASS,
    "test_maxpool_2d_same_upper": PASS,
    "test_maxpool_2d_same_lower": PASS,
    "test_maxpool_2d_strides": PASS,
    "test_maxpool_2d_dilations": PASS,
    "test_maxpool_2d_uint8": PASS,
    "test_maxpool_with_argmax_2d_precomputed_pads": PASS,
    "test_maxpool_with_argmax_2d_precomputed_strides": PASS,
    # AveragePool.
    "test_averagepool_2d_default": PASS,
    "test_averagepool_2d_ceil": PASS,
    "test_averagepool_2d_pads": PASS,
    "test_averagepool_2d_pads_count_include_pad": PASS,
    "test_averagepool_2d_precomputed_pads": PASS,
    "test_averagepool_2d_precomputed_pads_count_include_pad": PASS,
    "test_averagepool_2d_precomputed_same_upper": PASS,
    "test_averagepool_2d_precomputed_strides": PASS,
    "test_averagepool_2d_same_upper": PASS,
    "test_averagepool_2d_same_lower": PASS,
    "test_averagepool_2d_strides": PASS,
    # BatchNormalization (inference; the training-mode cases have 3 outputs and are not picked).
    "test_batchnorm_example": PASS,
    "test_batchnorm_epsilon": PASS,
    # Resize.
    "test_resize_downsample_scales_cubic": PASS,
    "test_resize_downsample_scales_cubic_A_n0p5_exclude_outside": PASS,
    "test_resize_downsample_scales_cubic_align_corners": PASS,
    "test_resize_downsample_sizes_cubic": PASS,
    "test_resize_upsample_scales_cubic": PASS,
    "test_resize_upsample_scales_cubic_A_n0p5_exclude_outside": PASS,
    "test_resize_upsample_scales_cubic_align_corners": PASS,
    "test_resize_upsample_scales_cubic_asymmetric": PASS,
    "test_resize_upsample_sizes_cubic": PASS,
    "test_resize_downsample_scales_linear": PASS,
    "test_resize_downsample_scales_linear_align_corners": PASS,
    "test_resize_downsample_sizes_linear_pytorch_half_pixel": PASS,
    "test_resize_upsample_scales_linear": PASS,
    "test_resize_upsample_scales_linear_align_corners": PASS,
    "test_resize_downsample_scales_nearest": PASS,
    "test_resize_downsample_sizes_nearest": PASS,
    "test_resize_upsample_scales_nearest": PASS,
    "test_resize_upsample_sizes_nearest": PASS,
    "test_resize_upsample_sizes_nearest_ceil_half_pixel": PASS,
    "test_resize_upsample_sizes_nearest_floor_align_corners": PASS,
    "test_resize_upsample_sizes_nearest_round_prefer_ceil_asymmetric": PASS,
    "test_resize_tf_crop_and_resize": PASS,
    # Activations (3-D cases run as (1, C, H, W); their 1-D cases are not picked).
    "test_celu_expanded": PASS,
    "test_relu": PASS,
    "test_leakyrelu": PASS,
    "test_leakyrelu_default": PASS,
    "test_elu": PASS,
    "test_elu_default": PASS,
    "test_sigmoid": PASS,
    "test_tanh": PASS,
    "test_clip": PASS,
    "test_clip_default_min": PASS,
    "test_clip_default_max": PASS,
    "test_clip_default_int8_min": PASS,
    "test_clip_default_int8_max": PASS,
}

TOLERANCE = 1e-4
KNOWN_ISAS = ["ref", "avx2", "avx512", "avx512amx", "neon"]


def generate_data(out_dir):
    """Runs onnx's generator in this process with numpy's removed aliases restored."""
    for alias, value in [("float", float), ("int", int), ("bool", bool), ("object", object),
                         ("complex", complex), ("str", str)]:
        if alias not in np.__dict__:
            setattr(np, alias, value)
    from onnx.backend.test.cmd_tools import main as onnx_tools_main
    saved = sys.argv
    sys.argv = ["onnx.backend.test.cmd_tools", "generate-data", "-o", out_dir]
    try:
        onnx_tools_main()
    finally:
        sys.argv = saved


def dims(value_info):
    return [d.dim_value for d in value_info.type.tensor_type.shape.dim]


def is_float(value_info):
    import onnx
    return value_info.type.tensor_type.elem_type == onnx.TensorProto.FLOAT


def lifted(model):
    """Whether a case is an element-wise activation on 3-D data, run as (1, C, H, W)."""
    graph = model.graph
    ops = {node.op_type for node in graph.node}
    return (ops <= ACTIVATIONS | HELPERS and bool(ops & ACTIVATIONS) and len(graph.input) > 0
            and len(dims(graph.input[0])) == 3 and all(len(dims(o)) == 3 for o in graph.output))


def picked(model):
    """Whether a case is one of this harness's: its ops are ours and its data is 4-D (or it is
    lifted())."""
    ops = {node.op_type for node in model.graph.node}
    if not ops <= OPERATORS | HELPERS or not ops & OPERATORS:
        return False
    if lifted(model):
        return True
    graph = model.graph
    if len(graph.input) == 0 or len(dims(graph.input[0])) != 4:
        return False
    return all(len(dims(o)) == 4 for o in graph.output)


def read_tensor(path):
    import onnx
    from onnx import numpy_helper
    tensor = onnx.TensorProto()
    with open(path, "rb") as f:
        tensor.ParseFromString(f.read())
    return numpy_helper.to_array(tensor)


def raise_opset(model):
    """Labels a case below opset 11 as opset 11 when that changes none of its operators."""
    from onnx import defs
    for opset in model.opset_import:
        if opset.domain not in ("", "ai.onnx") or opset.version >= 11:
            continue
        if all(defs.get_schema(n.op_type, 11).since_version <= opset.version
               for n in model.graph.node):
            opset.version = 11


def prepare(model, inputs):
    """Returns a batch-1 model whose only graph input is the first; the rest become initializers."""
    import onnx
    from onnx import numpy_helper
    raise_opset(model)
    graph = model.graph
    first = graph.input[0]
    lift = lifted(model)
    for value_info, value in zip(list(graph.input[1:]), inputs[1:]):
        graph.initializer.append(numpy_helper.from_array(value, value_info.name))
        graph.input.remove(value_info)
    for value_info in [first, *graph.output]:
        shape = value_info.type.tensor_type.shape
        if lift:
            shape.dim.insert(0, onnx.TensorShapeProto.Dimension(dim_value=1))
        elif shape.dim:
            shape.dim[0].dim_value = 1
    onnx.checker.check_model(model)
    return model


def run(cmd, env=None):
    return subprocess.run(cmd, capture_output=True, text=True, env=env)


def first_line(text):
    lines = [line for line in text.strip().splitlines() if line.strip()]
    return lines[-1] if lines else "(no message)"


def supported_isas(sfrt, model_file, input_file, work):
    """The ISAs `sfrt infer` runs on this CPU, asked on a model that runs on ref: an ISA the CPU
    lacks is refused with "cannot run"; any other failure is an error, not a missing ISA."""
    isas = []
    for isa in KNOWN_ISAS:
        env = dict(os.environ, SFRT_ISA=isa)
        result = run([sfrt, "infer", "--model", model_file, "--input-npy", input_file, "-o",
                      os.path.join(work, "isa_probe.npy")], env)
        if result.returncode == 0:
            isas.append(isa)
        elif "cannot run" not in result.stderr:
            raise RuntimeError(f"SFRT_ISA={isa} sfrt infer failed: {first_line(result.stderr)}")
    return isas


def run_case(sfrt, case_dir, work, isas):
    """Returns (None, worst error relative to max(1, max |expected|)) when the case passes on
    every ISA, else (what went wrong, None). A case with several outputs (MaxPool's values and
    Indices) is exported once per output with `--onnx-output`."""
    import onnx
    model = onnx.load(os.path.join(case_dir, "model.onnx"))
    data_dir = os.path.join(case_dir, "test_data_set_0")
    inputs = [read_tensor(os.path.join(data_dir, f"input_{i}.pb"))
              for i in range(len(model.graph.input))]
    names = [o.name for o in model.graph.output]
    expected = [read_tensor(os.path.join(data_dir, f"output_{k}.pb")) for k in range(len(names))]
    small_integers = (np.int8, np.uint8, np.int16, np.uint16)
    fed = inputs[0]
    for k, want in enumerate(expected):
        if inputs[0].dtype in small_integers and want.dtype == inputs[0].dtype:
            expected[k] = want.astype(np.float32)  # the values, as `sfrt infer` writes them
        elif inputs[0].dtype == np.float32 and want.dtype == np.int64:
            # MaxPool's Indices: sfrt writes them as float32, exact up to 2^24.
            if want.size and np.abs(want).max() >= 2 ** 24:
                return f"output {names[k]!r} holds indices beyond 2^24", None
            expected[k] = want.astype(np.float32)
        elif inputs[0].dtype != np.float32 or want.dtype != np.float32:
            return f"data is {inputs[0].dtype} -> {want.dtype}, not float32", None
    fed = fed.astype(np.float32)  # small integers: the values, as `sfrt infer` reads them
    if lifted(model):
        fed = fed[None]
        expected = [want[None] for want in expected]
    os.makedirs(work, exist_ok=True)
    model_file = os.path.join(work, "model.onnx")
    try:
        onnx.save(prepare(model, inputs), model_file)
    except Exception as e:  # the onnx checker's or numpy's message names the problem
        return f"preparing the model: {e}", None
    worst = 0.0
    for k, name in enumerate(names):
        what = f"output {name!r}: " if len(names) > 1 else ""
        sfrt_file = os.path.join(work, f"model_{k}.sfrt")
        chosen = ["--onnx-output", name] if len(names) > 1 else []
        exported = run([sfrt, "export", model_file, "-o", sfrt_file, "--input-kind", "tensor",
                        *chosen])
        if exported.returncode != 0:
            return what + "export: " + first_line(exported.stderr + exported.stdout), None
        for b in range(fed.shape[0]):
            input_file = os.path.join(work, f"input_{b}.npy")
            np.save(input_file, np.ascontiguousarray(fed[b].transpose(1, 2, 0)))
            want = expected[k][b].transpose(1, 2, 0)
            bound = TOLERANCE * max(1.0, float(np.abs(want).max()))
            for isa in isas:
                out_file = os.path.join(work, f"output_{k}_{b}_{isa}.npy")
                inferred = run([sfrt, "infer", "--model", sfrt_file, "--input-npy", input_file,
                                "-o", out_file], dict(os.environ, SFRT_ISA=isa))
                if inferred.returncode != 0:
                    return (what + f"infer ({isa}): " +
                            first_line(inferred.stderr + inferred.stdout)), None
                got = np.load(out_file)
                if got.shape != want.shape:
                    return what + f"{isa}: output shape {got.shape}, expected {want.shape}", None
                err = float(np.abs(got - want).max())
                worst = max(worst, err / bound * TOLERANCE)
                if not err <= bound:
                    return (what + f"{isa}: max |error| {err:.3g} > {bound:.3g} "
                            f"(batch item {b})"), None
    return None, worst


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sfrt", required=True, help="the sfrt binary")
    parser.add_argument("--work", required=True, help="directory for the data and the models")
    parser.add_argument("--isa", help="comma-separated ISAs (default: every one this CPU runs)")
    parser.add_argument("--case", nargs="*", help="run only these cases")
    args = parser.parse_args()

    import onnx
    data_root = os.path.join(args.work, "data")
    node_dir = os.path.join(data_root, "node")
    if not os.path.isdir(node_dir):
        print(f"generating onnx {onnx.__version__}'s node test data in {data_root}", flush=True)
        partial = data_root + ".partial"
        shutil.rmtree(partial, ignore_errors=True)
        generate_data(partial)
        os.rename(partial, data_root)

    cases = [d for d in sorted(os.listdir(node_dir))
             if picked(onnx.load(os.path.join(node_dir, d, "model.onnx")))]
    unlisted = [c for c in cases if c not in EXPECTED]
    missing = [c for c in EXPECTED if c not in cases]
    if args.case:
        cases = [c for c in cases if c in args.case]

    isas = args.isa.split(",") if args.isa else None
    failures = []
    passed = 0
    gaps = 0
    for case in cases:
        work = os.path.join(args.work, "cases", case)
        shutil.rmtree(work, ignore_errors=True)
        if isas is None and EXPECTED.get(case) == PASS:
            os.makedirs(work)
            probe = os.path.join(work, "probe")
            # Find the ISAs once, on the first case that should pass.
            problem, _ = run_case(args.sfrt, os.path.join(node_dir, case), probe, ["ref"])
            if problem is None:
                isas = supported_isas(args.sfrt, os.path.join(probe, "model_0.sfrt"),
                                      os.path.join(probe, "input_0.npy"), probe)
                print(f"ISAs this CPU runs: {','.join(isas)}")
        problem, worst = run_case(args.sfrt, os.path.join(node_dir, case), work, isas or ["ref"])
        want = EXPECTED.get(case, "unlisted")
        if want == PASS:
            if problem is None:
                passed += 1
                print(f"PASS  {case}: max |error| / max(1, max |expected|) = {worst:.2e}")
            else:
                failures.append(f"{case}: {problem}")
                print(f"FAIL  {case}: {problem}")
        elif problem is None:
            failures.append(f"{case}: passes but is listed as a gap ({want}); list it as pass")
            print(f"FAIL  {case}: passes but is listed as a gap ({want})")
        else:
            gaps += 1
            print(f"gap   {case} ({want}): {problem}")
    for case in unlisted:
        failures.append(f"{case}: a 4-D case of our operators that EXPECTED does not list")
    if missing and not args.case:
        failures.append("listed cases onnx did not write: " + ", ".join(missing))
    print(f"\n{passed} passed, {gaps} known gaps, {len(failures)} failures "
          f"(ISAs: {','.join(isas or ['ref'])}; onnx {onnx.__version__})")
    for failure in failures:
        print("  " + failure)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
