#!/bin/sh
# bench/mpi/run.sh — MPI's parallel efficiency on this machine and the tile costs for the
# simulation beyond it (issue 16; docs/distributed.md; results in bench/RESULTS.md).
#
# Part 1: two bench scenes, 1 process and 2 MPI ranks, 1 thread each, RUNS runs alternated.
#   Per run: wall seconds of the whole command, the render (rank 0's tile loop), the scene load
#   (parse + BVH) and the CPU seconds of all processes; the 1-process run also records its tile
#   costs (--tile-times) for validating the simulation. Images of 1 and 2 ranks are compared
#   (cmp: they must be identical).
# Part 2: the tile costs of a 2048x2048 render of hall-many (315 lights) at SIM_SPP eye rays per
#   pixel in 16-pixel tiles (larger tiles are sums of these), for bench/mpi/simulate.py.
#   usage: bench/mpi/run.sh [OUT_DIR]   (env: RUNS, SIM_SPP, SKIP_SIM, PENUMBRA)
set -u
HERE=$(cd "$(dirname "$0")/../.." && pwd)
P=${PENUMBRA:-$HERE/build/penumbra}
S=$HERE/../shared/scenes
OUT=${1:-$HERE/bench/results/mpi}
RUNS=${RUNS:-3}
SIM_SPP=${SIM_SPP:-1}
mkdir -p "$OUT"
root=""
[ "$(id -u)" -eq 0 ] && root="--allow-run-as-root"
M="mpirun $root --oversubscribe -np 2"
now() { date +%s.%N; }
# "render load" from a stats JSON
stat_of() { sed -n "s/^ *\"$2\": *\([0-9.e+-]*\).*/\1/p" "$1" | head -1; }

echo "# scene ranks run wall render load cpu identical" > "$OUT/efficiency.txt"
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)" > "$OUT/machine.txt"
for case in "cornell $S/cornell-box/cornell-box-matte.pbrt --resolution 256x256 --spp 64" \
    "hall $S/hall-many/hall-many-matte.pbrt --resolution 384x384 --spp 8"; do
    set -- $case
    name=$1
    scene=$2
    shift 2
    A="$* --threads 1 --tile-size 64 --quiet"
    for run in $(seq 1 "$RUNS"); do
        for ranks in 1 2; do
            t0=$(now)
            if [ $ranks -eq 1 ]; then
                /usr/bin/time -f "%U %S" -o "$OUT/cpu" "$P" render "$scene" $A -o "$OUT/$name-1.exr" \
                    --stats "$OUT/$name-1-$run.json" --tile-times "$OUT/$name-tiles-$run.txt"
            else
                /usr/bin/time -f "%U %S" -o "$OUT/cpu" $M "$P" render "$scene" $A -o "$OUT/$name-2.exr" \
                    --stats "$OUT/$name-2-$run.json"
            fi
            t1=$(now)
            js=$OUT/$name-$ranks-$run.json
            cpu=$(awk '{print $1 + $2}' "$OUT/cpu")
            load=$(awk "BEGIN{print $(stat_of "$js" parse_seconds) + $(stat_of "$js" bvh_seconds)}")
            same=-
            [ $ranks -eq 2 ] && { cmp -s "$OUT/$name-1.exr" "$OUT/$name-2.exr" && same=yes || same=NO; }
            echo "$name $ranks $run $(awk "BEGIN{print $t1 - $t0}") $(stat_of "$js" render_seconds) $load $cpu $same" \
                >> "$OUT/efficiency.txt"
        done
    done
done
echo "load average after part 1: $(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/machine.txt"

# Part 2: tile costs of the 2048x2048 many-light render (SKIP_SIM=1 leaves it out).
[ "${SKIP_SIM:-0}" = 1 ] && { cat "$OUT/efficiency.txt" "$OUT/machine.txt"; exit 0; }
t0=$(now)
"$P" render "$S/hall-many/hall-many-matte.pbrt" --resolution 2048x2048 --spp "$SIM_SPP" --threads 1 \
    --tile-size 16 --quiet -o "$OUT/hall-2048.exr" --stats "$OUT/hall-2048.json" --tile-times "$OUT/hall-2048-tiles.txt"
echo "hall-2048 wall $(awk "BEGIN{print $(now) - $t0}")" >> "$OUT/machine.txt"
echo "load average after part 2: $(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/machine.txt"
cat "$OUT/efficiency.txt" "$OUT/machine.txt"
