#!/usr/bin/env bash
# Issue 43 must-show 2 on 4-epoch `sim meds` tiles, by noise pairs: tile A (S/N 30), its noise-free
# twin F (same seed), and B = 2F - A, the same galaxies with A's noise negated (weights A's). With
# one metacal_seed on A and B their fixnoise fields are equal, so half the pair difference in e is
# the pixel noise's first-order effect (its second-order terms cancel); A with a second
# metacal_seed gives the fixnoise field's part. Each against the stated e_err, in
# docs/metacal/meds_noise_pairs.py; the plain bd fit's noise pairs beside them.
#
#   docs/metacal/meds_noise_pairs.sh OUTDIR
#
# Environment: OBJECTS=2000 (the tiles) SHARD=0/10 (the objects fitted with metacal) PLAIN_SHARD=0/2
# STAMPEDE=build/tools/stampede PYTHON=python3 (numpy, astropy) THREADS=
set -euo pipefail
out=${1:?usage: meds_noise_pairs.sh OUTDIR}
OBJECTS=${OBJECTS:-2000} SHARD=${SHARD:-0/10} PLAIN_SHARD=${PLAIN_SHARD:-0/2}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
PYTHON=${PYTHON:-python3}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
mkdir -p "$out"
[[ -f "$out/A/meds.fits" ]] || "$STAMPEDE" sim meds --out "$out/A" --objects "$OBJECTS" --snr 30 --seed 4360 "${threads[@]}" > /dev/null
[[ -f "$out/F/meds.fits" ]] || "$STAMPEDE" sim meds --out "$out/F" --objects "$OBJECTS" --snr 30 --seed 4360 --noise-free \
  "${threads[@]}" > /dev/null
[[ -f "$out/B/meds.fits" ]] || "$PYTHON" "$(dirname "$0")/meds_noise_pairs.py" negate "$out"
fit() {
  local f=$1 shard=$2
  shift 2
  [[ -f "$out/$f" ]] || "$STAMPEDE" fit "$@" -o "$out/$f" --shard "$shard" --quiet "${threads[@]}"
}
fit plain_A.fits "$PLAIN_SHARD" --meds "$out/A/meds.fits"
fit plain_B.fits "$PLAIN_SHARD" --meds "$out/B/meds.fits"
for model in bd wmom; do
  for run in A1 B1 A2; do
    fit "${model}_$run.fits" "$SHARD" --meds "$out/${run:0:1}/meds.fits" --set metacal=true --set metacal_model=$model \
      --set metacal_seed="${run:1:1}"
  done
done
"$PYTHON" "$(dirname "$0")/meds_noise_pairs.py" table "$out" | tee "$out/results.md"
