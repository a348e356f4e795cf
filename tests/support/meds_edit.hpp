// Edits a copy of a MEDS tile in place with CFITSIO, for tests of bad input: one cell of a table
// column, or any change given as a function of the open file.
#pragma once

#include <fitsio.h>
#include <gtest/gtest.h>

#include <string>

namespace stampede::testing {

class MedsEditor {
 public:
  explicit MedsEditor(std::string path) : path_(std::move(path)) {}
  template <class F>
  void edit(F&& change) {
    fitsfile* f = nullptr;
    int status = 0;
    fits_open_file(&f, path_.c_str(), READWRITE, &status);
    change(f, &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0) << path_;
  }
  void set_cell(const char* hdu, const char* column, long long row, long long element, long long value) {
    edit([&](fitsfile* f, int* status) {
      const int col = move_to_column(f, hdu, column, status);
      fits_write_col(f, TLONGLONG, col, row + 1, element + 1, 1, &value, status);
    });
  }
  void set_cell(const char* hdu, const char* column, long long row, long long element, double value) {
    edit([&](fitsfile* f, int* status) {
      const int col = move_to_column(f, hdu, column, status);
      fits_write_col(f, TDOUBLE, col, row + 1, element + 1, 1, &value, status);
    });
  }
  void delete_hdu(const char* hdu) {
    edit([&](fitsfile* f, int* status) {
      fits_movnam_hdu(f, ANY_HDU, const_cast<char*>(hdu), 0, status);
      fits_delete_hdu(f, nullptr, status);
    });
  }
  void delete_column(const char* hdu, const char* column) {
    edit([&](fitsfile* f, int* status) { fits_delete_col(f, move_to_column(f, hdu, column, status), status); });
  }

 private:
  static int move_to_column(fitsfile* f, const char* hdu, const char* column, int* status) {
    fits_movnam_hdu(f, BINARY_TBL, const_cast<char*>(hdu), 0, status);
    int col = 0;
    fits_get_colnum(f, CASEINSEN, const_cast<char*>(column), &col, status);
    return col;
  }
  std::string path_;
};

}  // namespace stampede::testing
