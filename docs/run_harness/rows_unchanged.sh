#!/usr/bin/env bash
# Regression check of the run-harness refactor (app/, io/, tools/): every kind of output table
# the two builds write has the same rows, bit for bit, every column but the timing column time_us.
#
#   docs/run_harness/rows_unchanged.sh [OLD_BUILD [NEW_BUILD [WORK]]]
#
# OLD_BUILD  build folder of the commit before the refactor (default /tmp/old_wt/build: 842e248,
#            made by `git worktree add /tmp/old_wt 842e248` and a Release build of the targets
#            stampede stampede-mpi stampede_python)
# NEW_BUILD  build folder of the refactored tree (default /work/main/build)
# WORK       scratch folder (default /tmp/rows_unchanged); WORK/old, WORK/new, WORK/inputs are
#            emptied first
# (also settable as environment variables of the same names). The binaries (stampede,
# stampede-mpi, python/stampede) are first copied to WORK/build_old and WORK/build_new, so that a
# rebuild of NEW_BUILD during the run cannot mix two binaries (SNAPSHOT=0: run them in place).
#
# Each configuration is run once with each build on the same inputs (simulated with the NEW
# build, in WORK/inputs; the simulations themselves are compared too), the outputs land in
# WORK/old and WORK/new under the same names, and docs/run_harness/compare_tables.py compares the
# table data (FITS BINTABLE layout and row bytes with time_us masked; --text tables token by token
# without time_us; the Python snippet's outputs byte for byte). Header keys are not compared.
# The kill -9 + --resume configurations run only the NEW build (killed once its checkpoint shows
# committed rows, then --resume) and compare its table with the OLD build's uninterrupted run.
# Prints one line per compared table; exits non-zero if anything differs or a run failed.
set -u

OLD_BUILD=${1:-${OLD_BUILD:-/tmp/old_wt/build}}
NEW_BUILD=${2:-${NEW_BUILD:-/work/main/build}}
WORK=${3:-${WORK:-/tmp/rows_unchanged}}
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
DATA=${STAMPEDE_DATA_DIR:-/work/shared/data}
PYTHON=${PYTHON:-/usr/bin/python3}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1

for b in "$OLD_BUILD" "$NEW_BUILD"; do
  for f in tools/stampede tools/stampede-mpi; do
    [ -x "$b/$f" ] || { echo "missing $b/$f" >&2; exit 2; }
  done
done
rm -rf "$WORK/old" "$WORK/new" "$WORK/inputs"
mkdir -p "$WORK/old" "$WORK/new" "$WORK/inputs" "$WORK/logs"
IN=$WORK/inputs
MANIFEST=$WORK/manifest.tsv
: > "$MANIFEST"

. "$(dirname "$0")/snapshot_builds.sh"
echo "work dir:  $WORK"
echo

build_of() { [ "$1" = old ] && echo "$OLD_BUILD" || echo "$NEW_BUILD"; }

