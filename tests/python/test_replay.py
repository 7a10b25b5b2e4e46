"""sfrt.replay() against `sfrt run`: the same windows, names and flow, bit for bit."""
import glob
import os

import numpy as np
import pytest

import sfrt
from conftest import DEFAULT_MODEL, SAMPLES, run_cli


def cli_windows(tmp_path, *source_args, size="96x128"):
    """The flow files `sfrt run` writes, by window stem."""
    out = tmp_path / "run"
    run_cli("run", "--model", DEFAULT_MODEL, *source_args, "--size", size, "--out", str(out),
            "--flow-format", "npy", "--no-png", "--progress", "off")
    return {os.path.basename(p)[:-4]: np.load(p) for p in glob.glob(str(out / "*.npy"))}


def test_replay_of_folders_equals_sfrt_run(tmp_path, model):
    left, right = (os.path.join(SAMPLES, "Driving", side) for side in ("left", "right"))
    expected = cli_windows(tmp_path, "--replay-left", left, "--replay-right", right)
    with sfrt.replay(model, left=left, right=right, size=(96, 128)) as windows:
        got = list(windows)
        summary = windows.summary
    assert [w.name for w in got] == sorted(expected)
    assert [w.index for w in got] == list(range(len(expected)))
    for w in got:
        np.testing.assert_array_equal(w.flow, expected[w.name])
        assert w.flow.dtype == np.float32 and w.flow.flags.c_contiguous
        assert w.sources["frame1"] == w.sources["frame0"] + 1
        assert w.sources["left0"].startswith(left)
        assert w.t1 >= w.t0 > 0
    assert summary["frames"]["written"] == len(expected)


def test_replay_of_a_dataset_equals_sfrt_run(tmp_path, model, synth_dataset):
    expected = cli_windows(tmp_path, "--replay", synth_dataset)
    got = {w.name: w.flow for w in sfrt.replay(model, dataset=synth_dataset, size=(96, 128))}
    assert sorted(got) == sorted(expected) and len(got) == 6  # 2 sequences of 4 frames
    for name, flow in got.items():
        np.testing.assert_array_equal(flow, expected[name])


def test_replay_waits_for_a_slow_reader_and_drops_nothing(model, synth_dataset):
    import time
    names = []
    for w in sfrt.replay(model, dataset=synth_dataset):  # size: the model's recorded 96x128
        time.sleep(0.05)  # slower than the pipeline
        names.append(w.name)
    assert len(names) == 6


def test_close_stops_early_and_max_frames_counts(model, synth_dataset):
    r = sfrt.replay(model, dataset=synth_dataset)
    first = next(r)
    r.close()
    with pytest.raises(StopIteration):
        next(r)
    assert first.index == 0
    assert len(list(sfrt.replay(model, dataset=synth_dataset, max_frames=2))) == 2


def test_replay_errors_name_the_source(model, tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere"):
        sfrt.replay(model, dataset=str(tmp_path / "nowhere"))
    with pytest.raises(ValueError, match="exactly one source"):
        sfrt.replay(model)
    with pytest.raises(ValueError, match="go together"):
        sfrt.replay(model, left=str(tmp_path))
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError):
        sfrt.replay(model, left=str(empty), right=str(empty))


def test_replay_of_a_bag_equals_sfrt_run(tmp_path, model, synth_dataset):
    bag = str(tmp_path / "inputs.mcap")  # the dataset's frames as a rosbag2 bag
    run_cli("run", "--model", DEFAULT_MODEL, "--replay", synth_dataset, "--out",
            str(tmp_path / "record"), "--record-bag", bag, "--flow-format",
            "none", "--no-png", "--progress", "off")
    expected = cli_windows(tmp_path, "--replay-bag", bag)
    got = list(sfrt.replay(model, bag=bag, size=(96, 128)))
    assert [w.name for w in got] == sorted(expected) and len(got) >= 3
    for w in got:
        np.testing.assert_array_equal(w.flow, expected[w.name])
        assert w.t1 > w.t0 > 1e9  # the bag's header stamps, seconds since the epoch
