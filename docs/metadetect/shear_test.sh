#!/usr/bin/env bash
# The metadetect shear test (docs/metadetect.md, "Shear tests"): CELLS shear pairs of cells from
# `stampede sim cells --pair` (its options after the fourth argument), each sign run through
# `stampede metadetect`, then `stampede metrics --metadetect` for m and c with bootstrap errors over
# cells. Prints the metrics and writes WORKDIR/LABEL.json.
#   usage: docs/metadetect/shear_test.sh BUILD_DIR WORKDIR CELLS LABEL [sim cells options ...]
#   e.g.:  docs/metadetect/shear_test.sh build /tmp/mdet 200 grid_nf --snr 1e4
set -euo pipefail
build=$1 work=$2 cells=$3 label=$4
shift 4
stampede=$build/tools/stampede
mkdir -p "$work"
dir=$work/$label
"$stampede" sim cells --out "$dir" --cells "$cells" --pair --overwrite "$@" 2>/dev/null
ls "$dir"/cell_*.fits >"$dir/plus.list"
ls "$dir"/minus/cell_*.fits >"$dir/minus.list"
start=$(date +%s.%N)
"$stampede" metadetect --input-list "$dir/plus.list" -o "$dir/plus.fits" --overwrite --quiet ${METADETECT_OPTIONS:-}
"$stampede" metadetect --input-list "$dir/minus.list" -o "$dir/minus.fits" --overwrite --quiet ${METADETECT_OPTIONS:-}
end=$(date +%s.%N)
echo "$label: $((2 * cells)) cells measured in $(echo "$end - $start" | bc) s wall"
"$stampede" metrics --metadetect "$dir/plus.fits" --minus "$dir/minus.fits" --json "$work/$label.json"
