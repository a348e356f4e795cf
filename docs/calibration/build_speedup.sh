#!/usr/bin/env bash
# `stampede calibrate build` on 1 thread and on 2 (issue 44: 2 threads >= 1.9x one), and what the
# fiducial table costs in CPU time.
#
#   docs/calibration/build_speedup.sh OUTDIR
#
# Builds one grid (GRID_ARGS; default the experiment's fine radii with 4 noise pairs: 3,264 fits at
# S/N 20 of the experiment's configuration) once per thread count in THREADS (default "1 2"), and
# prints per run the wall and CPU seconds, fits per wall second and per CPU second, the speed-up on
# the first run's wall time, and the load average before the run: on a machine shared with other
# work the wall times, and so the speed-up, measure the sharing too. The tables must be identical
# (results do not depend on the thread count); the script checks it.
set -euo pipefail
out=${1:?usage: build_speedup.sh OUTDIR}
STAMPEDE=${STAMPEDE:-build/tools/stampede}
THREADS=${THREADS:-"1 2"}
read -r -a grid <<< "${GRID_ARGS:---snr 20 --realisations 4 --radii 1.2,1.6,2.1,2.8}"
mkdir -p "$out"
cat > "$out/run.ini" <<INI
psf_input = moffat
psf_beta = 3
psf_fwhm = 2.85
psf_e1 = 0
psf_e2 = 0.05
noise_sigma = 1
INI
echo "| threads | fits | wall s | CPU s | fits / wall s | fits / CPU s | speed-up | load before |"
echo "|---|---|---|---|---|---|---|---|"
first_wall="" first_table=""
for t in $THREADS; do
  table="$out/speedup_t$t.fits"
  load=$(cut -d' ' -f1-3 /proc/loadavg)
  /usr/bin/time -f "%e %U %S" -o "$out/time_t$t.txt" \
    "$STAMPEDE" calibrate build -o "$table" --config "$out/run.ini" --threads "$t" --overwrite "${grid[@]}" \
    2> "$out/build_t$t.log"
  read -r wall user sys < "$out/time_t$t.txt"
  fits=$(sed -n 's/.*: \([0-9]*\) fits in .*/\1/p' "$out/build_t$t.log" | tail -1)
  first_wall=${first_wall:-$wall}
  awk -v t="$t" -v f="$fits" -v w="$wall" -v u="$user" -v s="$sys" -v w1="$first_wall" -v l="$load" \
    'BEGIN { printf "| %s | %d | %.1f | %.1f | %.1f | %.1f | %.2f | %s |\n", t, f, w, u + s, f / w, f / (u + s), w1 / w, l }'
  if [[ -z $first_table ]]; then
    first_table=$table
  elif ! cmp -s "$first_table" "$table"; then
    echo "error: $table differs from $first_table: a build must not depend on its thread count" >&2
    exit 1
  fi
done
