#!/usr/bin/env bash
# Issue 32 must-show 3: the joint fit of three bands at S/N 20 per band against one band's alone.
# `sim meds --bands g,r,i` tiles (4 epochs per band, random WCS, per-band PSFs and colours) of N
# objects (ring pairs) under shears in shear pairs (+g and -g on the same galaxies and noise),
# each fitted jointly (--meds x3 --bands g,r,i) and on its g tile alone; docs/multiband/snr20.py
# compares the shape errors with the ratio the summed S/N^2 predicts and measures m and c of both.
#
#   docs/multiband/snr20.sh OUTDIR
#
# With METACAL=1 each set is also fitted with metacal across the bands (joint_metacal.fits) and
# docs/metacal/meds_tiles.py gives the calibrated m and c of the same pairs.
#
# Environment: N=1000 SNR=20 SHEARS="0.04,0 0,0.04" METACAL=0 MODEL=bd (its metacal_model) THREADS=(all cores) STAMPEDE=build/tools/stampede
# PYTHON=/usr/bin/python3 (numpy; PYTHONPATH=build/python). Steps whose outputs exist are skipped.
set -euo pipefail
out=${1:?usage: snr20.sh OUTDIR}
N=${N:-1000}
SNR=${SNR:-20}
SHEARS=${SHEARS:-"0.04,0 0,0.04"}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
PYTHON=${PYTHON:-/usr/bin/python3}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
mkdir -p "$out"
k=0
for g in $SHEARS; do
  g1=${g%,*} g2=${g#*,}
  for sign in p m; do
    if [[ $sign == p ]]; then shear="$g1,$g2"; else shear="$(awk -v a="$g1" -v b="$g2" 'BEGIN{printf "%g,%g", -a, -b}')"; fi
    d="$out/set${k}$sign"
    [[ -f "$d/i/meds.fits" ]] || "$STAMPEDE" sim meds --out "$d" --bands g,r,i --objects "$N" --snr "$SNR" \
      --shear "$shear" --seed $((700 + k)) --overwrite "${threads[@]}" > /dev/null 2>&1
    [[ -f "$d/joint.fits" ]] || "$STAMPEDE" fit --meds "$d/g/meds.fits" --meds "$d/r/meds.fits" --meds "$d/i/meds.fits" \
      --bands g,r,i -o "$d/joint.fits" --quiet "${threads[@]}"
    [[ -f "$d/g_only.fits" ]] || "$STAMPEDE" fit --meds "$d/g/meds.fits" -o "$d/g_only.fits" --quiet "${threads[@]}"
    [[ "${METACAL:-0}" == 0 || -f "$d/joint_metacal.fits" ]] || "$STAMPEDE" fit --meds "$d/g/meds.fits" \
      --meds "$d/r/meds.fits" --meds "$d/i/meds.fits" --bands g,r,i --set metacal=true --set metacal_model="${MODEL:-bd}" -o "$d/joint_metacal.fits" \
      --quiet "${threads[@]}"
  done
  k=$((k + 1))
done
"$PYTHON" "$(dirname "$0")/snr20.py" "$out" "$SHEARS" | tee "$out/results.txt"
if [[ "${METACAL:-0}" != 0 ]]; then
  FIT=joint_metacal.fits "$PYTHON" "$(dirname "$0")/../metacal/meds_tiles.py" "$out" "$SHEARS" | tee -a "$out/results.txt"
fi
