#!/bin/sh
# oracle.sh — issue 15's visibility oracles (stop 20): relMSE x shadow rays of `reference` (O0),
# `reference` choosing each light in proportion to its visible contribution at the point (O1)
# and O1 sampling only the visible part of the chosen light (O2). Needs a build with
# bench/ias/oracle.patch applied (PN_ORACLE / PN_ORACLE_K / PN_ORACLE_DEF select the estimator;
# the extra rays that estimate each light's visible contribution are not counted).
#
#   bench/ias/oracle.sh BIN OUT NAME SCENE CONV7 CONV8 "CONFIG ..."
#
# CONFIG is MODE:SPP:K:DEF:SEED (MODE 0, 1 or 2). Each render is one thread at nice 10, crop
# CROP (default 0.375,0.625,0.375,0.625, the window of the converged renders CONV7/CONV8, e.g.
# beyond.sh's cached OUT/converged-NAME-512-seed7.exr). Prints one line per render: config, shadow rays per
# pixel (the render's stats), relMSE against CONV7 minus CONV7's own (half the relMSE of CONV8
# against CONV7), relMSE x rays, mean luminance relative to CONV7's, render seconds (wall, of the stats).
set -eu
BIN=$1 OUT=$2 NAME=$3 SCENE=$4 C7=$5 C8=$6 CONFIGS=$7
CROP=${CROP:-0.375,0.625,0.375,0.625}
mkdir -p "$OUT"
rel() { "$BIN" diff "$1" "$2" --json | python3 -c 'import json,sys; d=json.load(sys.stdin); print(d["relmse"], d["mean_luminance_image"]/d["mean_luminance_reference"])'; }
own=$(rel "$C7" "$C8" | python3 -c 'import sys; print(float(sys.stdin.read().split()[0])/2)')
echo "oracle: $NAME converged own relMSE $own"
for c in $CONFIGS; do
    IFS=: read -r mode spp k def seed <<E
$c
E
    img="$OUT/$NAME-O$mode-spp$spp-k$k-d$def-s$seed.exr"
    PN_ORACLE=$mode PN_ORACLE_K=$k PN_ORACLE_DEF=$def nice -n 10 "$BIN" render "$SCENE" --integrator reference \
        --spp "$spp" --seed "$seed" --threads 1 --crop "$CROP" -o "$img" --quiet --stats "$img.json" 2>/dev/null
    set -- $(rel "$C7" "$img")
    python3 - "$img.json" "$1" "$2" "$own" "$NAME" "$c" <<'PY'
import json, sys
st = json.load(open(sys.argv[1]))["stats"]
r, lum, own = float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
rays = st["shadow_rays_per_pixel_mean"]
print(f"{sys.argv[5]} {sys.argv[6]} rays/px {rays:.1f} relMSE {r - own:.5f} relMSE*rays {(r - own) * rays:.4f} "
      f"mean {lum:.4f} render_s {st['render_seconds']:.1f}", flush=True)
PY
done
