"""No memory grows over 1,000 calls: the resident set after 1,000 runs is where it was after a
warm-up (a leaked output of 96x128x3 floats per call would add 147 MB)."""
import gc

import numpy as np

import sfrt
from conftest import DEFAULT_MODEL, read_rgb, window_paths


def rss_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096


def test_a_thousand_calls_do_not_grow_the_resident_set():
    m = sfrt.Model(DEFAULT_MODEL)
    session = sfrt.Session(m, size=(96, 128))
    images = [read_rgb(p) for p in window_paths()]
    x = np.zeros((96, 128, 12), np.float32)
    out = np.empty((96, 128, 3), np.float32)

    def calls(n):
        for i in range(n):
            session.run(*images, color="rgb")
            session.run(*images, color="rgb", out=out)
            session.run_tensor(x)
            try:
                session.run(images[0], images[1], images[2], x)  # an error path too
            except (ValueError, TypeError):
                pass
            if i % 100 == 0:
                repr(session), m.info

    calls(100)
    gc.collect()
    before = rss_bytes()
    calls(1000)
    gc.collect()
    grown = rss_bytes() - before
    assert grown < 8 << 20, "resident set grew by %d bytes over 1,000 calls" % grown
