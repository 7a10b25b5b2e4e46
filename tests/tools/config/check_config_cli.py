#!/usr/bin/python3
"""Run `sfrt config check` on profiles and check its exit code and exact output.

usage: check_config_cli.py --sfrt BIN --expect ok|errors|mixed PROFILE...

ok:     exit 0; stdout has "<PROFILE>: OK" for each; stderr is empty.
errors: one PROFILE; exit 1; stderr is exactly the profile's "# expect:" lines ({file} = the
        path as given, {dir} = its directory, absolute) followed by
        "sfrt config check: <PROFILE>: N error(s)".
mixed:  exit 1; each ok PROFILE prints OK and each broken one its "N error(s)" line.
"""
import argparse
import os
import subprocess
import sys


def expected_errors(path):
    lines = []
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("# expect: "):
                text = line[len("# expect: "):].rstrip("\n")
                text = text.replace("{file}", path)
                text = text.replace("{dir}", os.path.dirname(os.path.abspath(path)))
                lines.append(text)
    return lines


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--sfrt", required=True)
    p.add_argument("--expect", choices=["ok", "errors", "mixed"], required=True)
    p.add_argument("profiles", nargs="+")
    args = p.parse_args()

    command = [args.sfrt, "config", "check"] + args.profiles
    proc = subprocess.run(command, capture_output=True, text=True, timeout=300)
    print("$ " + " ".join(command))
    print(f"--- exit code {proc.returncode}; stdout:")
    print(proc.stdout, end="")
    print("--- stderr:")
    print(proc.stderr, end="")
    print("---")

    failures = []
    if args.expect == "ok":
        if proc.returncode != 0:
            failures.append(f"exit code {proc.returncode}, expected 0")
        for profile in args.profiles:
            if f"{profile}: OK\n" not in proc.stdout:
                failures.append(f"stdout lacks '{profile}: OK'")
        if proc.stderr:
            failures.append("stderr is not empty")
    elif args.expect == "errors":
        if len(args.profiles) != 1:
            failures.append("--expect errors takes one profile")
        profile = args.profiles[0]
        want = expected_errors(profile)
        if not want:
            failures.append(f"{profile} has no '# expect:' lines")
        n = len(want)
        want.append(f"sfrt config check: {profile}: {n} error" + ("" if n == 1 else "s"))
        got = proc.stderr.splitlines()
        if proc.returncode != 1:
            failures.append(f"exit code {proc.returncode}, expected 1")
        if got != want:
            failures.append("stderr differs from the expected lines:\n  want: " +
                            "\n        ".join(want) + "\n  got:  " + "\n        ".join(got))
        if f"{profile}: OK" in proc.stdout:
            failures.append("stdout says OK")
    else:
        if proc.returncode != 1:
            failures.append(f"exit code {proc.returncode}, expected 1")
        for profile in args.profiles:
            want = expected_errors(profile)
            if want:
                n = len(want)
                line = f"sfrt config check: {profile}: {n} error" + ("" if n == 1 else "s")
                if line not in proc.stderr.splitlines():
                    failures.append(f"stderr lacks '{line}'")
            elif f"{profile}: OK\n" not in proc.stdout:
                failures.append(f"stdout lacks '{profile}: OK'")

    for failure in failures:
        print("FAIL: " + failure)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
