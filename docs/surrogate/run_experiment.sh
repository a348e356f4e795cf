#!/usr/bin/env bash
# Issue 29, must-show 2: the surrogate fit (the default) against every iteration exact on one
# 10,000-object S/N 20 GREAT08-like set: per-object |de| / sigma_e and the status, whole-process
# time of each; and the all-exact fit against itself with another initial damping (how far the
# estimator is determined by its own path). Writes results.md beside this script.
#   docs/surrogate/run_experiment.sh [BUILD_DIR] [WORK_DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-$here/../../build}
work=${2:-$(mktemp -d)}
stampede="$build/tools/stampede"
"$stampede" sim great08 --out "$work/sim" --sets 1 --grid 100 --snr 20 --seed 2020 --overwrite --threads 2 > /dev/null
for mode in true false; do
  /usr/bin/time -f "%e %U" -o "$work/time_$mode" "$stampede" fit "$work/sim/set_0.fits" -o "$work/fit_$mode.fits" \
    --text "$work/fit_$mode.txt" --overwrite --quiet --threads 2 --set noise_sigma=1 --set exact_surrogate=$mode
done
# The all-exact fit's own path dependence: the same fit with the LM's initial damping doubled.
"$stampede" fit "$work/sim/set_0.fits" -o "$work/fit_mu.fits" --text "$work/fit_mu.txt" --overwrite --quiet \
  --threads 2 --set noise_sigma=1 --set exact_surrogate=false --set levmar_LM_INIT_MU=0.002
{ /usr/bin/python3 "$here/summarize.py" "$work"; echo; /usr/bin/python3 "$here/by_ellipticity.py" "$work"; } | tee "$here/results.md"
