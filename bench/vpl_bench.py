#!/usr/bin/env python3
"""vpl_bench.py — IlluminationCut (Bus et al. 2015) Table 1, Table 5 and Fig. 5 at a size the 2-core
machine can afford an all-VPL reference for.

For each scene: the `vpl` reference (every point against every VPL), then lightcuts (1%),
illumcut (1.5%) and illumcut with adaptive visibility sampling (1%), all from the same VPL set
(same seed); render and preprocessing time, shadow rays and L_UB evaluations per pixel, RMSE and
relative error against `vpl`, peak memory. Then render time against the VPL count (Fig. 5) on the
first scene, without a reference. Every render is a separate `penumbra render` process, so the
peak memory is that render's.

usage: bench/vpl_bench.py [--build DIR] [--out DIR] [--scale F] [--vpls N] [--threads N]
                          [--scenes a,b,c] [--scaling 5000,20000,...] [--spp N]
Writes OUT/vpl-bench.md (tables) and OUT/vpl-bench.json (every number).
"""
import argparse
import json
import os
import struct
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.normpath(os.path.join(HERE, "..", "..", "shared"))

METHODS = [
    ("LC(1%)", ["--integrator", "lightcuts", "--error", "0.01"]),
    ("IC(1.5%)", ["--integrator", "illumcut", "--error", "0.015"]),
    ("IC-S(1%)", ["--integrator", "illumcut", "--error", "0.01", "--visibility", "sampling"]),
]


def read_pfm(path):
    with open(path, "rb") as f:
        f.readline()
        w, h = (int(x) for x in f.readline().split())
        scale = float(f.readline())
        data = f.read()
    fmt = ("<" if scale < 0 else ">") + "%df" % (w * h * 3)
    return w, h, struct.unpack(fmt, data)


def mean_relative_error(ref, img):
    """Mean over pixels of |a - b| / b in luminance, pixels with b above 1% of the mean."""
    _, _, r = ref
    _, _, a = img
    n = len(r) // 3
    lum = lambda v, i: 0.2126 * v[3 * i] + 0.7152 * v[3 * i + 1] + 0.0722 * v[3 * i + 2]
    lr = [lum(r, i) for i in range(n)]
    mean = sum(lr) / max(1, n)
    s, m = 0.0, 0
    for i in range(n):
        if lr[i] > 0.01 * mean:
            s += abs(lum(a, i) - lr[i]) / lr[i]
            m += 1
    return s / max(1, m)


def flat_stats(stats_path):
    with open(stats_path) as f:
        j = json.load(f)
    out = {}

    def walk(d):
        for k, v in d.items():
            if isinstance(v, dict):
                walk(v)
            elif not isinstance(v, list):
                out.setdefault(k, v)

    walk(j)
    return out


def run(penumbra, scene, out, args, common):
    cmd = [penumbra, "render", scene, "-o", out + ".pfm", "--stats", out + ".json", "--quiet"] + common + args
    t0 = time.time()
    subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
    st = flat_stats(out + ".json")
    st["wall_seconds"] = time.time() - t0
    return st


