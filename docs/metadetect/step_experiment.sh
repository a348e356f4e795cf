#!/usr/bin/env bash
# The metacal step experiment of docs/metadetect.md ("The metacal step and the random layouts' R"):
# the same shear-pair cells measured at several metacal steps, to see how the response's noise
# from selection events between 1p and 1m (sigma(R11) per rotated pair of cells) falls with the
# step, and what bias the larger step brings on the nearly noise-free grid.
#   usage: docs/metadetect/step_experiment.sh BUILD_DIR WORKDIR [PAIRS_RANDOM PAIRS_GRID PAIRS_RANDOM_NF [STEPS...]]
# (a noise-free random cell costs ~5x an S/N 20 one: its isophotes and stamps are large, so it may
# take fewer pairs; they are the first of the random cells simulated).
# Writes WORKDIR/<layout>_step<S>.json (stampede metrics --metadetect) and WORKDIR/steps.txt, a
# line per (layout, step): R11, sigma(R11) per unit (the bootstrap error x sqrt(pairs): a unit is a
# cell with its shear partner and, for the random layouts, its rotated scene and partner), m1 and
# its error, sigma_m per unit, the CPU-seconds per measured cell, and the pairs.
# THREADS (default 1) is passed to sim cells and metadetect; the CPU figure assumes a lone core.
set -euo pipefail
build=$1 work=$2 random=${3:-200} grid=${4:-300} random_nf=${5:-${3:-200}}
shift $(( $# < 5 ? $# : 5 ))
steps=("$@")
if [ ${#steps[@]} = 0 ]; then steps=(0.01 0.02 0.04); fi
stampede=$build/tools/stampede
threads=${THREADS:-1}
mkdir -p "$work"
: >"$work/steps.txt"

# simulate LABEL ROTATE CELLS sim-options...: the cells of one layout (and its rotated scenes), once.
simulate() {
  local label=$1 rotate=$2 cells=$3
  shift 3
  local variants=("")
  if [ "$rotate" = 1 ]; then variants+=(rot); fi
  for v in "${variants[@]}"; do
    local dir=$work/$label${v:+_$v}
    if [ -f "$dir/minus.list" ]; then continue; fi
    "$stampede" sim cells --out "$dir" --cells "$cells" --pair --overwrite --threads "$threads" ${v:+--rotate} "$@" 2>/dev/null
    ls "$dir"/cell_*.fits >"$dir/plus.list"
    ls "$dir"/minus/cell_*.fits >"$dir/minus.list"
  done
}

# lists LABEL ROTATE PAIRS: the first PAIRS cells of each list, in LIST.PAIRS.
lists() {
  local variants=("")
  if [ "$2" = 1 ]; then variants+=(rot); fi
  for v in "${variants[@]}"; do
    for sign in plus minus; do head -n "$3" "$work/$1${v:+_$v}/$sign.list" >"$work/$1${v:+_$v}/$sign.list.$3"; done
  done
}

# measure LABEL ROTATE STEP: every table of the layout at STEP, then its metrics and a line of steps.txt.
measure() {
  local label=$1 rotate=$2 step=$3 pairs=$4
  local variants=("") cells=0
  if [ "$rotate" = 1 ]; then variants+=(rot); fi
  local start end
  start=$(date +%s.%N)
  for v in "${variants[@]}"; do
    local dir=$work/$label${v:+_$v}
    for sign in plus minus; do
      "$stampede" metadetect --input-list "$dir/$sign.list.$pairs" -o "$dir/${sign}_step$step.fits" --step "$step" \
        --threads "$threads" --overwrite --quiet
      cells=$((cells + pairs))
    done
  done
  end=$(date +%s.%N)
  local rotated=()
  if [ "$rotate" = 1 ]; then
    rotated=(--rotated "$work/${label}_rot/plus_step$step.fits" --rotated-minus "$work/${label}_rot/minus_step$step.fits")
  fi
  "$stampede" metrics --metadetect "$work/$label/plus_step$step.fits" --minus "$work/$label/minus_step$step.fits" \
    "${rotated[@]}" --json "$work/${label}_step$step.json" >/dev/null
  python3 - "$work/${label}_step$step.json" "$label" "$step" "$pairs" "$start" "$end" "$cells" "$threads" \
    >>"$work/steps.txt" <<'EOF'
import json, math, sys
j = json.load(open(sys.argv[1]))
label, step, pairs = sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
seconds, cells, threads = float(sys.argv[6]) - float(sys.argv[5]), int(sys.argv[7]), int(sys.argv[8])
root = math.sqrt(pairs)
print(f"{label} step={step:g} R11={j['R11']:.5f} R11_err={j['R11_err']:.5f} sigmaR_unit={j['R11_err'] * root:.4f} "
      f"m1={j['m1']:+.3e} m1_err={j['m1_err']:.2e} sigmam_unit={j['m1_err'] * root:.3e} "
      f"c2={j['c2']:+.2e} c2_err={j['c2_err']:.1e} cpu_s_per_cell={seconds * threads / cells:.4f} pairs={pairs}")
EOF
  tail -n 1 "$work/steps.txt"
}

simulate random_s20 1 "$random" --snr 20 --layout random --keep-clear 4
simulate grid_nf 0 "$grid" --snr 1e4
simulate random_nf 1 "$random_nf" --snr 1e4 --layout random --keep-clear 4
lists random_s20 1 "$random"
lists grid_nf 0 "$grid"
lists random_nf 1 "$random_nf"
for layout in random_s20 grid_nf random_nf; do
  for step in "${steps[@]}"; do
    case $layout in
      random_s20) measure random_s20 1 "$step" "$random" ;;
      grid_nf) measure grid_nf 0 "$step" "$grid" ;;
      random_nf) measure random_nf 1 "$step" "$random_nf" ;;
    esac
  done
done
