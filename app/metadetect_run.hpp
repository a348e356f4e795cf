// A metadetection run (`stampede metadetect`): image files cut
// into cells (engine/metadetect/cell_layout), each cell measured by a CellMeasurer on the pipeline's
// parallel stage, the rows written in cell order by a MetadetectWriter. The pipeline's batch is a
// few cells; each cell yields a variable number of rows (the batch's extension carries them).
// Rows depend only on the cell (its fixnoise is keyed by its number in the run): the same for any
// thread count.
#pragma once
#include <atomic>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "app/run_harness.hpp"
#include "engine/metadetect/metadetect_options.hpp"
#include "engine/metadetect/metadetect_row.hpp"
#include "io/cell_image_reader.hpp"

namespace stampede::app {

struct MetadetectRunOptions {
  // Image files (io/cell_image_reader), or with `tile` a cell tile per band. With several bands an
  // image path is a template: each `{band}` in it stands for the band's name (scene_{band}.fits:
  // scene_g.fits, scene_r.fits), the bands' images of one scene the same size and pixel scale.
  std::vector<std::string> inputs;
  // inputs[0] is a cell tile (MEDS, DES Y6's "pizza slices"): each object_data row a cell, cutout 0
  // its coadd with weight (and bmask) cutouts and its PSF cutout; x, y are the tile's pixels
  // (orig_start_row/col + the cell's); --cell-size is the tile's box size.
  bool tile = false;
  // With several tiles (`--meds g.fits --meds r.fits --bands g,r`): a tile per band, in this order
  // (empty: b0, b1, ...); the table gains flux_<band> and snr_<band>. One tile with a name: its
  // band's columns. Image files: the names the inputs' `{band}` stands for (empty: one band, no
  // `{band}`; one name: its columns, `{band}` optional).
  std::vector<std::string> bands;
  // Band roles, by the names of `bands` (empty: every band): the bands detection sums, and those
  // whose moments give the shapes; every band's flux and S/N are measured (DES Y6: detect and
  // measure shapes on r, i, z). Recorded as header keys DETBANDS, SHRBANDS when given.
  std::vector<std::string> detect_bands, shear_bands;
  // Bright stars to mask (io/star_catalogue: x, y FITS pixels of every input, radius px), each
  // disc widened by star_margin px: its pixels masked and filled, no detection kept inside.
  // Recorded as STARCAT, its digest STARCATD, and STARMARG.
  std::string star_mask;
  double star_margin = 0;
  // Or each image file's own star table, its HDU of this name (`sim cells --stars` writes STARS);
  // recorded as STARHDU.
  std::string star_hdu;
  // Image files only: a PSFEx model (a `{band}` template with several bands) of every input image;
  // each cell's PSF is the model at the cell's centre (engine/metadetect/cell_layout's
  // cell_psfex_position), and the files' PSF HDUs are neither needed nor read. Empty: the PSF HDUs.
  std::string psfex;
  std::string output;
  // Also, once the table is complete, its rows in the reference metadetect package's layout
  // (io/metadetect_package_layout: an HDU per shear type, the package's column names). Not with
  // a shard (write it from the merged table's run).
  std::string package_output;
  MetadetectOptions metadetect;
  int threads = 0;     // 0: all cores
  int cells_per_batch = 2;
  // Job-array shard `shard` of `shards` (`--shard i/N`): the contiguous cells [T i / N, T (i + 1) /
  // N) of the run's T, numbered as in the whole run (their rows are the whole run's); header key
  // SHARD "i/N". app/shard_merge joins the shards' tables.
  int shard = 0, shards = 1;
  bool resume = false;
  bool overwrite = false;
  const std::atomic<bool>* stop = nullptr;
  std::function<void(const std::string&)> on_warning;  // e.g. a resume that found nothing committed
  std::function<void(const RunProgress&)> on_progress;  // at most every progress_interval seconds
  double progress_interval = 0.5;
};

struct MetadetectRunSummary {
  long long cells = 0, cells_failed = 0, rows = 0;
  long long cells_resumed = 0;  // committed by an earlier run
  bool skipped = false;  // resume found the output complete, this run's table (its RUNFP)
  int threads = 0;
  double seconds = 0;
  bool stopped = false;
  std::vector<std::string> problems;  // "FILE cell K: why" for each failed cell (first 100)
};

// An image in memory per band (Python's numpy arrays; options' detect_bands and shear_bands bits
// name them) cut into cells and measured on `threads` threads (0: all cores) through the same
// pipeline; the rows in cell order, as a file run writes them (cells numbered from 0). Throws
// io::ConfigError for bad options, bands of different sizes or an image smaller than a cell.
std::vector<MetadetectRow> metadetect_image(std::span<const io::CellImage> bands, const MetadetectOptions& options,
                                            int threads,
                                            long long* cells_failed = nullptr);

// The checks run_metadetect makes of its output before any work, for any front end; `parts`: the
// tables a job writes before joining them into the output (stampede-mpi's ranks' parts). None of
// them, nor the files written beside them, is an input or --psfex, and an existing output is
// replaced only with overwrite (or continued with resume). Throws io::ConfigError or io::FileError
// naming the files.
void check_metadetect_outputs(const MetadetectRunOptions& options, const std::vector<std::string>& parts = {});

// Throws stampede::Error subclasses (io::FitsError, io::CatalogError, ConfigError) naming the file,
// HDU, key or option.
MetadetectRunSummary run_metadetect(const MetadetectRunOptions& options);

// options.output's complete table rewritten in the reference package's layout to
// options.package_output (what run_metadetect does at its end; stampede-mpi after its merge).
void write_metadetect_package_output(const MetadetectRunOptions& options);

}  // namespace stampede::app
