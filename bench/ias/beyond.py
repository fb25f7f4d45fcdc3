#!/usr/bin/env python3
"""beyond.py — CPU time to equal relMSE against a converged render, per scene and method (issue 15).

For each scene (NAME:FILE:CROP) it renders, once and cached under OUT, a converged crop: a
fixed-spp `reference` render (CONV_SPP eye rays, seed 7) and a second one with seed 8, whose
relMSE against the first, halved, is the converged render's own noise (printed; it is subtracted
from every method's relMSE, the two errors being independent). Then every method renders the crop
at two levels (spp or threshold), RUNS times with seeds 0 .. RUNS-1, methods and levels
alternated, one thread each; a method's relMSE and mean luminance are the means over its runs.

Time is the render phase's CPU seconds: the child's user + system CPU (getrusage) minus the
scene's load CPU, the median of RUNS runs of `penumbra info SCENE` (parsing and the Embree BVH,
the same work for every method; measured in the same alternation). What remains is the method's
own preparation (light BVH, cluster trees), the render and writing the image. Each line also
gives the process total and the stats JSON's render_seconds (wall clock of the render loop alone,
which on a shared machine is no CPU measure and is printed only as a check). Medians over the
runs. Crops should be large enough that the per-render constant is small (CROP in beyond.sh). The table at the
end (bench/ias/beyond_table.py, which also makes it from logs) gives each method's CPU time at the
default ias's relMSE, the best baseline and the ratio.

    bench/ias/beyond.py BUILD_DIR OUT_DIR

Environment: SCENES (space-separated NAME:FILE:CROP[:SAMPLER], SAMPLER the converged render's
--light-sampler), CONV_SPP (1024), RUNS (3), METHODS (names
from METHOD_ARGS below, space-separated), IAS_T (the default ias's two thresholds, "0.01 0.0025"), BASE_SPP (the baselines' two spp levels, "16 64"), THREADS for the converged renders (1), SKIP (space-separated
SCENE:METHOD pairs not to run, e.g. the paper variant at 10^6 emitters, whose per-block arrays
over all clusters do not fit in memory), MAIN_BIN (a second penumbra, e.g. main's build: the
methods named *-main run it, so that a change is measured against its base in one run).
"""
import math
import os
import re
import resource
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from beyond_table import table  # noqa: E402

# method name -> (list of level argument lists, label). Levels are ordered from cheap to costly.
BASE_SPP = os.environ.get("BASE_SPP", "16 64").split()


def ias_at(*options):
    """ias with the given options at each of the thresholds IAS_T (the default variant's levels)."""
    return [["--integrator", "ias", *options, "--threshold", t] for t in os.environ.get("IAS_T", "0.01 0.0025").split()]


