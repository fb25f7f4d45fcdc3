#!/bin/sh
# crossing.sh — where dcm's 6% goal of issue 18 (rel L1 <= 0.008 against the full render) is met:
# for each scene, at the full prog-hr64 size (measure6.sh's SIZE=full settings), the full render
# with seeds 0 and 1, then one run per variant that writes a snapshot at every percentage of
# PCTS, with the CPU seconds (user + system, from /proc/PID/stat) at the moment each snapshot file
# appears; rel L1 / L2 of every snapshot against the seed-0 full render, and for dcm the noise
# floor at the snapshot's pattern (build/pn_noise_floor with the seed-1 render). A snapshot at P
# is the image of `--stop-at P` (same pixels evaluated, same reconstruction; checked with
# `penumbra diff` and the AOVs), so one run gives the whole curve, except inside the jumps of
# dcm's simplicity tests, which evaluate pixels that no snapshot or --stop-at splits: a snapshot
# requested there shows the image after the jump, and the tables give the share the driver
# reports. Its CPU includes the earlier snapshots' reconstructions and EXR writes (a fraction of
# a second each); CONFIRM=1 adds a plain `--stop-at` run of dcm and painter at the first share at
# or below GOAL for the direct figure; REFINE=1 a second dcm run with four snapshots between the
# two shares that bracket the crossing.
#   usage: bench/progressive/crossing.sh BINARY OUT_DIR [SCENE...]     (scenes: stair hall bath glossy)
# The dcm run stops at the first snapshot at or beyond TOP (default 25) whose L1 is at or below
# GOAL (default 0.008), and at the latest at MAX (default 50). painter runs to the same
# percentage and to every share of the work pixels dcm's snapshots reached; the paper variant
# (--dcm-variant paper) gets snapshots at 6% and at the first dcm share at or below GOAL. The
# crossing is interpolated linearly in L1 between the two measured shares that bracket it, and the
# CPU and painter's L1 there the same way; the first measured share at or below GOAL is printed
# too (dcm cannot stop inside the jump of its simplicity tests).
# Output: OUT/NAME-VARIANT.cpus (requested, evaluated %, CPU s per snapshot), .curve (with L1 and
# L2), OUT/crossing.txt (the tables, with pn_noise_floor's split by block class at the first share
# at or below GOAL).
# SEEDS="0" skips the seed-1 full render (and with it the floor).
# Runs under nice -n 10 with --threads THREADS (default 2); NOISE_FLOOR: pn_noise_floor's path
# (default beside BINARY); RES overrides the resolution (a quick trial of the script).
set -u
BIN=$1
OUT=$2
shift 2
HERE=$(cd "$(dirname "$0")/../.." && pwd)
S=${PN_SHARED:-$HERE/../shared}/scenes
SCENES=${*:-"stair hall bath glossy"}
PCTS=${PCTS:-"3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 20 22.5 25 27.5 30 32.5 35 37.5 40 45 50"}
TOP=${TOP:-25}
MAX=${MAX:-50}
GOAL=${GOAL:-0.008}
THREADS=${THREADS:-2}
CONFIRM=${CONFIRM:-0}
REFINE=${REFINE:-0}
SEEDS=${SEEDS:-"0 1"}
NF=${NOISE_FLOOR:-$(dirname "$BIN")/pn_noise_floor}
TCK=$(getconf CLK_TCK)
COMMONP="--spp 64 --shadow-rays 4 --crop 0.3,0.7,0.3,0.7 --threads $THREADS"
COMMON="$COMMONP --quiet"
mkdir -p "$OUT"

metric() { # reference image -> "L1 L2"
  "$BIN" diff "$1" "$2" --json | tr -d ' \n' | sed 's/.*"rel_l1":\([^,}]*\).*"rel_l2":\([^,}]*\).*/\1 \2/'
}
cpu_of() { # pid -> CPU seconds so far (all threads)
  awk -v t="$TCK" '{printf "%.2f", ($14 + $15) / t}' "/proc/$1/stat" 2>/dev/null
}
snapname() { # base.exr pct -> base-PCTpct.exr (the CLI's %g)
  printf '%s-%gpct.exr' "${1%.exr}" "$2"
}
pcts_upto() { # max -> the PCTS at or below max, comma-separated
  for p in $PCTS; do awk -v p="$p" -v m="$1" 'BEGIN { exit !(p <= m + 1e-9) }' && printf '%s ' "$p"; done
}

