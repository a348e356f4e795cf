#!/usr/bin/env bash
# Noise-bias calibration experiment (issue 5; im3shape section 5.3 and appendix C), GREAT08-like
# fiducial branch: co-elliptical bulge + disc, Rgp/Rp = 1.4, Moffat beta 3 FWHM 2.85 e = (0, 0.05).
#
#   docs/calibration/run_experiment.sh OUTDIR [STAGE ...]
#
# Stages (default: all, in this order; each skips work whose output exists, so a stopped run
# can be restarted):
#   science-SNR  sim + fit SETS sets of GRID^2 galaxies at S/N = SNR (SNR from SNRS)
#   deep         sim + fit the deep sample of the same population at S/N 200
#   extra        sim + fit the EXTRA_BATCHES (below), each in OUTDIR/snrSNR_seedSEED
#   build        stampede calibrate build at S/N 20 with the science configuration
#   apply        stampede calibrate apply (population mode, and per-object mode for comparison) to
#                every science set (an S/N's extra batches pooled with its sets); metrics of e, of the
#                population- and of the per-object-calibrated e -> OUTDIR/results.md; at an S/N
#                named in MATCHED_CALIBRATIONS also with the table measured at that S/N
#
# Environment (defaults = the issue's experiment): SETS=8 GRID=100 DEEP_GRID=100 SNRS="20 40 10"
# REALISATIONS=16 (noise pairs per calibration grid point) THREADS=(all cores) STAMPEDE=build/tools/stampede
# EXTRA_BATCHES="SNR:SETS:SEED ..." (default none): more sets at an S/N, simulated with another seed
# (so new galaxies, noise and shears) and pooled with its sets, e.g. "20:12:3020"
# BUILD_ARGS (extra options of calibrate build, e.g. --radii, or a smaller grid for a dry run)
# CALIBRATION=OUTDIR/calibration.fits (the table build makes and apply uses)
# MATCHED_CALIBRATIONS="SNR:TABLE ..." (default none): tables built by hand with `calibrate build
# --snr SNR`, applied (population mode) to that S/N's sets as well, e.g. "10:OUTDIR/cal_snr10.fits"
# PYTHON=python3 (with numpy and astropy, for the tables)
# SHEAR_PAIRS=1 (default 0): science and extra sets as shear pairs (sim --shear-pairs, SETS even):
# set 2j+1 repeats set 2j's galaxies and noise under -g, and metrics --shear-pairs measures m from
# half the pair differences, where shape noise and pixel noise cancel; SHEAR=G1,G2 fixes every
# pair's shear (a longer lever arm than U(-0.05, 0.05) shears)
#
# Every science set uses --noise-pairs: objects 4q+2, 4q+3 repeat the ring pair 4q, 4q+1 with the
# pixel noise negated. Expectations are those of plain GREAT08 sets; the scatter of the set means is
# ~3x smaller (measured: 0.034 vs 0.11 per group at S/N 20), i.e. ~10x fewer galaxies for the same
# error on m.
set -euo pipefail
out=${1:?usage: run_experiment.sh OUTDIR [STAGE ...]}
shift
stages=("$@")
SETS=${SETS:-8}
GRID=${GRID:-100}
DEEP_GRID=${DEEP_GRID:-100}
SNRS=${SNRS:-"20 40 10"}
REALISATIONS=${REALISATIONS:-16}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
SHEAR_PAIRS=${SHEAR_PAIRS:-0}
pairing=()  # sim options of the science and extra sets
[[ $SHEAR_PAIRS == 1 ]] && pairing+=(--shear-pairs)
[[ -n "${SHEAR:-}" ]] && pairing+=(--shear "$SHEAR")
EXTRA_BATCHES=${EXTRA_BATCHES:-}
CALIBRATION=${CALIBRATION:-$out/calibration.fits}
if [[ ${#stages[@]} -eq 0 ]]; then
  stages=()
  for s in $SNRS; do stages+=("science-$s"); done
  stages+=(extra deep build apply)
fi
mkdir -p "$out"

# The science configuration: the fitter's defaults, the PSF of the simulations, weights 1/sigma^2.
cat > "$out/run.ini" <<INI
# stampede fit configuration of the calibration experiment (written by run_experiment.sh)
psf_input = moffat
psf_beta = 3
psf_fwhm = 2.85
psf_e1 = 0
psf_e2 = 0.05
noise_sigma = 1
INI
sim_common=(--galaxy bd --size 1.4 --psf moffat --psf-beta 3 --psf-fwhm 2.85 --psf-e1 0 --psf-e2 0.05
            --noise-sigma 1 "${threads[@]}")

fit_sets() {  # DIR: fit every set_K.fits that has no fit_K.fits yet
  local dir=$1
  for set in "$dir"/set_*.fits; do
    local k=${set##*/set_}; k=${k%.fits}
    [[ -f "$dir/fit_$k.fits" ]] && continue
    local resume=()
    [[ -f "$dir/fit_$k.fits.partial" ]] && resume=(--resume)
    "$STAMPEDE" fit "$set" -o "$dir/fit_$k.fits" --config "$out/run.ini" "${threads[@]}" "${resume[@]}"
  done
}

science() {  # SNR
  local snr=$1 dir="$out/snr$1"
  if [[ ! -f "$dir/set_$((SETS - 1)).fits" ]]; then
    "$STAMPEDE" sim great08 --out "$dir" --sets "$SETS" --grid "$GRID" --snr "$snr" --noise-pairs --seed $((1000 + ${snr%.*})) \
      --overwrite "${sim_common[@]}" "${pairing[@]}"
  fi
  fit_sets "$dir"
}

extra() {
  local batch snr sets seed dir
  for batch in $EXTRA_BATCHES; do
    IFS=: read -r snr sets seed <<< "$batch"
    dir="$out/snr${snr}_seed$seed"
    if [[ ! -f "$dir/set_$((sets - 1)).fits" ]]; then
      "$STAMPEDE" sim great08 --out "$dir" --sets "$sets" --grid "$GRID" --snr "$snr" --noise-pairs --seed "$seed" \
        --overwrite "${sim_common[@]}" "${pairing[@]}"
    fi
    fit_sets "$dir"
  done
}

deep() {
  local dir="$out/deep"
  [[ -f "$dir/set_0.fits" ]] || "$STAMPEDE" sim great08 --out "$dir" --sets 1 --grid "$DEEP_GRID" --snr 200 --seed 2000 \
    --overwrite "${sim_common[@]}"
  fit_sets "$dir"
}

build() {
  [[ -f "$CALIBRATION" ]] && return 0
  local resume=()
  [[ -f "$CALIBRATION.partial" ]] && resume=(--resume)
  "$STAMPEDE" calibrate build -o "$CALIBRATION" --config "$out/run.ini" --snr 20 \
    --realisations "$REALISATIONS" "${threads[@]}" "${resume[@]}" ${BUILD_ARGS:-}
}

population() {  # TABLE FIT OUT: population-mode calibration against the deep sample
  "$STAMPEDE" calibrate apply "$2" --deep "$out/deep/fit_0.fits" --calibration "$1" -o "$3" --overwrite --quiet
}

apply() {
  local table="$out/results.md"
  : > "$table.tmp"
  for snr in $SNRS; do
    # snrSNR may be moved aside to use only the extra batches; the metrics still go there.
    local fits=() cal=() obj=() matched=() sets=() set_dir k matched_table="" entry
    for entry in ${MATCHED_CALIBRATIONS:-}; do [[ ${entry%%:*} == "$snr" ]] && matched_table=${entry#*:}; done
    for set in "$out/snr$snr"/set_*.fits "$out/snr${snr}_seed"*/set_*.fits; do [[ -e $set ]] && sets+=("$set"); done
    for set in "${sets[@]}"; do
      set_dir=${set%/set_*} k=${set##*/set_}; k=${k%.fits}
      if [[ ! -f "$set_dir/fit_$k.fits" ]]; then
        echo "apply: $set_dir/fit_$k.fits not made yet: set left out" >&2
        continue
      fi
      if [[ $SHEAR_PAIRS == 1 && ! -f "$set_dir/fit_$((k ^ 1)).fits" ]]; then
        echo "apply: $set_dir/fit_$((k ^ 1)).fits (the shear-pair partner) not made yet: set left out" >&2
        continue
      fi
      population "$CALIBRATION" "$set_dir/fit_$k.fits" "$set_dir/cal_$k.fits"
      "$STAMPEDE" calibrate apply "$set_dir/fit_$k.fits" --per-object --calibration "$CALIBRATION" \
        -o "$set_dir/obj_$k.fits" --overwrite --quiet
      if [[ -n $matched_table ]]; then
        population "$matched_table" "$set_dir/fit_$k.fits" "$set_dir/matched_$k.fits"
        matched+=(--fit "$set_dir/matched_$k.fits" --truth "$set_dir/truth_$k.fits")
      else
        rm -f "$set_dir/matched_$k.fits"  # galaxy_bias.py reads every matched_K.fits it finds
      fi
      fits+=(--fit "$set_dir/fit_$k.fits" --truth "$set_dir/truth_$k.fits")
      cal+=(--fit "$set_dir/cal_$k.fits" --truth "$set_dir/truth_$k.fits")
      obj+=(--fit "$set_dir/obj_$k.fits" --truth "$set_dir/truth_$k.fits")
    done
    if [[ ${#fits[@]} -eq 0 ]]; then
      echo "apply: no fitted sets at S/N $snr: left out" >&2
      continue
    fi
    local dir="$out/snr$snr" paired=()
    # Glob order keeps each pair's sets 2j, 2j+1 together, + before -, as --shear-pairs wants.
    [[ $SHEAR_PAIRS == 1 ]] && paired=(--shear-pairs)
    mkdir -p "$dir"
    "$STAMPEDE" metrics "${paired[@]}" "${fits[@]}" --json "$dir/metrics_uncalibrated.json" > "$dir/metrics_uncalibrated.txt"
    "$STAMPEDE" metrics "${paired[@]}" "${cal[@]}" --e-columns e1_cal,e2_cal --json "$dir/metrics_calibrated.json" > "$dir/metrics_calibrated.txt"
    "$STAMPEDE" metrics "${paired[@]}" "${obj[@]}" --e-columns e1_cal,e2_cal --json "$dir/metrics_per_object.json" > "$dir/metrics_per_object.txt"
    local line="$snr $dir/metrics_uncalibrated.json $dir/metrics_calibrated.json $dir/metrics_per_object.json"
    if [[ ${#matched[@]} -gt 0 ]]; then
      "$STAMPEDE" metrics "${paired[@]}" "${matched[@]}" --e-columns e1_cal,e2_cal --json "$dir/metrics_matched.json" > "$dir/metrics_matched.txt"
      line+=" $dir/metrics_matched.json"
    fi
    echo "$line" >> "$table.tmp"
  done
  local dirs=()
  for snr in $SNRS; do
    local pooled="$out/snr$snr" extra_dir
    for extra_dir in "$out/snr${snr}_seed"*; do [[ -d $extra_dir ]] && pooled+=",$extra_dir"; done
    dirs+=("$pooled")
  done
  {
    "${PYTHON:-python3}" "$(dirname "$0")/table.py" "$table.tmp"
    echo
    echo "Per-galaxy bias against the truth (galaxy_bias.py):"
    echo
    "${PYTHON:-python3}" "$(dirname "$0")/galaxy_bias.py" "${dirs[@]}"
  } > "$table"
  rm -f "$table.tmp"
  cat "$table"
}

for stage in "${stages[@]}"; do
  echo "== $stage ($(date -u +%H:%M:%S))" >&2
  case $stage in
    science-*) science "${stage#science-}" ;;
    extra) extra ;;
    deep) deep ;;
    build) build ;;
    apply) apply ;;
    *) echo "unknown stage '$stage'" >&2; exit 2 ;;
  esac
done
