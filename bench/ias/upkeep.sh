#!/bin/sh
# upkeep.sh — ias's own upkeep (stop 21): CPU seconds of two penumbra binaries on the bench crops,
# alternated, one thread, nice 10, and whether their images are bit-identical (cmp).
#   usage: bench/ias/upkeep.sh OLD_BINARY NEW_BINARY [RUNS] [OUT_DIR]
# Prints per case the median user+sys CPU seconds of the process (parse and BVH included) of
# each binary over RUNS (5) alternated runs, their ratio old/new, and same / DIFFERENT.
# Cases: PN_UPKEEP_CASES (a space-separated subset of the names below) or all.
set -u
OLD=$1
NEW=$2
RUNS=${3:-5}
OUT=${4:-bench/out/upkeep}
HERE=$(cd "$(dirname "$0")/../.." && pwd)
S=${PN_SHARED:-$HERE/../shared}/scenes
CROP="--crop 0.375,0.625,0.375,0.625 --threads 1 --seed 0 --quiet"
mkdir -p "$OUT"
scene_of() {
  case $1 in
  hall-many) echo "$S/hall-many/hall-many.pbrt" ;;
  hall-many-matte) echo "$S/hall-many/hall-many-matte.pbrt" ;;
  staircase-832) echo "$S/staircase-832/staircase-832.pbrt" ;;
  bathroom-72-matte) echo "$S/bathroom-72/bathroom-72-matte.pbrt" ;;
  living-env-138) echo "$S/living-env-138/living-env-138.pbrt" ;;
  hall-many-paper) echo "$S/hall-many/hall-many.pbrt" ;;
  esac
}
args_of() {
  case $1 in
  *-paper) echo "--integrator ias --ias-variant paper" ;;
  *) echo "--integrator ias --threshold 0.01" ;;
  esac
}
cpu() { # binary scene out args... -> user+sys seconds
  b=$1; sc=$2; o=$3; shift 3
  /usr/bin/time -f "%U %S" -o "$OUT/time" nice -n 10 "$b" render "$sc" -o "$o" "$@" >/dev/null 2>&1
  awk '{ printf "%.3f\n", $1 + $2 }' "$OUT/time"
}
median() { sort -n | awk '{ a[NR] = $1 } END { print a[int((NR + 1) / 2)] }'; }
CASES=${PN_UPKEEP_CASES:-"hall-many hall-many-matte staircase-832 bathroom-72-matte living-env-138 hall-many-paper"}
printf "%-20s %8s %8s %7s  %s\n" case old_cpu new_cpu ratio image
for c in $CASES; do
  sc=$(scene_of "$c")
  : >"$OUT/$c.old" && : >"$OUT/$c.new"
  i=0
  while [ $i -lt "$RUNS" ]; do
    # alternate which binary goes first
    if [ $((i % 2)) -eq 0 ]; then
      cpu "$OLD" "$sc" "$OUT/$c.old.exr" $CROP $(args_of "$c") >>"$OUT/$c.old"
      cpu "$NEW" "$sc" "$OUT/$c.new.exr" $CROP $(args_of "$c") >>"$OUT/$c.new"
    else
      cpu "$NEW" "$sc" "$OUT/$c.new.exr" $CROP $(args_of "$c") >>"$OUT/$c.new"
      cpu "$OLD" "$sc" "$OUT/$c.old.exr" $CROP $(args_of "$c") >>"$OUT/$c.old"
    fi
    i=$((i + 1))
  done
  a=$(median <"$OUT/$c.old")
  b=$(median <"$OUT/$c.new")
  same=DIFFERENT
  cmp -s "$OUT/$c.old.exr" "$OUT/$c.new.exr" && same=same
  printf "%-20s %8s %8s %7s  %s\n" "$c" "$a" "$b" "$(awk -v a="$a" -v b="$b" 'BEGIN { printf "%.3f", a / b }')" "$same"
done
