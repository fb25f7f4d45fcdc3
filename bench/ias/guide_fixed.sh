#!/bin/sh
# guide_fixed.sh — one fixed-pass render of bathroom-72-matte's 128x128 crop with `ias` and its relMSE
# against the 512-spp converged render (docs/methods/ias.md, "The light guide's gap to the oracles").
#
#   bench/ias/guide_fixed.sh LABEL PASSES SEED [render options...]
#
# Environment: BIN (build/penumbra), PN_SHARED (../shared), SCENE (another scene's .pbrt; then CONV its crop), CONV (the converged seed-7 render:
# beyond.sh's cached OUT/converged-bathroom-72-matte-512-seed7.exr, default
# bench/out/beyond/converged-bathroom-72-matte-512-seed7.exr), OUT (bench/out/guide-fixed). Prints LABEL,
# passes, seed, relMSE (the converged render's own not subtracted) and the process's CPU seconds.
# The throw-away switches are environment variables read by a build with a patch applied (in a copy
# of the tree): bench/ias/guide-experiments.patch (on c10acb2: PN_GX_REFRESH, PN_GX_ALL, PN_GX_PRIOR,
# PN_GX_SUB, PN_GX_SUBK) or bench/ias/guide-experiments-side.patch (on ebc220a: PN_GX_SIDE, PN_GX_HIER).
set -eu
L=$1; P=$2; S=$3; shift 3
B=${BIN:-build/penumbra}
SC=${SCENE:-${PN_SHARED:-../shared}/scenes/bathroom-72/bathroom-72-matte.pbrt}
CONV=${CONV:-bench/out/beyond/converged-bathroom-72-matte-512-seed7.exr}
OUT=${OUT:-bench/out/guide-fixed}
mkdir -p "$OUT"
o=$OUT/$L-$P-$S.exr
/usr/bin/time -f "%U %S" -o "$OUT/$L.time" nice -n 10 "$B" render "$SC" --integrator ias --threads 1 --seed "$S" \
    --crop 0.375,0.625,0.375,0.625 --quiet --threshold 1e-7 --max-passes "$P" --ias-aa-threshold 0 -o "$o" "$@" 2>/dev/null
r=$("$B" diff "$CONV" "$o" --json | python3 -c 'import json,sys;print("%.5f"%json.load(sys.stdin)["relmse"])')
echo "$L P=$P seed=$S relmse=$r cpu=$(cat "$OUT/$L.time")"
