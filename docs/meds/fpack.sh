#!/usr/bin/env bash
# Issue 43 item 11: how much fpack's default (lossy) quantisation of a `sim meds` tile moves the
# fitted e, against `-q 0` (gzip, floats kept exactly). Fits four versions of one tile: fpack -q 0,
# fpack's default (images and weights quantised), and the uncompressed tile with only its weight
# cutouts or only its image cutouts replaced by the quantised ones (funpack of the default), then
# compares each row's e with the uncompressed tile's (docs/meds/fpack.py).
#
#   docs/meds/fpack.sh OUTDIR
#
# Environment: OBJECTS=200 SNR=30 SEED=4350 TILE=10240 (fpack -t: a MEDS cutout array is one 1-D
# image, and fpack's default tile is its whole row, so each cutout read would decompress the whole
# HDU) STAMPEDE=build/tools/stampede PYTHON=python3 (numpy, astropy) THREADS=
set -euo pipefail
out=${1:?usage: fpack.sh OUTDIR}
OBJECTS=${OBJECTS:-200} SNR=${SNR:-30} SEED=${SEED:-4350} TILE=${TILE:-10240}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
PYTHON=${PYTHON:-python3}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
command -v fpack > /dev/null || { echo "fpack.sh: fpack not found (Debian libcfitsio-bin)" >&2; exit 1; }
t="$out/tile"
[[ -f "$t/meds.fits" ]] || "$STAMPEDE" sim meds --out "$t" --objects "$OBJECTS" --snr "$SNR" --seed "$SEED" "${threads[@]}" > /dev/null
[[ -f "$t/q0.fits.fz" ]] || fpack -t "$TILE" -g -q 0 -O "$t/q0.fits.fz" "$t/meds.fits"
[[ -f "$t/lossy.fits.fz" ]] || fpack -t "$TILE" -O "$t/lossy.fits.fz" "$t/meds.fits"
if [[ ! -f "$t/wlossy.fits" || ! -f "$t/ilossy.fits" ]]; then
  rm -f "$t/lossy_unpacked.fits"
  funpack -O "$t/lossy_unpacked.fits" "$t/lossy.fits.fz"
  "$PYTHON" "$(dirname "$0")/fpack.py" splice "$t"
fi
for f in meds.fits q0.fits.fz lossy.fits.fz wlossy.fits ilossy.fits; do
  n=${f%%.*}
  # The PSFEx paths are relative to the tile's directory, so every version lives beside meds.fits.
  [[ -f "$out/fit_$n.fits" ]] || "$STAMPEDE" fit --meds "$t/$f" -o "$out/fit_$n.fits" --quiet "${threads[@]}"
done
"$PYTHON" "$(dirname "$0")/fpack.py" compare "$out" | tee "$out/results.md"
