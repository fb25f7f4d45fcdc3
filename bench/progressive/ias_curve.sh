#!/bin/sh
# ias_curve.sh — error against time of ias under the dcm driver against ias rendered in full
# (--driver full: the same work image and Gaussian), issue 18. Prints one line per snapshot:
# percent of work pixels, wall seconds since the render started (the CLI's snapshot line), that
# time over the full render's wall time, rel L1 and rel L2 against the full render.
# Also the full render with another seed: the noise floor of the comparison (two independent
# estimates of the same image differ by this much).
#   usage: bench/progressive/ias_curve.sh BINARY OUT_DIR [SCENE RES THRESHOLD]
set -u
BIN=$1
OUT=$2
HERE=$(cd "$(dirname "$0")/../.." && pwd)
SCENE=${3:-$HERE/../shared/scenes/hall-many/hall-many-matte.pbrt}
RES=${4:-128x128}
THR=${5:-0.01}
COMMON="--integrator ias --threshold $THR --crop 0.3,0.7,0.3,0.7 --resolution $RES --threads 2"
mkdir -p "$OUT"
start=$(date +%s.%N)
nice "$BIN" render "$SCENE" -o "$OUT/ias-full.exr" $COMMON --seed 0 --driver full --quiet 2>/dev/null
tfull=$(echo "$(date +%s.%N) $start" | awk '{print $1 - $2}')
nice "$BIN" render "$SCENE" -o "$OUT/ias-full-seed1.exr" $COMMON --seed 1 --driver full --quiet 2>/dev/null
nice "$BIN" render "$SCENE" -o "$OUT/ias-dcm.exr" $COMMON --seed 0 --driver dcm --snapshots 1,2,4,6,10,15,25,50,75 \
  2>"$OUT/ias-dcm.log" >/dev/null
echo "full render: $tfull s (wall)"
printf "%8s %8s %8s %8s %8s\n" pct seconds fraction relL1 relL2
grep '^penumbra: snapshot' "$OUT/ias-dcm.log" | sed 's/penumbra: snapshot \([^ ]*\) (\([0-9.]*\)% of the work pixels, \([0-9.]*\) s)/\1 \2 \3/' |
while read -r file pct sec; do
  m=$("$BIN" diff "$OUT/ias-full.exr" "$file" --json | tr -d ' \n' | sed 's/.*"rel_l1":\([^,}]*\).*"rel_l2":\([^,}]*\).*/\1 \2/')
  printf "%8.2f %8.2f %8.3f %8.4f %8.4f\n" "$pct" "$sec" "$(echo "$sec $tfull" | awk '{print $1 / $2}')" $m
done
m=$("$BIN" diff "$OUT/ias-full.exr" "$OUT/ias-dcm.exr" --json | tr -d ' \n' | sed 's/.*"rel_l1":\([^,}]*\).*"rel_l2":\([^,}]*\).*/\1 \2/')
echo "final (100%): rel L1 / L2 $m"
m=$("$BIN" diff "$OUT/ias-full.exr" "$OUT/ias-full-seed1.exr" --json | tr -d ' \n' | sed 's/.*"rel_l1":\([^,}]*\).*"rel_l2":\([^,}]*\).*/\1 \2/')
echo "noise floor (full, seed 1 against seed 0): rel L1 / L2 $m"
