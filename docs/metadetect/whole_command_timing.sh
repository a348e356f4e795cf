#!/usr/bin/env bash
# The whole `stampede metadetect` command timed for two binaries side by side (docs/metadetect.md,
# the whole command's tables in "Detection (issue 53)" and "Single-precision images (issue 53)"):
# 100 cells of each kind (the reference test's grid and random cells at S/N 1e6 and at S/N 20), one
# thread, the binaries interleaved run by run, REPS runs each; then one and two threads of NEW on
# the 200 deep cells, alternating, and their tables compared byte for byte. Prints the medians of
# CPU time (user + system) per cell.
#   usage: docs/metadetect/whole_command_timing.sh OLD_STAMPEDE NEW_STAMPEDE [WORK_DIR] [REPS]
# (OLD: the commit before the change, built in a worktree (8d6612b for the single-precision
# images); NEW: build/tools/stampede.)
set -euo pipefail
old=$(realpath "$1") new=$(realpath "$2") work=${3:-/tmp/whole_command_timing} reps=${4:-5}
mkdir -p "$work"
cd "$work"
for layout in grid random; do
  [[ -d ref_$layout ]] || "$new" sim cells --reference --layout $layout --cells 100 --seed 77 --out ref_$layout >/dev/null 2>&1
  [[ -d s20_$layout ]] || "$new" sim cells --reference --layout $layout --snr 20 --cells 100 --seed 77 --out s20_$layout >/dev/null 2>&1
done
rm -f times.txt
for ((rep = 1; rep <= reps; ++rep)); do
  for d in ref_grid ref_random s20_grid s20_random; do
    for b in old new; do
      bin=$old; [[ $b == new ]] && bin=$new
      /usr/bin/time -f "$d $b %e %U %S" "$bin" metadetect $d/cell_*.fits -o out_$b.fits --overwrite --quiet --threads 1 2>> times.txt
    done
  done
  for th in 1 2; do
    /usr/bin/time -f "threads$th new %e %U %S" "$new" metadetect ref_random/cell_*.fits ref_grid/cell_*.fits \
      -o out_threads$th.fits --overwrite --quiet --threads $th 2>> times.txt
  done
done
cmp out_threads1.fits out_threads2.fits && echo "1 and 2 threads: the tables are byte-identical"
python3 - <<'PY'
import collections, statistics
d = collections.defaultdict(list)
for line in open("times.txt"):
    f = line.split()
    if len(f) == 5:
        d[(f[0], f[1])].append((float(f[2]), float(f[3]) + float(f[4])))
for k in ("ref_grid", "ref_random", "s20_grid", "s20_random"):
    o = [c for _, c in d[(k, "old")]]; n = [c for _, c in d[(k, "new")]]
    print("%-10s old %.1f ms, new %.1f ms per cell (CPU, median; new %.1f-%.1f), ratio %.2f" %
          (k, statistics.median(o) * 10, statistics.median(n) * 10, min(n) * 10, max(n) * 10,
           statistics.median(o) / statistics.median(n)))
one = [w for w, _ in d[("threads1", "new")]]; two = [w for w, _ in d[("threads2", "new")]]
print("200 deep cells, wall: 1 thread median %.2f s, 2 threads %.2f s, ratio %.2f (run by run %s)" %
      (statistics.median(one), statistics.median(two), statistics.median(one) / statistics.median(two),
       ", ".join("%.2f" % (a / b) for a, b in zip(one, two))))
PY
