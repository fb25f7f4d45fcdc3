#!/usr/bin/env python3
"""beyond_table.py — the equal-relMSE table of bench/ias/beyond.py, from its logs.

    bench/ias/beyond_table.py LOG [LOG ...]

Reads the per-render lines ("SCENE METHOD level K: T s CPU  relMSE E  peak M MB"); a scene measured
and method measured in a later log replaces the earlier measurement (a re-run after a change).

The target relMSE of a scene is the default ias's at its more accurate level, so that ias's time is
measured, not modelled. A fixed-spp baseline's time at the target comes from its two levels
through the model of fixed-spp Monte Carlo, time = a + b / relMSE (a: loading and building, b: the
cost of precision; relMSE falls as 1/spp), which extrapolates soundly. The paper variant, whose
relMSE does not fall as 1/cost, is read on its log-log line only between its two levels; outside
them its time is given as a bound ("<= t" when both its levels are already more accurate, "> t"
when neither is). The ratio is the best baseline's time over ias's.
"""
import math
import re
import sys

BASELINES = ("ref", "bvh")
LINE = re.compile(r"^(\S+)\s+(\S+)\s+level (\d): +([0-9.]+) s CPU +relMSE ([0-9.eE+-]+) +peak (\d+) MB")


def fixed_spp_time(points, target):
    """t = a + b / e through the two (t, e) points, at e = target."""
    (t0, e0), (t1, e1) = points
    if e0 == e1:
        return float("nan")
    b = (t1 - t0) / (1.0 / e1 - 1.0 / e0)
    a = t0 - b / e0
    return a + b / target


def loglog_time(points, target):
    """(time, relation): the log-log line between the two points, or a bound outside them."""
    (t0, e0), (t1, e1) = points
    lo, hi = min(e0, e1), max(e0, e1)
    if target < lo:
        return max(t0, t1), ">"
    if target > hi:
        return (t0 if e0 >= e1 else t1) if e0 != e1 else min(t0, t1), "<="
    if e0 == e1:
        return min(t0, t1), "="
    slope = (math.log(t1) - math.log(t0)) / (math.log(e1) - math.log(e0))
    return math.exp(math.log(t0) + slope * (math.log(target) - math.log(e0))), "="


def read(paths):
    scenes, order = {}, []
    for path in paths:
        seen_here = set()
        for line in open(path):
            m = LINE.match(line)
            if not m:
                continue
            name, method, k, t, e, mem = m.groups()
            if name not in order:
                order.append(name)
            if (name, method) not in seen_here:  # a later log's measurement replaces an earlier one
                seen_here.add((name, method))
                scenes.setdefault(name, {})[method] = {"pts": [None, None], "mem": 0}
            entry = scenes[name][method]
            entry["pts"][int(k)] = (float(t), float(e))
            entry["mem"] = max(entry["mem"], int(mem))
    return scenes, order


def table(scenes, order):
    methods = []
    for name in order:
        for meth in scenes[name]:
            if meth not in methods:
                methods.append(meth)
    out = []
    head = "| scene | ias relMSE (target) | ias CPU s | " + " | ".join(
        f"{m} CPU s" for m in methods if m != "ias") + " | best baseline / ias | ias peak MB |"
    out.append(head)
    out.append("|" + "---|" * (head.count("|") - 1))
    for name in order:
        d = scenes[name]
        if "ias" not in d or None in d["ias"]["pts"]:
            continue
        t_ias, target = min(d["ias"]["pts"], key=lambda p: p[1])
        cells, base = [], []
        for m in methods:
            if m == "ias":
                continue
            if m not in d or None in d[m]["pts"]:
                cells.append("—")
                continue
            if m in BASELINES:
                t = fixed_spp_time(d[m]["pts"], target)
                base.append(t)
                cells.append(f"{t:.3g}")
            else:
                t, rel = loglog_time(d[m]["pts"], target)
                cells.append(f"{rel if rel != '=' else ''}{t:.3g}")
        best = min(base) if base else float("nan")
        out.append(f"| {name} | {target:.3g} | {t_ias:.3g} | " + " | ".join(cells) +
                   f" | {best / t_ias:.2f}× | {d['ias']['mem']} |")
    return "\n".join(out)


def main():
    scenes, order = read(sys.argv[1:])
    print(table(scenes, order))


if __name__ == "__main__":
    main()
