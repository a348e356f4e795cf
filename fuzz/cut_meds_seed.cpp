// Cuts a small MEDS seed for fuzz_meds out of the meds package's own tile: objects 0 and 1 only,
// two cutouts each of 4 x 4 pixels (the first 160 pixels of every flat array), everything else
// (columns, image_info, metadata, HDU order) as the writer made it.
// usage: cut_meds_seed IN.fits OUT.fits   (built and run by fuzz/make_seeds.sh)
#include <fitsio.h>

#include <cstdio>
#include <string>

int main(int argc, char** argv) {
  if (argc != 3) return 2;
  fitsfile *in = nullptr, *out = nullptr;
  int status = 0;
  fits_open_file(&in, argv[1], READONLY, &status);
  fits_create_file(&out, (std::string("!") + argv[2]).c_str(), &status);
  fits_copy_file(in, out, 1, 1, 1, &status);
  fits_close_file(in, &status);
  auto column = [&](const char* name) {
    int col = 0;
    fits_get_colnum(out, CASEINSEN, const_cast<char*>(name), &col, &status);
    return col;
  };
  fits_movnam_hdu(out, BINARY_TBL, const_cast<char*>("object_data"), 0, &status);
  long rows = 0;
  fits_get_num_rows(out, &rows, &status);
  fits_delete_rows(out, 3, rows - 2, &status);
  for (long long row = 1; row <= 2; ++row) {
    long long box = 4, ncut = 2;
    fits_write_col(out, TLONGLONG, column("box_size"), row, 1, 1, &box, &status);
    fits_write_col(out, TLONGLONG, column("ncutout"), row, 1, 1, &ncut, &status);
    for (long long i = 0; i < 5; ++i) {
      long long start = ((row - 1) * 5 + i) * 16;
      double centre = 1.5;
      fits_write_col(out, TLONGLONG, column("start_row"), row, i + 1, 1, &start, &status);
      fits_write_col(out, TDOUBLE, column("cutout_row"), row, i + 1, 1, &centre, &status);
      fits_write_col(out, TDOUBLE, column("cutout_col"), row, i + 1, 1, &centre, &status);
    }
  }
  for (const char* hdu : {"image_cutouts", "weight_cutouts", "seg_cutouts", "bmask_cutouts"}) {
    fits_movnam_hdu(out, IMAGE_HDU, const_cast<char*>(hdu), 0, &status);
    int bitpix = 0;
    fits_get_img_type(out, &bitpix, &status);
    long n = 160;
    fits_resize_img(out, bitpix, 1, &n, &status);
  }
  fits_close_file(out, &status);
  if (status) fits_report_error(stderr, status);
  return status ? 1 : 0;
}
