"""sfrt: SceneEDNet scene flow on the CPU, from Python.

    import sfrt
    m = sfrt.Model("models/sceneednet-default.sfrt")
    s = sfrt.Session(m, size=(96, 128))
    flow = s.run(left0, right0, left1, right1)      # float32 (H, W, 3), metres per pixel

    for w in sfrt.replay(m, left="seq/left", right="seq/right"):
        print(w.index, w.flow.shape)

    print(sfrt.evaluate(m, "data/heldout")["sfrt"]["epe3d"])

Everything here is the C++ library (the same code `sfrt infer`, `sfrt run` and `sfrt eval` run):
the results are theirs, bit for bit. Threads: the GIL is released while the library works; use
one Session per thread, share a Model between any number of them.
"""

from ._sfrt import Error, Model, Replay, Session, Window, __version__, evaluate, replay

__all__ = ["Error", "Model", "Replay", "Session", "Window", "__version__", "evaluate", "replay"]
