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
