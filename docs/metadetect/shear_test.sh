#!/usr/bin/env bash
# The metadetect shear test (docs/metadetect.md, "Shear tests"): CELLS shear pairs of cells from
# `stampede sim cells --pair` (its options after the fourth argument), each sign run through
# `stampede metadetect`, then `stampede metrics --metadetect` for m and c with bootstrap errors over
# cells. With ROTATE=1 the same cells' scenes turned by 90 degrees (`sim cells --rotate`) join their
# cells (ring-pair cancellation of the intrinsic shapes). Prints the metrics and writes
# WORKDIR/LABEL.json; METADETECT_OPTIONS are passed to `stampede metadetect`, METRICS_OPTIONS to
# `stampede metrics` (e.g. --cut-t-ratio 0.5 for --measurement pgauss).
#   usage: docs/metadetect/shear_test.sh BUILD_DIR WORKDIR CELLS LABEL [sim cells options ...]
#   e.g.:  ROTATE=1 docs/metadetect/shear_test.sh build /tmp/mdet 200 random_nf --snr 1e4 --layout random
set -euo pipefail
build=$1 work=$2 cells=$3 label=$4
shift 4
stampede=$build/tools/stampede
mkdir -p "$work"
variants=("")
if [ "${ROTATE:-0}" = 1 ]; then variants+=(rot); fi
start=$(date +%s.%N)
for v in "${variants[@]}"; do
  dir=$work/$label${v:+_$v}
  "$stampede" sim cells --out "$dir" --cells "$cells" --pair --overwrite ${v:+--rotate} "$@" 2>/dev/null
  for sign in plus minus; do
    if [ $sign = plus ]; then ls "$dir"/cell_*.fits >"$dir/$sign.list"; else ls "$dir"/minus/cell_*.fits >"$dir/$sign.list"; fi
    "$stampede" metadetect --input-list "$dir/$sign.list" -o "$dir/$sign.fits" --overwrite --quiet ${METADETECT_OPTIONS:-}
  done
done
end=$(date +%s.%N)
echo "$label: ${#variants[@]} x $((2 * cells)) cells simulated and measured in $(echo "$end - $start" | bc) s wall"
rotated=()
if [ "${ROTATE:-0}" = 1 ]; then rotated=(--rotated "$work/${label}_rot/plus.fits" --rotated-minus "$work/${label}_rot/minus.fits"); fi
"$stampede" metrics --metadetect "$work/$label/plus.fits" --minus "$work/$label/minus.fits" "${rotated[@]}" \
  --json "$work/$label.json" ${METRICS_OPTIONS:-}
