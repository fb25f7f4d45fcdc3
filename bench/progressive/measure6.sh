#!/bin/sh
# measure6.sh — the 6% table of issue 18 on reduced prog-hr64 crops: for each scene the full
# render (--driver full, cached in OUT) and the progressive runs stopped at 6% of the work pixels,
# with rel L1 / L2 against the full render and CPU seconds (user + system) of every run.
#   usage: bench/progressive/measure6.sh BINARY OUT_DIR [SCENE...]
# Scenes: stair hall bath glossy (bathroom-72 with its original materials). Variants: dcm
# (default), dcm-paper (--dcm-variant paper), painter; set VARIANTS to choose. Runs under nice;
# methods alternate scene by scene, so ratios within one scene come from one stretch of load.
# SIZE=full renders at the prog-hr64 cases' own resolutions (bench/bench.conf: staircase 576x1024,
# the others 1024x1024, the same crop); the default, quarter, at 288x512 and 384x384.
set -u
BIN=$1
OUT=$2
shift 2
HERE=$(cd "$(dirname "$0")/../.." && pwd)
S=$HERE/../shared/scenes
SCENES=${*:-"stair hall bath glossy"}
VARIANTS=${VARIANTS:-"dcm dcm-paper painter"}
STOP=${STOP:-6}
SIZE=${SIZE:-quarter}
COMMON="--spp 64 --shadow-rays 4 --seed 0 --crop 0.3,0.7,0.3,0.7 --threads 2 --quiet"
mkdir -p "$OUT"
cpu() { # label command...: runs it, prints CPU seconds
  label=$1; shift
  /usr/bin/time -f "%U %S" -o "$OUT/$label.time" nice "$@" >/dev/null 2>"$OUT/$label.err" || { echo "FAILED $label" >&2; cat "$OUT/$label.err" >&2; }
  awk '{printf "%.2f", $1 + $2}' "$OUT/$label.time"
}
metric() { # reference image -> "L1 L2"
  "$BIN" diff "$1" "$2" --json | tr -d ' \n' | sed 's/.*"rel_l1":\([^,}]*\).*"rel_l2":\([^,}]*\).*/\1 \2/'
}
printf "%-8s %-10s %8s %8s %8s %8s\n" scene method relL1 relL2 cpu_s fraction
for sc in $SCENES; do
  case $sc in
    stair) file=$S/staircase-832/staircase-832-matte.pbrt; res=288x512; fullres=576x1024 ;;
    hall) file=$S/hall-many/hall-many-matte.pbrt; res=384x384; fullres=1024x1024 ;;
    bath) file=$S/bathroom-72/bathroom-72-matte.pbrt; res=384x384; fullres=1024x1024 ;;
    glossy) file=$S/bathroom-72/bathroom-72.pbrt; res=384x384; fullres=1024x1024 ;;
    *) echo "unknown scene $sc" >&2; exit 2 ;;
  esac
  [ "$SIZE" = full ] && res=$fullres
  full=$OUT/$sc-full.exr
  if [ ! -f "$full" ]; then
    t=$(cpu "$sc-full" "$BIN" render "$file" -o "$full" --resolution $res $COMMON --driver full)
    echo "$t" > "$OUT/$sc-full.cpu"
  fi
  tf=$(cat "$OUT/$sc-full.cpu")
  printf "%-8s %-10s %8s %8s %8s %8s\n" "$sc" full 0 0 "$tf" 1
  for v in $VARIANTS; do
    case $v in
      dcm) args="--driver dcm" ;;
      dcm-paper) args="--driver dcm --dcm-variant paper" ;;
      painter) args="--driver painter" ;;
      uniform) args="--driver uniform" ;;
      *) args="--driver dcm $(echo "$v" | sed 's/^dcm://; s/+/ /g')" ;;
    esac
    img=$OUT/$sc-$(echo "$v" | tr ':+ ' '___').exr
    t=$(cpu "$sc-$v" "$BIN" render "$file" -o "$img" --resolution $res $COMMON $args --stop-at $STOP)
    m=$(metric "$full" "$img")
    printf "%-8s %-10s %8.4f %8.4f %8s %8.3f\n" "$sc" "$v" $m "$t" "$(echo "$t $tf" | awk '{print $1 / $2}')"
  done
done