# Substitutes the placeholders of one argument for build TAG:
#   {S} the stampede binary, {MPI} stampede-mpi, {PYPATH} the build's python folder,
#   {W} the build's output folder WORK/TAG, {IN} the shared inputs WORK/inputs.
subst() {
  local tag=$1 a=$2 b
  b=$(build_of "$tag")
  a=${a//\{S\}/$b/tools/stampede}
  a=${a//\{MPI\}/$b/tools/stampede-mpi}
  a=${a//\{PYPATH\}/$b/python}
  a=${a//\{W\}/$WORK/$tag}
  a=${a//\{IN\}/$IN}
  printf '%s' "$a"
}

# one TAG LOG CMD... : runs CMD (placeholders substituted) with build TAG; stdout+stderr to
# WORK/logs/TAG_LOG.log. Returns the command's status.
one() {
  local tag=$1 log=$2 a
  shift 2
  local args=()
  for a in "$@"; do args+=("$(subst "$tag" "$a")"); done
  printf '%q ' "${args[@]}" > "$WORK/logs/${tag}_$log.log"
  echo >> "$WORK/logs/${tag}_$log.log"
  "${args[@]}" >> "$WORK/logs/${tag}_$log.log" 2>&1
}

FAILED=()
# both LOG CMD... : runs CMD with the old build, then the new; a failure is recorded under LOG.
both() {
  local log=$1 tag rc
  shift
  for tag in old new; do
    one "$tag" "$log" "$@"
    rc=$?
    if [ $rc -ne 0 ]; then
      FAILED+=("$log")
      printf '%s\t!\t%s build exited %d (log %s)\n' "$log" "$tag" "$rc" "$WORK/logs/${tag}_$log.log" >> "$MANIFEST"
      return 1
    fi
  done
}

# pair LABEL REL : compare WORK/old/REL with WORK/new/REL.
pair() { printf '%s\t%s\t%s\n' "$1" "$WORK/old/$2" "$WORK/new/$2" >> "$MANIFEST"; }

# kill_resume LABEL OUT MIN_ROWS CMD... : the NEW build's CMD (writing OUT, a {W}-relative path)
# killed with SIGKILL once OUT.checkpoint records at least MIN_ROWS committed rows, then CMD
# --resume; the resumed table is compared with the OLD build's uninterrupted run of CMD.
kill_resume() {
  local label=$1 out=$2 min=$3 a
  shift 3
  if ! one old "$label" "$@"; then
    FAILED+=("$label")
    printf '%s\t!\told build exited non-zero (log %s)\n' "$label" "$WORK/logs/old_$label.log" >> "$MANIFEST"
    return
  fi
  local args=()
  for a in "$@"; do args+=("$(subst new "$a")"); done
  local target=$WORK/new/$out log=$WORK/logs/new_$label.log
  printf '%q ' "${args[@]}" > "$log"; echo >> "$log"
  "${args[@]}" >> "$log" 2>&1 &
  local pid=$! rows=0 t
  for t in $(seq 1 3000); do  # up to 60 s
    if [ -f "$target.checkpoint" ]; then
      rows=$(sed -n 's/^rows \([0-9]*\)$/\1/p' "$target.checkpoint" 2>/dev/null | head -1)
      [ -n "$rows" ] && [ "$rows" -ge "$min" ] && break
    fi
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.02
  done
  kill -9 "$pid" 2>/dev/null
  wait "$pid" 2>/dev/null
  local rc=$?
  echo "killed at checkpoint rows=${rows:-0}: exit $rc" | tee -a "$log" > "$WORK/logs/new_$label.kill"
  if [ $rc -ne 137 ] || [ -e "$target" ]; then
    FAILED+=("$label")
    printf '%s\t!\tthe new build run was not killed mid-run (exit %d; rows %s)\n' "$label" "$rc" "${rows:-0}" >> "$MANIFEST"
    return
  fi
  if ! "${args[@]}" --resume >> "$log" 2>&1; then
    FAILED+=("$label")
    printf '%s\t!\tthe new build --resume failed (log %s)\n' "$label" "$log" >> "$MANIFEST"
    return
  fi
  printf '%s (killed at %s rows)\t%s\t%s\n' "$label" "$rows" "$WORK/old/$out" "$target" >> "$MANIFEST"
}

GRID_NF=$DATA/galsim-great08-mini/nf/set_0.fits
GRID_40=$DATA/galsim-great08-mini/snr40/set_0.fits
MEDS1=$DATA/meds-sample/meds.fits
PSF=(--set psf_beta=3 --set psf_fwhm=2.85 --set psf_e1=0 --set psf_e2=0.05)
CHEAP=(--set upsampling=2 --set n_central_pixels_to_upsample=1 --set padding=0 --set minimizer_max_iterations=20 "${PSF[@]}")
Q=(--quiet)

# ---------------------------------------------------------------- simulated inputs (new build)
echo "simulating inputs with the new build ..." >&2
S_NEW=$NEW_BUILD/tools/stampede
{
  "$S_NEW" sim great08 --out "$IN/g08" --sets 2 --grid 6 --snr 40 --seed 3 --threads 2 &&
  "$S_NEW" sim meds --out "$IN/m3" --objects 12 --bands g,r,i --threads 2 &&
  "$S_NEW" sim cells --out "$IN/cells" --cells 4 --seed 5 --threads 2 &&
  "$S_NEW" sim cells --out "$IN/tile1" --cells 4 --seed 5 --tile --threads 2 &&
  "$S_NEW" sim cells --out "$IN/tileb" --cells 4 --seed 5 --tile --bands g,r,i --threads 2 &&
  "$S_NEW" sim cells --out "$IN/cells12" --cells 12 --seed 9 --layout random --threads 2
} > "$WORK/logs/inputs.log" 2>&1 || { echo "simulating the inputs failed: $WORK/logs/inputs.log" >&2; exit 2; }
CELLS=("$IN"/cells/cell_000{0,1,2,3}.fits)
CELLS12=("$IN"/cells12/cell_00*.fits)
# A text catalogue on the GREAT08-mini snr40 image: 30 objects at stamp centres (1-based FITS pixels,
# stamp (ix, iy) centred on ix * 39 + 20, iy * 39 + 20), three over an edge, one wholly outside; with
# per-object Moffat PSF columns for psf_input = moffat_catalog.
"$PYTHON" - "$IN/cat.txt" <<'EOF'
import sys
with open(sys.argv[1], "w") as f:
    f.write("# id x y psf_beta psf_fwhm psf_e1 psf_e2\n")
    for k in range(30):
        ix, iy = (7 * k) % 20, (3 * k + k // 7) % 20
        f.write("%d %r %r %r %r %r %r\n" % (1000 + k, ix * 39 + 20.0, iy * 39 + 20.25, 2.9 + 0.01 * k, 2.8 + 0.005 * k,
                                           0.001 * (k - 15), 0.05 - 0.001 * k))
    for k, (x, y) in enumerate([(12.0, 60.0), (775.0, 300.5), (400.0, 779.0), (-80.0, -80.0)]):
        f.write("%d %r %r 3 2.85 0 0.05\n" % (2000 + k, x, y))
EOF
printf '%s\n' "$IN/g08/set_0.fits" "# a comment" "$IN/g08/set_1.fits" > "$IN/grids.list"
printf '%s\n' "${CELLS[@]}" > "$IN/cells.list"

# ---------------------------------------------------------------- the simulations' own tables
echo "running the configurations ..." >&2
both sim_great08 {S} sim great08 --out {W}/sim/g08 --sets 1 --grid 6 --snr 40 --seed 3 --threads 2 &&
  pair sim_great08:truth sim/g08/truth_0.fits
both sim_meds_bands {S} sim meds --out {W}/sim/m3 --objects 12 --bands g,r,i --threads 2 &&
  { pair sim_meds_bands:g/meds sim/m3/g/meds.fits; pair sim_meds_bands:i/truth sim/m3/i/truth.fits; }
both sim_cells_tile {S} sim cells --out {W}/sim/tileb --cells 4 --seed 5 --tile --bands g,r --threads 2 &&
  { pair sim_cells_tile:r/cells_meds sim/tileb/r/cells_meds.fits; pair sim_cells_tile:truth sim/tileb/truth.fits; }

# ---------------------------------------------------------------- fit on a grid
both fit_grid_plain {S} fit "$GRID_NF" -o {W}/fit_grid_plain.fits --text {W}/fit_grid_plain.txt "${CHEAP[@]}" --threads 2 "${Q[@]}" &&
  { pair fit_grid_plain fit_grid_plain.fits; pair fit_grid_plain:text fit_grid_plain.txt; }
both fit_grid_weighted {S} fit "$GRID_40" -o {W}/fit_grid_weighted.fits "${CHEAP[@]}" --set noise_sigma=1 --set batch_size=7 --threads 2 "${Q[@]}" &&
  pair fit_grid_weighted fit_grid_weighted.fits
both fit_grid_metacal_wmom {S} fit "$GRID_NF" -o {W}/fit_grid_metacal_wmom.fits "${CHEAP[@]}" --set metacal=true --set metacal_model=wmom --threads 2 "${Q[@]}" &&
  pair fit_grid_metacal_wmom fit_grid_metacal_wmom.fits
both fit_grid_metacal_bd {S} fit "$GRID_NF" -o {W}/fit_grid_metacal_bd.fits --text {W}/fit_grid_metacal_bd.txt "${CHEAP[@]}" --set metacal=true --set metacal_model=bd --threads 2 "${Q[@]}" &&
  { pair fit_grid_metacal_bd fit_grid_metacal_bd.fits; pair fit_grid_metacal_bd:text fit_grid_metacal_bd.txt; }
both fit_input_list {S} fit --input-list "$IN/grids.list" -o {W}/fit_list "${CHEAP[@]}" --set noise_sigma=1 --threads 2 "${Q[@]}" &&
  { pair fit_input_list:set_0 fit_list/set_0_fit.fits; pair fit_input_list:set_1 fit_list/set_1_fit.fits; }

# ---------------------------------------------------------------- fit with a catalogue
both fit_catalog {S} fit "$GRID_40" --catalog "$IN/cat.txt" -o {W}/fit_catalog.fits --text {W}/fit_catalog.txt "${CHEAP[@]}" --set noise_sigma=1 --threads 2 "${Q[@]}" &&
  { pair fit_catalog fit_catalog.fits; pair fit_catalog:text fit_catalog.txt; }
both fit_catalog_moffat {S} fit "$GRID_40" --catalog "$IN/cat.txt" -o {W}/fit_catalog_moffat.fits --set psf_input=moffat_catalog --set upsampling=2 --set n_central_pixels_to_upsample=1 --set padding=0 --set minimizer_max_iterations=20 --set noise_sigma=1 --set batch_size=4 --threads 2 "${Q[@]}" &&
  pair fit_catalog_moffat fit_catalog_moffat.fits

# ---------------------------------------------------------------- fit on MEDS tiles
both fit_meds_1band {S} fit --meds "$MEDS1" -o {W}/fit_meds_1band.fits --threads 2 "${Q[@]}" &&
  pair fit_meds_1band fit_meds_1band.fits
MEDS3=(--meds "$IN/m3/g/meds.fits" --meds "$IN/m3/r/meds.fits" --meds "$IN/m3/i/meds.fits" --bands g,r,i)
both fit_meds_3bands {S} fit "${MEDS3[@]}" -o {W}/fit_meds_3bands.fits --set batch_size=5 --threads 2 "${Q[@]}" &&
  pair fit_meds_3bands fit_meds_3bands.fits
both fit_meds_3bands_metacal {S} fit "${MEDS3[@]}" -o {W}/fit_meds_3bands_metacal.fits --set metacal=true --threads 2 "${Q[@]}" &&
  pair fit_meds_3bands_metacal fit_meds_3bands_metacal.fits

# ---------------------------------------------------------------- fit shards and merge
both fit_shard0 {S} fit "$GRID_NF" -o {W}/fit_shard0.fits --shard 0/2 "${CHEAP[@]}" --set batch_size=7 --threads 2 "${Q[@]}" &&
  pair fit_shard_0/2 fit_shard0.fits
both fit_shard1 {S} fit "$GRID_NF" -o {W}/fit_shard1.fits --shard 1/2 "${CHEAP[@]}" --set batch_size=7 --threads 2 "${Q[@]}" &&
  pair fit_shard_1/2 fit_shard1.fits
both fit_merge {S} merge -o {W}/fit_merged.fits {W}/fit_shard1.fits {W}/fit_shard0.fits "${Q[@]}" &&
  pair fit_shard_merged fit_merged.fits
both fit_meds_shard1 {S} fit "${MEDS3[@]}" -o {W}/fit_meds_shard1.fits --shard 1/3 --set batch_size=5 --threads 2 "${Q[@]}" &&
  pair fit_meds_3bands_shard_1/3 fit_meds_shard1.fits

# ---------------------------------------------------------------- fit over MPI ranks
both fit_mpi mpirun -n 2 --oversubscribe {MPI} fit "$GRID_NF" -o {W}/fit_mpi.fits "${CHEAP[@]}" --set batch_size=9 --threads 1 "${Q[@]}" &&
  pair fit_mpi_2ranks fit_mpi.fits
both fit_mpi_metacal mpirun -n 2 --oversubscribe {MPI} fit "$IN/g08/set_0.fits" -o {W}/fit_mpi_metacal.fits --set noise_sigma=1 --set metacal=true --set batch_size=4 --threads 1 "${Q[@]}" &&
  pair fit_mpi_2ranks_metacal fit_mpi_metacal.fits
both fit_mpi_catalog mpirun -n 2 --oversubscribe {MPI} fit "$GRID_40" --catalog "$IN/cat.txt" -o {W}/fit_mpi_catalog.fits --set psf_input=moffat_catalog --set upsampling=2 --set n_central_pixels_to_upsample=1 --set padding=0 --set minimizer_max_iterations=20 --set noise_sigma=1 --set batch_size=4 --threads 1 "${Q[@]}" &&
  pair fit_mpi_2ranks_catalog fit_mpi_catalog.fits
both fit_mpi_meds mpirun -n 2 --oversubscribe {MPI} fit --meds "$MEDS1" -o {W}/fit_mpi_meds.fits --set batch_size=4 --threads 1 "${Q[@]}" &&
  pair fit_mpi_2ranks_meds fit_mpi_meds.fits

# ---------------------------------------------------------------- Python: arrays and run_fit
both python_arrays env PYTHONPATH={PYPATH} "$PYTHON" "$HERE/python_arrays.py" "$GRID_NF" "${CELLS[0]}" {W}/py &&
  for f in fit_stamps_plain fit_stamps_metacal_wmom fit_stamps_metacal_bd metadetect_cell; do
    pair "python:$f.repr" "py/$f.repr"
    pair "python:$f.npy" "py/$f.npy"
  done && pair python:fit_stamp.repr py/fit_stamp.repr && pair python:run_fit.fits py/run_fit.fits

# ---------------------------------------------------------------- calibration
both calibrate_build {S} calibrate build -o {W}/cal.fits --radii 1.2,2 --bulge-fractions 0,1 --e-steps 6 --e-max 0.5 --realisations 3 --set stamp_size=25 --set noise_sigma=1 --set psf_e2=0.05 --threads 2 "${Q[@]}" &&
  pair calibrate_build cal.fits
both calibrate_apply {S} calibrate apply {W}/fit_grid_weighted.fits --calibration {W}/cal.fits --per-object -o {W}/cal_applied.fits "${Q[@]}" &&
  pair calibrate_apply_per_object cal_applied.fits

# ---------------------------------------------------------------- metadetect
both md_images {S} metadetect "${CELLS[@]}" -o {W}/md_images.fits --threads 1 "${Q[@]}" &&
  pair md_images md_images.fits
both md_input_list_pgauss {S} metadetect --input-list "$IN/cells.list" -o {W}/md_list_pgauss.fits --measurement pgauss --threads 2 "${Q[@]}" &&
  pair md_input_list_pgauss md_list_pgauss.fits
both md_tile_1band {S} metadetect --meds "$IN/tile1/cells_meds.fits" -o {W}/md_tile_1band.fits --threads 1 "${Q[@]}" &&
  pair md_tile_1band md_tile_1band.fits
both md_tile_bands {S} metadetect --meds "$IN/tileb/g/cells_meds.fits" --meds "$IN/tileb/r/cells_meds.fits" --meds "$IN/tileb/i/cells_meds.fits" --bands g,r,i -o {W}/md_tile_bands.fits --threads 2 "${Q[@]}" &&
  pair md_tile_bands md_tile_bands.fits
both md_image_bands {S} metadetect "$IN/tileb/{band}/cell_0000.fits" "$IN/tileb/{band}/cell_0001.fits" --bands g,r,i -o {W}/md_image_bands.fits --threads 2 "${Q[@]}" &&
  pair md_image_bands md_image_bands.fits
both md_shard0 {S} metadetect "${CELLS12[@]}" -o {W}/md_shard0.fits --shard 0/2 --threads 2 "${Q[@]}" &&
  pair md_shard_0/2 md_shard0.fits
both md_shard1 {S} metadetect "${CELLS12[@]}" -o {W}/md_shard1.fits --shard 1/2 --threads 2 "${Q[@]}" &&
  pair md_shard_1/2 md_shard1.fits
both md_merge {S} merge -o {W}/md_merged.fits {W}/md_shard0.fits {W}/md_shard1.fits "${Q[@]}" &&
  pair md_shard_merged md_merged.fits
both md_mpi mpirun -n 2 --oversubscribe {MPI} metadetect "${CELLS12[@]}" -o {W}/md_mpi.fits --threads 1 "${Q[@]}" &&
  pair md_mpi_2ranks md_mpi.fits
both md_mpi_tile mpirun -n 2 --oversubscribe {MPI} metadetect --meds "$IN/tile1/cells_meds.fits" -o {W}/md_mpi_tile.fits --threads 1 "${Q[@]}" &&
  pair md_mpi_2ranks_tile md_mpi_tile.fits

# ---------------------------------------------------------------- kill -9, then --resume (new build)
kill_resume fit_kill9_resume fit_killed.fits 40 {S} fit "$GRID_40" -o {W}/fit_killed.fits "${CHEAP[@]}" --set noise_sigma=1 --set batch_size=5 --threads 1 "${Q[@]}"
kill_resume md_kill9_resume md_killed.fits 1 {S} metadetect "${CELLS12[@]}" -o {W}/md_killed.fits --threads 1 "${Q[@]}"

# ---------------------------------------------------------------- compare
echo
printf '%-40s %7s  %s\n' "configuration" "rows" "result (table data; time_us masked; headers not compared)"
"$PYTHON" "$HERE/compare_tables.py" --manifest "$MANIFEST"
status=$?
echo
n=$(grep -c . "$MANIFEST")
if [ $status -eq 0 ]; then
  echo "ALL SAME: $n tables"
else
  echo "NOT ALL SAME ($n entries; failed runs: ${FAILED[*]:-none}); logs in $WORK/logs"
fi
exit $status
