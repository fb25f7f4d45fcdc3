#!/bin/sh
# scaling.sh — issue 15's light-count goal: CPU time and peak memory of `ias` (default variant,
# threshold T) and of `reference --light-sampler bvh` (SPP spp) on the generated scenes of
# bench/ias/gen_many.py from 10^3 to 10^6 emitting triangles, same crop, one thread, at low
# priority; RUNS runs per case alternated (methods, and binaries when BASE is set), median CPU
# seconds (user + system, process total: parsing, BVH and light-hierarchy builds included) and
# median render seconds (the stats' render_seconds: wall clock of the render alone, without the
# integrator's preparation). Every pixel takes the same eye rays (ias: aa-rays per pixel), so
# render time per eye ray grows as the render time does; its growth from the first count is
# printed per method. With BASE, the images of the two binaries are compared with cmp (last run).
# Render CPU: the render's own seconds are wall clock, which the shared machine's load inflates.
# The table's render CPU is render_seconds x (process CPU / process wall clock), the render's wall
# time at the process's own share of a CPU (the load taken as steady over the run); per eye ray and
# its growth from the first count follow from it. With SETUP=1 every run is paired instead with a
# run of the same case on a crop of about one pixel (parsing, builds, preparation), and render CPU
# = CPU - that run's CPU (noisier where the set-up is most of the process: at 10^6 emitters).
#
#   bench/ias/scaling.sh [BUILD_DIR] [OUT_DIR]     (defaults: build, bench/out/scaling)
#
# Environment: GEN ("1000 10000 100000 1000000"), GEN_DIR (OUT_DIR/gen: generated scenes, kept and
# reused), GEN_CROP (0.3,0.7,0.55,0.95), T (0.01), SPP (16), RUNS (3), BASE (a second penumbra
# binary, e.g. a build of the base commit, BASE_BUILD/penumbra), METHODS ("ias bvh"), SETUP (0),
# VARIANTS (more cases of the new binary only: "name=args;name=args", e.g.
# "cap256=--integrator ias --threshold 0.01 --ias-cut-max 256"; named cases run after METHODS).
set -eu
BUILD=${1:-build}
OUT=${2:-bench/out/scaling}
GEN=${GEN:-1000 10000 100000 1000000}
GEN_DIR=${GEN_DIR:-$OUT/gen}
GEN_CROP=${GEN_CROP:-0.3,0.7,0.55,0.95}
T=${T:-0.01}
SPP=${SPP:-16}
RUNS=${RUNS:-3}
BASE=${BASE:-}
METHODS=${METHODS:-ias bvh}
SETUP=${SETUP:-0}
VARIANTS=${VARIANTS:-}
mkdir -p "$OUT" "$GEN_DIR"
for n in $GEN; do
    [ -f "$GEN_DIR/many-$n.pbrt" ] || python3 "$(dirname "$0")/gen_many.py" "$n" "$GEN_DIR"
done
exec nice -n 15 python3 - "$BUILD/penumbra" "$OUT" "$GEN_CROP" "$T" "$SPP" "$RUNS" "$GEN_DIR" "$BASE" "$METHODS" "$SETUP" "$VARIANTS" $GEN <<'PY'
import filecmp, json, resource, subprocess, sys, time
pn, out, crop, t, spp, runs, gen, base, methods, setup, variants = sys.argv[1:12]
counts = sys.argv[12:]
setup = setup == "1"
allcases = {"ias": ["--integrator", "ias", "--threshold", t], "bvh": ["--integrator", "reference", "--light-sampler", "bvh", "--spp", spp]}
bins = {"new": pn}
if base:
    bins = {"base": base, "new": pn}
# (method, binary) -> (executable, arguments)
cases = {}
for m in methods.split():
    for b, exe in bins.items():
        cases[(m, b)] = (exe, allcases[m])
for v in filter(None, (x.strip() for x in variants.split(";"))):
    name, _, args = v.partition("=")
    cases[(name.strip(), "new")] = (pn, args.split())
# A crop of about one pixel (at 128 x 128) at the crop's corner, for the setup's CPU.
c = [float(x) for x in crop.split(",")]
one = f"{c[0]},{c[0] + 0.01},{c[2]},{c[2] + 0.01}"


def run(exe, scene, cr, args, stem):
    js = f"{stem}.json"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    subprocess.run([exe, "render", scene, "--crop", cr, "--threads", "1", "--quiet", "-o", f"{stem}.exr", "--stats", js] + args, check=True)
    wall = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    st = json.load(open(js))["stats"]
    st["render_cpu_est"] = st["render_seconds"] * min(1.0, cpu / wall) if wall > 0 else st["render_seconds"]
    return cpu, st


res = {}
for n in counts:
    scene = f"{gen}/many-{n}.pbrt"
    for r in range(int(runs)):
        for (m, b), (exe, args) in cases.items():
            cpu, st = run(exe, scene, crop, args, f"{out}/many-{n}-{m}-{b}")
            rcpu = cpu - run(exe, scene, one, args, f"{out}/one-{n}-{m}-{b}")[0] if setup else st["render_cpu_est"]
            res.setdefault((n, m, b), []).append((cpu, st, rcpu))
print("| emitters | method | binary | CPU s (median) | render CPU s (median) | render CPU µs / eye ray | growth | render s (wall, median) | eye rays | shadow rays/px | clusters/point | peak MB | image |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
first = {}
for n in counts:
    for (m, b) in cases:
        rs = res[(n, m, b)]
        med = lambda xs: sorted(xs)[len(xs) // 2]
        cpu = med([x[0] for x in rs])
        ren = med([x[1]["render_seconds"] for x in rs])
        rcpu = med([x[2] for x in rs])
        st = rs[-1][1]
        per = rcpu / st["eye_rays"] * 1e6
        first.setdefault((m, b), per)
        same = ""
        if base and b == "new" and (m, "base") in cases:
            same = "same" if filecmp.cmp(f"{out}/many-{n}-{m}-base.exr", f"{out}/many-{n}-{m}-new.exr", shallow=False) else "DIFFERENT"
        print(f"| {int(n):,} | {m} | {b} | {cpu:.3f} | {rcpu:.3f} | {per:.2f} | {per / first[(m, b)]:.1f}x | {ren:.3f} | {st['eye_rays']} | {st['shadow_rays_per_pixel_mean']:.1f} | {st.get('clusters_per_point_mean', 0):.0f} | {st['peak_memory_bytes'] / 1e6:.0f} | {same} |")
    sys.stdout.flush()
PY
