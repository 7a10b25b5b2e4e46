"""Shared fixtures of the Python package's tests (run by ctest: tests/python/CMakeLists.txt sets
SFRT_BIN, SFRT_SOURCE_DIR and PYTHONPATH to the build tree's package)."""
import os
import subprocess

import numpy as np
import pytest
from PIL import Image

import sfrt

ROOT = os.environ.get("SFRT_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
SAMPLES = os.path.join(ROOT, "tests", "data", "sceneflow-samples", "images")
DEFAULT_MODEL = os.path.join(ROOT, "models", "sceneednet-default.sfrt")
INT8_MODEL = os.path.join(ROOT, "models", "sceneednet-default-int8.sfrt")
DEMO_MODEL = os.path.join(ROOT, "tools", "demo", "sceneednet-w16-demo.sfrt")


def sfrt_bin():
    return os.environ["SFRT_BIN"]


def run_cli(*args, env=None):
    """Runs the sfrt command; fails the test with its output when it fails."""
    done = subprocess.run([sfrt_bin(), *args], capture_output=True, text=True, env=env)
    assert done.returncode == 0, "sfrt %s failed:\n%s%s" % (" ".join(args), done.stdout,
                                                          done.stderr)
    return done


def window_paths(scene="Driving", first=6):
    """The four committed frames of one window: left0, right0, left1, right1."""
    return [os.path.join(SAMPLES, scene, side, "%04d.png" % frame)
            for frame in (first, first + 1) for side in ("left", "right")]


def read_rgb(path):
    """An image as PIL decodes it: uint8 (H, W, 3) in RGB order."""
    return np.asarray(Image.open(path).convert("RGB"))


@pytest.fixture(scope="session")
def model():
    return sfrt.Model(DEFAULT_MODEL)


@pytest.fixture(scope="session")
def synth_dataset(tmp_path_factory):
    """A small held-out sequence with exact ground truth, from `sfrt synth` (seed 4242)."""
    root = str(tmp_path_factory.mktemp("synth") / "data")
    run_cli("synth", "--out", root, "--scene", "robot", "--seed", "4242", "--sequences", "2",
            "--frames", "4", "--size", "96x128", "--focal", "90", "--baseline", "0.12",
            "--objects", "4")
    return root
