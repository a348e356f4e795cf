#!/usr/bin/env bash
# One campaign run of one fuzz target (docs/reliability.md, "Campaign record"): from the committed
# seeds plus WORK's corpus, at nice 19, stopped with SIGINT once the process has used QUOTA seconds
# of CPU (user + system, read from /proc), however busy the machine is, so that the figure carries
# over between machines. The log ends with libFuzzer's final stats and /usr/bin/time's CPU line;
# crashing inputs go to WORK/findings/.
# usage: fuzz/campaign.sh TARGET [QUOTA_SECONDS (3600)] [BUILD_DIR (build-fuzz)] [WORK (/tmp/stampede-fuzz)]
set -euo pipefail
cd "$(dirname "$0")/.."
T="$1"; QUOTA="${2:-3600}"; B="${3:-build-fuzz}"; W="${4:-/tmp/stampede-fuzz}/$T"
declare -A dict=([run_config]=ini.dict [fit_command_line]=args.dict [metadetect_metrics_arguments]=metadetect_metrics.dict)
mkdir -p "$W/corpus" "$W/findings"
log="$W/campaign.log"
nice -n 19 /usr/bin/time -f 'cpu: user %U s, system %S s' "$B/fuzz/fuzz_$T" "$W/corpus" "fuzz/corpus/$T" \
  -dict="fuzz/${dict[$T]:-fits.dict}" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
  -artifact_prefix="$W/findings/" -print_final_stats=1 > "$log" 2>&1 &
sleep 2
pid="$(pgrep -n -f "fuzz/fuzz_$T $W/corpus")"
tick="$(getconf CLK_TCK)"
while kill -0 "$pid" 2>/dev/null; do
  read -r -a stat < "/proc/$pid/stat" || break
  if (( (stat[13] + stat[14]) / tick >= QUOTA )); then kill -INT "$pid"; break; fi
  sleep 10
done
wait || true
grep -E '^#[0-9]+' "$log" | tail -1
tail -1 "$log"
ls "$W/findings"
