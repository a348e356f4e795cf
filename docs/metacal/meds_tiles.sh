#!/usr/bin/env bash
# Issue 30 item 1: metacal on `sim meds` tiles (4 epochs, random WCS, per-epoch PSFEx PSFs).
# Sets of N objects (ring pairs) under shears in shear pairs (+g and -g on the same galaxies
# and noise: the tile's noise does not depend on the shear), fitted with metacal = true, measured
# by docs/metacal/meds_tiles.py (m from half the pair differences, c from half the sums).
#
#   docs/metacal/meds_tiles.sh OUTDIR
#
# Environment: N=32 SNR=30 NOISE_FREE=0 (1: --noise-free and metacal_fixnoise = false, the
# weight maps then describe a noise the pixels lack) SHEARS="0.02,-0.015 0.0,0.02"
# THREADS=(all cores) STAMPEDE=build/tools/stampede PYTHON=python3 (with numpy; PYTHONPATH=build/python)
# SHARD= (e.g. 0/2: fit only that shard of each tile, the same objects in every set) MODEL= (a
# metacal_model; empty: the run's default) KEEP_TILES=1 (0: delete each tile once fitted; ~185 kB
# an object).
set -euo pipefail
out=${1:?usage: meds_tiles.sh OUTDIR}
N=${N:-32}
SNR=${SNR:-30}
SHEARS=${SHEARS:-"0.02,-0.015 0.0,0.02"}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
PYTHON=${PYTHON:-python3}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
sim=(--objects "$N" --snr "$SNR")
fit=(--set metacal=true)
[[ -n "${SHARD:-}" ]] && fit+=(--shard "$SHARD")
[[ -n "${MODEL:-}" ]] && fit+=(--set metacal_model="$MODEL")
if [[ "${NOISE_FREE:-0}" == 1 ]]; then sim+=(--noise-free); fit+=(--set metacal_fixnoise=false); fi
mkdir -p "$out"
k=0
for g in $SHEARS; do
  g1=${g%,*} g2=${g#*,}
  for sign in p m; do
    if [[ $sign == p ]]; then shear="$g1,$g2"; else shear="$(awk -v a="$g1" -v b="$g2" 'BEGIN{printf "%g,%g", -a, -b}')"; fi
    d="$out/set${k}$sign"
    if [[ ! -f "$d/fit.fits" ]]; then
      [[ -f "$d/meds.fits" ]] || "$STAMPEDE" sim meds --out "$d" "${sim[@]}" --shear "$shear" --seed $((500 + k)) \
        --overwrite "${threads[@]}" > /dev/null 2>&1
      "$STAMPEDE" fit --meds "$d/meds.fits" -o "$d/fit.fits" "${fit[@]}" --quiet "${threads[@]}"
      [[ "${KEEP_TILES:-1}" == 1 ]] || rm -f "$d/meds.fits"
    fi
  done
  k=$((k + 1))
done
"$PYTHON" "$(dirname "$0")/meds_tiles.py" "$out" "$SHEARS" | tee "$out/results.txt"
