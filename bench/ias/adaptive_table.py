#!/usr/bin/env python3
"""adaptive_table.py — the equal-relMSE table of bench/ias/adaptive.sh's output: for every threshold
render, the CPU seconds that fixed --spp needs for the same relMSE (log-log interpolation between the
two bracketing --spp renders; '>' or '<' marks an extrapolation from the nearest two) and the speed-up
of threshold mode over it (> 1: threshold mode is faster).

    bench/ias/adaptive_table.py OUT_DIR/*.txt
"""
import math
import re
import sys

LINE = re.compile(r"^(\S+)\s+(\S+)\s+cpu\s+(\S+)\s+relmse\s+(\S+)\s+rel_l1\s+(\S+)\s+dmean\s+(\S+)%")


def fixed_cpu_at(points, e):
    """CPU seconds of fixed spp at relMSE e, from (relmse, cpu) points, log-log."""
    pts = sorted((p for p in points if p[0] > 0 and p[1] > 0), key=lambda p: -p[0])  # relMSE falling
    if len(pts) < 2:
        return None, ""
    mark = ""
    for a, b in zip(pts, pts[1:]):
        if a[0] >= e >= b[0]:
            break
    else:
        a, b = (pts[0], pts[1]) if e > pts[0][0] else (pts[-2], pts[-1])
        mark = "<" if e > pts[0][0] else ">"
    x = (math.log(e) - math.log(a[0])) / (math.log(b[0]) - math.log(a[0]))
    return math.exp(math.log(a[1]) + x * (math.log(b[1]) - math.log(a[1]))), mark


def main(paths):
    print("| scene | mode | CPU s | relMSE | rel L1 | mean lum. | fixed spp CPU s at that relMSE | speed-up |")
    print("|---|---|---|---|---|---|---|---|")
    for path in paths:
        rows = [m.groups() for m in map(LINE.match, open(path)) if m]
        fixed = [(float(r[3]), float(r[2])) for r in rows if r[1].startswith("spp=")]
        for name, tag, cpu, rel, l1, dm in rows:
            if tag == "ref-seed2":
                print(f"| {name} | second seed of the converged render | | {float(rel):.2e} | {float(l1):.4f} | {dm}% | | |")
                continue
            line = f"| {name} | {tag} | {float(cpu):.2f} | {float(rel):.2e} | {float(l1):.4f} | {dm}% |"
            if tag.startswith("spp="):
                print(line + " | |")
                continue
            f, mark = fixed_cpu_at(fixed, float(rel))
            if f is None or float(cpu) <= 0:
                print(line + " | |")
            else:
                print(line + f" {mark}{f:.2f} | {f / float(cpu):.2f}x |")


if __name__ == "__main__":
    main(sys.argv[1:])
