#!/usr/bin/env bash
# The shear tests of docs/metadetect.md ("Shear tests"), in order: the noise-free grid, noise-free
# random positions (blends) with per-object metacal at the noshear detections beside it, and S/N 20
# random positions. Each prints `stampede metrics --metadetect` and writes WORKDIR/<label>.json.
#   usage: docs/metadetect/run_experiments.sh BUILD_DIR WORKDIR [PAIRS_GRID PAIRS_RANDOM]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=$1 work=$2 grid=${3:-300} random=${4:-500}
stampede=$build/tools/stampede
"$here/shear_test.sh" "$build" "$work" "$grid" grid_nf --snr 1e4
ROTATE=1 "$here/shear_test.sh" "$build" "$work" "$random" random_nf --snr 1e4 --layout random --keep-clear 4
# Per-object metacal on the same cells: detection on the noshear image only.
for v in random_nf random_nf_rot; do
  for sign in plus minus; do
    "$stampede" metadetect --input-list "$work/$v/$sign.list" -o "$work/$v/po_$sign.fits" --per-object-metacal \
      --overwrite --quiet
  done
done
echo "random_nf, per-object metacal at the noshear detections:"
"$stampede" metrics --metadetect "$work/random_nf/po_plus.fits" --minus "$work/random_nf/po_minus.fits" \
  --rotated "$work/random_nf_rot/po_plus.fits" --rotated-minus "$work/random_nf_rot/po_minus.fits" \
  --json "$work/random_nf_per_object.json"
ROTATE=1 "$here/shear_test.sh" "$build" "$work" "$random" random_s20 --snr 20 --layout random --keep-clear 4
