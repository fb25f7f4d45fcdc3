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

Large images (--crop-reference x0,x1,y0,y1): the all-VPL reference costs a full all-pairs sum per
pixel, so at realistic sizes it is rendered on a crop window only (`--crop`, pbrt's rounding:
pixels ceil(res * fraction)); the methods render the whole image and are compared on the same
window, cut out of their images. `vpl` shades each pixel on its own, so its crop equals the same
pixels of its full image (--verify-crop SCALE checks this at a small scale). With --repeats N the
methods run in alternation (LC, IC, IC-S, LC, IC, IC-S, ...) and each speed-up is the median over
the rounds of the ratio within a round (the machine is shared: absolute times drift, ratios of
neighbouring runs less). --compare NAME=DIR adds the illumcut methods of another build (e.g.
the code before a change) to the same rounds. Peak memory: the render's getrusage maximum RSS
(stats) and /usr/bin/time's for the whole process.

Equal RMSE (--equal-rmse, with --crop-reference): each method is run at every error parameter of
--sweep (e.g. "LC=0.005,0.01,0.02;IC=0.015,0.03;IC-S=0.01,0.02"), the levels interleaved (the
first level of every method, then the second, ...), and its render CPU time is interpolated
log-log in the crop's RMSE at common targets, the RMSE of lightcuts at 1% and of illumcut at 1.5%
when those levels are in the sweep (then the same for the mean relative error). A target outside
a method's range is not extrapolated: the time is given as a bound (">" the time of its most
accurate level when the target is below all its errors, "<" that of its least accurate level when
above), and so is the ratio. --reference-dir reuses the vpl crop references of an earlier run
(same scene, resolution, VPLs and crop; file names as this script writes them); --reuse reuses
the runs already in --out (an interrupted sweep).

Full pixel density, cheaply (--render-crop x0,x1,y0,y1, with --equal-rmse): the methods render only
this window of the film at --scale (e.g. 1.0, the paper's pixel density: the point tree of illumcut
then holds the same points per unit of surface as a full render, over a smaller part of the scene),
and the RMSE is taken on the --crop-reference window cut out of it; that window must lie inside the
render window, with a margin so that the point clusters of its pixels are not cut by the border.
Every method and the reference see the same pixels; all times are of the render window only.
"""
import argparse
import json
import math
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


def env_for(penumbra):
    """The build's own libpenumbra first (the binaries have a RUNPATH, which LD_LIBRARY_PATH
    overrides), so that copies of older builds run with their own library."""
    env = dict(os.environ)
    env["LD_LIBRARY_PATH"] = os.path.dirname(os.path.abspath(penumbra))
    return env


def loadavg():
    try:
        with open("/proc/loadavg") as f:
            return float(f.read().split()[0])
    except OSError:
        return -1.0


def run(penumbra, scene, out, args, common):
    # The bench measures global illumination through VPLs, as it always has: the shared scenes say
    # Integrator maxdepth 1, which penumbra would otherwise read as direct light only.
    if "--vpl-depth" not in args + common and "--vpl-direct-only" not in args + common:
        args = args + ["--vpl-depth", "10"]
    cmd = [penumbra, "render", scene, "-o", out + ".pfm", "--stats", out + ".json", "--quiet"] + common + args
    timed = os.path.exists("/usr/bin/time")
    if timed:
        cmd = ["/usr/bin/time", "-f", "%M %U %S", "-o", out + ".rss"] + cmd
    load0 = loadavg()
    t0 = time.time()
    subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL, env=env_for(penumbra))
    st = flat_stats(out + ".json")
    st["wall_seconds"] = time.time() - t0
    st["load_before"] = load0
    st["load_after"] = loadavg()
    if timed:
        with open(out + ".rss") as f:
            rss, user, sys_ = f.read().split()[-3:]
        st["max_rss_bytes"] = int(rss) * 1024
        st["cpu_seconds"] = float(user) + float(sys_)
    return st


def overhead_cpu(penumbra, scene, out, vpls, common):
    """CPU seconds of everything but the render (parse, BVH, VPLs, light tree, image output): a
    lightcuts render of one pixel with the same scene and VPLs. Subtracted from each process's
    CPU time to give the render's CPU time."""
    c = list(common)
    c[c.index("--resolution") + 1] = "1x1"
    st = run(penumbra, scene, out + "-overhead", ["--integrator", "lightcuts", "--vpls", str(vpls)], c)
    return st.get("cpu_seconds", 0.0)


