#!/bin/sh
# scaling.sh — issue 15's light-count goal: CPU time and peak memory of `ias` (default variant,
# threshold T) and of `reference --light-sampler bvh` (SPP spp) on the generated scenes of
# bench/ias/gen_many.py from 10^3 to 10^6 emitting triangles, same crop, one thread, at low
# priority; RUNS runs per case alternated, median CPU seconds (user + system, process total:
# parsing and building included, and the render alone from the stats' render_seconds ratio).
# Every pixel takes the same eye rays (ias: aa-rays per pixel), so CPU time per eye ray grows as
# the CPU time does.
#
#   bench/ias/scaling.sh [BUILD_DIR] [OUT_DIR]     (defaults: build, bench/out/scaling)
#
# Environment: GEN ("1000 10000 100000 1000000"), GEN_CROP (0.3,0.7,0.55,0.95), T (0.01), SPP (16),
# RUNS (3).
set -eu
BUILD=${1:-build}
OUT=${2:-bench/out/scaling}
GEN=${GEN:-1000 10000 100000 1000000}
GEN_CROP=${GEN_CROP:-0.3,0.7,0.55,0.95}
T=${T:-0.01}
SPP=${SPP:-16}
RUNS=${RUNS:-3}
mkdir -p "$OUT/gen"
for n in $GEN; do
    [ -f "$OUT/gen/many-$n.pbrt" ] || python3 "$(dirname "$0")/gen_many.py" "$n" "$OUT/gen"
done
exec nice -n 15 python3 - "$BUILD/penumbra" "$OUT" "$GEN_CROP" "$T" "$SPP" "$RUNS" $GEN <<'PY'
import json, resource, subprocess, sys
pn, out, crop, t, spp, runs = sys.argv[1:7]
counts = sys.argv[7:]
cases = {"ias": ["--integrator", "ias", "--threshold", t], "bvh": ["--integrator", "reference", "--light-sampler", "bvh", "--spp", spp]}
res = {}
for n in counts:
    scene = f"{out}/gen/many-{n}.pbrt"
    for r in range(int(runs)):
        for m, args in cases.items():
            js = f"{out}/many-{n}-{m}.json"
            b = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run([pn, "render", scene, "--crop", crop, "--threads", "1", "--quiet", "-o", f"{out}/many-{n}-{m}.exr", "--stats", js] + args, check=True)
            a = resource.getrusage(resource.RUSAGE_CHILDREN)
            st = json.load(open(js))["stats"]
            res.setdefault((n, m), []).append((a.ru_utime - b.ru_utime + a.ru_stime - b.ru_stime, st))
print("| emitters | method | CPU s (median) | render share | eye rays | shadow rays/px | peak MB |")
print("|---|---|---|---|---|---|---|")
for n in counts:
    for m in cases:
        rs = sorted(res[(n, m)], key=lambda x: x[0])
        cpu, st = rs[len(rs) // 2]
        total = st["parse_seconds"] + st["bvh_seconds"] + st["render_seconds"]
        share = st["render_seconds"] / total if total > 0 else 0
        print(f"| {int(n):,} | {m} | {cpu:.3f} | {share:.2f} | {st['eye_rays']} | {st['shadow_rays_per_pixel_mean']:.1f} | {st['peak_memory_bytes'] / 1e6:.0f} |")
    sys.stdout.flush()
PY
