#!/usr/bin/env bash
# Issue 56, must-shows 1 and 2 at scale: masked_shear_test.sh's cells and variants (the reference
# package's random-layout test, bright stars masked through each image's STARS table; default,
# --no-mask-symmetry, --no-mask-fill, no star table; the default without the mfrac cut) over CHUNKS
# chunks of PAIRS shear pairs each (sim cells --seed 1000 + k), each chunk's simulation deleted once
# measured (a chunk of 2,000 pairs is 4,000 cells, ~4 GB), its tables reduced to per-cell sums
# (pair_statistics.py extract) and deleted. Then every variant over every chunk's pairs
# (pair_statistics.py combine: per-cell and pooled estimators, bootstrap over pairs).
# SIM_OPTIONS adds `sim cells` options (e.g. "--stars 0 --bad-columns 2": masks from BMASK alone);
# VARIANTS picks the variants (default: the four above; no_fill_no_symmetry also exists).
#   usage: docs/survey_metadetect/masked_shear_campaign.sh [CHUNKS (12)] [PAIRS (2000)] [STARS (2)] [BUILD (build)] [WORK (/tmp/stampede-masked-campaign)]
set -euo pipefail
cd "$(dirname "$0")/../.."
chunks="${1:-12}" pairs="${2:-2000}" stars="${3:-2}" build="${4:-build}" work="${5:-/tmp/stampede-masked-campaign}"
S="$(realpath "$build/tools/stampede")"
P="docs/survey_metadetect/pair_statistics.py"
export PYTHONPATH="$(realpath "$build/python")"
mkdir -p "$work/sums"
read -r -a variants <<< "${VARIANTS:-default no_symmetry no_fill no_stars_mask}"
star=""
if ((stars > 0)); then star="--star-mask-hdu STARS"; fi
declare -A options=([default]="$star" [no_symmetry]="$star --no-mask-symmetry" [no_fill]="$star --no-mask-fill"
                    [no_fill_no_symmetry]="$star --no-mask-fill --no-mask-symmetry" [no_stars_mask]="")
for ((k = 0; k < chunks; ++k)); do
  if [[ -f "$work/sums/${variants[-1]}.$k.npz" ]]; then continue; fi  # done by an earlier run
  sims="$work/sims"
  # shellcheck disable=SC2086
  "$S" sim cells --out "$sims" --cells "$pairs" --pair --reference --layout random --stars "$stars" \
    --seed $((1000 + k)) --overwrite ${SIM_OPTIONS:-} 2>/dev/null
  ls "$sims"/cell_*.fits > "$work/plus.list"
  ls "$sims"/minus/cell_*.fits > "$work/minus.list"
  for v in "${variants[@]}"; do
    for sign in plus minus; do
      # shellcheck disable=SC2086
      "$S" metadetect --input-list "$work/$sign.list" -o "$work/${v}_$sign.fits" --keep-unlensed --overwrite --quiet ${options[$v]}
    done
    /usr/bin/python3 "$P" extract "$work/${v}_plus.fits" "$work/${v}_minus.fits" "$work/sums/${v}.$k.npz"
    if [[ $v == default ]]; then  # must-show 2: the default's m at other mfrac cuts, on the same pairs
      /usr/bin/python3 "$P" extract "$work/${v}_plus.fits" "$work/${v}_minus.fits" "$work/sums/default_no_mfrac_cut.$k.npz" \
        --cut-mfrac 1
      for cut in 0.02 0.05 0.3; do
        /usr/bin/python3 "$P" extract "$work/${v}_plus.fits" "$work/${v}_minus.fits" "$work/sums/default_mfrac_$cut.$k.npz" \
          --cut-mfrac "$cut"
      done
    fi
    rm -f "$work/${v}_plus.fits" "$work/${v}_minus.fits"
  done
  rm -rf "$sims"
  echo "chunk $k of $chunks done: $(date -u +%H:%M:%S)"
done
for v in "${variants[@]}" default_no_mfrac_cut; do
  compgen -G "$work/sums/$v.*.npz" > /dev/null || continue
  echo "== $v"
  /usr/bin/python3 "$P" combine "$work"/sums/"${v}".*.npz
done
