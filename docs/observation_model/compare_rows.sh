#!/usr/bin/env bash
# Rows before and after a refactor: the same commands run with REF_BUILD's binaries into WORKDIR/ref
# and with NEW_BUILD's into WORKDIR/new, on the same inputs (simulated once by REF_BUILD into
# WORKDIR/in; NEW_BUILD's simulations of them are compared byte for byte), then every output table
# is compared by compare_rows.py (next to this script) and a table of results is printed.
#
#   docs/observation_model/compare_rows.sh REF_BUILD NEW_BUILD [WORKDIR]
#   REF_BUILD, NEW_BUILD: build folders (tools/stampede, tools/stampede-mpi, python/stampede).
#   WORKDIR: default a new /tmp/compare_rows.XXXXXX; its in/ ref/ new/ newsim/ logs/ are replaced.
#   Environment: PYTHON (/usr/bin/python3), STAMPEDE_DATA (the shared data folder), THREADS (2).
#
# Cases and verdicts (exit status 1 when any case fails; every case runs whatever others gave):
#   sim-*        NEW's `stampede sim` outputs = REF's, byte for byte (same command, same relative --out)
#   grid-*       `stampede fit` on grids: plain (sim S/N 20, also with renderer = upsampled; GalSim's nf
#                set 0 and S/N 40 set 1), metacal wmom and bd: every column but time_us, the row count, the column names and the header
#                (keys holding times, dates or versions aside; RUNFP reported only) bit for bit
#   py-*         stampede.fit_stamps on a numpy stack of the grid's stamps (plain, metacal, a PSF image
#                per stamp with masked rows) and
#                stampede.run_fit on the grid file: bitwise as grids
#   meds-*       `fit --meds`: the shared sample tile, `sim meds` 4-epoch tiles noise-free and S/N 30, a
#                3-band tile set (--bands g,r,i); plain, metacal wmom, and bord (1 and 3 bands). Noise-free: |de| <= 1e-7 and
#                the same status for every object; noisy: >= 99.9 % of objects with |de| <= 0.01 e_err
#                and the same status. BITWISE when the tables are identical.
#   mpi-*        NEW only: `mpirun -n 2 stampede-mpi fit` bitwise against NEW's single-process table, on
#                a grid (validates the harness) and MEDS tiles (1 band, 3 bands); a run killed with
#                kill -9 (mpirun's process group and every rank) after its first committed batch, then
#                finished with --resume, against the uninterrupted single-process table. A refused run
#                is a failed case (REFUSED, with its message) and the script goes on.
set -uo pipefail

