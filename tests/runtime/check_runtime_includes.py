"""The runtime's one-way door (docs/architecture.md): every #include under runtime/ is the C++
standard library, a POSIX/Linux/compiler header from the allowed list, the shared vocabulary
(sfrt/vocabulary/, header-only), FlatBuffers (through the
generated schema header), or a file of runtime/ itself. Fails naming each file:line that reaches
elsewhere (OpenCV, YAML, ONNX, another module of ours...).

usage: check_runtime_includes.py RUNTIME_DIR
"""
import os
import re
import sys

# Headers outside the C++ standard library the runtime may use: OS and compiler interfaces for
# threads, futexes, memory maps, CPU features and SIMD intrinsics.
SYSTEM = {"immintrin.h", "arm_neon.h", "cpuid.h", "unistd.h", "pthread.h", "sched.h", "fcntl.h",
          "sys/syscall.h", "sys/stat.h", "sys/mman.h", "sys/auxv.h", "linux/futex.h",
          "asm/hwcap.h", "stdlib.h", "stdint.h", "string.h"}
GENERATED = {"sfrt_model_generated.h"}  # flatc's output for runtime/schema/sfrt_model.fbs
# The shared words (vocabulary/, header-only, standard C++ only): the one module the runtime uses.
VOCABULARY = re.compile(r"sfrt/vocabulary/[a-z_]+\.h")
INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]')


def main():
    root = os.path.abspath(sys.argv[1])
    search = [root, os.path.join(root, "include"), os.path.join(root, "src")]
    bad, seen = [], 0
    for dirpath, _, files in os.walk(root):
        for name in sorted(files):
            if not name.endswith((".h", ".cc")):
                continue
            path = os.path.join(dirpath, name)
            with open(path, encoding="utf-8") as f:
                for number, line in enumerate(f, 1):
                    m = INCLUDE.match(line)
                    if not m:
                        continue
                    seen += 1
                    kind, header = m.groups()
                    if kind == "<":
                        ok = re.fullmatch(r"[a-z_]+", header) is not None or header in SYSTEM
                    else:
                        ok = header in GENERATED or VOCABULARY.fullmatch(header) or any(
                            os.path.isfile(os.path.join(d, header))
                            for d in [dirpath] + search)
                    if not ok:
                        bad.append("%s:%d: #include %s" % (os.path.relpath(path, root), number,
                                                          line.split("include", 1)[1].strip()))
    if seen == 0:
        print("FAIL: no #include found under %s" % root)
        return 1
    for b in bad:
        print("FAIL: runtime/%s reaches outside the runtime" % b)
    if bad:
        return 1
    print("%d includes under %s: all standard, allowed system or runtime headers" % (seen, root))
    return 0


if __name__ == "__main__":
    sys.exit(main())
