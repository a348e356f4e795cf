#!/usr/bin/env bash
# Rewrites the seed corpora of fuzz/corpus/ with the project's own writers (a built `stampede`); seeds
# kept from findings (f<N>_*) stay.
# usage: fuzz/make_seeds.sh [path/to/stampede]   (default: build/tools/stampede)
set -euo pipefail
cd "$(dirname "$0")/.."
S="$(realpath "${1:-build/tools/stampede}")"
C=fuzz/corpus
T="$(mktemp -d)"
trap 'rm -rf "$T"' EXIT
mkdir -p "$C"/{stamp_grid,weight_map,catalogue,run_config,psf_image,calibration_table,catalog_reader,meds,psfex}
mkdir -p "$C"/{metadetect_table,cell_image,metadetect_metrics_arguments}
q=(--quiet --threads 1)

# Grids: 2 x 2 stamps of 8 (16 x 16, the weight target's image shape) and 1 x 1 stamp of 8.
"$S" sim great08 --out "$T/a" --sets 1 --grid 2 --stamp 8 --threads 1 >/dev/null
"$S" sim great08 --out "$T/b" --sets 1 --grid 1 --stamp 8 --psf airy --threads 1 >/dev/null
cp "$T/a/set_0.fits" "$C/stamp_grid/grid_2x2_8.fits"
cp "$T/b/set_0.fits" "$C/stamp_grid/grid_1x1_8.fits"
cp "$T/a/set_0.fits" "$C/weight_map/weight_16x16.fits"
cp "$T/a/psf_0.fits" "$C/psf_image/psf_moffat.fits"
cp "$T/b/psf_0.fits" "$C/psf_image/psf_airy.fits"

# Result tables: a grid fit and a catalogue fit (whose table, with x_image / y_image, is also a
# FITS catalogue); text catalogues with and without the PSF columns.
"$S" fit "$T/a/set_0.fits" -o "$T/grid_fit.fits" --set noise_sigma=1 "${q[@]}"
printf '# id x y\n1 4.5 4.5\n2 12 12.5\n3 -3 40\n' > "$C/catalogue/text_id_x_y.txt"
printf 'id x y psf_beta psf_fwhm psf_e1 psf_e2\n7 8 8 3 2.85 0 0.05\n8 15.5 2 2.5 3 0.01 0\n ' > "$C/catalogue/text_with_psf.txt"
"$S" fit "$T/a/set_0.fits" -o "$T/cat_fit.fits" --catalog "$C/catalogue/text_id_x_y.txt" --set stamp_size=8 \
  --set noise_sigma=1 "${q[@]}"
cp "$T/grid_fit.fits" "$C/catalog_reader/grid_fit.fits"
cp "$T/cat_fit.fits" "$C/catalog_reader/catalogue_fit.fits"
cp "$T/cat_fit.fits" "$C/catalogue/fits_table.fits"

# Configurations: the documented template, and a short file of set keys.
"$S" fit --help-config > "$C/run_config/template.ini"
printf '[fit]\nstamp_size = 8\nnoise_sigma = 1.5  # trailing comment\npsf_input = airy\nsave_images = 1,2\n' \
  > "$C/run_config/short.ini"

# A calibration table: the smallest grid (one radius, one bulge fraction, four e steps).
"$S" calibrate build -o "$C/calibration_table/small.fits" --radii 2 --bulge-fractions 0.5 --e-steps 4 \
  --realisations 2 --set stamp_size=12 --set noise_sigma=1 "${q[@]}"
# MEDS and PSFEx: cut from the tile the meds package wrote (../shared/data/meds-sample): two
# objects of two 4 x 4 cutouts (fuzz/cut_meds_seed.cpp), and a degree-1 and a degree-0 PSFEx model.
SAMPLE=../shared/data/meds-sample
c++ -O1 -o "$T/cut_meds_seed" fuzz/cut_meds_seed.cpp $(pkg-config --cflags --libs cfitsio)
"$T/cut_meds_seed" "$SAMPLE/meds.fits" "$C/meds/sample_2_objects.fits"
cp "$SAMPLE/psfex/se_e1.psf" "$C/psfex/degree1.psf"
cp "$SAMPLE/psfex/se_e2.psf" "$C/psfex/degree0.psf"
chmod 644 "$C/psfex/"*.psf
# Metadetection: a 32 x 32 cell image (WEIGHT, NOISE, PSF 9 x 9), one band and two; the tables of
# metadetect over them (16-pixel interiors); metrics --metadetect command lines over the fixed
# tables fuzz_metadetect_metrics_arguments makes.
"$S" sim cells --out "$T/c1" --cells 1 --size 32 --buffer 8 --grid 1 --psf-size 9 --threads 1 >/dev/null 2>&1
"$S" sim cells --out "$T/c2" --cells 1 --size 32 --buffer 8 --grid 1 --psf-size 9 --bands g,r --threads 1 >/dev/null 2>&1
cp "$T/c1/cell_0000.fits" "$C/cell_image/cell_32.fits"
md=(--cell-size 32 --cell-buffer 8 "${q[@]}")
"$S" metadetect "$T/c1/cell_0000.fits" -o "$C/metadetect_table/one_band.fits" "${md[@]}" 2>/dev/null
"$S" metadetect "$T/c2/{band}/cell_0000.fits" --bands g,r -o "$C/metadetect_table/two_bands.fits" "${md[@]}" 2>/dev/null
F=/tmp/stampede-fuzz-metadetect-metrics
args() { printf '%s\0' "$@" | head -c -1; }  # NUL-separated, as the target splits them
args --metadetect $F/plus.fits --minus $F/minus.fits > "$C/metadetect_metrics_arguments/pair"
args --metadetect $F/plus.fits --minus $F/minus.fits --rotated $F/turned.fits --rotated-minus $F/turned_minus.fits \
  > "$C/metadetect_metrics_arguments/turned_pair"
args --metadetect $F/pgauss.fits --cut-snr 5 --estimator package --bootstrap 20 > "$C/metadetect_metrics_arguments/pgauss_cuts"
args --metadetect $F/plus.fits --minus $F/copy.fits --shear 0.02,0 > "$C/metadetect_metrics_arguments/copy"
ls -l "$C"/*
