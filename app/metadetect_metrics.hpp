// The response, shear and shear-pair biases of metadetection catalogues (`stampede metrics
// --metadetect`, Python `stampede.metadetect_metrics`, the report): the tables read, cut and summed
// per cell (engine/analysis/metadetect_shear). A pair is checked by what its tables record, not by
// their names: the same options, other input files, and where the inputs record their scene
// (SHEAR1, SHEAR2, SCNSEED, SCNROT) opposite shears of one scene, turned where a table is given as
// turned. The true shear is the one the inputs record (or, for an older table, its first input's
// G1, G2 keys while that file is unchanged) unless given. No kept row is an error, not NaN.
#pragma once
#include <array>
#include <optional>
#include <string>

#include "engine/analysis/metadetect_shear.hpp"

namespace stampede::app {

struct MetadetectMetricsOptions {
  std::string table;                        // +g (or the only) catalogue
  std::string minus;                        // its shear pair, "" none
  std::string rotated, rotated_minus;       // the same cells' scenes turned by 90 degrees, "" none
  std::optional<std::array<double, 2>> shear;  // the true shear of `table`
  // The cuts; unset: the measurement's defaults (default_metadetect_cuts).
  std::optional<double> cut_snr, cut_t_ratio, cut_mfrac;
  MetadetectEstimator estimator = MetadetectEstimator::kComposed;
  int resamples = 200;
  std::uint64_t seed = 1;
};

struct MetadetectMetrics {
  MetadetectCuts cuts;                 // as applied
  MetadetectShear shear;               // of `table` (with `rotated` joined)
  bool has_bias = false;               // a pair was given
  std::array<double, 2> true_shear{};  // the pair's
  MetadetectBias bias;
};

// The cuts of the reference's shear test for a table of `measurement` (its MEASURE key): flags 0,
// snr > 10, T_ratio > 1.2; pgauss's T_ratio (pre-PSF T over the PSF's) > 0.5.
MetadetectCuts default_metadetect_cuts(const std::string& measurement);

// Throws std::invalid_argument (options that do not go together, tables that are not a pair, cuts
// that keep no row) and io::FitsError or io::CatalogError (a table or input that cannot be read or
// is unfinished).
MetadetectMetrics metadetect_metrics(const MetadetectMetricsOptions& options);

}  // namespace stampede::app
