"""Each ISA's kernels are compiled with their own instruction-set flags (runtime/CMakeLists.txt,
sfrt_add_isa_kernels), so no function they define may also be defined by another object file:
the linker keeps one copy of a weak (inline, template) function for the whole program, and where
it keeps the copy compiled for AVX-512 (or AMX, or Armv8.2 dot products) a CPU without them
stops with an illegal instruction wherever that function runs, in the scalar emulation of the
AMX tiles for one. The kernel drivers (kernels/simd/*_inl.h) avoid it by templates on the
per-ISA vocabulary (an anonymous-namespace type), `static` functions and trivial structs.

Fails naming each function (demangled) that a kernel object and another object both define
(nm types T and W), and the objects. Data (static constexpr tables) is not code and is not
checked.

usage: check_kernel_linkage.py NM KERNEL_OBJECTS.txt OTHER_OBJECTS.txt
  (each file: one object path a line)
"""
import subprocess
import sys

PROG = "check_kernel_linkage.py"


def objects(listing):
    with open(listing, encoding="utf-8") as f:
        return [line.strip() for line in f if line.strip()]


def functions(nm, obj):
    """The global and weak functions `obj` defines (mangled names)."""
    proc = subprocess.run([nm, "--defined-only", obj], capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"{PROG}: {nm} --defined-only {obj} failed: {proc.stderr.strip()}")
    names = set()
    for line in proc.stdout.splitlines():
        parts = line.split()
        if len(parts) >= 3 and parts[1] in ("T", "W"):
            names.add(parts[2])
    return names


def demangle(names):
    proc = subprocess.run(["c++filt"], input="\n".join(names), capture_output=True, text=True)
    lines = proc.stdout.splitlines() if proc.returncode == 0 else []
    return lines if len(lines) == len(names) else list(names)


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__.split("usage: ")[1])
    nm, kernel_list, other_list = sys.argv[1:]
    kernels, others = objects(kernel_list), objects(other_list)
    if not kernels:
        sys.exit(f"{PROG}: {kernel_list} lists no kernel object: nothing would be checked")
    defined_by = {}
    for obj in kernels + others:
        for name in functions(nm, obj):
            defined_by.setdefault(name, []).append(obj)
    kernel_set = set(kernels)
    shared = sorted(name for name, objs in defined_by.items()
                    if len(objs) > 1 and any(o in kernel_set for o in objs))
    checked = sum(1 for objs in defined_by.values() if any(o in kernel_set for o in objs))
    if checked == 0:
        sys.exit(f"{PROG}: the kernel objects define no function: nm listed nothing to check")
    if shared:
        for name, shown in zip(shared, demangle(shared)):
            print(f"{shown}\n    defined in: {', '.join(defined_by[name])}")
        sys.exit(f"{PROG}: {len(shared)} function(s) of a kernel object are also defined "
                 "elsewhere; the linker may run the copy built for another instruction set")
    print(f"{PROG}: {checked} functions of {len(kernels)} kernel objects, none defined elsewhere "
          f"(against {len(others)} other objects)")


if __name__ == "__main__":
    main()
