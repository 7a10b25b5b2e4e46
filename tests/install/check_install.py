"""Installs the build tree to a fresh prefix, builds tests/install/consumer against it with
find_package(sfrt 0.2), runs it (static and shared) on the default model and checks that its
flow equals `sfrt infer --input-npy` bit for bit.

usage: check_install.py --build DIR --sfrt BIN --model M --work DIR [--cxx C] [--cxx-flags F]
       [--linker-flags F]
"""
import argparse
import os
import shutil
import subprocess
import sys

import numpy as np

HEIGHT, WIDTH = 96, 128


def run(cmd, **kw):
    print("+ " + " ".join(cmd), flush=True)
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)
    print(p.stdout, flush=True)
    if p.returncode != 0:
        print("FAIL: exit %d: %s" % (p.returncode, " ".join(cmd)))
        sys.exit(1)
    return p.stdout


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", required=True)
    ap.add_argument("--sfrt", required=True)
    ap.add_argument("--model", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--cxx", default="")
    ap.add_argument("--cxx-flags", default="")
    ap.add_argument("--linker-flags", default="")
    a = ap.parse_args()

    shutil.rmtree(a.work, ignore_errors=True)
    prefix = os.path.join(a.work, "prefix")
    run(["cmake", "--install", a.build, "--prefix", prefix])
    for must in ["include/sfrt/session.h", "lib/cmake/sfrt/sfrtConfig.cmake",
                 "lib/cmake/sfrt/sfrtConfigVersion.cmake", "lib/libsfrt_runtime.a"]:
        if not os.path.exists(os.path.join(prefix, must)):
            print("FAIL: the install has no %s" % must)
            sys.exit(1)

    src = os.path.join(os.path.dirname(os.path.abspath(__file__)), "consumer")
    build = os.path.join(a.work, "consumer-build")
    cfg = ["cmake", "-S", src, "-B", build, "-DCMAKE_PREFIX_PATH=" + prefix,
           "-DCMAKE_BUILD_TYPE=Release"]
    if a.cxx:
        cfg.append("-DCMAKE_CXX_COMPILER=" + a.cxx)
    if a.cxx_flags:
        cfg.append("-DCMAKE_CXX_FLAGS=" + a.cxx_flags)
    if a.linker_flags:
        cfg.append("-DCMAKE_EXE_LINKER_FLAGS=" + a.linker_flags)
    run(cfg)
    run(["cmake", "--build", build, "-j2"])

    rng = np.random.default_rng(7)
    x = rng.uniform(0, 255, size=(HEIGHT, WIDTH, 12)).astype(np.float32)
    raw = os.path.join(a.work, "input.f32")
    x.tofile(raw)
    npy = os.path.join(a.work, "input.npy")
    np.save(npy, x)
    expected_path = os.path.join(a.work, "infer.npy")
    run([a.sfrt, "infer", "--model", a.model, "--input-npy", npy, "-o", expected_path])
    expected = np.load(expected_path).astype(np.float32).reshape(-1)

    ok = True
    for kind in ["static", "shared"]:
        out = os.path.join(a.work, "consumer_%s.f32" % kind)
        run([os.path.join(build, "consumer_" + kind), a.model, raw, str(HEIGHT), str(WIDTH), out])
        got = np.fromfile(out, dtype=np.float32)
        if got.shape != expected.shape:
            print("FAIL: %s consumer wrote %d floats, sfrt infer %d" %
                  (kind, got.size, expected.size))
            ok = False
        elif not np.array_equal(got.view(np.uint32), expected.view(np.uint32)):
            diff = np.abs(got - expected).max()
            print("FAIL: %s consumer differs from sfrt infer (max |diff| %g)" % (kind, diff))
            ok = False
        else:
            print("%s consumer: %d values, bit-identical to sfrt infer" % (kind, got.size))
    if not ok:
        sys.exit(1)
    print("PASS")


if __name__ == "__main__":
    main()