def write_pfm(path, w, h, data):
    with open(path, "wb") as f:
        f.write(b"PF\n%d %d\n-1.0\n" % (w, h))
        f.write(struct.pack("<%df" % (w * h * 3), *data))


def crop_bounds(size, f0, f1):
    """Pixel range [ceil(size * f0), ceil(size * f1)) in float32 arithmetic, as the renderer."""
    f32 = lambda x: struct.unpack("<f", struct.pack("<f", x))[0]
    import math
    return int(math.ceil(f32(f32(float(size)) * f32(f0)))), int(math.ceil(f32(f32(float(size)) * f32(f1))))


def cut_window(img, crop):
    """The crop window of a full image (PFM rows run bottom to top)."""
    w, h, d = img
    x0, x1 = crop_bounds(w, crop[0], crop[1])
    y0, y1 = crop_bounds(h, crop[2], crop[3])
    out = []
    for row in range(h - y1, h - y0):  # file rows of image rows y1-1 .. y0
        out.extend(d[3 * (row * w + x0):3 * (row * w + x1)])
    return x1 - x0, y1 - y0, out


def cut_window_of_crop(img, full, render_crop, crop):
    """The reference window `crop` (fractions of the full film `full` = (w, h)) cut out of an image
    rendered on the window `render_crop` of the same film: both windows are rounded to pixels as the
    renderer rounds them, and the reference window must lie inside the render window."""
    w, h, d = img
    rx0, rx1 = crop_bounds(full[0], render_crop[0], render_crop[1])
    ry0, ry1 = crop_bounds(full[1], render_crop[2], render_crop[3])
    x0, x1 = crop_bounds(full[0], crop[0], crop[1])
    y0, y1 = crop_bounds(full[1], crop[2], crop[3])
    if (w, h) != (rx1 - rx0, ry1 - ry0) or not (rx0 <= x0 < x1 <= rx1 and ry0 <= y0 < y1 <= ry1):
        raise SystemExit("reference window %s is not inside the render window %s" % (crop, render_crop))
    out = []
    for yy in range(y1 - 1, y0 - 1, -1):  # PFM rows run bottom to top: file row of image row yy
        row = (ry1 - 1) - yy
        out.extend(d[3 * (row * w + (x0 - rx0)):3 * (row * w + (x1 - rx0))])
    return x1 - x0, y1 - y0, out


def diff(penumbra, ref, img):
    p = subprocess.run([penumbra, "diff", "--json", ref, img], check=True, capture_output=True, text=True,
                       env=env_for(penumbra))
    return json.loads(p.stdout)


def median(v):
    v = sorted(v)
    n = len(v)
    return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


def verify_crop(a, penumbra, scene, common_for, crop):
    """vpl's crop against the same window of its full image, at a small scale: the pixels must be
    identical for the crop reference to stand for the full one."""
    saved = a.scale
    a.scale = a.verify_crop
    res, common = common_for(scene)
    a.scale = saved
    base = os.path.join(a.out, "verify-crop-%s" % res)
    vc = ["--integrator", "vpl", "--vpls", str(min(a.vpls, 20000))]
    run(penumbra, scene, base + "-full", vc, common)
    run(penumbra, scene, base + "-crop", vc + ["--crop", ",".join("%g" % c for c in crop)], common)
    full = cut_window(read_pfm(base + "-full.pfm"), crop)
    part = read_pfm(base + "-crop.pfm")
    same = (full[0], full[1]) == (part[0], part[1]) and list(full[2]) == list(part[2])
    return res, "%dx%d" % (part[0], part[1]), same


