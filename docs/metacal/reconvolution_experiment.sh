#!/usr/bin/env bash
# Issue 52 must-show 4: `fit --metacal` (wmom, the default) with each reconvolution-PSF rule on the
# same S/N 20 sets: the population and shear pairs of docs/metacal/wmom_experiment.sh (co-elliptical
# bulge + disc, Moffat beta 3 FWHM 2.85 e = (0, 0.05), ring and noise pairs, shear +-(0.02, 0.02),
# seed 9020: the same galaxies and noise as its S/N 20 rows), each set fitted with
# metacal_reconvolution_psf = gauss and = moffat; `stampede metrics --shear-pairs --metacal` per rule
# into OUTDIR/RULE.txt. A set whose two fits exist is skipped.
#   docs/metacal/reconvolution_experiment.sh OUTDIR [PAIRS=8]
set -euo pipefail
out=${1:?usage: reconvolution_experiment.sh OUTDIR [PAIRS]}
pairs=${2:-8}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
psf=(--set psf_input=moffat --set psf_beta=3 --set psf_fwhm=2.85 --set psf_e1=0 --set psf_e2=0.05 --set noise_sigma=1
     --set renderer=exact)
mkdir -p "$out"
for ((j = 0; j < pairs; j++)); do
  for k in $((2 * j)) $((2 * j + 1)); do
    [[ -f "$out/gauss_$k.fits" && -f "$out/moffat_$k.fits" ]] && continue
    [[ -f "$out/set_$k.fits" ]] || "$STAMPEDE" sim great08 --out "$out" --first-set $((2 * j)) --sets 2 --grid 50 \
      --snr 20 --noise-pairs --shear-pairs --shear 0.02,0.02 --seed 9020 --overwrite --galaxy bd --size 1.4 \
      --psf moffat --psf-beta 3 --psf-fwhm 2.85 --psf-e1 0 --psf-e2 0.05 --noise-sigma 1 > /dev/null
    for rule in gauss moffat; do
      "$STAMPEDE" fit "$out/set_$k.fits" -o "$out/${rule}_$k.fits" "${psf[@]}" --set metacal=true \
        --set metacal_reconvolution_psf=$rule --quiet --overwrite
    done
    rm -f "$out/set_$k.fits"
  done
done
for rule in gauss moffat; do
  args=()
  for ((k = 0; k < 2 * pairs; k++)); do args+=(--fit "$out/${rule}_$k.fits" --truth "$out/truth_$k.fits"); done
  "$STAMPEDE" metrics --shear-pairs --metacal "${args[@]}" > "$out/$rule.txt"
  echo "== $rule"; cat "$out/$rule.txt"
done
