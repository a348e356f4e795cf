// Stamps cut from a large image around the objects of a catalogue (FITS table, or whitespace text
// with columns `id x y [psf_beta psf_fwhm psf_e1 psf_e2]`, `#` comments), streamed in chunks.
// Positions are FITS 1-based pixels; the stamp is centred on the nearest pixel. Pixels outside the
// image are masked (weight 0) and the object flagged kFlagEdge; it is still fitted. A position
// whose stamp cannot reach the image (however far, or not finite) is a kFlagEdge row with no data.
// Ids are 64-bit integers: a text id must be an integer literal (or an integral number below 2^53,
// e.g. 3.0), a FITS id an integer column or integral doubles within the 64-bit range.
#pragma once

#include <cstdint>
#include <fstream>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "engine/pipeline/stamp_batch.hpp"
#include "io/fits_file.hpp"

namespace stampede::io {

struct CatalogueColumns {
  std::string id = "id", x = "x", y = "y";
  bool with_psf = false;  // psf_input = moffat_catalog
  std::string psf_beta = "psf_beta", psf_fwhm = "psf_fwhm", psf_e1 = "psf_e1", psf_e2 = "psf_e2";
};

class CatalogueStampSource final : public StampSource {
 public:
  // Throws FitsError / std::runtime_error naming the file and the missing column, bad line or row
  // (a non-integer id, an id used twice), or the first of `save_images` (ids whose images the run
  // saves) not in the catalogue, before any fitting: a first streaming pass validates the whole
  // catalogue, holding 16 bytes per object while it runs (to find repeated ids).
  CatalogueStampSource(const std::string& image_path, const std::string& weight_path,
                       const std::string& catalogue_path, int stamp_size, const CatalogueColumns& columns,
                       std::span<const std::int64_t> save_images = {});
  ~CatalogueStampSource() override;

  long long total_objects() const override { return total_; }
  void skip_to(long long index) override;
  bool fill(StampBatch& batch) override;

 private:
  struct Entry {
    std::int64_t id;
    double x, y, beta, fwhm, e1, e2;
  };
  bool next_entry(Entry* e);
  // Ids of rows [first_row, first_row + out.size()) of a FITS catalogue; throws naming a non-integer one.
  void table_ids(long long first_row, std::span<std::int64_t> out);
  void check_ids(std::span<const std::int64_t> save_images);
  void cut(const Entry& e, int k, StampBatch& batch);

  FitsFile image_;
  std::unique_ptr<FitsFile> weight_;
  std::string catalogue_path_;
  CatalogueColumns columns_;
  int stamp_;
  long long total_ = 0;
  long long next_ = 0;
  bool fits_catalogue_ = false;
  bool integer_ids_ = false;  // the FITS id column holds integers (else doubles, checked integral: table_ids)
  std::unique_ptr<FitsFile> table_;
  std::ifstream text_;
  long long text_line_ = 0;
  std::vector<double> cutout_;
};

}  // namespace stampede::io
