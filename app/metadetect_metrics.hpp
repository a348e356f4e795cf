// The response, shear and shear-pair biases of metadetection catalogues (`stampede metrics
// --metadetect`, Python `stampede.metadetect_metrics`): the tables read, cut and summed per cell
// (engine/analysis/metadetect_shear), the true shear from the first input's G1, G2 keys unless
// given.
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
  MetadetectCuts cuts;
  MetadetectEstimator estimator = MetadetectEstimator::kComposed;
  int resamples = 200;
  std::uint64_t seed = 1;
};

struct MetadetectMetrics {
  MetadetectShear shear;               // of `table` (with `rotated` joined)
  bool has_bias = false;               // a pair was given
  std::array<double, 2> true_shear{};  // the pair's
  MetadetectBias bias;
};

// Throws std::invalid_argument (options that do not go together, another metacal step) and
// io::FitsError (a table or input that cannot be read).
MetadetectMetrics metadetect_metrics(const MetadetectMetricsOptions& options);

}  // namespace stampede::app
