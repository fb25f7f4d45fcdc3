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
#
#   bench/ias/scaling.sh [BUILD_DIR] [OUT_DIR]     (defaults: build, bench/out/scaling)
#
# Environment: GEN ("1000 10000 100000 1000000"), GEN_DIR (OUT_DIR/gen: generated scenes, kept and
# reused), GEN_CROP (0.3,0.7,0.55,0.95), T (0.01), SPP (16), RUNS (3), BASE (a second penumbra
# binary, e.g. a build of the base commit, BASE_BUILD/penumbra), METHODS ("ias bvh").
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
mkdir -p "$OUT" "$GEN_DIR"
for n in $GEN; do
    [ -f "$GEN_DIR/many-$n.pbrt" ] || python3 "$(dirname "$0")/gen_many.py" "$n" "$GEN_DIR"
done
exec nice -n 15 python3 - "$BUILD/penumbra" "$OUT" "$GEN_CROP" "$T" "$SPP" "$RUNS" "$GEN_DIR" "$BASE" "$METHODS" $GEN <<'PY'
import filecmp, json, resource, subprocess, sys
pn, out, crop, t, spp, runs, gen, base, methods = sys.argv[1:10]
counts = sys.argv[10:]
allcases = {"ias": ["--integrator", "ias", "--threshold", t], "bvh": ["--integrator", "reference", "--light-sampler", "bvh", "--spp", spp]}
cases = {m: allcases[m] for m in methods.split()}
bins = {"new": pn}
if base:
    bins = {"base": base, "new": pn}
res = {}
for n in counts:
    scene = f"{gen}/many-{n}.pbrt"
    for r in range(int(runs)):
        for m, args in cases.items():
            for b, exe in bins.items():
                js = f"{out}/many-{n}-{m}-{b}.json"
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                subprocess.run([exe, "render", scene, "--crop", crop, "--threads", "1", "--quiet", "-o", f"{out}/many-{n}-{m}-{b}.exr", "--stats", js] + args, check=True)
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                st = json.load(open(js))["stats"]
                res.setdefault((n, m, b), []).append((after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, st))
print("| emitters | method | binary | CPU s (median) | render s (median) | render µs / eye ray | growth | eye rays | shadow rays/px | peak MB | image |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
first = {}
for n in counts:
    for m in cases:
        for b in bins:
            rs = res[(n, m, b)]
            cpu = sorted(x[0] for x in rs)[len(rs) // 2]
            ren = sorted(x[1]["render_seconds"] for x in rs)[len(rs) // 2]
            st = rs[-1][1]
            per = ren / st["eye_rays"] * 1e6
            first.setdefault((m, b), per)
            same = ""
            if base and b == "new":
                same = "same" if filecmp.cmp(f"{out}/many-{n}-{m}-base.exr", f"{out}/many-{n}-{m}-new.exr", shallow=False) else "DIFFERENT"
            print(f"| {int(n):,} | {m} | {b} | {cpu:.3f} | {ren:.3f} | {per:.2f} | {per / first[(m, b)]:.1f}x | {st['eye_rays']} | {st['shadow_rays_per_pixel_mean']:.1f} | {st['peak_memory_bytes'] / 1e6:.0f} | {same} |")
    sys.stdout.flush()
PY
