#!/usr/bin/env bash
# Instruction counts (callgrind's Ir, the whole process) of one small fit run and one small
# metadetect run, old build against new: the cost of the run-harness refactor.
#
#   docs/run_harness/callgrind.sh [OLD_BUILD [NEW_BUILD [WORK]]]
#
# Defaults: /tmp/old_wt/build (commit 842e248), /work/main/build, /tmp/run_harness_callgrind.
# The two builds' binaries are copied into WORK first (SNAPSHOT=0: run them in place).
# The runs (both --threads 1, outputs overwritten):
#   fit        stampede fit GREAT08-mini nf/set_0.fits (400 stamps), the cheap options of
#              tests/tools/fit_command_test.cpp (kCheap + kGreat08Psf): a plain grid fit
#   metadetect stampede metadetect of `stampede sim cells --cells 4 --seed 5` (4 cells, wmom)
# Under valgrind the CPU dispatch sees no AVX-512 (valgrind does not emulate it), so both builds
# take the same AVX2 kernels; the counts are of that path. Also lists the 15 functions whose self
# Ir changed most between the builds (symbol names; Release builds carry no line tables).
set -u
OLD_BUILD=${1:-${OLD_BUILD:-/tmp/old_wt/build}}
NEW_BUILD=${2:-${NEW_BUILD:-/work/main/build}}
WORK=${3:-${WORK:-/tmp/run_harness_callgrind}}
DATA=${STAMPEDE_DATA_DIR:-/work/shared/data}
PYTHON=${PYTHON:-/usr/bin/python3}
command -v valgrind > /dev/null || { echo "valgrind is not installed" >&2; exit 2; }
mkdir -p "$WORK"
echo "valgrind: $(valgrind --version)"
. "$(dirname "$0")/snapshot_builds.sh"

"$NEW_BUILD/tools/stampede" sim cells --cells 4 --seed 5 --out "$WORK/cells" --threads 1 --overwrite > "$WORK/sim.log" 2>&1 ||
  { echo "sim cells failed: $WORK/sim.log" >&2; exit 2; }
CHEAP=(--set upsampling=2 --set n_central_pixels_to_upsample=1 --set padding=0 --set minimizer_max_iterations=20
       --set psf_beta=3 --set psf_fwhm=2.85 --set psf_e1=0 --set psf_e2=0.05)

# measure NAME TAG ARGS... : callgrind of `stampede ARGS` with build TAG; prints the total Ir.
measure() {
  local name=$1 tag=$2 build
  shift 2
  [ "$tag" = old ] && build=$OLD_BUILD || build=$NEW_BUILD
  local out=$WORK/callgrind.$name.$tag.out
  rm -f "$out"
  valgrind --tool=callgrind --callgrind-out-file="$out" "$build/tools/stampede" "$@" > "$WORK/$name.$tag.log" 2>&1 ||
    { echo "valgrind $name $tag failed: $WORK/$name.$tag.log" >&2; return 1; }
  sed -n 's/^totals: *\([0-9]*\).*/\1/p' "$out" | head -1
}

declare -A IR
for tag in old new; do
  IR[fit.$tag]=$(measure fit "$tag" fit "$DATA/galsim-great08-mini/nf/set_0.fits" -o "$WORK/fit.$tag.fits" "${CHEAP[@]}" \
                   --threads 1 --quiet --overwrite) || exit 1
  IR[md.$tag]=$(measure md "$tag" metadetect "$WORK"/cells/cell_000{0,1,2,3}.fits -o "$WORK/md.$tag.fits" \
                  --threads 1 --quiet --overwrite) || exit 1
done

echo
printf '%-44s %16s %16s %16s %9s\n' "run (--threads 1)" "Ir old" "Ir new" "new - old" "new/old"
row() {
  "$PYTHON" -c 'import sys; o, n = int(sys.argv[2]), int(sys.argv[3]); print("%-44s %16d %16d %+16d %9.6f" % (sys.argv[1], o, n, n - o, n / o))' "$@"
}
row "fit GREAT08-mini nf/set_0 (400 stamps, plain)" "${IR[fit.old]}" "${IR[fit.new]}"
row "metadetect 4 cells (sim cells --seed 5)" "${IR[md.old]}" "${IR[md.new]}"

# The functions whose self cost moved most (callgrind_annotate, symbol level).
for name in fit md; do
  echo
  echo "$name: the 15 largest changes of self Ir by function (new - old)"
  for tag in old new; do
    callgrind_annotate --threshold=100 --inclusive=no "$WORK/callgrind.$name.$tag.out" 2> /dev/null > "$WORK/annotate.$name.$tag.txt"
  done
  "$PYTHON" - "$WORK/annotate.$name.old.txt" "$WORK/annotate.$name.new.txt" <<'EOF'
import re, sys
def table(path):
    out = {}
    for line in open(path, errors="replace"):
        m = re.match(r"\s*([\d,]+)\s+(?:\(\s*[\d.]+%\)\s+)?(.*\S)\s*$", line)
        if m and ":" in m.group(2) or (m and m.group(2).startswith("???")):
            fn = m.group(2)
            fn = re.sub(r"\s*\[[^\]]*\]$", "", fn)  # the object file
            out[fn] = out.get(fn, 0) + int(m.group(1).replace(",", ""))
    return out
a, b = table(sys.argv[1]), table(sys.argv[2])
d = sorted(((b.get(k, 0) - a.get(k, 0), k) for k in set(a) | set(b)), key=lambda t: -abs(t[0]))
for delta, k in d[:15]:
    if delta:
        print("  %+14d  %14d -> %14d  %s" % (delta, a.get(k, 0), b.get(k, 0), k[:150]))
EOF
done
