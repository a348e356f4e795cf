#!/usr/bin/env bash
# Issue 43 item 3: metacal's stated e errors and S/N against the scatter over noise, for one
# build or two (before and after), by docs/metacal/noise_errors.py.
#   Grids: one `sim great08 --noise-pairs` set at S/N 30 (objects 4q+2, 4q+3 are 4q, 4q+1 with the
#     pixel noise negated, and metacal negates their fixnoise fields alike), so half a pair's
#     difference in e is the images' noise's first-order effect: its rms over the stated error.
#   MEDS: a 4-epoch `sim meds` tile (S/N 30) fitted twice with different metacal_seed: the
#     difference is the fixnoise fields', half the images' noise power (issue 43's measure), so
#     its rms over the stated error is ~1 when the error is right.
#   Each against the plain fit of the same input for the S/N.
#
#   docs/metacal/noise_errors.sh OUTDIR
#
# Environment: STAMPEDE=build/tools/stampede, BEFORE= (another build's stampede: its rows too),
# GRID=40 (wmom; bd uses GRID_BD=24), OBJECTS=200 (MEDS; bd OBJECTS_BD=100), THREADS= (all cores),
# PYTHON=python3 with numpy, PYTHONPATH=build/python.
set -euo pipefail
out=${1:?usage: noise_errors.sh OUTDIR}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
GRID=${GRID:-40} GRID_BD=${GRID_BD:-24} OBJECTS=${OBJECTS:-200} OBJECTS_BD=${OBJECTS_BD:-100}
PYTHON=${PYTHON:-python3}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
mkdir -p "$out"
builds=("after=$STAMPEDE")
[[ -n "${BEFORE:-}" ]] && builds+=("before=$BEFORE")
for grid in "$GRID" "$GRID_BD"; do
  [[ -f "$out/grid$grid/set_0.fits" ]] || "$STAMPEDE" sim great08 --out "$out/grid$grid" --sets 1 --grid "$grid" --snr 30 \
    --noise-pairs --seed 4343 "${threads[@]}" > /dev/null
done
for objects in "$OBJECTS" "$OBJECTS_BD"; do
  [[ -f "$out/meds$objects/meds.fits" ]] || "$STAMPEDE" sim meds --out "$out/meds$objects" --objects "$objects" --snr 30 \
    --seed 4344 "${threads[@]}" > /dev/null
done
for b in "${builds[@]}"; do
  name=${b%%=*} exe=${b#*=}
  for model in wmom bd; do
    grid=$GRID objects=$OBJECTS
    [[ $model == bd ]] && grid=$GRID_BD objects=$OBJECTS_BD
    g="$out/grid$grid" m="$out/meds$objects"
    for dil in 0 1.5; do
      f="$out/${name}_grid_${model}_dil$dil.fits"
      [[ -f "$f" ]] || "$exe" fit "$g/set_0.fits" -o "$f" --set metacal=true --set metacal_model=$model \
        --set metacal_psf_dilation=$dil --quiet "${threads[@]}" 2> /dev/null
    done
    for seed in 1 2; do
      f="$out/${name}_meds_${model}_seed$seed.fits"
      [[ -f "$f" ]] || "$exe" fit --meds "$m/meds.fits" -o "$f" --set metacal=true --set metacal_model=$model \
        --set metacal_seed=$seed --quiet "${threads[@]}"
    done
  done
done
for objects in "$OBJECTS" "$OBJECTS_BD"; do
  [[ -f "$out/plain_meds$objects.fits" ]] || "$STAMPEDE" fit --meds "$out/meds$objects/meds.fits" -o "$out/plain_meds$objects.fits" --quiet "${threads[@]}"
done
for grid in "$GRID" "$GRID_BD"; do
  [[ -f "$out/plain_grid$grid.fits" ]] || "$STAMPEDE" fit "$out/grid$grid/set_0.fits" -o "$out/plain_grid$grid.fits" --quiet "${threads[@]}" 2> /dev/null
done
"$PYTHON" "$(dirname "$0")/noise_errors.py" "$out" "$GRID" "$GRID_BD" "$OBJECTS" "$OBJECTS_BD" | tee "$out/results.md"
