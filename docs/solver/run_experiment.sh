#!/usr/bin/env bash
# The solver experiment of docs/solver.md: GREAT08-like sets at S/N 10, 20 and 40 fitted with the
# amplitudes projected out (project_amplitudes = true, the default) and jointly (false, the
# paper's), both with the exact renderer; the S/N 20 sets also with the upsampled renderer.
# Then docs/solver/summarize.py writes the table of docs/solver.md.
#   docs/solver/run_experiment.sh OUT_DIR [SETS (8)] [GRID (32)]
# ~25 minutes on 2 cores for the defaults. Restartable: existing sets and fits are kept.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
S="$root/build/tools/stampede"
out=${1:?usage: run_experiment.sh OUT_DIR [SETS] [GRID]}
sets=${2:-8}
grid=${3:-32}
mkdir -p "$out"
for snr in 10 20 40; do
  d="$out/snr$snr"
  if [[ ! -f "$d/set_$((sets - 1)).fits" ]]; then
    "$S" sim great08 --out "$d" --sets "$sets" --grid "$grid" --snr "$snr" --seed "$((5000 + snr))" --overwrite > /dev/null
  fi
  for ((k = 0; k < sets; ++k)); do
    renderers=(exact)
    if [[ $snr == 20 && $k -lt 2 ]]; then renderers+=(upsampled); fi
    for r in "${renderers[@]}"; do
      for mode in true false; do
        f="$d/fit_${k}_${r}_$mode"
        [[ -f "$f.txt" ]] && continue
        "$S" fit "$d/set_$k.fits" -o "$f.fits" --text "$f.txt" --set renderer="$r" --set noise_sigma=1 \
          --set project_amplitudes="$mode" --threads 2 --overwrite > /dev/null
      done
    done
  done
done
/usr/bin/python3 "$root/docs/solver/summarize.py" "$out" "$sets"
