#!/usr/bin/python3
"""roofline_acceptance.py's verdicts on made-up `sfrt bench --json` results: the bar held and
missed on AMX, no AMX, and a step faster than its unit's peak (the peak's measurement disturbed),
which holds nothing however good the ratio; and the exit codes they give."""

import importlib.util
import sys

sys.dont_write_bytecode = True
spec = importlib.util.spec_from_file_location("roofline_acceptance", sys.argv[1])
ra = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ra)


def result(unit, ratio, shares):
    steps = [{"layers": f"conv{k}"} for k in range(len(shares))]
    points = [{"unit": u, "share_of_roof": share} for u, share in shares]
    return {"steps": steps, "roofline": {"main_unit": unit, "median_over_main_floor": ratio,
                                         "steps": points}}


failures = []


def expect(what, got, want):
    if got != want:
        failures.append(f"{what}: got {got!r}, want {want!r}")


amx = "amx int8"
expect("ratio under the bar", ra.verdict("int8", result(amx, 1.6, [(amx, 0.6)]), 2.0)[0], "held")
expect("ratio over the bar", ra.verdict("int8", result(amx, 2.4, [(amx, 0.4)]), 2.0)[0], "missed")
expect("no AMX", ra.verdict("int8", result("int8 vnni", 1.1, [("int8 vnni", 0.9)]), 2.0)[0],
       "no-amx")
status, text = ra.verdict("bf16", result("amx bf16", 0.55, [("amx bf16", 1.9), ("memory", None)]),
                          2.0)
expect("a step at 190% of its peak", status, "disturbed")
expect("the disturbed verdict names the step", "conv0 ran at 190%" in text, True)
expect("memory steps beyond the measured bandwidth (cached data) disturb nothing",
       ra.verdict("int8", result(amx, 1.5, [(amx, 0.7), ("memory", 1.4)]), 2.0)[0], "held")
expect("exit: all held or no AMX", ra.exit_code(["held", "no-amx"]), 0)
expect("exit: one missed", ra.exit_code(["held", "missed", "disturbed"]), ra.EXIT_BAR_MISSED)
expect("exit: one disturbed", ra.exit_code(["held", "disturbed"]), ra.EXIT_PEAK_DISTURBED)

for f in failures:
    print("FAIL:", f)
print("PASS" if not failures else f"{len(failures)} failures")
sys.exit(1 if failures else 0)
