// The catalogue of `stampede metadetect`: a FITS binary table (EXTNAME 'METADETECT'), a row per
// (cell, shear type, detection) and one flagged row per cell that could not be measured, written
// cell batch by cell batch so that a killed run resumes without remeasuring committed cells.
//
// The commit protocol is the durable table's (io/durable_table.hpp), whose units here are cells (a
// cell yields any number of rows, so the run resumes at the next cell, not row); finish() records
// the cells in header key NCELLSW (its room reserved at creation) and renames the partial to PATH.
// resume() refuses a checkpoint of another run (the fingerprint: inputs' digests, options, version).
//
// Columns (TUNITn, TCOMMn in the header): cell shear_type id x y u v e1 e2 e1_err e2_err T T_ratio
// psf_T flux snr mfrac box_size isophotal_area sep_flags flags [flux_<band>... snr_<band>...]. Not thread-safe: the pipeline's
// serial output stage drives it.
#pragma once
#include <map>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "engine/metadetect/metadetect_row.hpp"
#include "io/catalog_error.hpp"
#include "io/header_value.hpp"

namespace stampede::io {

struct MetadetectWriterOptions {
  std::string path;
  std::vector<std::pair<std::string, std::string>> header;  // string keys, as CatalogWriterOptions::header
  std::map<std::string, HeaderValueType> header_types;
  std::string fingerprint;
  // Band names (several bands, or one named): columns flux_<band> and snr_<band> after the
  // others, from each row's band_flux and band_snr.
  std::vector<std::string> bands;
};

// The column names in order (readers and tests).
std::vector<std::string> metadetect_columns(const std::vector<std::string>& bands = {});

class MetadetectWriter {
 public:
  // Throws CatalogError naming the path.
  static std::unique_ptr<MetadetectWriter> create(const MetadetectWriterOptions& options);
  // *cells_committed: the cells whose rows are all on disk; the run continues at that cell.
  // *started (if not null): nothing was committed, the table was started anew.
  static std::unique_ptr<MetadetectWriter> resume(const MetadetectWriterOptions& options, long long* cells_committed,
                                                  bool* started = nullptr);
  ~MetadetectWriter();
  MetadetectWriter(const MetadetectWriter&) = delete;
  MetadetectWriter& operator=(const MetadetectWriter&) = delete;
  // Appends the rows of the next `cells` cells and commits them.
  void append(std::span<const MetadetectRow> rows, long long cells);
  void finish();
  // A failed run: removes the partial and checkpoint unless a write failed after commits (kept
  // for --resume). Never throws.
  void abandon() noexcept;
  long long rows() const;
  long long cells() const;

 private:
  struct State;
  explicit MetadetectWriter(std::unique_ptr<State> s);
  std::unique_ptr<State> s_;
};

}  // namespace stampede::io
