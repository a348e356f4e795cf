#!/usr/bin/env bash
# The reference shear test's runs of docs/metadetect.md ("The reference shear test"), each through
# docs/metadetect/shear_test.py into docs/metadetect/results/LABEL (chunk files: a stopped run goes
# on where it was). Cells: `sim cells --reference` (per-object S/N 1e6, round exponentials, reference
# positions), the 7 x 7 grid and random positions, and random positions at S/N 20; metadetect with
# its defaults. The labels before issue 53's were measured with SEP's detector, the default then:
# extending them needs --metadetect="... --detector sep" (the chunks' headers do not record it);
# the labels before the *_f32 ones were measured with double-precision images, and extending them
# needs "--double-images" (and, the fixnoise field being drawn in pairs since, their chunks are not
# reproduced bit for bit).
#   usage: docs/metadetect/run_reference_tests.sh [BUILD_DIR] [WORK_DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-build} work=${2:-/tmp/shear_test}
run() { /usr/bin/python3 "$here/shear_test.py" --build "$build" --work "$work" "$@"; }
run --label ref_grid --pairs 200 --chunk 100 --sim="--reference --layout grid"
run --label ref_random --pairs "${RANDOM_PAIRS:-10000}" --chunk 250 --sim="--reference --layout random"
run --label ref_random_snr20 --pairs "${SNR20_PAIRS:-5000}" --chunk 250 --sim="--reference --layout random --snr 20"
# The random cells again, each detection kept by its position with the cells' recorded shear undone
# too (a lone cell then keeps the same objects under +g and -g, as tiled cells do); the same seeds.
run --label ref_random_keepunl --pairs "${RANDOM_PAIRS:-10000}" --chunk 250 --sim="--reference --layout random" \
  --metadetect="--keep-unlensed"
run --label ref_random_snr20_keepunl --pairs "${SNR20_PAIRS:-5000}" --chunk 250 \
  --sim="--reference --layout random --snr 20" --metadetect="--keep-unlensed"
# Issue 53: the random cells with our detector (the default) on 40,000 pairs; the first 10,000 are
# ref_random_keepunl's seeds (shear_test.py --compare ref_random_keepunl pairs them).
run --label ref_random_keepunl_tree --pairs "${TREE_PAIRS:-40000}" --chunk 250 --sim="--reference --layout random" \
  --metadetect="--keep-unlensed --detector tree"
run --label ref_grid_tree --pairs 200 --chunk 100 --sim="--reference --layout grid" --metadetect="--detector tree"
run --label ref_random_snr20_keepunl_tree --pairs "${SNR20_PAIRS:-5000}" --chunk 250 \
  --sim="--reference --layout random --snr 20" --metadetect="--keep-unlensed --detector tree"
# Issue 53: the same with the cells' images in single precision (the default since) and fixnoise's
# field drawn in pairs; the seeds of the labels above (shear_test.py --compare pairs them).
run --label ref_grid_f32 --pairs 200 --chunk 100 --sim="--reference --layout grid" --metadetect="--detector tree"
run --label ref_random_snr20_keepunl_f32 --pairs "${SNR20_PAIRS:-5000}" --chunk 250 \
  --sim="--reference --layout random --snr 20" --metadetect="--keep-unlensed --detector tree"
run --label ref_random_keepunl_f32 --pairs "${F32_PAIRS:-40000}" --chunk 250 --sim="--reference --layout random" \
  --metadetect="--keep-unlensed --detector tree"
