#!/bin/sh
# seed_means.sh — the mean luminance of a render against a converged one, over several seeds:
# prints the mean over seeds 0 .. N-1 of (mean luminance / converged mean luminance - 1), its
# standard error, and the mean relMSE (issue 21: is a method biased, and by how much?).
#
#   bench/ias/seed_means.sh PENUMBRA SCENE CONVERGED.exr N render-options...
#
# Environment: CROP (0.45,0.55,0.45,0.55, the crop the converged render was made with), THREADS (2).
# Example (the weights' bias of docs/adaptive-sampling.md, "ias"; converged renders from
# bench/ias/aa_converge.sh):
#   sh bench/ias/seed_means.sh build/penumbra ../shared/scenes/hall-many/hall-many-matte.pbrt \
#       OUT/hall-many-matte-ref2048-s1000.exr 8 --integrator ias --threshold 1e-7 --max-passes 4 --ias-aa-threshold 0
# and the environment floor's (stop 17): living-env-138-matte, `--integrator ias --threshold 0.001`
# with `--ias-env-floor 0`, `1`, `2` (the default), each also with `--adaptive-rule cross`.
set -eu
PN=$1
SCENE=$2
REF=$3
N=$4
shift 4
CROP=${CROP:-0.45,0.55,0.45,0.55}
THREADS=${THREADS:-2}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
seed=0
while [ "$seed" -lt "$N" ]; do
    "$PN" render "$SCENE" --crop "$CROP" --threads "$THREADS" --quiet --seed "$seed" "$@" -o "$tmp/img.exr" 2>/dev/null
    "$PN" diff "$REF" "$tmp/img.exr" --json | awk '
        /"mean_luminance_reference"/ { gsub(",", "", $2); r = $2 }
        /"mean_luminance_image"/ { gsub(",", "", $2); i = $2 }
        /"relmse"/ { gsub(",", "", $2); m = $2 }
        END { printf "%.6f %s\n", 100 * (i / r - 1), m }'
    seed=$((seed + 1))
done | awk -v args="$*" '
    { s += $1; q += $1 * $1; m += $2; n++ }
    END { mu = s / n; sd = n > 1 ? sqrt((q / n - mu * mu) * n / (n - 1)) : 0;
          printf "%-60s dmean %+.3f%% +- %.3f%% (n=%d) relmse %.3e\n", args, mu, sd / sqrt(n), n, m / n }'
