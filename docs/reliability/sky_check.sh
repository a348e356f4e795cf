#!/usr/bin/env bash
# Issue 55, finding 5: the cell sky check (io/cell_image_reader's cell_sky_level) on the shear
# test's cells, clean and with a sky added. For each configuration: how many of its cells
# `metadetect` fails for their sky, and the levels it names. Then m of a noise-free pair with a
# +5 sigma sky: refused now (exit 3), where it gave m1 = +0.74 before the check.
# usage: docs/reliability/sky_check.sh [STAMPEDE (build/tools/stampede)] [WORK (/tmp/stampede-sky)]
set -uo pipefail
cd "$(dirname "$0")/../.."
S="$(realpath "${1:-build/tools/stampede}")"; W="${2:-/tmp/stampede-sky}"
ADD="$(realpath docs/reliability/add_sky.py)"
mkdir -p "$W" && cd "$W"
sim() { local d="$1"; shift; [[ -d "$d" ]] || "$S" sim cells --out "$d" --cells 3 "$@" >/dev/null 2>&1; }
with_sky() {  # with_sky FROM TO K: every cell of FROM (and FROM/minus) with K x NOISESIG added
  mkdir -p "$2"
  for f in "$1"/cell_*.fits; do /usr/bin/python3 "$ADD" "$f" "$2/$(basename "$f")" "$3" >/dev/null; done
  if [[ -d "$1/minus" ]]; then with_sky "$1/minus" "$2/minus" "$3"; fi
}
sim ref --reference;                      sim refr --reference --layout random
sim n20g;                                 sim n20r --layout random --density 300
sim nfg --noise-free --pair;              sim nfr --noise-free --layout random
sim nfr300 --noise-free --layout random --density 300
sim nfbig --noise-free --layout random --hlr 2
with_sky nfg nfg+5 5; with_sky nfg nfg-5 -5; with_sky nfg nfg+1.5 1.5; with_sky n20g n20g+3 3; with_sky n20g n20g+1 1
printf '%-10s %-48s %s\n' cells configuration "flagged (levels)"
for c in "ref:--reference (grid, S/N 1e6)" "refr:--reference --layout random" "n20g:S/N 20 grid" \
         "n20r:S/N 20 random, 300/arcmin^2" "nfg:--noise-free grid" "nfr:--noise-free random" \
         "nfr300:--noise-free random, 300/arcmin^2" "nfbig:--noise-free random, hlr 2 arcsec" \
         "nfg+5:--noise-free grid, sky +5 sigma" "nfg-5:--noise-free grid, sky -5 sigma" \
         "nfg+1.5:--noise-free grid, sky +1.5 sigma" "n20g+3:S/N 20 grid, sky +3 sigma" "n20g+1:S/N 20 grid, sky +1 sigma"; do
  d="${c%%:*}"
  out="$("$S" metadetect "$d"/cell_*.fits -o "$d.fits" --overwrite 2>&1)"
  levels="$(grep -o 'sky at [-+0-9.]*' <<<"$out" | cut -d' ' -f3 | tr '\n' ' ')"
  printf '%-10s %-48s %s (%s)\n' "$d" "${c#*:}" "$(grep -c 'sky at' <<<"$out")/3" "${levels% }"
done
echo "== noise-free pair with a +5 sigma sky"
"$S" metadetect nfg+5/minus/cell_*.fits -o nfg+5-m.fits --overwrite --quiet 2>&1 | tail -1; echo "exit ${PIPESTATUS[0]}"
