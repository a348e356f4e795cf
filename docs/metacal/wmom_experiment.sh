#!/usr/bin/env bash
# Issue 30 must-shows 1 and 2 with metacal_model = wmom: GREAT08-like sets (the population of
# docs/metacal/run_experiment.sh: co-elliptical bulge + disc, Rgp/Rp 1.4, Moffat beta 3 FWHM 2.85
# e = (0, 0.05), 39 px stamps, ring and noise pairs) in shear pairs at a fixed shear (sets 2j and
# 2j+1: the same galaxies and noise under +g and -g), each set fitted with metacal = true,
# metacal_model = wmom; `stampede metrics --shear-pairs --metacal` over every set, without a cut
# and with the cut (S/N >= 15 and size ratio >= 0.5 on every image) with R_S and without it, into
# OUTDIR/snrS/{all,cut,cut_without_rs}.txt.
#
#   docs/metacal/wmom_experiment.sh OUTDIR
#
# Environment: SNRS="20 40 10" PAIRS_20=32 PAIRS_40=8 PAIRS_10=8 (shear pairs per S/N, 2 x 2,500
# galaxies each) SHEAR=0.02,0.02 THREADS=(all cores) STAMPEDE=build/tools/stampede DEADLINE= (seconds
# since the epoch: no pair starts after it; the metrics cover the pairs done). A pair whose fits
# exist is skipped, so a stopped run goes on where it was and the metrics cover the pairs done.
# Cost per galaxy: ~12 CPU-ms to simulate, ~2 for the metacal row.
set -euo pipefail
out=${1:?usage: wmom_experiment.sh OUTDIR}
SNRS=${SNRS:-"20 40 10"}
SHEAR=${SHEAR:-0.02,0.02}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
psf=(--set psf_input=moffat --set psf_beta=3 --set psf_fwhm=2.85 --set psf_e1=0 --set psf_e2=0.05 --set noise_sigma=1
     --set renderer=exact)
for snr in $SNRS; do
  dir="$out/snr$snr"
  mkdir -p "$dir"
  pairs_var="PAIRS_$snr"
  pairs=${!pairs_var:-8}
  args=()
  for ((j = 0; j < pairs; j++)); do
    if [[ -n "${DEADLINE:-}" && ! -f "$dir/wmom_$((2 * j + 1)).fits" && $(date +%s) -ge $DEADLINE ]]; then
      echo "S/N $snr: deadline reached after $j pairs" >&2
      break
    fi
    for k in $((2 * j)) $((2 * j + 1)); do
      if [[ ! -f "$dir/wmom_$k.fits" ]]; then
        [[ -f "$dir/set_$k.fits" ]] || "$STAMPEDE" sim great08 --out "$dir" --first-set $((2 * j)) --sets 2 --grid 50 \
          --snr "$snr" --noise-pairs --shear-pairs --shear "$SHEAR" --seed $((9000 + snr)) --overwrite --galaxy bd \
          --size 1.4 --psf moffat --psf-beta 3 --psf-fwhm 2.85 --psf-e1 0 --psf-e2 0.05 --noise-sigma 1 "${threads[@]}" > /dev/null
        "$STAMPEDE" fit "$dir/set_$k.fits" -o "$dir/wmom_$k.fits" "${psf[@]}" --set metacal=true --set metacal_model=wmom \
          --quiet --overwrite "${threads[@]}"
        rm -f "$dir/set_$k.fits"  # 24 MB a set; the truth and the fit stay
      fi
      args+=(--fit "$dir/wmom_$k.fits" --truth "$dir/truth_$k.fits")
    done
  done
  "$STAMPEDE" metrics --shear-pairs --metacal "${args[@]}" > "$dir/all.txt"
  "$STAMPEDE" metrics --shear-pairs --metacal --cut-snr 15 --cut-size-ratio 0.5 "${args[@]}" > "$dir/cut.txt"
  "$STAMPEDE" metrics --shear-pairs --metacal --cut-snr 15 --cut-size-ratio 0.5 --no-selection-response "${args[@]}" \
    > "$dir/cut_without_rs.txt"
done
