// The inputs of a metadetect run (app/metadetect_run): its bands, checked, every file it reads
// (image paths expanded per band, PSFEx models), as the cell source and the output checks take them,
// the cell source itself, and the table's identity (what it records of them).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "app/metadetect_run.hpp"
#include "io/cell_source.hpp"
#include "io/metadetect_writer.hpp"

namespace stampede::app {

// The run's band names (empty: one band, no band columns), checked: one per tile, distinct
// whatever their case, column-name characters, at most kMaxMetadetectBands; image paths (and
// --psfex) that are templates exactly when several bands are named, no file a band of itself;
// throws io::ConfigError naming the option.
std::vector<std::string> metadetect_bands(const MetadetectRunOptions& options);

// The band mask (bit b: bands[b]) of the names `role` gives for `flag` (--detect-bands,
// --shear-bands); 0 for none (every band). Throws io::ConfigError naming the flag and a name that
// is not one of `bands`, a name given twice, or roles without several bands.
std::uint32_t band_role_mask(const std::vector<std::string>& role, const std::vector<std::string>& bands,
                             const std::string& flag);

// `path` with each `{band}` replaced by `band`.
std::string expand_band(const std::string& path, const std::string& band);

// Every file a run reads: the inputs (each image path expanded per band, scene by scene), then the
// PSFEx models (one per band).
struct MetadetectFiles {
  io::CellSource::Images images;  // image files: as the cell source takes them
  std::vector<std::string> files;  // the inputs, band by band within a scene
};
MetadetectFiles metadetect_files(const MetadetectRunOptions& options, const std::vector<std::string>& bands);

// The run's cell source over what it reads (image files or cell tiles), with its bright stars (one
// catalogue for every input, or each image's own table). Throws io::ConfigError naming the star
// options that do not go together or are out of range.
io::CellSource open_cell_source(const MetadetectRunOptions& options, const MetadetectOptions& measure,
                                const MetadetectFiles& read);

// The table's schema and identity: its band columns, and the header keys and fingerprint lines of
// what the run reads and how — the inputs and their digests (each image once), the options and band
// roles, the PSFEx models, the star catalogue, what every image records of its scene, the run's
// `cells`. Throws io::ConfigError for an image given twice (the same bytes).
io::MetadetectWriterOptions metadetect_table_options(const MetadetectRunOptions& options,
                                                     const std::vector<std::string>& bands,
                                                     const MetadetectOptions& measure, const MetadetectFiles& read,
                                                     long long cells);

}  // namespace stampede::app
