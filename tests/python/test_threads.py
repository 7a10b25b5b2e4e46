"""The GIL is released while the library works, and sessions on two threads give what they give
on one. No test here reads a clock: the speed of parallel sessions is measured by
tools/bench/python_bench.py."""
import threading

import numpy as np

import sfrt
from conftest import DEFAULT_MODEL, read_rgb, window_paths


def test_another_thread_runs_python_while_a_run_is_in_progress():
    # While thread A is inside Session.run, thread B calls the same session and is refused
    # ("running on another thread"). B can only run Python during A's run if the GIL is released:
    # with the GIL held through the run the refusal could never happen.
    session = sfrt.Session(sfrt.Model(DEFAULT_MODEL), size=(192, 256))
    images = [read_rgb(p) for p in window_paths()]
    refused = []
    stop = threading.Event()

    def worker():
        while not stop.is_set():
            try:
                session.run(*images, color="rgb")
            except sfrt.Error as e:
                assert "another thread" in str(e)
                refused.append(1)
                if len(refused) >= 3:
                    stop.set()

    threads = [threading.Thread(target=worker) for _ in range(2)]
    for t in threads:
        t.start()
    stop.wait(timeout=120)
    stop.set()
    for t in threads:
        t.join()
    assert len(refused) >= 3


def test_two_sessions_on_two_threads_give_the_single_thread_results():
    m = sfrt.Model(DEFAULT_MODEL)
    windows = [[read_rgb(p) for p in window_paths(scene)] for scene in ("Driving", "Monkaa")]
    solo = sfrt.Session(m, size=(96, 128))
    expected = [solo.run(*w, color="rgb") for w in windows]
    results = [[], []]

    def worker(k):
        s = sfrt.Session(m, size=(96, 128))
        for _ in range(20):
            results[k].append(s.run(*windows[k], color="rgb"))

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(2):
        assert len(results[k]) == 20
        for r in results[k]:
            np.testing.assert_array_equal(r, expected[k])
