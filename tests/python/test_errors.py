"""Every error path raises a Python exception with the library's message (naming the argument,
file or value), and nothing a caller passes crashes the interpreter."""
import itertools
import os

import numpy as np
import pytest

import sfrt
from conftest import DEFAULT_MODEL, DEMO_MODEL, read_rgb, window_paths


@pytest.fixture(scope="module")
def session():
    return sfrt.Session(sfrt.Model(DEFAULT_MODEL), size=(96, 128))


@pytest.fixture(scope="module")
def images():
    return [read_rgb(p) for p in window_paths()]


def test_error_is_a_runtime_error():
    assert issubclass(sfrt.Error, RuntimeError)


def test_model_file_errors_name_the_path(tmp_path):
    missing = str(tmp_path / "missing.sfrt")
    with pytest.raises(FileNotFoundError, match="missing.sfrt") as e:
        sfrt.Model(missing)
    assert e.value.filename == missing
    with pytest.raises(IsADirectoryError):
        sfrt.Model(str(tmp_path))
    garbage = tmp_path / "garbage.sfrt"
    garbage.write_bytes(b"not a model" * 100)
    with pytest.raises(sfrt.Error, match="garbage.sfrt"):
        sfrt.Model(str(garbage))
    truncated = tmp_path / "truncated.sfrt"
    truncated.write_bytes(open(DEFAULT_MODEL, "rb").read()[:5000])
    with pytest.raises(sfrt.Error):
        sfrt.Model(str(truncated))


def test_session_arguments_are_checked():
    m = sfrt.Model(DEFAULT_MODEL)
    with pytest.raises(ValueError, match="size"):
        sfrt.Session(m, size=(8, 8))
    with pytest.raises(ValueError, match="size"):
        sfrt.Session(m, size="96x128")
    with pytest.raises(ValueError, match="isa: 'sse9'"):
        sfrt.Session(m, isa="sse9")
    for threads in (-1, 100000):
        with pytest.raises(ValueError, match="threads"):
            sfrt.Session(m, threads=threads)
    with pytest.raises(TypeError):
        sfrt.Session("models/sceneednet-default.sfrt")


def test_image_errors_name_the_argument_and_the_expectation(session, images):
    l0, r0, l1, r1 = images
    with pytest.raises(ValueError, match=r"right1: dtype float32; expected \(H, W, 3\) of uint8"):
        session.run(l0, r0, l1, r1.astype(np.float32))
    with pytest.raises(ValueError, match=r"left0: shape \(270, 480\)"):
        session.run(l0[..., 0], r0, l1, r1)
    with pytest.raises(ValueError, match=r"left1 is 100x480 but left0 is 270x480"):
        session.run(l0, r0, l1[:100], r1[:100])
    with pytest.raises(ValueError, match="color: expected 'bgr'"):
        session.run(l0, r0, l1, r1, color="hsv")
    with pytest.raises(TypeError, match="right0: expected a numpy array"):
        session.run(l0, [[1, 2, 3]], l1, r1)
    with pytest.raises(ValueError, match="reads stereo pairs: use run"):
        session.run_rgbd(l0, r0, l1, r1)
    with pytest.raises(ValueError, match="squeezes"):
        session.run(*[np.zeros((480, 360, 3), np.uint8)] * 4)  # (W, H) of the session's aspect


def test_out_errors_say_what_out_must_be(session, images):
    for bad in (np.zeros((96, 128, 3), np.float64), np.zeros((96, 128, 2), np.float32),
                np.zeros((128, 96, 3), np.float32).transpose(1, 0, 2)):
        with pytest.raises(ValueError, match=r"out: .*expected \(96, 128, 3\) of float32"):
            session.run(*images, out=bad)
    readonly = np.zeros((96, 128, 3), np.float32)
    readonly.flags.writeable = False
    with pytest.raises(ValueError, match="read-only"):
        session.run(*images, out=readonly)


