#!/usr/bin/env bash
# Speed before and after a change where wall times are too noisy to resolve 5 %: the instructions
# one `stampede fit` run executes (valgrind --tool=callgrind, one thread), REF_BUILD's binary against
# NEW_BUILD's, on the same small inputs. Counts repeat to ~0.1 % whatever the machine's load; they
# include the run's start (reading, FFT plans), the same for both sides.
#
#   docs/observation_model/count_instructions.sh REF_BUILD NEW_BUILD [WORKDIR]
#   WORKDIR: default a new /tmp/count_instructions.XXXXXX (inputs simulated there by REF_BUILD).
#   Prints a table: case, REF's and NEW's instructions (millions), NEW / REF.
set -euo pipefail
REF=$(cd "$1" && pwd); NEW=$(cd "$2" && pwd)
WORK=${3:-$(mktemp -d /tmp/count_instructions.XXXXXX)}
mkdir -p "$WORK" && cd "$WORK"
S=$REF/tools/stampede
[[ -e in/s20/set_0.fits ]] || "$S" sim great08 --sets 1 --grid 8 --snr 20 --seed 7 --out in/s20 >/dev/null
[[ -e in/s20bd/set_0.fits ]] || "$S" sim great08 --sets 1 --grid 4 --snr 20 --seed 3 --out in/s20bd >/dev/null
[[ -e in/meds/meds.fits ]] || "$S" sim meds --objects 8 --snr 30 --seed 12 --out in/meds >/dev/null
[[ -e in/meds3/g/meds.fits ]] || "$S" sim meds --objects 4 --bands g,r,i --seed 13 --out in/meds3 >/dev/null
B3=(--meds in/meds3/g/meds.fits --meds in/meds3/r/meds.fits --meds in/meds3/i/meds.fits --bands g,r,i)
cases=(
  "grid-plain|in/s20/set_0.fits"
  "grid-metacal-wmom|in/s20/set_0.fits --set metacal=true"
  "grid-metacal-bd|in/s20bd/set_0.fits --set metacal=true --set metacal_model=bd"
  "meds-4epoch|--meds in/meds/meds.fits"
  "meds-4epoch-metacal-wmom|--meds in/meds/meds.fits --set metacal=true"
  "meds-3band|${B3[*]}"
)
count() {  # BUILD CASE ARGS...: instructions (Ir) of one run
  local build=$1 name=$2; shift 2
  valgrind --tool=callgrind --callgrind-out-file="$WORK/$name.out" "$build/tools/stampede" fit "$@" \
    -o "$WORK/$name.fits" --threads 1 --overwrite >"$WORK/$name.log" 2>&1
  sed -n 's/^summary: //p' "$WORK/$name.out"
}
echo "| case | REF (M instructions) | NEW (M instructions) | NEW / REF |"
echo "|---|---|---|---|"
for c in "${cases[@]}"; do
  name=${c%%|*}; read -r -a args <<< "${c#*|}"
  r=$(count "$REF" "ref.$name" "${args[@]}"); n=$(count "$NEW" "new.$name" "${args[@]}")
  awk -v c="$name" -v r="$r" -v n="$n" 'BEGIN { printf "| %s | %.1f | %.1f | %.4f |\n", c, r / 1e6, n / 1e6, n / r }'
done
