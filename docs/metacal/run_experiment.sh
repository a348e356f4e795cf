#!/usr/bin/env bash
# Metacalibration on GREAT08-like noisy sets (issue 21, must-show 3): the population of
# docs/calibration (co-elliptical bulge + disc, Rgp/Rp = 1.4, Moffat beta 3 FWHM 2.85 e = (0, 0.05),
# |g| < 0.05, 39 px stamps, ring pairs and noise pairs) in shear pairs (sets 2j and 2j+1: the same
# galaxies and noise under +g and -g), fitted with the exact renderer twice per
# set: plainly (the uncalibrated figure) and with metacal = true; `stampede metrics` of both, the
# metacal table through --metacal, both also paired (--shear-pairs), into OUTDIR/results.md (docs/metacal/summarize.py).
#
#   docs/metacal/run_experiment.sh OUTDIR
#
# Environment: SETS=8 GRID=100 (10,000 galaxies per set) SNRS="20 40 10" THREADS=(all cores)
# STAMPEDE=build/tools/stampede PYTHON=python3. Each step skips outputs that exist (a stopped run
# restarts where it was; a fit's .partial is resumed). Cost per galaxy on this machine's cores:
# ~25 CPU-ms to simulate, ~60 for metacal, ~9 for the plain fit: ~7,500 CPU-seconds per S/N level
# at the default size (the session that ran it: S/N 20 at 8 x 10,000, S/N 40 and 10 at GRID=50).
set -euo pipefail
out=${1:?usage: run_experiment.sh OUTDIR}
SETS=${SETS:-8}  # even: shear pairs
GRID=${GRID:-100}
SNRS=${SNRS:-"20 40 10"}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
PYTHON=${PYTHON:-python3}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
mkdir -p "$out"
psf=(--set psf_input=moffat --set psf_beta=3 --set psf_fwhm=2.85 --set psf_e1=0 --set psf_e2=0.05 --set noise_sigma=1
     --set renderer=exact)

fit() {  # SET OUTPUT [--set ...]
  local set=$1 output=$2
  shift 2
  [[ -f "$output" ]] && return 0
  local resume=()
  [[ -f "$output.partial" ]] && resume=(--resume)
  "$STAMPEDE" fit "$set" -o "$output" "${psf[@]}" "$@" "${threads[@]}" "${resume[@]}"
}

for snr in $SNRS; do
  dir="$out/snr$snr"
  if [[ ! -f "$dir/set_$((SETS - 1)).fits" ]]; then
    "$STAMPEDE" sim great08 --out "$dir" --sets "$SETS" --grid "$GRID" --snr "$snr" --noise-pairs --shear-pairs \
      --seed $((5000 + snr)) --overwrite --galaxy bd --size 1.4 --psf moffat --psf-beta 3 --psf-fwhm 2.85 \
      --psf-e1 0 --psf-e2 0.05 --noise-sigma 1 "${threads[@]}"
  fi
  plain=() metacal=()
  for ((k = 0; k < SETS; k++)); do
    fit "$dir/set_$k.fits" "$dir/plain_$k.fits"
    fit "$dir/set_$k.fits" "$dir/metacal_$k.fits" --set metacal=true --set metacal_model=bd
    plain+=(--fit "$dir/plain_$k.fits" --truth "$dir/truth_$k.fits")
    metacal+=(--fit "$dir/metacal_$k.fits" --truth "$dir/truth_$k.fits")
  done
  "$STAMPEDE" metrics --shear-pairs "${plain[@]}" --json "$dir/plain.json" | tee "$dir/plain.txt"
  "$STAMPEDE" metrics --shear-pairs --metacal "${metacal[@]}" --json "$dir/metacal.json" | tee "$dir/metacal.txt"
done
"$PYTHON" "$(dirname "$0")/summarize.py" "$out" $SNRS > "$out/results.md"
cat "$out/results.md"