METHOD_ARGS = {
    "ref": [["--integrator", "reference", "--spp", s] for s in BASE_SPP],
    "bvh": [["--integrator", "reference", "--light-sampler", "bvh", "--spp", s] for s in BASE_SPP],
    "ias-paper": [["--integrator", "ias", "--ias-variant", "paper", "--threshold", t] for t in ("0.04", "0.01")],
    "ias": ias_at(),
    # the default variant with the paper's fixed eye rays (issue 21's growing eye rays off)
    "ias-aa32": ias_at("--ias-aa-threshold", "0"),
    # the default variant with eye rays growing as 1 / sqrt(T) below T0 = 0.1 (ias-aa-power; the
    # balance of eye and shadow rays measured on hall-many, docs/methods/ias.md)
    "ias-eyesqrt": ias_at("--ias-aa-threshold", "0.1", "--ias-aa-power", "0.5"),
    # neighbours of ias-eyesqrt (the eye-ray / shadow-ray balance as a default, stop 20): T0 = 0.05
    # with P = 0.5 (fewer eye rays at every T), and T0 = 0.1 with P = 0.75 (more)
    "ias-eye05": ias_at("--ias-aa-threshold", "0.05", "--ias-aa-power", "0.5"),
    "ias-eye075": ias_at("--ias-aa-threshold", "0.1", "--ias-aa-power", "0.75"),
    # the default variant with each cluster cut named (issue 15: which one is the default)
    "ias-bvh": ias_at("--ias-cut", "bvh"),
    "ias-trees": ias_at("--ias-cut", "trees"),
    # the default variant with the ratio estimator (ias_ratio.h) in each of its modes
    **{f"ias-ratio-{mode}": ias_at("--ias-ratio", mode) for mode in ("off", "pixel", "cluster", "control")},
    # the default variant with MIS of its light samples and BSDF samples (ias_mis.h): 'glossy' (BSDF rays
    # at points with a glossy lobe only) and 'on' (at every shaded point)
    "ias-mis": ias_at("--ias-mis", "glossy"),
    "ias-mis-on": ias_at("--ias-mis", "on"),
    "ias-nomis": ias_at("--ias-mis", "off"),
    # the default variant with the light guide (ias_guide.h) named on and off
    **{f"ias-{name}": ias_at("--ias-light-guide", mode) for name, mode in (("guide", "on"), ("noguide", "off"))},
    # the default variant with the guided numbers not rotated (ias-guide-rotate off: the guide before stop 20's
    # rotation)
    "ias-norot": ias_at("--ias-guide-rotate", "off"),
    # the default variant with the first pass guided from the block's earlier pixels (ias-guide-refresh)
    "ias-gref": ias_at("--ias-guide-refresh", "1"),
    # the default variant with a cluster's light picked by importance at the point (ias-cluster-pick), with and
    # without a capped cut (ias-cut-max K): the light-count session's cap and what repairs it
    "ias-imp": ias_at("--ias-cluster-pick", "importance"),
    **{f"ias-cap{k}{sfx}": ias_at("--ias-cut-max", k, *extra)
       for k in ("128", "256")
       for sfx, extra in (("", []), ("-imp", ["--ias-cluster-pick", "importance"]),
                          ("-large", ["--ias-cluster-pick", "large"]))},
    "ias-large": ias_at("--ias-cluster-pick", "large"),
}
# The same methods run by MAIN_BIN (the base of a change), named NAME-main.
for _m in list(METHOD_ARGS):
    METHOD_ARGS[_m + "-main"] = METHOD_ARGS[_m]


