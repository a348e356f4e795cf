#!/usr/bin/env bash
# Issue 20's tile experiments (results: docs/meds.md):
#  1. noise-free four-epoch tiles under four shears: m and c of the fitted mean e against the
#     galaxies' sheared e (must-show 1, at a larger size than the test's);
#  2. the same noisy galaxies and noise fitted clean, with hot bad columns (bmask), with neighbours
#     (seg map, uberseg) and with both: the shear difference against the clean shear's error
#     (must-show 3).
# usage: docs/meds/run_experiment.sh OUTDIR [OBJECTS (2000)] [NOISE_FREE_OBJECTS (200)] [THREADS (2)]
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="$1"; N="${2:-2000}"; NF="${3:-200}"; T="${4:-2}"
S=build/tools/stampede
A="python3 docs/meds/analyse.py"
mkdir -p "$OUT"
shears=("0.02,-0.015" "-0.03,0.01" "0.0,0.035" "0.04,0.025")
dirs=()
for k in 0 1 2 3; do
  d="$OUT/nf$k"
  $S sim meds --out "$d" --objects "$NF" --noise-free --shear "${shears[$k]}" --seed $((200 + k)) --threads "$T" --overwrite 2>/dev/null
  $S fit --meds "$d/meds.fits" -o "$d/fit.fits" --text "$d/fit.txt" --threads "$T" --overwrite --quiet
  dirs+=("$d")
done
echo "== 1. noise-free, 4 epochs, 4 shears x $NF objects"
$A mc "${dirs[@]}"
for name in clean bad crowded both; do
  case $name in
    clean) opts=() ;;
    bad) opts=(--bad-columns 0.3) ;;
    crowded) opts=(--neighbours 0.3) ;;
    both) opts=(--bad-columns 0.3 --neighbours 0.3) ;;
  esac
  d="$OUT/$name"
  $S sim meds --out "$d" --objects "$N" --snr 30 --seed 300 --threads "$T" --overwrite "${opts[@]}" 2>/dev/null
  /usr/bin/time -f "$name: fit %e s wall, %U s user" $S fit --meds "$d/meds.fits" -o "$d/fit.fits" --text "$d/fit.txt" \
    --threads "$T" --overwrite --quiet
done
echo "== 2. S/N 30, 4 epochs, $N objects: masked against clean (same galaxies and noise)"
$A shear "$OUT/clean" "$OUT"/{clean,bad,crowded,both}/fit.txt
for name in bad crowded both; do
  echo "-- $name"
  $A paired "$OUT/clean" "$OUT/clean/fit.txt" "$OUT/$name/fit.txt"
done
