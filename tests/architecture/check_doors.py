"""The one-way doors between sfrt's modules (docs/architecture.md), read off the sources: every
quoted #include is resolved the way the compiler would (the including file's folder, then every
module's include folders) to the module that owns the header, and a header of another module must
be one the including module may use. Fails naming each file:line that goes through a forbidden
door, and any module folder missing from the table (a new module must be placed in it).

usage: check_doors.py SOURCE_DIR
"""
import os
import re
import sys

# module folder -> (its include folders, the modules it may use)
MODULES = {
    "vocabulary": (["vocabulary/include"], set()),
    "runtime": (["runtime/include", "runtime/src", "runtime"], {"vocabulary"}),
    "exporter": (["exporter/include", "exporter/src"], {"vocabulary", "runtime"}),
    "camera": (["camera/common/include", "camera/v4l2/include", "camera/sources/include"],
               {"vocabulary"}),
    "firmware-cfg": (["firmware-cfg/include"], {"vocabulary", "runtime", "camera"}),
    "pipeline": (["pipeline/include"], {"vocabulary", "runtime", "camera", "firmware-cfg"}),
    "ros": (["ros/include"], {"vocabulary", "runtime", "camera", "firmware-cfg", "pipeline"}),
    "ros2": (["ros2/include"], {"vocabulary", "runtime", "camera", "firmware-cfg", "pipeline"}),
    "tools": (["tools"], {"vocabulary", "runtime", "exporter", "camera", "firmware-cfg", "pipeline",
                          "ros", "ros2"}),
    # The Python package binds the runtime, the pipeline and the eval and bag libraries of tools/.
    "python": ([], {"vocabulary", "runtime", "camera", "firmware-cfg", "pipeline", "tools"}),
    "examples": ([], {"vocabulary", "runtime", "camera", "firmware-cfg", "pipeline"}),
    # The tests use what they test and their own helpers (tests/common, ...); nothing uses them.
    "tests": (["tests"], {"vocabulary", "runtime", "exporter", "camera", "firmware-cfg",
                          "pipeline", "ros", "ros2", "tools", "examples"}),
}
# Top-level folders that are not modules of the library.
NOT_MODULES = {"docs", "cmake", "models", "build", "out", "data", ".ci", ".git"}
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')


def owner(root, path):
    rel = os.path.relpath(path, root).split(os.sep)[0]
    return rel if rel in MODULES else None


def main():
    root = os.path.abspath(sys.argv[1])
    bad, seen, crossings = [], 0, {}
    for entry in sorted(os.listdir(root)):
        if (os.path.isdir(os.path.join(root, entry)) and entry not in MODULES
                and entry not in NOT_MODULES and not entry.startswith(".")):
            bad.append("%s/ is a top-level folder missing from the module table" % entry)
    search = [os.path.join(root, d) for dirs, _ in MODULES.values() for d in dirs]
    for module, (_, allowed) in MODULES.items():
        for dirpath, _, files in os.walk(os.path.join(root, module)):
            for name in sorted(files):
                if not name.endswith((".h", ".cc", ".in")):
                    continue
                path = os.path.join(dirpath, name)
                with open(path, encoding="utf-8") as f:
                    for number, line in enumerate(f, 1):
                        m = INCLUDE.match(line)
                        if not m:
                            continue
                        seen += 1
                        header = m.group(1)
                        found = next((os.path.join(d, header) for d in [dirpath] + search
                                      if os.path.isfile(os.path.join(d, header))), None)
                        target = owner(root, found) if found else None
                        if target is None or target == module:
                            continue
                        crossings[(module, target)] = crossings.get((module, target), 0) + 1
                        if target not in allowed:
                            bad.append("%s:%d: #include \"%s\" is %s/'s; %s/ may use %s" % (
                                os.path.relpath(path, root), number, header, target, module,
                                ", ".join(sorted(allowed)) or "no other module"))
    if seen == 0:
        print("FAIL: no #include found under %s" % root)
        return 1
    for b in bad:
        print("FAIL: " + b)
    if bad:
        return 1
    print("%d includes checked; doors used:" % seen)
    for (a, b), n in sorted(crossings.items()):
        print("  %s -> %s (%d)" % (a, b, n))
    return 0


if __name__ == "__main__":
    sys.exit(main())