def cpu_run(cmd):
    """Runs cmd; returns the child's user + system CPU seconds."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def diff(penumbra, ref, img):
    """(relMSE, mean luminance of img over ref's, minus 1) from `penumbra diff`."""
    out = subprocess.run([penumbra, "diff", ref, img], check=True, capture_output=True, text=True).stdout
    m = re.search(r"^relMSE\s+([0-9.eE+-]+)", out, re.M)
    lum = re.search(r"mean luminance reference ([0-9.eE+-]+), image ([0-9.eE+-]+)", out)
    return float(m.group(1)), float(lum.group(2)) / float(lum.group(1)) - 1.0


def relmse(penumbra, ref, img):
    return diff(penumbra, ref, img)[0]


def render_seconds(stats_path):
    with open(stats_path) as f:
        m = re.search(r'"render_seconds":\s*([0-9.eE+-]+)', f.read())
    return float(m.group(1)) if m else float("nan")


def peak_memory(stats_path):
    with open(stats_path) as f:
        m = re.search(r'"peak_memory_bytes":\s*([0-9]+)', f.read())
    return int(m.group(1)) if m else 0


def median(xs):
    s = sorted(xs)
    n = len(s)
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def main():
    build, out = sys.argv[1], sys.argv[2]
    penumbra = os.path.join(build, "penumbra")
    os.makedirs(out, exist_ok=True)
    conv_spp = os.environ.get("CONV_SPP", "1024")
    runs = int(os.environ.get("RUNS", "3"))
    all_methods = os.environ.get("METHODS", "ref bvh ias-paper ias").split()
    threads = os.environ.get("THREADS", "1")
    scenes = os.environ["SCENES"].split()
    measured, order = {}, []
    for spec in scenes:
        fields = spec.split(":")
        name, path, crop = fields[:3]
        # An optional fourth field: the converged render's light sampler (bvh for scenes whose
        # O(N)-per-point irradiance PDF would take hours at 512 spp; the result is the same image).
        conv_extra = ["--light-sampler", fields[3]] if len(fields) > 3 else []
        common = ["--crop", crop, "--quiet"]
        conv = [os.path.join(out, f"converged-{name}-{conv_spp}-seed{s}.exr") for s in (7, 8)]
        for seed, img in zip((7, 8), conv):
            if not os.path.exists(img):
                print(f"beyond: {name}: converged reference, {conv_spp} spp, seed {seed}", file=sys.stderr)
                subprocess.run([penumbra, "render", path, "--integrator", "reference", "--spp", conv_spp, "--seed",
                                str(seed), "--threads", threads, "-o", img] + common + conv_extra, check=True)
        floor, conv_bias = diff(penumbra, conv[0], conv[1])
        floor *= 0.5
        print(f"beyond: {name}: converged render's own relMSE {floor:.3g}, mean luminance of the second seed "
              f"{100 * conv_bias:+.3f}%", file=sys.stderr)
        skip = os.environ.get("SKIP", "").split()
        methods = [m for m in all_methods if f"{name}:{m}" not in skip]
        times = {(m, k): [] for m in methods for k in range(2)}
        walls = {(m, k): [] for m in methods for k in range(2)}
        load = []
        err, mem, bias = {}, {}, {}
        main_bin = os.environ.get("MAIN_BIN", "")
        for r in range(runs):
            load.append(cpu_run([penumbra, "info", path]))
            for k in range(2):
                for m in methods:
                    exe = main_bin if m.endswith("-main") else penumbra
                    if not exe:
                        sys.exit(f"beyond: method {m} needs MAIN_BIN")
                    img = os.path.join(out, f"{name}-{m}-{k}.exr")
                    stats = os.path.join(out, f"{name}-{m}-{k}.json")
                    # Seed r in run r: the error is the mean over the runs, not one image's (a scene
                    # with rare bright eye paths, staircase-832, gave relMSE 2.2e-3, 2.3e-3 and
                    # 1.2e-2 for three seeds of the same ias settings).
                    cmd = [exe, "render", path, "--threads", "1", "--seed", str(r), "-o", img, "--stats", stats]
                    times[(m, k)].append(cpu_run(cmd + common + METHOD_ARGS[m][k]))
                    walls[(m, k)].append(render_seconds(stats))
                    e, b = diff(penumbra, conv[0], img)
                    err[(m, k)] = err.get((m, k), 0.0) + e / runs
                    bias[(m, k)] = bias.get((m, k), 0.0) + b / runs
                    mem[(m, k)] = max(mem.get((m, k), 0), peak_memory(stats))
        t_load = median(load)
        print(f"beyond: {name}: scene load {t_load:.3f} s CPU (median of {runs}), subtracted", file=sys.stderr)
        err = {key: max(e - floor, 1e-12) for key, e in err.items()}
        pts = {m: [(median(times[(m, k)]) - t_load, err[(m, k)]) for k in range(2)] for m in methods}
        for m in methods:
            for k in range(2):
                t, e = pts[m][k]
                print(f"{name:16s} {m:10s} level {k}: {t:8.3f} s CPU  relMSE {e:.4g}  peak {mem[(m, k)] / 1e6:.0f} MB"
                      f"  (process {median(times[(m, k)]):.3f} s CPU, render loop {median(walls[(m, k)]):.3f} s wall,"
                      f" mean luminance {100 * bias[(m, k)]:+.3f}%)")
        measured[name] = {m: {"pts": pts[m], "mem": max(round(mem[(m, k)] / 1e6) for k in range(2))} for m in methods}
        order.append(name)
        sys.stdout.flush()
    print()
    print(table(measured, order))


if __name__ == "__main__":
    main()
