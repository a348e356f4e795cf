// MedsFile: a multi-epoch data structure (MEDS 0.9) tile, read object by object
// (../shared/reference/survey-formats.md). Opening reads the small `image_info` table and checks
// the layout: the required HDUs and columns, and the length of every flat cutout array. Objects
// are read one `object_data` row at a time and cutouts pixel range by pixel range, so memory is
// one object's, whatever the tile's size.
//
// Errors: a bad file (missing HDU or column, wrong types) throws FitsError naming the file, HDU
// and column. A bad object is not a bad file: object() returns it with `problem` set (a box size
// or cutout count out of range) or with the unusable cutouts' `problem` set (pixels past the end
// of an array, a file_id outside image_info, a Jacobian with zero determinant), each message
// naming file, HDU, object and column, so the caller can skip cutouts or flag the row and go on.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "io/fits_file.hpp"

namespace stampede::io {

enum class MedsCutoutType { kImage, kWeight, kSeg, kBmask, kNoise, kOrmask, kMfrac };
inline constexpr int kNumMedsCutoutTypes = 7;
const char* meds_hdu_name(MedsCutoutType type);  // "image_cutouts", ...

// Off-chip pixels in bmask cutouts (the meds package's BMASK_EDGE).
inline constexpr std::uint32_t kMedsBmaskEdge = 1u << 30;

// One row of image_info: a source image (row 0 is usually the coadd).
struct MedsImageInfo {
  std::string image_path;
  std::string psf_path;  // the optional `psf_path` column ("" when absent)
  long long image_id = 0, image_flags = 0;
  double magzp = 0, scale = 1, position_offset = 0;
};

// One cutout of an object: where its pixels are, where it came from, and its WCS Jacobian.
struct MedsCutout {
  long long file_id = 0;    // row in image_info
  long long start_row = 0;  // first pixel in the flat arrays
  double orig_row = 0, orig_col = 0;  // the object's position in the source image, 0-based
  long long orig_start_row = 0, orig_start_col = 0;
  double cutout_row = 0, cutout_col = 0;  // the object's centre in the cutout, 0-based
  // (du, dv) = J (drow, dcol), arcsec: J = [[dudrow, dudcol], [dvdrow, dvdcol]].
  double dudrow = 0, dudcol = 0, dvdrow = 0, dvdcol = 0;
  std::string problem;  // empty, or why this cutout cannot be used (it names the column)
  // Its PSF image in the `psf` HDU, when the tile has one (MedsFile::has_psf_cutouts): rows x cols
  // samples at the cutout's pixel pitch from psf_start_row, centred on (psf_cutout_row,
  // psf_cutout_col), 0-based.
  long long psf_start_row = -1, psf_rows = 0, psf_cols = 0;
  double psf_cutout_row = 0, psf_cutout_col = 0;
  std::string psf_problem;  // empty, or why its PSF image cannot be read (it names the column)
};

struct MedsObject {
  long long row = 0;  // in object_data
  long long id = 0, number = 0;
  long long box_size = 0;
  double ra = 0, dec = 0;
  std::vector<MedsCutout> cutouts;  // ncutout of them; cutout 0 is the coadd's
  std::string problem;              // empty, or why this object cannot be fitted (it names the column)
};

class MedsFile {
 public:
  // Throws FitsError for a file that is not a MEDS tile, naming the HDU or column at fault.
  static MedsFile open(const std::string& path);

  const std::string& path() const { return path_; }
  long long size() const { return n_objects_; }  // objects
  int max_cutouts() const { return nmax_; }      // NMAX, the length of the per-cutout columns
  const std::vector<MedsImageInfo>& images() const { return images_; }
  bool has(MedsCutoutType type) const { return length_[static_cast<int>(type)] >= 0; }
  // Pixels in a cutout type's flat array (-1: the HDU is absent).
  long long array_length(MedsCutoutType type) const { return length_[static_cast<int>(type)]; }
  // Whether the tile has PSF images per cutout: the `psf` HDU and object_data's psf_start_row,
  // psf_cutout_row, psf_cutout_col and psf_box_size (or psf_row_size and psf_col_size), each one
  // value per object or NMAX. Otherwise psf_cutouts_problem() says what is missing.
  bool has_psf_cutouts() const { return psf_problem_.empty(); }
  const std::string& psf_cutouts_problem() const { return psf_problem_; }

  // The ids of object_data rows [first, first + out.size()).
  void read_ids(long long first, std::span<long long> out);
  // The ra and dec (degrees) of object_data rows [first, first + ra.size()); dec.size() == ra.size().
  void read_positions(long long first, std::span<double> ra, std::span<double> dec);
  // Row `row` of object_data (0 <= row < size()); sets `problem` for an object that cannot be fitted.
  MedsObject object(long long row);
  // The box_size^2 pixels (row-major, rows slow) of cutout `icut` of `object` from one array;
  // `object` must have no problem and `type` must be present. out.size() must be box_size^2.
  void read_cutout(const MedsObject& object, int icut, MedsCutoutType type, std::span<double> out);
  // The psf_rows x psf_cols PSF samples of cutout `icut` (row-major); the tile must have PSF
  // cutouts and the cutout no psf_problem. out.size() must be psf_rows * psf_cols.
  void read_psf_cutout(const MedsObject& object, int icut, std::span<double> out);

 private:
  MedsFile(FitsFile file, std::string path) : file_(std::move(file)), path_(std::move(path)) {}
  std::string describe_object(const MedsObject& o);
  void find_psf_cutouts();                // at open: sets psf_problem_ or the PSF columns
  void read_psf_columns(MedsObject& o);   // each cutout's PSF image place, or its psf_problem

  FitsFile file_;
  std::string path_;
  long long n_objects_ = 0;
  int nmax_ = 0;
  std::vector<MedsImageInfo> images_;
  std::array<long long, kNumMedsCutoutTypes> length_{};
  std::array<int, kNumMedsCutoutTypes> hdu_{};  // 0-based HDU index of each array (moving by index is cheap)
  int object_hdu_ = 0;
  std::string psf_problem_ = "no PSF cutouts";  // empty when the tile has them
  int psf_hdu_ = 0;
  long long psf_length_ = -1;
  // object_data's PSF columns: {start_row, cutout_row, cutout_col, rows, cols}; repeat 1 or NMAX.
  std::array<std::string, 5> psf_columns_;
  std::array<long long, 5> psf_repeat_{};
  std::vector<double> psf_scratch_;
  // Scratch for one object_data row's per-cutout columns.
  std::vector<long long> ints_;
  std::vector<double> doubles_;
};

}  // namespace stampede::io