# run LABEL "PCT..." STOP_AT EARLY_STOP ARGS...: one render with snapshots; OUT/LABEL.cpus gets
# "requested evaluated cpu" per snapshot (evaluated: the share of the work pixels the driver
# reports for it, which is above the requested one where dcm's simplicity tests evaluate pixels in
# one go, never split by a snapshot or --stop-at); with EARLY_STOP=1 the run is ended after the
# first snapshot at or beyond TOP whose L1 against the seed-0 full render is at or below GOAL.
run() {
  label=$1 list=$2 stopat=$3 early=$4
  shift 4
  img=$OUT/$label.exr
  : >"$OUT/$label.cpu0"
  nice -n 10 "$BIN" render "$file" -o "$img" --resolution "$res" $COMMONP --seed 0 "$@" \
    --stop-at "$stopat" --snapshots "$(echo $list | tr ' ' ',')" >/dev/null 2>"$OUT/$label.err" &
  pid=$!
  set -- $list
  while [ $# -gt 0 ]; do
    snap=$(snapname "$img" "$1")
    if [ -f "$snap" ]; then
      c=$(cpu_of $pid)
      [ -n "$c" ] || c=NA
      echo "$1 $c" >>"$OUT/$label.cpu0"
      if [ "$early" = 1 ]; then
        l1=$(metric "$full" "$snap" | cut -d' ' -f1)
        if awk -v p="$1" -v l="$l1" -v t="$TOP" -v g="$GOAL" 'BEGIN { exit !(p >= t - 1e-9 && l <= g) }'; then
          sleep 0.5 # let the log line of the snapshot through
          kill $pid 2>/dev/null
          break
        fi
      fi
      shift
      continue
    fi
    kill -0 $pid 2>/dev/null || break
    sleep 0.1
  done
  wait $pid 2>/dev/null
  # the evaluated share of each snapshot, from the CLI's log line
  while read -r p c; do
    e=$(grep -F "$(snapname "$img" "$p") (" "$OUT/$label.err" | sed 's/.*(\([0-9.]*\)% of the work pixels.*/\1/')
    echo "$p ${e:-NA} $c"
  done <"$OUT/$label.cpu0" >"$OUT/$label.cpus"
}

# crossing FILE GOAL: FILE has "pct l1 cpu" lines in order; prints "pct cpu" where l1 first
# falls to GOAL (linear between the bracketing points), or "none"
crossing() {
  awk -v g="$2" 'NR > 1 && pl > g && $2 <= g { f = (pl - g) / (pl - $2); printf "%.2f %.2f\n", pp + f * ($1 - pp), pc + f * ($3 - pc); found = 1; exit }
    NR == 1 && $2 <= g { printf "<=%s %s\n", $1, $3; found = 1; exit }
    { pp = $1; pl = $2; pc = $3 } END { if (!found) print "none" }' "$1"
}
at_pct() { # FILE PCT: column 2 interpolated linearly in column 1
  awk -v x="$2" '$1 >= x - 1e-9 { if (NR == 1 || $1 == x) print $2; else printf "%.4f\n", pl + (x - pp) / ($1 - pp) * ($2 - pl); done = 1; exit }
    { pp = $1; pl = $2 } END { if (!done) print "NA" }' "$1"
}

for sc in $SCENES; do
  case $sc in
    stair) file=$S/staircase-832/staircase-832-matte.pbrt; res=576x1024 ;;
    hall) file=$S/hall-many/hall-many-matte.pbrt; res=1024x1024 ;;
    bath) file=$S/bathroom-72/bathroom-72-matte.pbrt; res=1024x1024 ;;
    glossy) file=$S/bathroom-72/bathroom-72.pbrt; res=1024x1024 ;;
    *) echo "unknown scene $sc" >&2; exit 2 ;;
  esac
  res=${RES:-$res} # RES: another resolution, for trying the script out
  full=$OUT/$sc-full.exr
  for seed in $SEEDS; do
    f=$full; [ $seed = 1 ] && f=$OUT/$sc-full-seed1.exr
    if [ ! -f "$f" ]; then
      /usr/bin/time -f "%U %S" -o "${f%.exr}.time" nice -n 10 "$BIN" render "$file" -o "$f" --resolution $res \
        $COMMON --seed $seed --driver full >/dev/null 2>"${f%.exr}.err"
      awk '{printf "%.2f\n", $1 + $2}' "${f%.exr}.time" >"${f%.exr}.cpu"
    fi
  done
  tf=$(cat "$OUT/$sc-full.cpu")
  [ -s "$OUT/$sc-dcm.cpus" ] || run "$sc-dcm" "$(pcts_upto $MAX)" "$MAX" 1 --driver dcm --aov sampling_pattern,block_map
  last=$(tail -n 1 "$OUT/$sc-dcm.cpus" | cut -d' ' -f2)
  # painter at the grid and at every share dcm's snapshots reached
  plist=$( (pcts_upto $last | tr ' ' '\n'; cut -d' ' -f2 "$OUT/$sc-dcm.cpus") | grep -v '^$' | sort -g -u | tr '\n' ' ')
  [ -s "$OUT/$sc-painter.cpus" ] || run "$sc-painter" "$plist" "$last" 0 --driver painter
  # the curves: "requested evaluated L1 L2 cpu", one line per distinct image (the first snapshot
  # of each evaluated share)
  for v in dcm painter; do
    while read -r p e c; do
      echo "$p $e $(metric "$full" "$(snapname "$OUT/$sc-$v.exr" "$p")") $c"
    done <"$OUT/$sc-$v.cpus" | awk '!seen[$2]++' >"$OUT/$sc-$v.curve"
  done
  awk '{print $2, $3, $5}' "$OUT/$sc-dcm.curve" >"$OUT/$sc-dcm.l1"
  awk '{print $2, $3}' "$OUT/$sc-painter.curve" >"$OUT/$sc-painter.l1"
  cross=$(crossing "$OUT/$sc-dcm.l1" "$GOAL")
  # REFINE=1: a second dcm run with snapshots at four shares between the two measured ones that
  # bracket the crossing, stopped at the upper one (its CPU from /usr/bin/time: four snapshots,
  # not the main run's many); the crossing is then taken from both runs' points
  if [ "$REFINE" = 1 ] && [ ! -s "$OUT/$sc-dcm-fine.cpus" ]; then
    br=$(awk -v g="$GOAL" 'NR > 1 && pl > g && $2 <= g { print pp, $1; exit } { pp = $1; pl = $2 }' "$OUT/$sc-dcm.l1")
    if [ -n "$br" ]; then
      flist=$(echo "$br" | awk '{ for (k = 1; k <= 4; k++) printf "%.1f ", $1 + k * ($2 - $1) / 5; print $2 }')
      run "$sc-dcm-fine" "$flist" "$(echo "$br" | cut -d' ' -f2)" 0 --driver dcm --aov sampling_pattern,block_map
    fi
  fi
  if [ -s "$OUT/$sc-dcm-fine.cpus" ]; then
    while read -r p e c; do
      echo "$p $e $(metric "$full" "$(snapname "$OUT/$sc-dcm-fine.exr" "$p")") $c"
    done <"$OUT/$sc-dcm-fine.cpus" >"$OUT/$sc-dcm-fine.curve"
    awk '{print $2, $3, $5}' "$OUT/$sc-dcm.curve" "$OUT/$sc-dcm-fine.curve" | sort -g -k1,1 | awk '!seen[$1]++' >"$OUT/$sc-dcm.l1"
    cross=$(crossing "$OUT/$sc-dcm.l1" "$GOAL")
  fi
  cp=$(echo "$cross" | cut -d' ' -f1)
  # the first measured dcm image at or below GOAL (either run): evaluated share, its file
  for v in dcm dcm-fine; do
    [ -f "$OUT/$sc-$v.curve" ] && awk -v f="$OUT/$sc-$v" '{ printf "%s %s %s-%gpct.exr\n", $2, $3, f, $1 }' "$OUT/$sc-$v.curve"
  done | sort -g -k1,1 >"$OUT/$sc-dcm.all"
  first=$(awk -v g="$GOAL" '$2 <= g { print $1, $3; exit }' "$OUT/$sc-dcm.all")
  # the paper variant at 6% and at the first measured percentage at or below GOAL
  if [ ! -s "$OUT/$sc-dcm-paper.cpus" ] && [ -n "$first" ]; then
    list=$(printf '%s\n' 6 "$(echo "$first" | cut -d' ' -f1)" | sort -g -u | tr '\n' ' ')
    run "$sc-dcm-paper" "$list" "$(echo $list | awk '{print $NF}')" 0 --driver dcm --dcm-variant paper
  fi
  if [ -s "$OUT/$sc-dcm-paper.cpus" ]; then
    while read -r p e c; do
      echo "$p $e $(metric "$full" "$(snapname "$OUT/$sc-dcm-paper.exr" "$p")") $c"
    done <"$OUT/$sc-dcm-paper.cpus" >"$OUT/$sc-dcm-paper.curve"
  fi
  # CONFIRM=1: plain --stop-at runs (no snapshots) at the first measured share at or below GOAL
  if [ "$CONFIRM" = 1 ] && [ -n "$first" ] && [ ! -f "$OUT/$sc-confirm-painter.curve" ]; then
    x=$(echo "$first" | cut -d' ' -f1)
    for v in dcm painter; do
      /usr/bin/time -f "%U %S" -o "$OUT/$sc-confirm-$v.time" nice -n 10 "$BIN" render "$file" \
        -o "$OUT/$sc-confirm-$v.exr" --resolution $res $COMMON --seed 0 --driver $v --stop-at $x >/dev/null 2>&1
      echo "$x $(metric "$full" "$OUT/$sc-confirm-$v.exr") $(awk '{printf "%.2f", $1 + $2}' "$OUT/$sc-confirm-$v.time")" \
        >"$OUT/$sc-confirm-$v.curve"
    done
  fi
  {
    echo "## $sc ($res), full render $tf CPU s (seed 1: $(cat "$OUT/$sc-full-seed1.cpu" 2>/dev/null) s)"
    printf "%6s %6s | %-30s | %-24s | %-6s | %s\n" req eval "dcm L1 / L2, CPU s (/full)" "painter L1 / L2, CPU s" "p/dcm" "floor L1 / L2 at the dcm pattern"
    while read -r p e l1 l2 c; do
      pl=$(awk -v e="$e" '{ d = $2 - e; d = d < 0 ? -d : d } d <= 0.05 && (!n++ || d < b) { b = d; r = $3 " " $4 " " $5 } END { if (n) print r }' "$OUT/$sc-painter.curve")
      snap=$(snapname "$OUT/$sc-dcm.exr" "$p")
      fl=; [ -f "$OUT/$sc-full-seed1.exr" ] && fl=$("$NF" "$full" "$OUT/$sc-full-seed1.exr" "$snap" "$snap" | sed -n 's/^floor at this pattern.*relL1 \([^ ]*\) relL2 \([^ ]*\)/\1 \/ \2/p')
      echo "$p $e $l1 $l2 $c $tf $pl" | awk -v fl="$fl" '{ r = (NF >= 9) ? sprintf("%.2f", $7 / $3) : ""; q = (NF >= 9) ? sprintf("%.4f / %.4f, %6.1f", $7, $8, $9) : "";
        printf "%6s %6s | %.4f / %.4f, %6.1f (1/%.1f) | %-24s | %-6s | %s\n", $1, $2, $3, $4, $5, $6 / $5, q, r, fl }'
    done <"$OUT/$sc-dcm.curve"
    if [ "$cross" = none ]; then
      echo "dcm: L1 <= $GOAL not reached by $last%"
    else
      ccpu=$(echo "$cross" | cut -d' ' -f2)
      pl1=$(at_pct "$OUT/$sc-painter.l1" "${cp#<=}")
      echo "crossing: dcm L1 = $GOAL at $cp% of the work pixels (interpolated in the evaluated share), CPU $ccpu s = $(awk -v a="$ccpu" -v b="$tf" 'BEGIN { printf "1/%.1f", b / a }') of the full render; painter L1 there $pl1 ($(awk -v a="$pl1" -v g="$GOAL" 'BEGIN { printf "%.2f", a / g }')x)"
      [ -f "$OUT/$sc-dcm-fine.curve" ] && awk '{ printf "refined: requested %s%% (evaluated %s%%): L1 / L2 %.4f / %.4f, CPU %s s\n", $1, $2, $3, $4, $5 }' "$OUT/$sc-dcm-fine.curve"
      echo "first measured dcm image at or below $GOAL: $(echo "$first" | cut -d' ' -f1)% evaluated"
      snap=$(echo "$first" | cut -d' ' -f2)
      [ -f "$OUT/$sc-full-seed1.exr" ] && "$NF" "$full" "$OUT/$sc-full-seed1.exr" "$snap" "$snap" | sed -n 's/^  class/  there, class/p'
    fi
    [ -f "$OUT/$sc-dcm-paper.curve" ] && awk '{ printf "paper variant, requested %s%% (evaluated %s%%): L1 / L2 %.4f / %.4f, CPU %s s\n", $1, $2, $3, $4, $5 }' "$OUT/$sc-dcm-paper.curve"
    for v in dcm painter; do
      [ -f "$OUT/$sc-confirm-$v.curve" ] && awk -v v=$v '{ printf "confirm: %s --stop-at %s: L1 / L2 %.4f / %.4f, CPU %s s\n", v, $1, $2, $3, $4 }' "$OUT/$sc-confirm-$v.curve"
    done
    echo
  } | tee -a "$OUT/crossing.txt"
done