def test_tensor_errors(session):
    x = np.zeros((96, 128, 12), np.float32)
    x[3, 4, 5] = np.nan
    with pytest.raises(ValueError, match=r"x: element \[3, 4, 5\] \(flat index 4661\) is NaN"):
        session.run_tensor(x)
    with pytest.raises(ValueError, match=r"x: shape \(96, 128, 11\)"):
        session.run_tensor(np.zeros((96, 128, 11), np.float32))
    with pytest.raises(ValueError, match="dtype float64"):
        session.run_tensor(np.zeros((96, 128, 12)))
    with pytest.raises(ValueError, match="larger than the session's 96x128"):
        session.run_tensor(np.zeros((100, 128, 12), np.float32))


def test_evaluate_errors(tmp_path):
    m = sfrt.Model(DEFAULT_MODEL)
    with pytest.raises(FileNotFoundError, match="nowhere"):
        sfrt.evaluate(m, str(tmp_path / "nowhere"))
    with pytest.raises(sfrt.Error):
        sfrt.evaluate(m, str(tmp_path))  # no camera.json: not a dataset
    with pytest.raises(ValueError, match="thresholds"):
        sfrt.evaluate(m, str(tmp_path), thresholds="loose")


GARBAGE = [None, 0, -1, 1.5, float("nan"), "", "x" * 10000, b"\x00\xff", [], [1, 2], {},
           object(), np.zeros(0), np.zeros((0, 0, 3), np.uint8), np.zeros((1, 1, 3), np.uint8),
           np.zeros((2, 3, 3), np.int8), np.zeros((4, 4, 3), np.uint8)[:, ::2],
           np.ones((3, 3, 3, 3), np.uint8), np.array(["a", "b"]), np.zeros((5, 5, 3), object),
           np.zeros((40000, 1, 3), np.uint8), np.zeros((17, 17, 12), np.float32),
           np.full((16, 16, 12), np.inf, np.float32), np.zeros((16, 16), np.uint16),
           np.zeros((16, 16, 3), ">f4")]
ALLOWED = (TypeError, ValueError, sfrt.Error, OSError, StopIteration)


def attempt(call, *args, **kwargs):
    try:
        call(*args, **kwargs)
    except ALLOWED:
        pass


def test_garbage_at_every_entry_point_raises_and_never_crashes(session, images, tmp_path):
    m = session.model
    for g in GARBAGE:
        attempt(sfrt.Model, g)
        attempt(sfrt.Session, m, size=g)
        attempt(sfrt.Session, m, threads=g)
        attempt(sfrt.Session, m, isa=g)
        attempt(sfrt.Session, g)
        for i in range(4):
            args = list(images)
            args[i] = g
            attempt(session.run, *args)
            attempt(session.run_rgbd, *args)
        attempt(session.run, *images, color=g)
        attempt(session.run, *images, out=g)
        attempt(session.run_tensor, g)
        attempt(session.run_tensor, np.zeros((96, 128, 12), np.float32), out=g)
        attempt(sfrt.evaluate, g, g)
        attempt(sfrt.evaluate, m, str(tmp_path), size=g)
        for key in ("left", "dataset", "video", "bag", "size", "threads", "isa", "max_frames",
                    "rendering_pass", "on_bad_frame"):
            attempt(lambda: list(sfrt.replay(m, **{key: g})))
    # Pairs of odd but valid images: every size combination is refused or run, never a crash.
    shapes = [(16, 16), (17, 33), (1, 1), (300, 7)]
    for a, b in itertools.product(shapes, shapes):
        imgs = [np.zeros(a + (3,), np.uint8)] * 2 + [np.zeros(b + (3,), np.uint8)] * 2
        attempt(session.run, *imgs)
    # The session still works after all of it.
    assert np.isfinite(session.run(*images)).all()


def test_a_session_used_by_the_demo_model_plans_its_own_size():
    s = sfrt.Session(sfrt.Model(DEMO_MODEL), size=(64, 96), threads=2)
    assert s.run_tensor(np.zeros((64, 96, 12), np.float32)).shape == (64, 96, 3)