def diff(penumbra, ref, img):
    p = subprocess.run([penumbra, "diff", "--json", ref, img], check=True, capture_output=True, text=True)
    return json.loads(p.stdout)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default="build")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "vpl"))
    ap.add_argument("--scale", type=float, default=0.09, help="fraction of each scene's film resolution")
    ap.add_argument("--vpls", type=int, default=20000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--scenes", default="bathroom,staircase,living-room")
    ap.add_argument("--scaling", default="5000,20000,80000,320000")
    ap.add_argument("--resolution-sweep", default="", help="scales for a resolution sweep of the first scene")
    a = ap.parse_args()
    penumbra = os.path.join(a.build, "penumbra")
    os.makedirs(a.out, exist_ok=True)
    results = {"scale": a.scale, "vpls": a.vpls, "spp": a.spp, "threads": a.threads, "scenes": {}, "scaling": {}}
    lines = ["# IlluminationCut bench (%g of the film resolution, %d spp, %d VPLs, %d threads)" % (a.scale, a.spp, a.vpls, a.threads), ""]

    def common_for(scene):
        info = subprocess.run([penumbra, "info", scene], capture_output=True, text=True).stdout
        film = [l for l in info.splitlines() if l.startswith("film")][0].split()[1]
        fw, fh = (int(x) for x in film.split("x"))
        res = "%dx%d" % (max(1, round(fw * a.scale)), max(1, round(fh * a.scale)))
        return res, ["--resolution", res, "--threads", str(a.threads), "--seed", "0", "--spp", str(a.spp)]

    lines.append("Table 1 (ours). Speed-up: LC render time / method render time.")
    lines.append("")
    lines.append("| scene | method | preproc s | render s | shadow rays/px | bounds/px | RMSE | rel. error | speed-up | peak MiB |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|")
    for s in a.scenes.split(","):
        scene = os.path.join(SHARED, "scenes", s, s + ".pbrt")
        res, common = common_for(scene)
        base = os.path.join(a.out, "%s-%s" % (s, res))
        vcount = ["--vpls", str(a.vpls)]
        ref = run(penumbra, scene, base + "-vpl", ["--integrator", "vpl"] + vcount, common)
        row = {"vpl": ref}
        refimg = read_pfm(base + "-vpl.pfm")
        lines.append("| %s %s | all VPLs | %.2f | %.2f | %.0f | - | 0 | 0 | - | %.0f |" % (
            s, res, ref["preprocess_seconds"], ref["render_seconds"], ref["shadow_rays_per_pixel_mean"],
            ref["peak_memory_bytes"] / 2**20))
        lc_time = None
        for name, args in METHODS:
            tag = name.split("(")[0].lower()
            st = run(penumbra, scene, base + "-" + tag, args + vcount, common)
            d = diff(penumbra, base + "-vpl.pfm", base + "-" + tag + ".pfm")
            st["rmse"] = d["rmse"]
            st["rel_l1"] = d["rel_l1"]
            st["mean_relative_error"] = mean_relative_error(refimg, read_pfm(base + "-" + tag + ".pfm"))
            if lc_time is None:
                lc_time = st["render_seconds"]
            st["speedup"] = lc_time / st["render_seconds"] if st["render_seconds"] > 0 else 0.0
            row[name] = st
            lines.append("| %s | %s | %.2f | %.2f | %.0f | %.0f | %.5f | %.4f | %.2f | %.0f |" % (
                s, name, st["preprocess_seconds"], st["render_seconds"], st["shadow_rays_per_pixel_mean"],
                st["bound_evaluations_per_pixel_mean"], st["rmse"], st["mean_relative_error"], st["speedup"],
                st["peak_memory_bytes"] / 2**20))
            print(lines[-1], flush=True)
        results["scenes"][s] = row
    # Fig. 5: render time against the VPL count (first scene, no reference).
    s = a.scenes.split(",")[0]
    scene = os.path.join(SHARED, "scenes", s, s + ".pbrt")
    res, common = common_for(scene)
    lines += ["", "Fig. 5 (ours): render seconds against the VPL count, %s at %s." % (s, res), ""]
    lines.append("| VPLs | " + " | ".join(n for n, _ in METHODS) + " | preproc s | peak MiB (IC) |")
    lines.append("|---" * (len(METHODS) + 3) + "|")
    for n in [int(x) for x in a.scaling.split(",") if x]:
        base = os.path.join(a.out, "%s-%s-n%d" % (s, res, n))
        times, pre, mem = [], 0.0, 0.0
        for name, args in METHODS:
            tag = name.split("(")[0].lower()
            st = run(penumbra, scene, base + "-" + tag, args + ["--vpls", str(n)], common)
            times.append(st["render_seconds"])
            pre = st["preprocess_seconds"]
            if tag == "ic":
                mem = st["peak_memory_bytes"] / 2**20
            results["scaling"].setdefault(str(n), {})[name] = st
        lines.append("| %d | " % n + " | ".join("%.2f" % t for t in times) + " | %.2f | %.0f |" % (pre, mem))
        print(lines[-1], flush=True)
    # Amortisation against resolution: the same view at growing resolution (no reference).
    sweep = [float(x) for x in a.resolution_sweep.split(",") if x]
    if sweep:
        lines += ["", "Resolution sweep (ours), %s, %d VPLs: render s, shadow rays/px, bounds/px." % (s, a.vpls), ""]
        lines.append("| resolution | " + " | ".join(n for n, _ in METHODS) + " | IC speed-up | IC-S speed-up |")
        lines.append("|---" * (len(METHODS) + 3) + "|")
        saved = a.scale
        for f in sweep:
            a.scale = f
            res, common = common_for(scene)
            cells, times = [], []
            for name, args in METHODS:
                tag = name.split("(")[0].lower()
                st = run(penumbra, scene, os.path.join(a.out, "%s-%s-sweep-%s" % (s, res, tag)), args + ["--vpls", str(a.vpls)], common)
                times.append(st["render_seconds"])
                cells.append("%.2f s, %.0f, %.0f" % (st["render_seconds"], st["shadow_rays_per_pixel_mean"],
                                                   st["bound_evaluations_per_pixel_mean"]))
                results.setdefault("sweep", {}).setdefault(res, {})[name] = st
            lines.append("| %s | " % res + " | ".join(cells) + " | %.2f | %.2f |" % (times[0] / times[1], times[0] / times[2]))
            print(lines[-1], flush=True)
        a.scale = saved
    with open(os.path.join(a.out, "vpl-bench.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(a.out, "vpl-bench.json"), "w") as f:
        json.dump(results, f, indent=1)
    print("\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())