if [[ $# -lt 2 || $# -gt 3 ]]; then
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
fi
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REF=$(cd "$1" && pwd) || exit 2
NEW=$(cd "$2" && pwd) || exit 2
WORK=${3:-$(mktemp -d /tmp/compare_rows.XXXXXX)}
PY=${PYTHON:-/usr/bin/python3}
DATA=${STAMPEDE_DATA:-$(cd "$here/../../.." && pwd)/shared/data}
[[ -d $DATA/galsim-great08-mini ]] || DATA=/work/shared/data
T=${THREADS:-2}
NICE=(nice -n 10)
MPIRUN=(mpirun --allow-run-as-root --oversubscribe -n 2)
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1

for b in "$REF" "$NEW"; do
  for f in tools/stampede tools/stampede-mpi python/stampede; do
    [[ -e $b/$f ]] || { echo "compare_rows.sh: $b/$f is missing" >&2; exit 2; }
  done
done
mkdir -p "$WORK" || exit 2
WORK=$(cd "$WORK" && pwd)
cd "$WORK" || exit 2
rm -rf in ref new newsim logs results.tsv
mkdir -p in ref new newsim logs
RESULTS=$WORK/results.tsv
start=$SECONDS

# compare_rows.py with REF's module (the same FITS reader for both sides)
cmp_py() { PYTHONPATH="$REF/python" "${NICE[@]}" "$PY" "$here/compare_rows.py" "$@" --results "$RESULTS" >/dev/null; }
record() { cmp_py record "$1" "$2" "$3" ${4:+--rows "$4"}; }  # CASE VERDICT DETAIL [ROWS]
# The first error line of a log, for a verdict's detail.
why() {
  grep -m1 -E '^stampede[^:]*: error' "$1" 2>/dev/null || grep -m1 -iE 'error|refus|abort' "$1" 2>/dev/null ||
    tail -n1 "$1" 2>/dev/null || echo "no log"
}
# Rows committed by a run's checkpoint (0 when it has none yet).
committed() { local n; n=$(sed -n 's/^rows //p' "$1.checkpoint" 2>/dev/null | head -n1); echo "${n:-0}"; }
bin() { [[ $1 == ref ]] && echo "$REF" || echo "$NEW"; }

# sim_both NAME ARGS...: `stampede sim ARGS --out in/NAME` by REF (in WORKDIR) and by NEW (in newsim/).
sim_both() {
  local name=$1; shift
  if ! "${NICE[@]}" "$REF/tools/stampede" sim "$@" --out "in/$name" --threads "$T" >"logs/ref.sim-$name.log" 2>&1; then
    record "sim-$name" ERROR "ref: $(why "logs/ref.sim-$name.log")"
    return 1
  fi
  if ! (cd newsim && "${NICE[@]}" "$NEW/tools/stampede" sim "$@" --out "in/$name" --threads "$T") \
      >"logs/new.sim-$name.log" 2>&1; then
    record "sim-$name" ERROR "new: $(why "logs/new.sim-$name.log")"
    return 0
  fi
  cmp_py files "sim-$name" "in/$name" "newsim/in/$name"
  return 0
}

# fit_both CASE MODE FIT_ARGS...: `stampede fit FIT_ARGS -o SIDE/CASE.fits` for both builds, then compare.
fit_both() {
  local name=$1 mode=$2 side; shift 2
  for side in ref new; do
    if ! "${NICE[@]}" "$(bin $side)/tools/stampede" fit "$@" -o "$side/$name.fits" --threads "$T" \
        >"logs/$side.$name.log" 2>&1; then
      record "$name" ERROR "$side: $(why "logs/$side.$name.log")"
      return
    fi
  done
  cmp_py table "$name" "$mode" "ref/$name.fits" "new/$name.fits"
}

# mpi_vs CASE SINGLE.fits FIT_ARGS...: 2 ranks x 1 thread of NEW's stampede-mpi against SINGLE.fits.
mpi_vs() {
  local name=$1 single=$2; shift 2
  if [[ ! -e $single ]]; then
    record "$name" ERROR "no single-process table $single to compare with"
    return
  fi
  if ! "${NICE[@]}" "${MPIRUN[@]}" "$NEW/tools/stampede-mpi" fit "$@" -o "new/$name.fits" --threads 1 \
      >"logs/new.$name.log" 2>&1; then
    local v=ERROR
    grep -qiE 'stampede-mpi.*error|refus' "logs/new.$name.log" && v=REFUSED
    record "$name" "$v" "$(why "logs/new.$name.log")"
    return
  fi
  cmp_py table "$name" bitwise "$single" "new/$name.fits"
}

descendants() {
  local c
  for c in $(ps -o pid= --ppid "$1" 2>/dev/null); do
    echo "$c"
    descendants "$c"
  done
}

# mpi_kill_resume CASE FIT_ARGS...: NEW's 2-rank run killed by kill -9 (mpirun's process group and
# every rank under it) KILL_AFTER (1) s after its checkpoint first commits rows, finished with --resume, compared
# with NEW's uninterrupted single-process run of the same arguments (written to new/CASE.single.fits).
mpi_kill_resume() {
  local name=$1; shift
  local out=new/$name.fits pid t0 tk pids p rc
  setsid "${NICE[@]}" "${MPIRUN[@]}" "$NEW/tools/stampede-mpi" fit "$@" -o "$out" --threads 1 \
    >"logs/new.$name.killed.log" 2>&1 &
  pid=$!
  t0=$SECONDS
  while kill -0 "$pid" 2>/dev/null && (($(committed "$out") == 0)) && ((SECONDS - t0 < 120)); do sleep 0.2; done
  if kill -0 "$pid" 2>/dev/null; then
    sleep "${KILL_AFTER:-1}"
    tk=$((SECONDS - t0))
    pids=$(descendants "$pid")
    kill -9 -- "-$pid" 2>/dev/null
    for p in $pids; do kill -9 "$p" 2>/dev/null; done
    wait "$pid" 2>/dev/null
    for p in $pids; do while kill -0 "$p" 2>/dev/null; do sleep 0.1; done; done
  else
    wait "$pid"
    rc=$?
    if ((rc != 0)); then
      local v=ERROR
      grep -qiE 'stampede-mpi.*error|refus' "logs/new.$name.killed.log" && v=REFUSED
      record "$name" "$v" "$(why "logs/new.$name.killed.log")"
    else
      record "$name" FAIL "the run ended before the kill (the input is too small to interrupt)"
    fi
    return
  fi
  if [[ -e $out ]]; then
    record "$name" FAIL "the run completed before the kill (the input is too small to interrupt)"
    return
  fi
  if [[ ! -e $out.partial ]]; then
    record "$name" FAIL "killed before anything was written: no $out.partial to resume"
    return
  fi
  if ! "${NICE[@]}" "$NEW/tools/stampede" fit "$@" -o "new/$name.single.fits" --threads "$T" \
      >"logs/new.$name.single.log" 2>&1; then
    record "$name" ERROR "single-process run: $(why "logs/new.$name.single.log")"
    return
  fi
  if ! "${NICE[@]}" "${MPIRUN[@]}" "$NEW/tools/stampede-mpi" fit "$@" -o "$out" --threads 1 --resume \
      >"logs/new.$name.resume.log" 2>&1; then
    record "$name" ERROR "--resume: $(why "logs/new.$name.resume.log")"
    return
  fi
  local resumed
  resumed=$(grep -oE '\([0-9]+ resumed\)' "logs/new.$name.resume.log" | tail -n1 | tr -d '()')
  cmp_py table "$name" bitwise "new/$name.single.fits" "$out" --note "killed after ${tk} s, ${resumed:-? resumed}"
}

GS=$DATA/galsim-great08-mini
SAMPLE=$DATA/meds-sample/meds.fits
MC=(--set metacal=true)  # metacal_model = wmom is the default
BD=(--set metacal=true --set metacal_model=bd)

# --- inputs (REF simulates; NEW's simulations must be the same bytes)
sim_both s20 great08 --sets 1 --grid 16 --snr 20 --seed 7
sim_both s20bd great08 --sets 1 --grid 10 --snr 20 --seed 3
sim_both meds-nf meds --objects 40 --noise-free --seed 11
sim_both meds-noisy meds --objects 100 --snr 30 --seed 12
sim_both meds-3band meds --objects 40 --bands g,r,i --seed 13
"${NICE[@]}" "$REF/tools/stampede" sim meds --out in/meds-big --objects 400 --seed 21 --threads "$T" \
  >logs/ref.sim-meds-big.log 2>&1 || record sim-meds-big ERROR "ref: $(why logs/ref.sim-meds-big.log)"

# --- 1. grids, plain fits
fit_both grid-s20 bitwise in/s20/set_0.fits
fit_both grid-gs-nf0 bitwise "$GS/nf/set_0.fits"
fit_both grid-gs-snr40-1 bitwise "$GS/snr40/set_1.fits"
# --- 2. grids, metacal
fit_both grid-mc-wmom bitwise in/s20/set_0.fits "${MC[@]}"
fit_both grid-mc-bd bitwise in/s20bd/set_0.fits "${BD[@]}"
fit_both grid-s20-upsampled bitwise in/s20/set_0.fits --set renderer=upsampled

# --- 3. Python
py_ok=()
for side in ref new; do
  if PYTHONPATH="$(bin $side)/python" "${NICE[@]}" "$PY" "$here/compare_rows.py" python "$side" in/s20/set_0.fits \
      >"logs/$side.python.log" 2>&1; then
    py_ok+=("$side")
  fi
done
for c in py-fit_stamps py-fit_stamps-mc py-fit_stamps-psfs py-run_fit; do
  ext=npy; [[ $c == py-run_fit ]] && ext=fits
  if [[ ${#py_ok[@]} -eq 2 ]]; then
    cmp_py table "$c" bitwise "ref/$c.$ext" "new/$c.$ext"
  else
    s=new; [[ ${py_ok[0]:-} != ref ]] && s=ref
    record "$c" ERROR "$s: $(tail -n1 "logs/$s.python.log")"
  fi
done

# --- 4. MEDS tiles and multi-band
fit_both meds-sample noisy --meds "$SAMPLE"
fit_both meds-sample-mc noisy --meds "$SAMPLE" "${MC[@]}"
fit_both meds-nf nf --meds in/meds-nf/meds.fits
fit_both meds-nf-mc nf --meds in/meds-nf/meds.fits "${MC[@]}"
fit_both meds-noisy noisy --meds in/meds-noisy/meds.fits
fit_both meds-noisy-mc noisy --meds in/meds-noisy/meds.fits "${MC[@]}"
B3=(--meds in/meds-3band/g/meds.fits --meds in/meds-3band/r/meds.fits --meds in/meds-3band/i/meds.fits --bands g,r,i)
fit_both meds-3band noisy "${B3[@]}"
fit_both meds-3band-mc noisy "${B3[@]}" "${MC[@]}"
fit_both meds-noisy-bord noisy --meds in/meds-noisy/meds.fits --set meds_model=bord
fit_both meds-3band-bord noisy "${B3[@]}" --set meds_model=bord

# --- 5. MPI (NEW only): 2 ranks = one process; kill -9 then --resume = uninterrupted
mpi_vs mpi-grid new/grid-s20.fits in/s20/set_0.fits
mpi_kill_resume mpi-grid-resume "$GS/snr40/set_0.fits" "${BD[@]}" --set batch_size=8
mpi_vs mpi-meds-1band new/meds-noisy.fits --meds in/meds-noisy/meds.fits
mpi_vs mpi-meds-3band new/meds-3band.fits "${B3[@]}"
mpi_kill_resume mpi-meds-resume --meds in/meds-big/meds.fits --set batch_size=8

echo "compare_rows: REF $REF vs NEW $NEW, $((SECONDS - start)) s, logs and tables in $WORK"
PYTHONPATH="$REF/python" "$PY" "$here/compare_rows.py" report "$RESULTS"
