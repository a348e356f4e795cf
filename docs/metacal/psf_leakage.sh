#!/usr/bin/env bash
# Issue 30 item 3: metacal's additive response to the PSF's ellipticity, alpha_i = dc_i / de_psf,i.
# The same galaxies and noise (one seed) drawn under four PSFs, e_psf = (+-A, 0) and (0, +-A)
# (Moffat beta 3, FWHM 2.85), in shear pairs with ring and noise pairs at S/N 20, fitted with
# metacal; docs/metacal/psf_leakage.py takes c per component from each PSF's shear pairs and
# alpha from the differences, with a bootstrap over the noise-pair groups shared by all four runs
# (so the galaxies' and the noise's common part cancels), into OUTDIR/results.md.
#
#   docs/metacal/psf_leakage.sh OUTDIR
#
# Environment: A=0.06 GRID=40 SNR=20 MODEL=bd (metacal_model) THREADS=(all cores)
# STAMPEDE=build/tools/stampede PYTHON=python3 (with numpy; PYTHONPATH=build/python).
set -euo pipefail
out=${1:?usage: psf_leakage.sh OUTDIR}
A=${A:-0.06}
GRID=${GRID:-40}
SNR=${SNR:-20}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
PYTHON=${PYTHON:-python3}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
model=(--set metacal_model="${MODEL:-bd}")
mkdir -p "$out"
for psf in "p1 $A 0" "m1 -$A 0" "p2 0 $A" "m2 0 -$A"; do
  read -r name e1 e2 <<< "$psf"
  dir="$out/$name"
  if [[ ! -f "$dir/set_1.fits" ]]; then
    "$STAMPEDE" sim great08 --out "$dir" --sets 2 --grid "$GRID" --snr "$SNR" --noise-pairs --shear-pairs \
      --psf-e1 "$e1" --psf-e2 "$e2" --seed 4040 --overwrite "${threads[@]}"
  fi
  for k in 0 1; do
    [[ -f "$dir/fit_$k.fits" ]] && continue
    "$STAMPEDE" fit "$dir/set_$k.fits" -o "$dir/fit_$k.fits" --set metacal=true "${model[@]}" --set noise_sigma=1 \
      "${threads[@]}"
  done
done
"$PYTHON" "$(dirname "$0")/psf_leakage.py" "$out" "$A" | tee "$out/results.md"
