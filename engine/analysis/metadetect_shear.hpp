// The shear a metadetection catalogue measures (Sheldon et al. 2020): from each shear type's own
// catalogue, cut on that catalogue's own quantities, so that the response includes how detection
// and selection change with shear:
//   R11 = (<e1>_1p - <e1>_1m) / (2 step),  R22 = (<e2>_2p - <e2>_2m) / (2 step),
//   g = (<e1>_noshear / R11, <e2>_noshear / R22).
// From a shear pair (the same scene under +g and -g), the reference package's estimator:
//   m = (<e1>+ - <e1>-) / 2 / ((R11+ + R11-) / 2) / g1_true - 1,
//   c = (<e2>+ + <e2>-) / 2 / ((R22+ + R22-) / 2),
// means over every cell's kept rows; errors by bootstrap over cells (a pair's two cells together).
//
// Metacal's step composes with the shear already in the image: the images of types 1p/1m hold the
// scene under g composed with (+-step, 0), (g + d) / (1 + g* d) in complex reduced shear, whose
// derivative in d is 1 - |g|^2. R measures the response to d, so the response to the sky's shear
// is R / (1 - |g|^2): the package's estimator over-reads |g| by |g|^2 (m = +3.8e-4 at g = 0.02 on
// its noise-free grid). MetadetectEstimator::kComposed divides it out (g = <e> (1 - |g|^2) / R,
// solved by iteration); kPackage is the reference package's (docs/metadetect.md, "The grid's bias").
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace stampede {

struct MetadetectCuts {
  double min_snr = 10;
  double min_t_ratio = 1.2;
  // Rows whose masked share (mfrac) is above this are cut, each catalogue by its own mfrac: the
  // selection's response is then inside R. DES Y6's.
  double max_mfrac = 0.1;
  std::uint32_t excluded_flags = 0xffffffffu;  // any flag excludes a row
};

// One catalogue's kept rows summed per cell: sums[cell][type] of (n, e1, e2).
struct MetadetectCellSums {
  struct Sums {
    double n = 0, e1 = 0, e2 = 0;
  };
  std::vector<long long> cells;           // cell numbers, ascending
  std::vector<std::array<Sums, 5>> sums;  // per cell, per shear type (MetacalType order)
};

// rows: any order; cells with no kept row still count (a cell is a unit of the bootstrap).
MetadetectCellSums sum_metadetect_cells(const std::vector<long long>& cell, const std::vector<int>& shear_type,
                                        const std::vector<double>& e1, const std::vector<double>& e2,
                                        const std::vector<long long>& flags, const std::vector<double>& snr,
                                        const std::vector<double>& t_ratio, const std::vector<double>& mfrac,
                                        const MetadetectCuts& cuts);

// Adds `more`'s sums to `into`'s cells of the same numbers (the rotated scene of each cell joins its
// cell: one bootstrap unit). Throws std::invalid_argument when the cells differ.
void add_cell_sums(const MetadetectCellSums& more, MetadetectCellSums* into);

enum class MetadetectEstimator { kComposed, kPackage };
// "composed", "package".
const char* metadetect_estimator_name(MetadetectEstimator e);
// Case-insensitive inverse of metadetect_estimator_name; false for anything else.
bool parse_metadetect_estimator(const std::string& name, MetadetectEstimator* out);

struct MetadetectShear {
  double r11 = 0, r22 = 0, g1 = 0, g2 = 0;
  double r11_err = 0, r22_err = 0, g1_err = 0, g2_err = 0;
  long long cells = 0;
  double kept_noshear = 0;  // rows kept in the noshear catalogue
};

MetadetectShear metadetect_shear(const MetadetectCellSums& s, double step, int resamples = 200,
                                 std::uint64_t seed = 1, MetadetectEstimator estimator = MetadetectEstimator::kComposed);

struct MetadetectBias {
  double m1 = 0, m1_err = 0, c2 = 0, c2_err = 0;  // shear along g1 (the reference test's), c from e2
  double m2 = 0, m2_err = 0, c1 = 0, c1_err = 0;  // the same for a shear along g2 (NaN when g2 = 0)
  long long pairs = 0;
};

// plus and minus: the same cells (by number) under +g and -g. Throws std::invalid_argument when
// their cells differ or g is zero.
MetadetectBias metadetect_pair_bias(const MetadetectCellSums& plus, const MetadetectCellSums& minus, double g1,
                                    double g2, double step, int resamples = 200, std::uint64_t seed = 1,
                                    MetadetectEstimator estimator = MetadetectEstimator::kComposed);

}  // namespace stampede