def realistic(a, penumbra, common_for, lines, results):
    """Full-size renders of every method against a crop reference, in alternating rounds."""
    crop = [float(x) for x in a.crop_reference.split(",")]
    methods = [(name, penumbra, args) for name, args in METHODS]
    for spec in [c for c in a.compare.split(",") if c]:
        tag, d = spec.split("=", 1)
        methods += [("%s %s" % (name, tag), os.path.join(d, "penumbra"), args) for name, args in METHODS[1:]]
    vcount = ["--vpls", str(a.vpls)]
    lines.append("Full-size renders against a crop reference (window %s of the image), %d VPLs, %d round(s) "
                 "in alternation; render s = median (all runs); render CPU s = the process's user + system time "
                 "minus that of a 1x1 lightcuts render with the same VPLs (parse, BVH, VPLs, tree); speed-up = "
                 "median over rounds of LC's time / the method's in the same round (wall, CPU); phase I / II s "
                 "and the counters are from the first round." % (a.crop_reference, a.vpls, a.repeats))
    lines.append("")
    lines.append("| scene | method | render s | render CPU s | preproc s | phase I / II s | shadow rays/px | bounds/px "
                 "| RMSE (crop) | rel. error (crop) | speed-up (wall) | speed-up (CPU) | peak MiB (render) | max RSS MiB | load |")
    lines.append("|---" * 15 + "|")
    for s in a.scenes.split(","):
        scene = os.path.join(SHARED, "scenes", s, s + ".pbrt")
        if a.verify_crop > 0:
            vres, wsize, same = verify_crop(a, penumbra, scene, common_for, crop)
            lines.append("| %s %s | vpl crop %s = full image's window: %s | | | | | | | | | | | | | |" % (
                s, vres, wsize, "identical" if same else "DIFFERENT"))
            print(lines[-1], flush=True)
        res, common = common_for(scene)
        base = os.path.join(a.out, "%s-%s-n%d" % (s, res, a.vpls))
        cropargs = ["--crop", ",".join("%g" % c for c in crop)]
        ref = run(penumbra, scene, base + "-vpl-crop", ["--integrator", "vpl"] + vcount + cropargs, common)
        refimg = read_pfm(base + "-vpl-crop.pfm")
        row = {"vpl_crop": ref, "runs": {}}
        lines.append("| %s %s | all VPLs (crop %dx%d) | %.2f | - | %.2f | - | %.0f | - | 0 | 0 | - | - | %.0f | %.0f | %.1f |" % (
            s, res, refimg[0], refimg[1], ref["render_seconds"], ref["preprocess_seconds"],
            ref["shadow_rays_per_pixel_mean"], ref["peak_memory_bytes"] / 2**20, ref.get("max_rss_bytes", 0) / 2**20,
            ref["load_before"]))
        print(lines[-1], flush=True)
        over = overhead_cpu(penumbra, scene, base, a.vpls, common)
        runs = {name: [] for name, _, _ in methods}
        for k in range(a.repeats):
            for name, binary, args in methods:
                tag = name.replace("(", "").replace(")", "").replace("%", "").replace(" ", "-").replace(".", "").lower()
                out = base + "-" + tag
                st = run(binary, scene, out, args + vcount, common)
                if k == 0:
                    w = cut_window(read_pfm(out + ".pfm"), crop)
                    write_pfm(out + "-window.pfm", *w)
                    d = diff(penumbra, base + "-vpl-crop.pfm", out + "-window.pfm")
                    st["rmse_crop"] = d["rmse"]
                    st["mean_relative_error_crop"] = mean_relative_error(refimg, w)
                st["render_cpu_seconds"] = st.get("cpu_seconds", 0.0) - over
                runs[name].append(st)
                print("  round %d %s %s: %.2f s, %.1f CPU s (load %.1f)" % (
                    k, s, name, st["render_seconds"], st["render_cpu_seconds"], st["load_before"]), flush=True)
        lc = runs[METHODS[0][0]]
        for name, _, _ in methods:
            r = runs[name]
            first = r[0]
            ratios = [lc[k]["render_seconds"] / r[k]["render_seconds"] for k in range(len(r))]
            times = [x["render_seconds"] for x in r]
            cpu = [x["render_cpu_seconds"] for x in r]
            cratios = [lc[k]["render_cpu_seconds"] / r[k]["render_cpu_seconds"] for k in range(len(r))]
            lines.append("| %s | %s | %.2f (%s) | %.1f (%s) | %.2f | %.2f / %.2f | %.0f | %.0f | %.5f | %.4f | %.2f (%s) | %.2f (%s) | %.0f | %.0f | %.1f-%.1f |" % (
                s, name, median(times), ", ".join("%.1f" % t for t in times), median(cpu), ", ".join("%.1f" % t for t in cpu),
                first["preprocess_seconds"],
                first.get("phase1_seconds", 0), first.get("phase2_seconds", 0), first["shadow_rays_per_pixel_mean"],
                first["bound_evaluations_per_pixel_mean"], first["rmse_crop"], first["mean_relative_error_crop"],
                median(ratios), ", ".join("%.2f" % x for x in ratios), median(cratios), ", ".join("%.2f" % x for x in cratios),
                max(x["peak_memory_bytes"] for x in r) / 2**20,
                max(x.get("max_rss_bytes", 0) for x in r) / 2**20, min(x["load_before"] for x in r),
                max(x["load_before"] for x in r)))
            print(lines[-1], flush=True)
        row["runs"] = runs
        results["scenes"][s] = row


