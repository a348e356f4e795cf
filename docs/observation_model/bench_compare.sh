#!/usr/bin/env bash
# Speed before and after a change, side by side: the same benchmark binaries of two builds run in
# alternation (old, new, new, old, ...) ROUNDS times, so that the machine's drift hits both alike;
# prints each benchmark's median wall time per build and their ratio (new / old).
#
#   docs/observation_model/bench_compare.sh OLD_BUILD NEW_BUILD [ROUNDS (5)] [TARGETS]
#   OLD_BUILD, NEW_BUILD: build folders with bench/ (bench/run's build-bench, or a worktree's);
#   TARGETS default "bench_fit bench_multi_epoch bench_metacal"; FILTER: a --benchmark_filter regex.
set -euo pipefail
old=$1; new=$2; rounds=${3:-5}
targets=(${4:-bench_fit bench_multi_epoch bench_metacal})
filter=${FILTER:-.}
out=$(mktemp -d)
for ((r = 0; r < rounds; ++r)); do
  order=(old new); ((r % 2)) && order=(new old)
  for side in "${order[@]}"; do
    dir=$old; [[ $side == new ]] && dir=$new
    for t in "${targets[@]}"; do
      "$dir/bench/$t" --benchmark_filter="$filter" --benchmark_format=json > "$out/$side.$t.$r.json" 2>/dev/null
    done
  done
  echo "round $((r + 1))/$rounds" >&2
done
python3 - "$out" <<'PY'
import glob, json, statistics, sys, collections
times = collections.defaultdict(lambda: collections.defaultdict(list))
for path in glob.glob(sys.argv[1] + '/*.json'):
    side = path.split('/')[-1].split('.')[0]
    for b in json.load(open(path))['benchmarks']:
        if b.get('run_type', 'iteration') != 'iteration': continue
        scale = {'ns': 1e-6, 'us': 1e-3, 'ms': 1.0, 's': 1e3}[b.get('time_unit', 'ns')]
        times[b['name']][side].append(b['real_time'] * scale)
print('| benchmark | old (ms) | new (ms) | new/old |')
print('|---|---|---|---|')
for name in sorted(times):
    o, n = times[name]['old'], times[name]['new']
    if not o or not n: continue
    mo, mn = statistics.median(o), statistics.median(n)
    print(f'| {name} | {mo:.4g} | {mn:.4g} | {mn / mo:.3f} |')
PY
rm -rf "$out"
