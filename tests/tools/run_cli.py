#!/usr/bin/python3
"""Run one sfrt command and check its exit code and output.

usage: run_cli.py --exit N [--stdout REGEX]... [--stderr REGEX]... [--cwd DIR] -- COMMAND ARGS...

Every REGEX must match somewhere in the stream (re.search, MULTILINE). When N is not 0, stderr
must also be exactly one line of the form "sfrt[ <command>]: <message>" (the tool's error
convention). Both streams are echoed so ctest --output-on-failure shows them.
"""
import argparse
import re
import subprocess
import sys


def main():
    argv = sys.argv[1:]
    if "--" not in argv:
        print("run_cli.py: missing '--' before the command", file=sys.stderr)
        return 2
    split = argv.index("--")
    p = argparse.ArgumentParser()
    p.add_argument("--exit", type=int, required=True)
    p.add_argument("--stdout", action="append", default=[])
    p.add_argument("--stderr", action="append", default=[])
    p.add_argument("--cwd", default=None)
    args = p.parse_args(argv[:split])
    command = argv[split + 1:]

    proc = subprocess.run(command, capture_output=True, text=True, cwd=args.cwd, timeout=600)
    print("$ " + " ".join(command))
    print(f"--- exit code {proc.returncode}; stdout:")
    print(proc.stdout, end="")
    print("--- stderr:")
    print(proc.stderr, end="")
    print("---")

    failures = []
    if proc.returncode != args.exit:
        failures.append(f"exit code {proc.returncode}, expected {args.exit}")
    for pattern in args.stdout:
        if not re.search(pattern, proc.stdout, re.MULTILINE):
            failures.append(f"stdout does not match {pattern!r}")
    for pattern in args.stderr:
        if not re.search(pattern, proc.stderr, re.MULTILINE):
            failures.append(f"stderr does not match {pattern!r}")
    if args.exit != 0:
        lines = proc.stderr.splitlines()
        if len(lines) != 1 or not re.match(r"^sfrt( [a-z]+)?: \S", lines[0]):
            failures.append("stderr is not one line 'sfrt <command>: <message>'")
    for f in failures:
        print("FAIL: " + f)
    if not failures:
        print("OK")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
