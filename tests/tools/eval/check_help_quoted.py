#!/usr/bin/python3
"""Checks that a document quotes lines of an `sfrt` command's --help verbatim.

usage: check_help_quoted.py --sfrt BIN --doc FILE --lines REGEX -- ARGS...

Runs `BIN ARGS...`, takes every stdout line that matches REGEX (at least one must), and fails
naming each such line that FILE does not contain as a whole line.
"""
import argparse
import re
import subprocess
import sys


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--sfrt", required=True)
    p.add_argument("--doc", required=True)
    p.add_argument("--lines", required=True, help="regex selecting the help lines to look for")
    p.add_argument("args", nargs="+")
    a = p.parse_args()
    proc = subprocess.run([a.sfrt] + a.args, capture_output=True, text=True, timeout=60)
    if proc.returncode != 0:
        print("FAIL: %s %s exited %d: %s" % (a.sfrt, " ".join(a.args), proc.returncode,
                                           proc.stderr))
        return 1
    wanted = [line for line in proc.stdout.splitlines() if re.search(a.lines, line)]
    if not wanted:
        print("FAIL: no line of `sfrt %s` matches %r:\n%s" % (" ".join(a.args), a.lines,
                                                             proc.stdout))
        return 1
    with open(a.doc, encoding="utf-8") as f:
        doc = set(f.read().splitlines())
    missing = [line for line in wanted if line not in doc]
    for line in wanted:
        print("%s %r" % ("MISSING" if line in missing else "found  ", line))
    if missing:
        print("FAIL: %s does not quote %d line(s) of `sfrt %s`" % (a.doc, len(missing),
                                                                  " ".join(a.args)))
        return 1
    print("all %d line(s) quoted in %s" % (len(wanted), a.doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