def scaling(a, penumbra, common_for, lines, results):
    """Render time and peak memory against the VPL count, alternating the methods per count."""
    s = a.scenes.split(",")[0]
    scene = os.path.join(SHARED, "scenes", s, s + ".pbrt")
    saved = a.scale
    a.scale = a.scaling_scale if a.scaling_scale > 0 else a.scale
    res, common = common_for(scene)
    a.scale = saved
    methods = [(n, args) for n, args in METHODS if n.split("(")[0] in a.scaling_methods.split(",")]
    lines += ["", "Render s (median of %d alternating rounds) and peak memory against the VPL count, %s at %s." % (
        a.repeats, s, res), ""]
    lines.append("| VPLs | " + " | ".join("%s s | %s CPU s | %s MiB" % (n, n, n) for n, _ in methods) +
                 " | preproc s | " + " | ".join("speed-up %s (wall / CPU)" % n for n, _ in methods[1:]) + " | load |")
    lines.append("|---" * (4 * len(methods) + 2) + "|")
    for n in [int(x) for x in a.scaling.split(",") if x]:
        base = os.path.join(a.out, "%s-%s-n%d" % (s, res, n))
        over = overhead_cpu(penumbra, scene, base, n, common)
        runs = {name: [] for name, _ in methods}
        for k in range(a.repeats):
            for name, args in methods:
                tag = name.split("(")[0].lower()
                st = run(penumbra, scene, base + "-" + tag, args + ["--vpls", str(n)], common)
                st["render_cpu_seconds"] = st.get("cpu_seconds", 0.0) - over
                runs[name].append(st)
                print("  %d VPLs round %d %s: %.2f s, %.1f CPU s (load %.1f)" % (
                    n, k, name, st["render_seconds"], st["render_cpu_seconds"], st["load_before"]), flush=True)
        cells = []
        for name, _ in methods:
            cells.append("%.2f" % median([x["render_seconds"] for x in runs[name]]))
            cells.append("%.1f" % median([x["render_cpu_seconds"] for x in runs[name]]))
            cells.append("%.0f" % (max(x.get("max_rss_bytes", x["peak_memory_bytes"]) for x in runs[name]) / 2**20))
        ratio = []
        for name, _ in methods[1:]:
            ratio.append("%.2f / %.2f" % (
                median([runs[methods[0][0]][k]["render_seconds"] / runs[name][k]["render_seconds"] for k in range(a.repeats)]),
                median([runs[methods[0][0]][k]["render_cpu_seconds"] / runs[name][k]["render_cpu_seconds"]
                        for k in range(a.repeats)])))
        loads = [x["load_before"] for r in runs.values() for x in r]
        lines.append("| %d | " % n + " | ".join(cells) + " | %.2f | " % runs[methods[0][0]][0]["preprocess_seconds"] +
                     " | ".join(ratio) + " | %.1f-%.1f |" % (min(loads), max(loads)))
        print(lines[-1], flush=True)
        results["scaling"][str(n)] = runs


