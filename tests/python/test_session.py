"""sfrt.Model and sfrt.Session against the command line: the same flow, bit for bit, from the
same library code; arrays read and written in place; the objects' lifetimes."""
import gc
import os

import numpy as np
import pytest

import sfrt
from conftest import (DEFAULT_MODEL, INT8_MODEL, DEMO_MODEL, ROOT, read_rgb, run_cli,
                      window_paths)

SHIPPED = [DEFAULT_MODEL, INT8_MODEL, DEMO_MODEL,
           os.path.join(ROOT, "models", "sceneednet-paper-int8.sfrt")]


def cli_infer(tmp_path, model_path, paths, size, name="cli"):
    out = str(tmp_path / (name + ".npy"))
    run_cli("infer", "--model", model_path, "--left0", paths[0], "--right0", paths[1],
            "--left1", paths[2], "--right1", paths[3], "--size", "%dx%d" % size, "-o", out)
    return np.load(out)


@pytest.mark.parametrize("model_path", SHIPPED, ids=os.path.basename)
def test_run_equals_sfrt_infer_bit_for_bit(tmp_path, model_path):
    paths = window_paths()
    expected = cli_infer(tmp_path, model_path, paths, (96, 128))
    session = sfrt.Session(sfrt.Model(model_path), size=(96, 128))
    rgb = [read_rgb(p) for p in paths]
    # PIL's RGB arrays as they are, the same pixels as OpenCV's BGR (read in place), and a
    # reversed view (negative strides: copied once).
    got_rgb = session.run(*rgb, color="rgb")
    got_bgr = session.run(*[np.ascontiguousarray(a[..., ::-1]) for a in rgb])
    got_view = session.run(*[a[..., ::-1] for a in rgb])
    assert got_rgb.dtype == np.float32 and got_rgb.shape == expected.shape
    for got in (got_rgb, got_bgr, got_view):
        np.testing.assert_array_equal(got, expected)


def test_run_at_the_images_own_size_and_enlarged_equals_sfrt_infer(tmp_path, model):
    paths = window_paths("Monkaa")
    rgb = [read_rgb(p) for p in paths]
    for size in [(270, 480), (288, 512)]:  # read in place; enlarged (bilinear)
        expected = cli_infer(tmp_path, DEFAULT_MODEL, paths, size, "cli%d" % size[0])
        got = sfrt.Session(model, size=size).run(*rgb, color="rgb")
        np.testing.assert_array_equal(got, expected)


def test_run_tensor_equals_sfrt_infer_input_npy(tmp_path, model):
    rng = np.random.default_rng(7)
    x = rng.standard_normal((96, 128, 12)).astype(np.float32)
    np.save(tmp_path / "x.npy", x)
    run_cli("infer", "--model", DEFAULT_MODEL, "--input-npy", str(tmp_path / "x.npy"), "-o",
            str(tmp_path / "y.npy"))
    session = sfrt.Session(model, size=(96, 128))
    np.testing.assert_array_equal(session.run_tensor(x), np.load(tmp_path / "y.npy"))
    np.testing.assert_array_equal(session.run_tensor(x[None]), np.load(tmp_path / "y.npy"))
    # Smaller than the session's size: the session runs it at that size.
    small = x[:64, :96].copy()
    np.save(tmp_path / "s.npy", small)
    run_cli("infer", "--model", DEFAULT_MODEL, "--input-npy", str(tmp_path / "s.npy"), "-o",
            str(tmp_path / "sy.npy"))
    np.testing.assert_array_equal(session.run_tensor(small), np.load(tmp_path / "sy.npy"))


def test_out_is_written_in_place_and_returned(model):
    session = sfrt.Session(model, size=(96, 128))
    images = [read_rgb(p) for p in window_paths()]
    buf = np.full((96, 128, 3), np.nan, dtype=np.float32)
    got = session.run(*images, color="rgb", out=buf)
    assert got is buf or np.shares_memory(got, buf)
    assert np.isfinite(buf).all()
    np.testing.assert_array_equal(buf, session.run(*images, color="rgb"))


def test_each_result_owns_its_memory(model):
    session = sfrt.Session(model, size=(96, 128))
    a = [read_rgb(p) for p in window_paths("Driving")]
    b = [read_rgb(p) for p in window_paths("Monkaa")]
    first = session.run(*a, color="rgb")
    kept = first.copy()
    second = session.run(*b, color="rgb")
    assert first.flags.owndata or first.base is not None
    assert not np.shares_memory(first, second)
    np.testing.assert_array_equal(first, kept)  # the second call did not overwrite the first
    assert not np.array_equal(first, second)


