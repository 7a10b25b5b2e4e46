"""sfrt.evaluate() against `sfrt eval --json`: the same dict, number for number."""
import json

import pytest

import sfrt
from conftest import DEFAULT_MODEL, run_cli


@pytest.mark.parametrize("extra", [[], ["--size", "64x96", "--thresholds", "relative",
                                       "--allow-camera-mismatch"]])
def test_evaluate_equals_sfrt_eval_json(tmp_path, model, synth_dataset, extra):
    out = tmp_path / "eval.json"
    run_cli("eval", "--model", DEFAULT_MODEL, "--dataset", synth_dataset, "--json", str(out),
            "--quiet", *extra)
    expected = json.loads(out.read_text())
    kwargs = {}
    if extra:
        kwargs = {"size": (64, 96), "thresholds": "relative", "allow_camera_mismatch": True}
    got = sfrt.evaluate(model, synth_dataset, **kwargs)
    assert got == expected
    assert got["sfrt"]["frames"] == 6


def test_evaluate_without_a_model_scores_the_baselines(tmp_path, synth_dataset):
    out = tmp_path / "eval.json"
    run_cli("eval", "--dataset", synth_dataset, "--json", str(out), "--quiet", "--no-classical")
    assert sfrt.evaluate(None, synth_dataset, classical=False) == json.loads(out.read_text())


def test_evaluate_on_the_kitti_layout_equals_sfrt_eval_json(tmp_path, model):
    root = str(tmp_path / "kitti")
    run_cli("synth", "--layout", "kitti", "--out", root, "--scene", "robot", "--seed", "7",
            "--sequences", "1", "--frames", "3", "--size", "96x128", "--focal", "90",
            "--baseline", "0.12", "--objects", "3")
    out = tmp_path / "eval.json"
    run_cli("eval", "--model", DEFAULT_MODEL, "--dataset", root, "--json", str(out), "--quiet",
            "--depth", "stereo")
    got = sfrt.evaluate(model, root, depth="stereo")
    assert got == json.loads(out.read_text())
    assert got["layout"] == "kitti" and got["sfrt"]["kitti"]["depth"] == "stereo"