METHOD_ARGS = {
    "LC": ["--integrator", "lightcuts"],
    "IC": ["--integrator", "illumcut"],
    "IC-S": ["--integrator", "illumcut", "--visibility", "sampling"],
}


def loglog_at(points, target):
    """CPU time at RMSE `target` by log-log interpolation over points [(error, rmse, cpu)], taken
    in order of the error parameter; returns (cpu, mark): mark "" when interpolated, ">" when the
    target is below every RMSE of the sweep (cpu is then the time of the most accurate point, a
    lower bound), "<" when it is above every RMSE (cpu is the time of the least accurate point,
    an upper bound)."""
    pts = sorted(points)
    if not pts:
        return float("nan"), "?"
    for (e0, r0, c0), (e1, r1, c1) in zip(pts, pts[1:]):
        if r0 == target:
            return c0, ""
        if min(r0, r1) <= target <= max(r0, r1) and r0 != r1:
            t = (math.log(target) - math.log(r0)) / (math.log(r1) - math.log(r0))
            return math.exp(math.log(c0) + t * (math.log(c1) - math.log(c0))), ""
    if pts[-1][1] == target:
        return pts[-1][2], ""
    if target < min(p[1] for p in pts):
        return min(pts, key=lambda p: p[1])[2], ">"
    return max(pts, key=lambda p: p[1])[2], "<"


