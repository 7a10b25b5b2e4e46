"""The Python examples run as the README shows them (pictures written, not shown)."""
import os
import subprocess
import sys

from conftest import ROOT, sfrt_bin

EXAMPLES = os.path.join(ROOT, "examples", "python")


def run_example(name, *args):
    env = dict(os.environ, MPLBACKEND="Agg")
    done = subprocess.run([sys.executable, os.path.join(EXAMPLES, name), *args],
                          capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def test_show_flow_writes_its_figure(tmp_path, synth_dataset):
    picture = tmp_path / "flow.png"
    out = run_example("show_flow.py", "--frames",
                      os.path.join(synth_dataset, "frames_cleanpass", "0000"), "--save",
                      str(picture))
    assert "flow 96x128" in out
    assert picture.stat().st_size > 10000
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_evaluate_synthetic_prints_the_three_methods_and_every_window():
    out = run_example("evaluate_synthetic.py", "--sfrt", sfrt_bin(), "--frames", "4")
    for method in ("sfrt", "zero_flow", "classical"):
        assert "\n  %s " % method in out
    assert out.count("frames_cleanpass_0000_00000") == 3
