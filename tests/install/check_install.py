"""Installs the build tree to a fresh prefix, builds tests/install/consumer against it with
find_package(sfrt 0.2), runs it (static and shared) on the default model and checks that its
flow equals `sfrt infer --input-npy` bit for bit. With --example and --preload it also builds
the example robot program (examples/robot_flow, sfrt::pipeline) against the same prefix and runs
it on the fake V4L2 camera pair (the LD_PRELOAD shim): every one of --frames flow frames must
reach its callback sink, each with a finite latency and mean dZ, and it must exit 0.

usage: check_install.py --build DIR --sfrt BIN --model M --work DIR [--cxx C] [--cxx-flags F]
       [--linker-flags F] [--example DIR --preload SHIM [--frames N]]
"""
import re
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
    ap.add_argument("--example", default="")
    ap.add_argument("--preload", default="")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--python-package", action="store_true",
                    help="also check the installed Python package (lib/python3/dist-packages)")
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
    if a.example:
        example_build = os.path.join(a.work, "example-build")
        run(cfg[:2] + [a.example, "-B", example_build] + cfg[5:])
        run(["cmake", "--build", example_build, "-j2"])

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
    if a.example and not check_example(a, os.path.join(a.work, "example-build", "robot_flow")):
        ok = False
    if a.python_package and not check_python(a, prefix, npy, expected_path):
        ok = False
    if not ok:
        sys.exit(1)
    print("PASS")


def check_python(a, prefix, npy, expected_path):
    """`import sfrt` from the installed package (Debian's layout: <prefix>/lib/python3/
    dist-packages/sfrt), in a fresh interpreter, gives sfrt infer's output bit for bit."""
    package = os.path.join(prefix, "lib", "python3", "dist-packages")
    for must in ["__init__.py", "__init__.pyi", "py.typed"]:
        if not os.path.exists(os.path.join(package, "sfrt", must)):
            print("FAIL: the install has no lib/python3/dist-packages/sfrt/%s" % must)
            return False
    code = ("import sys, numpy as np, sfrt\n"
            "assert sfrt.__file__.startswith(sys.argv[1]), sfrt.__file__\n"
            "s = sfrt.Session(sfrt.Model(sys.argv[2]), size=(%d, %d))\n"
            "got = s.run_tensor(np.load(sys.argv[3]))\n"
            "assert np.array_equal(got.view(np.uint32), np.load(sys.argv[4]).view(np.uint32))\n"
            "print('installed package', sfrt.__version__, 'at', sfrt.__file__)\n" % (HEIGHT, WIDTH))
    env = dict(os.environ)
    env["PYTHONPATH"] = package
    out = run([sys.executable, "-c", code, package, a.model, npy, expected_path], env=env)
    print(out.strip() + ": run_tensor bit-identical to sfrt infer")
    return True


def check_example(a, binary):
    env = dict(os.environ)
    env["LD_PRELOAD"] = a.preload
    env["SFRT_FAKE_V4L2"] = "/dev/video0:side=0;/dev/video1:side=1,phase_ms=2"
    # ASan wants its runtime first in the library list; the shim is preloaded before it.
    env["ASAN_OPTIONS"] = env.get("ASAN_OPTIONS", "") + ":verify_asan_link_order=0"
    out = run([binary, a.model, "/dev/video0", "/dev/video1", str(a.frames)], env=env)
    frames = re.findall(r"^window (\d+) frames (\d+)-(\d+) latency ([0-9.]+) ms dZ (\S+)$",
                        out, re.M)
    ok = len(frames) == a.frames
    if not ok:
        print("FAIL: the example printed %d flow frames, expected %d" % (len(frames), a.frames))
    windows = [int(f[0]) for f in frames]
    if windows != sorted(windows) or len(set(windows)) != len(windows):
        print("FAIL: the example's windows are not strictly increasing: %s" % windows)
        ok = False
    for f in frames:
        if not (float(f[3]) > 0 and np.isfinite(float(f[4]))):
            print("FAIL: frame %s: latency %s ms, dZ %s" % (f[0], f[3], f[4]))
            ok = False
    if not re.search(r"^received %d frames \(max-frames\)" % a.frames, out, re.M):
        print("FAIL: the example's summary line does not say %d frames (max-frames)" % a.frames)
        ok = False
    if ok:
        print("example robot_flow: %d flow frames through the callback sink" % a.frames)
    return ok


if __name__ == "__main__":
    main()
