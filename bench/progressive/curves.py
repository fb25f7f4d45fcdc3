#!/usr/bin/env python3
"""curves.py - the progressive drivers' curves from penumbra_bench's progressive.md, as SVG.

For every scene (the case name without its driver suffix) one row of three panels: relative L1
and relative L2 error against the full render versus the percentage of evaluated work pixels
(log-scaled error), and the error versus the time as a fraction of the full render. One line per
driver (dcm, painter, uniform). Dashed lines mark the issue's goal (6% of the pixels, L1 0.008,
L2 0.02, 1/8 of the full render's time).

    python3 bench/progressive/curves.py OUT/progressive.md curves.svg [--only PREFIX]

Python 3 standard library only.
"""
import math
import sys

COLOURS = {"dcm": "#c0392b", "painter": "#2471a3", "uniform": "#7f8c8d"}


def read_rows(path, only):
    """Rows of the table: (scene, driver, percent, l1, l2, seconds, time_over_full)."""
    rows = []
    with open(path, encoding="utf-8") as f:
        for line in f:
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if len(cells) < 8 or cells[0] in ("case", "") or cells[0].startswith("---"):
                continue
            name = cells[0]
            if only and not name.startswith(only):
                continue
            scene, _, driver = name.rpartition("-")
            try:
                pct, l1, l2, sec, frac = (float(cells[i]) for i in (2, 3, 4, 5, 6))
            except ValueError:
                continue
            rows.append((scene, driver, pct, l1, l2, sec, frac))
    return rows


class Panel:
    """A plot box with linear x and log10 y."""

    def __init__(self, x, y, w, h, xr, yr, xlabel, ylabel, title):
        self.x, self.y, self.w, self.h = x, y, w, h
        self.x0, self.x1 = xr
        self.ly0, self.ly1 = math.log10(yr[0]), math.log10(yr[1])
        self.xlabel, self.ylabel, self.title = xlabel, ylabel, title

    def px(self, v):
        return self.x + (v - self.x0) / (self.x1 - self.x0) * self.w

    def py(self, v):
        lv = math.log10(max(v, 10 ** self.ly0))
        return self.y + self.h - (lv - self.ly0) / (self.ly1 - self.ly0) * self.h

    def frame(self, out):
        out.append(f'<rect x="{self.x}" y="{self.y}" width="{self.w}" height="{self.h}" fill="none" stroke="#333"/>')
        out.append(f'<text x="{self.x + self.w / 2}" y="{self.y - 8}" text-anchor="middle" font-size="13">{self.title}</text>')
        out.append(f'<text x="{self.x + self.w / 2}" y="{self.y + self.h + 32}" text-anchor="middle" font-size="11">{self.xlabel}</text>')
        out.append(f'<text x="{self.x - 44}" y="{self.y + self.h / 2}" text-anchor="middle" font-size="11" '
                   f'transform="rotate(-90 {self.x - 44} {self.y + self.h / 2})">{self.ylabel}</text>')
        for k in range(6):
            v = self.x0 + (self.x1 - self.x0) * k / 5
            out.append(f'<text x="{self.px(v):.1f}" y="{self.y + self.h + 14}" text-anchor="middle" font-size="10">{v:g}</text>')
        e = math.floor(self.ly0)
        while e <= self.ly1:
            for m in (1, 2, 5):
                v = m * 10 ** e
                if self.ly0 <= math.log10(v) <= self.ly1:
                    yy = self.py(v)
                    out.append(f'<line x1="{self.x}" y1="{yy:.1f}" x2="{self.x + self.w}" y2="{yy:.1f}" stroke="#ddd"/>')
                    out.append(f'<text x="{self.x - 4}" y="{yy + 3:.1f}" text-anchor="end" font-size="10">{v:g}</text>')
            e += 1

    def guide(self, out, xv=None, yv=None):
        if xv is not None and self.x0 <= xv <= self.x1:
            out.append(f'<line x1="{self.px(xv):.1f}" y1="{self.y}" x2="{self.px(xv):.1f}" y2="{self.y + self.h}" '
                       'stroke="#555" stroke-dasharray="4 3"/>')
        if yv is not None and self.ly0 <= math.log10(yv) <= self.ly1:
            out.append(f'<line x1="{self.x}" y1="{self.py(yv):.1f}" x2="{self.x + self.w}" y2="{self.py(yv):.1f}" '
                       'stroke="#555" stroke-dasharray="4 3"/>')

    def line(self, out, pts, colour):
        pts = sorted(pts)
        path = " ".join(f"{self.px(a):.1f},{self.py(b):.1f}" for a, b in pts if self.x0 <= a <= self.x1)
        out.append(f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="1.6"/>')
        for a, b in pts:
            if self.x0 <= a <= self.x1:
                out.append(f'<circle cx="{self.px(a):.1f}" cy="{self.py(b):.1f}" r="2.2" fill="{colour}"/>')


def main(argv):
    if len(argv) < 3:
        sys.stderr.write(__doc__)
        return 2
    only = argv[argv.index("--only") + 1] if "--only" in argv else ""
    rows = read_rows(argv[1], only)
    if not rows:
        sys.stderr.write(f"{argv[1]}: no progressive rows\n")
        return 1
    scenes = sorted({r[0] for r in rows}, key=lambda s: [r[0] for r in rows].index(s))
    errs = [v for r in rows for v in (r[3], r[4]) if v > 0]
    yr = (10 ** math.floor(math.log10(min(errs + [0.008]))), 10 ** math.ceil(math.log10(max(errs))))
    fr_max = max(0.7, max(r[6] for r in rows))
    W, PH, PW = 1080, 230, 270
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{60 + len(scenes) * (PH + 80)}" '
           'font-family="sans-serif">', '<rect width="100%" height="100%" fill="white"/>']
    lx = 80
    for d, c in COLOURS.items():
        out.append(f'<line x1="{lx}" y1="20" x2="{lx + 24}" y2="20" stroke="{c}" stroke-width="2"/>')
        out.append(f'<text x="{lx + 30}" y="24" font-size="12">{d}</text>')
        lx += 110
    out.append(f'<text x="{lx + 20}" y="24" font-size="11">dashed: goal (6%, L1 0.008, L2 0.02, 1/8 of the full time)</text>')
    for si, scene in enumerate(scenes):
        top = 70 + si * (PH + 80)
        panels = [Panel(90, top, PW, PH, (0, 50), yr, "evaluated work pixels (%)", "rel L1", f"{scene}: rel L1"),
                  Panel(90 + PW + 90, top, PW, PH, (0, 50), yr, "evaluated work pixels (%)", "rel L2", f"{scene}: rel L2"),
                  Panel(90 + 2 * (PW + 90), top, PW, PH, (0, fr_max), yr, "time / full render", "rel L1",
                        f"{scene}: rel L1 vs time")]
        for p in panels:
            p.frame(out)
        panels[0].guide(out, 6, 0.008)
        panels[1].guide(out, 6, 0.02)
        panels[2].guide(out, 1 / 8, 0.008)
        for d, c in COLOURS.items():
            rs = [r for r in rows if r[0] == scene and r[1] == d]
            if not rs:
                continue
            panels[0].line(out, [(r[2], r[3]) for r in rs], c)
            panels[1].line(out, [(r[2], r[4]) for r in rs], c)
            panels[2].line(out, [(r[6], r[3]) for r in rs], c)
    out.append("</svg>")
    with open(argv[2], "w", encoding="utf-8") as f:
        f.write("\n".join(out) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