def test_session_keeps_its_model_alive(tmp_path):
    m = sfrt.Model(DEFAULT_MODEL)
    session = sfrt.Session(m, size=(96, 128))
    del m
    gc.collect()
    x = np.zeros((96, 128, 12), dtype=np.float32)
    assert np.isfinite(session.run_tensor(x)).all()
    assert session.model.path == DEFAULT_MODEL


def test_info_says_what_the_model_file_says(model):
    info = model.info
    assert info["input"]["kind"] == "stereo"
    assert info["input"]["slots"] == ["left0", "right0", "left1", "right1"]
    assert info["input"]["channels"] == 12
    assert info["input"]["traced_size"] == (96, 128)
    assert info["output"]["channels"] == 3 and info["output"]["units"] == "metres"
    assert info["trained"] is True
    assert info["training_camera"]["focal_px"] == pytest.approx(90)
    assert info["training_camera"]["baseline"] == pytest.approx(0.12)
    assert {layer["precision"] for layer in info["layers"]} == {"fp32"}
    int8 = sfrt.Model(INT8_MODEL).info
    assert "int8" in {layer["precision"] for layer in int8["layers"]}


def test_repr_and_properties_say_what_the_object_is(model):
    session = sfrt.Session(model, size=(96, 128), threads=1, isa="ref")
    assert session.size == (96, 128) and session.isa == "ref" and session.threads == 1
    assert "sceneednet-default.sfrt" in repr(model) and "trained" in repr(model)
    text = repr(session)
    for part in ("96x128", "ref", "fp32", "sceneednet-default.sfrt"):
        assert part in text
    assert sfrt.__version__ == run_cli("--version").stdout.split()[1]


def test_size_defaults_to_the_size_a_trained_model_records(model):
    assert sfrt.Session(model).size == (96, 128)
    with pytest.raises(ValueError, match="records no training size"):
        sfrt.Session(sfrt.Model(DEMO_MODEL))


def test_rgbd_run_equals_sfrt_infer(tmp_path):
    torch = pytest.importorskip("torch")
    from torch import nn
    torch.manual_seed(3)
    net = nn.Sequential(nn.Conv2d(8, 8, 3, padding=1), nn.ReLU(), nn.Conv2d(8, 3, 3, padding=1))
    onnx_path = str(tmp_path / "rgbd.onnx")
    torch.onnx.export(net.eval(), torch.zeros(1, 8, 24, 32), onnx_path, opset_version=13)
    model_path = str(tmp_path / "rgbd.sfrt")
    run_cli("export", onnx_path, "-o", model_path, "--input-kind", "rgbd", "--color-order",
            "RGB", "--scale", "0.00392156862745098", "--depth-mean", "2", "--depth-std", "1.5",
            "--depth-invalid", "-1")
    rng = np.random.default_rng(1)
    color = [rng.integers(0, 256, (30, 40, 3), dtype=np.uint8) for _ in range(2)]
    depth = [rng.integers(0, 4000, (30, 40), dtype=np.uint16) for _ in range(2)]
    depth[0][5:9, 5:9] = 0
    from PIL import Image
    files = []
    for i in range(2):
        Image.fromarray(color[i][..., ::-1].copy()).save(tmp_path / ("c%d.png" % i))  # BGR->RGB
        np.save(tmp_path / ("d%d.npy" % i), depth[i].astype(np.float32) / 1000)
        files += [str(tmp_path / ("c%d.png" % i)), str(tmp_path / ("d%d.npy" % i))]
    out = str(tmp_path / "flow.npy")
    run_cli("infer", "--model", model_path, "--color0", files[0], "--depth0", files[1],
            "--color1", files[2], "--depth1", files[3], "--size", "24x32", "-o", out)
    session = sfrt.Session(sfrt.Model(model_path), size=(24, 32))
    metres = [d.astype(np.float32) / 1000 for d in depth]
    got = session.run_rgbd(color[0], metres[0], color[1], metres[1])
    np.testing.assert_array_equal(got, np.load(out))
    # 16-bit millimetres give the same depths in metres here (exact: the table divides by 1000).
    got16 = session.run_rgbd(color[0], depth[0], color[1], depth[1], depth_units=1000.0)
    assert np.abs(got16 - got).max() <= 1e-5 * max(1.0, np.abs(got).max())
