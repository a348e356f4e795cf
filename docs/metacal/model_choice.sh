#!/usr/bin/env bash
# Issue 30 item 4: which model metacal's five fits should use (metacal_model = bd, exp, gauss),
# judged by the per-object response scatter, the shear error per object and the cost. GREAT08-like
# S/N 20 sets (the docs/calibration population: co-elliptical bulge + disc, Rgp/Rp 1.4, Moffat
# beta 3 FWHM 2.85 e = (0, 0.05)), ring pairs, noise pairs and shear pairs (sets 2j, 2j+1: the same
# galaxies and noise under +g and -g), each fitted with metacal once per model; `stampede metrics
# --metacal --shear-pairs` per model, and the response's distribution, into OUTDIR/results.md
# (docs/metacal/model_choice.py).
#
#   docs/metacal/model_choice.sh OUTDIR
#
# Environment: SETS=2 GRID=40 SNR=20 MODELS="bd exp gauss" THREADS=(all cores)
# STAMPEDE=build/tools/stampede PYTHON=python3 (with numpy; PYTHONPATH=build/python). Outputs that
# exist are kept.
set -euo pipefail
out=${1:?usage: model_choice.sh OUTDIR}
SETS=${SETS:-2}
GRID=${GRID:-40}
SNR=${SNR:-20}
MODELS=${MODELS:-"bd exp gauss"}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
PYTHON=${PYTHON:-python3}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
mkdir -p "$out"
if [[ ! -f "$out/sim/set_$((SETS - 1)).fits" ]]; then
  "$STAMPEDE" sim great08 --out "$out/sim" --sets "$SETS" --grid "$GRID" --snr "$SNR" --noise-pairs --shear-pairs \
    --seed 3030 --overwrite "${threads[@]}"
fi
for model in $MODELS; do
  for ((k = 0; k < SETS; ++k)); do
    o="$out/$model/fit_$k.fits"
    [[ -f "$o" ]] && continue
    mkdir -p "$out/$model"
    "$STAMPEDE" fit "$out/sim/set_$k.fits" -o "$o" --set metacal=true --set metacal_model="$model" \
      --set noise_sigma=1 "${threads[@]}"
  done
  args=()
  for ((k = 0; k < SETS; ++k)); do args+=(--fit "$out/$model/fit_$k.fits" --truth "$out/sim/truth_$k.fits"); done
  "$STAMPEDE" metrics "${args[@]}" --metacal --shear-pairs --json "$out/$model/metrics.json" > "$out/$model/metrics.txt"
done
"$PYTHON" "$(dirname "$0")/model_choice.py" "$out" $MODELS | tee "$out/results.md"