def equal_rmse(a, penumbra, common_for, lines, results):
    """Error-parameter sweeps of every method on the full image against the vpl crop; CPU time
    interpolated at common RMSE targets."""
    crop = [float(x) for x in a.crop_reference.split(",")]
    sweep = []
    for part in [p for p in a.sweep.split(";") if p]:
        name, levels = part.split("=", 1)
        sweep.append((name.strip(), [float(x) for x in levels.split(",") if x]))
    vcount = ["--vpls", str(a.vpls)]
    cropargs = ["--crop", ",".join("%g" % c for c in crop)]
    rcrop = [float(x) for x in a.render_crop.split(",")] if a.render_crop else None
    rcropargs = ["--crop", ",".join("%g" % c for c in rcrop)] if rcrop else []
    lines.append("Equal RMSE: %s renders against the vpl crop (window %s), %d VPLs, one run per "
                 "level, levels interleaved across methods. render CPU s = the process's user + system time "
                 "minus that of a 1x1 lightcuts render with the same VPLs." % (
                     "full-image" if not rcrop else "render-window (%s)" % a.render_crop, a.crop_reference, a.vpls))
    for s in a.scenes.split(","):
        scene = os.path.join(SHARED, "scenes", s, s + ".pbrt")
        res, common = common_for(scene)
        base = os.path.join(a.out, "%s-%s-n%d" % (s, res, a.vpls))
        refpath = base + "-vpl-crop.pfm"
        if a.reference_dir:
            refpath = os.path.join(a.reference_dir, "%s-%s-n%d-vpl-crop.pfm" % (s, res, a.vpls))
        else:
            run(penumbra, scene, base + "-vpl-crop", ["--integrator", "vpl"] + vcount + cropargs, common)
        refimg = read_pfm(refpath)
        over = overhead_cpu(penumbra, scene, base, a.vpls, common)
        runs = {name: [] for name, _ in sweep}
        depth = max(len(levels) for _, levels in sweep)
        for i in range(depth):
            for name, levels in sweep:
                if i >= len(levels):
                    continue
                e = levels[i]
                out = base + "-eq-%s-%g" % (name.lower(), e)
                if a.reuse and all(os.path.exists(out + x) for x in (".pfm", ".json", ".rss")):
                    st = flat_stats(out + ".json")  # --reuse: a run of an interrupted sweep
                    with open(out + ".rss") as f:
                        rss, user, sys_ = f.read().split()[-3:]
                    st.update(max_rss_bytes=int(rss) * 1024, cpu_seconds=float(user) + float(sys_),
                              load_before=-1.0, wall_seconds=0.0)
                else:
                    st = run(penumbra, scene, out, METHOD_ARGS[name] + ["--error", "%g" % e] + vcount + rcropargs,
                             common)
                if rcrop:
                    full = [int(x) for x in res.split("x")]
                    w = cut_window_of_crop(read_pfm(out + ".pfm"), full, rcrop, crop)
                else:
                    w = cut_window(read_pfm(out + ".pfm"), crop)
                write_pfm(out + "-window.pfm", *w)
                st["rmse_crop"] = diff(penumbra, refpath, out + "-window.pfm")["rmse"]
                st["mean_relative_error_crop"] = mean_relative_error(refimg, w)
                st["render_cpu_seconds"] = st.get("cpu_seconds", 0.0) - over
                st["error_parameter"] = e
                runs[name].append(st)
                print("  %s %s(%g): %.1f CPU s, %.2f s, RMSE %.6f (load %.1f)" % (
                    s, name, e, st["render_cpu_seconds"], st["render_seconds"], st["rmse_crop"], st["load_before"]),
                    flush=True)
        lines += ["", "%s %s, sweep:" % (s, res), "",
                  "| method | error | render CPU s | render s | shadow rays/px | bounds/px | RMSE (crop) | rel. error (crop) | load |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for name, _ in sweep:
            for st in runs[name]:
                lines.append("| %s | %g%% | %.1f | %.2f | %.0f | %.0f | %.6f | %.4f | %s |" % (
                    name, 100 * st["error_parameter"], st["render_cpu_seconds"], st["render_seconds"],
                    st["shadow_rays_per_pixel_mean"], st["bound_evaluations_per_pixel_mean"], st["rmse_crop"],
                    st["mean_relative_error_crop"],
                    "%.1f" % st["load_before"] if st["load_before"] >= 0 else "-"))  # - : reused run
        eq = {}
        for key, metric, fmt in (("rmse_crop", "RMSE", "%.6f"), ("mean_relative_error_crop", "mean relative error", "%.4f")):
            targets = []
            for name, e in (("LC", 0.01), ("IC", 0.015)):
                hit = [st for st in runs.get(name, []) if abs(st["error_parameter"] - e) < 1e-9]
                if hit:
                    targets.append((("%s of %s(%g%%) = " + fmt) % (metric, name, 100 * e, hit[0][key]), hit[0][key]))
            lines += ["", "%s, render CPU s interpolated log-log at equal %s; ratio = LC's / the method's:" % (s, metric), "",
                      "| target | " + " | ".join("%s CPU s" % n for n, _ in sweep) + " | " +
                      " | ".join("ratio %s" % n for n, _ in sweep[1:]) + " |",
                      "|---" * (1 + 2 * len(sweep) - 1) + "|"]
            for label, target in targets:
                cells, cpus = [], {}
                for name, _ in sweep:
                    c, ex = loglog_at([(st["error_parameter"], st[key], st["render_cpu_seconds"])
                                       for st in runs[name] if st[key] > 0 and st["render_cpu_seconds"] > 0], target)
                    cpus[name] = (c, ex)
                    cells.append("%s%.1f" % (ex, c))
                lc = cpus[sweep[0][0]]
                flip = {">": "<", "<": ">", "": ""}

                def ratio(n):
                    # LC's time over the method's; a bound on either side makes the ratio a bound.
                    m = flip[cpus[n][1]] if cpus[n][1] else lc[1]
                    if cpus[n][1] and lc[1] and flip[cpus[n][1]] != lc[1]:
                        return "?"
                    return "%s%.2f" % (m, lc[0] / cpus[n][0])
                ratios = [ratio(n) for n, _ in sweep[1:]]
                lines.append("| %s | " % label + " | ".join(cells) + " | " + " | ".join(ratios) + " |")
                eq[label] = {n: cpus[n] for n, _ in sweep}
        print("\n".join(lines), flush=True)
        results["scenes"][s] = {"runs": runs, "equal_rmse": eq}
        with open(os.path.join(a.out, "vpl-bench.json"), "w") as f:
            json.dump(results, f, indent=1)


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
    ap.add_argument("--crop-reference", default="", help="x0,x1,y0,y1: full-size renders against a vpl crop")
    ap.add_argument("--verify-crop", type=float, default=0.0, help="scale at which to check vpl crop = full window")
    ap.add_argument("--repeats", type=int, default=1, help="alternating rounds (--crop-reference, scaling)")
    ap.add_argument("--compare", default="", help="NAME=BUILDDIR,...: illumcut methods of other builds too")
    ap.add_argument("--scaling-scale", type=float, default=0.0, help="resolution of the VPL-count scaling")
    ap.add_argument("--scaling-methods", default="LC,IC,IC-S")
    ap.add_argument("--equal-rmse", action="store_true", help="error sweeps, CPU time at equal RMSE (--crop-reference)")
    ap.add_argument("--sweep", default="LC=0.005,0.01,0.02;IC=0.015,0.03,0.06;IC-S=0.01,0.02,0.04",
                    help="NAME=e1,e2,...;... for --equal-rmse (NAME: LC, IC, IC-S; LC first)")
    ap.add_argument("--render-crop", default="",
                    help="x0,x1,y0,y1: --equal-rmse methods render only this window (containing --crop-reference)")
    ap.add_argument("--reuse", action="store_true", help="--equal-rmse: reuse the runs already in --out")
    ap.add_argument("--reference-dir", default="", help="reuse the vpl crop references in this folder")
    a = ap.parse_args()
    penumbra = os.path.join(a.build, "penumbra")
    os.makedirs(a.out, exist_ok=True)
    results = {"scale": a.scale, "vpls": a.vpls, "spp": a.spp, "threads": a.threads, "scenes": {}, "scaling": {}}
    lines = ["# IlluminationCut bench (%g of the film resolution, %d spp, %d VPLs, %d threads)" % (a.scale, a.spp, a.vpls, a.threads), ""]

    def common_for(scene):
        info = subprocess.run([penumbra, "info", scene], capture_output=True, text=True, env=env_for(penumbra)).stdout
        film = [l for l in info.splitlines() if l.startswith("film")][0].split()[1]
        fw, fh = (int(x) for x in film.split("x"))
        res = "%dx%d" % (max(1, round(fw * a.scale)), max(1, round(fh * a.scale)))
        return res, ["--resolution", res, "--threads", str(a.threads), "--seed", "0", "--spp", str(a.spp)]

    def write_report():
        """The markdown report, headed by the command that made it."""
        lines.insert(1, "Command: `%s`" % " ".join(["python3", "bench/vpl_bench.py"] + sys.argv[1:]))
        lines.insert(2, "")
        with open(os.path.join(a.out, "vpl-bench.md"), "w") as f:
            f.write("\n".join(lines) + "\n")

    if a.equal_rmse:
        equal_rmse(a, penumbra, common_for, lines, results)
        write_report()
        return 0
    if a.crop_reference or a.repeats > 1:
        if a.crop_reference:
            realistic(a, penumbra, common_for, lines, results)
        if a.scaling:
            scaling(a, penumbra, common_for, lines, results)
        write_report()
        with open(os.path.join(a.out, "vpl-bench.json"), "w") as f:
            json.dump(results, f, indent=1)
        print("\n".join(lines))
        return 0
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
