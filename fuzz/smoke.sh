#!/usr/bin/env bash
# Runs every fuzz target of BUILD_DIR (two at a time) from the committed seeds for a fixed number of
# inputs with a fixed seed, so that a smoke run is repeatable: a finding here is a regression that
# reproduces, not a lucky draw (the long, random campaigns are docs/reliability.md's). The input
# counts are ~15 s each on the CI machine; SECONDS caps each target on a slower one. Fails, keeping
# the crashing inputs in BUILD_DIR/fuzz-findings/, if any target finds something.
# usage: fuzz/smoke.sh [BUILD_DIR (build-fuzz)] [SECONDS (60)]
set -euo pipefail
cd "$(dirname "$0")/.."
B="${1:-build-fuzz}"
SECONDS_EACH="${2:-60}"
F="$B/fuzz-findings"
mkdir -p "$F"
declare -A dict=([run_config]=ini.dict [catalogue]=fits.dict [stamp_grid]=fits.dict [weight_map]=fits.dict
                 [psf_image]=fits.dict [calibration_table]=fits.dict [catalog_reader]=fits.dict
                 [meds]=fits.dict [psfex]=fits.dict [fit_command_line]=args.dict [metadetect_table]=fits.dict
                 [cell_image]=fits.dict [metadetect_metrics_arguments]=metadetect_metrics.dict)
declare -A runs=([stamp_grid]=60000 [weight_map]=30000 [catalogue]=30000 [psf_image]=2000
                 [calibration_table]=18000 [catalog_reader]=13000 [run_config]=5000
                 [meds]=30000 [psfex]=50000 [fit_command_line]=40000 [metadetect_table]=15000 [cell_image]=12000
                 [metadetect_metrics_arguments]=100000)
run() {
  local t="$1" work="$B/fuzz-corpus/$1"
  mkdir -p "$work"  # new inputs go here; the committed corpus is only read
  if ! "$B/fuzz/fuzz_$t" "$work" "fuzz/corpus/$t" -dict="fuzz/${dict[$t]}" -seed=1 -runs="${runs[$t]}" -max_total_time="$SECONDS_EACH" \
      -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 -artifact_prefix="$F/${t}-" -print_final_stats=1 \
      > "$F/$t.log" 2>&1; then
    echo "fuzz_$t: FINDING (log $F/$t.log)"; tail -40 "$F/$t.log"; return 1
  fi
  echo "fuzz_$t: $(grep -E '^#[0-9]+' "$F/$t.log" | tail -1)"
}
status=0
targets=(stamp_grid weight_map catalogue psf_image calibration_table catalog_reader run_config meds psfex
         fit_command_line metadetect_table cell_image metadetect_metrics_arguments)
for ((i = 0; i < ${#targets[@]}; i += 2)); do
  run "${targets[i]}" & a=$!
  if ((i + 1 < ${#targets[@]})); then run "${targets[i + 1]}" & b=$!; wait "$b" || status=1; fi
  wait "$a" || status=1
done
exit "$status"
