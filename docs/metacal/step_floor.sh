#!/usr/bin/env bash
# metacal_step's floor (issue 43 item 6): R of the same 100 objects at each step, against R at the
# default 0.01, noise-free and at S/N 20, for bd and wmom. One Gamma for every step
# (metacal_psf_dilation = 1.15: the default widens Gamma with the step, which moves R itself), so
# what differs is what the step resolves. Prints the table of docs/metacal.md, "The step's floor".
# Steps below the floor (0.001) are refused by a build that has it: run those rows with a build
# before it (STAMPEDE=...; its R are bitwise those of this one at the steps both take).
#
#   docs/metacal/step_floor.sh OUTDIR
#
# Environment: GRID=10 THREADS=(all cores) STAMPEDE=build/tools/stampede
# PYTHON=python3 (with numpy; PYTHONPATH=build/python).
set -euo pipefail
out=${1:?usage: step_floor.sh OUTDIR}
GRID=${GRID:-10}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
PYTHON=${PYTHON:-python3}
threads=()
[[ -n "${THREADS:-}" ]] && threads=(--threads "$THREADS")
steps="0.03 0.01 0.003 0.001 0.0003 0.0001 1e-5 1e-6 1e-8"
mkdir -p "$out"
"$STAMPEDE" sim great08 --out "$out/nf" --sets 1 --grid "$GRID" --noise-free --overwrite "${threads[@]}"
"$STAMPEDE" sim great08 --out "$out/n20" --sets 1 --grid "$GRID" --snr 20 --overwrite "${threads[@]}"
for set in nf n20; do
  for model in bd wmom; do
    for step in $steps; do
      "$STAMPEDE" fit "$out/$set/set_0.fits" -o "$out/$set-$model-$step.fits" --overwrite --quiet "${threads[@]}" \
        --set metacal=true --set metacal_model="$model" --set metacal_step="$step" --set metacal_psf_dilation=1.15 \
        2> "$out/$set-$model-$step.log" || echo "$set $model $step: refused ($(tail -1 "$out/$set-$model-$step.log"))"
    done
  done
done
"$PYTHON" - "$out" $steps <<'PY'
import os, sys
import numpy as np
import stampede
out, steps = sys.argv[1], sys.argv[2:]
print("| set | model | step | ⟨R11⟩ | ⟨R22⟩ | \\|ΔR\\| median | 90 % | max | objects with \\|ΔR\\| > 0.1 |")
print("|---|---|---|---|---|---|---|---|---|")
for s, label in (("nf", "noise-free"), ("n20", "S/N 20")):
    for m in ("bd", "wmom"):
        ref = stampede.read_results(f"{out}/{s}-{m}-0.01.fits")
        for st in steps:
            path = f"{out}/{s}-{m}-{st}.fits"
            if not os.path.exists(path):
                continue
            r = stampede.read_results(path)
            ok = (r["status"] == 0) & ((r["flags"] & 262144) == 0)
            d = np.maximum(np.abs(r["R11"] - ref["R11"]), np.abs(r["R22"] - ref["R22"]))[ok]
            print(f"| {label} | {m} | {st} | {np.mean(r['R11'][ok]):+.4f} | {np.mean(r['R22'][ok]):+.4f} | "
                  f"{np.median(d):.1e} | {np.percentile(d, 90):.1e} | {d.max():.1e} | {np.sum(d > 0.1)} |")
PY
