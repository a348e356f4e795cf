// Metrics of metadetection catalogues; see metadetect_metrics.hpp.
#include "app/metadetect_metrics.hpp"

#include <filesystem>
#include <stdexcept>

#include "io/fits_file.hpp"
#include "io/metadetect_reader.hpp"

namespace stampede::app {

MetadetectMetrics metadetect_metrics(const MetadetectMetricsOptions& o) {
  if (o.table.empty()) throw std::invalid_argument("no metadetect table given");
  if (o.rotated.empty() != o.rotated_minus.empty() && !o.minus.empty())
    throw std::invalid_argument("--rotated and --rotated-minus go together with --minus");
  const io::MetadetectTable plus = io::read_metadetect_table(o.table);
  auto sums = [&](const io::MetadetectTable& t) {
    return sum_metadetect_cells(t.cell, t.shear_type, t.e1, t.e2, t.flags, t.snr, t.t_ratio, o.cuts);
  };
  auto add = [&](const std::string& path, MetadetectCellSums* into) {
    const io::MetadetectTable t = io::read_metadetect_table(path);
    if (t.step != plus.step) throw std::invalid_argument(path + " was run with another metacal step than " + o.table);
    add_cell_sums(sums(t), into);
  };
  MetadetectCellSums ps = sums(plus);
  if (!o.rotated.empty()) add(o.rotated, &ps);
  MetadetectMetrics out;
  out.shear = metadetect_shear(ps, plus.step, o.resamples, o.seed, o.estimator);
  if (o.minus.empty()) return out;
  const io::MetadetectTable minus = io::read_metadetect_table(o.minus);
  if (minus.step != plus.step) throw std::invalid_argument(o.minus + " was run with another metacal step than " + o.table);
  MetadetectCellSums ms = sums(minus);
  if (!o.rotated_minus.empty()) add(o.rotated_minus, &ms);
  if (o.shear) {
    out.true_shear = *o.shear;
  } else {
    if (plus.first_input.empty()) throw std::invalid_argument("the true shear is needed: " + o.table + " records no input");
    // The input's path as the run was given it: relative to where it ran, which may be the table's
    // directory.
    namespace fs = std::filesystem;
    std::string input = plus.first_input;
    if (!fs::exists(input) && fs::path(input).is_relative()) {
      const fs::path beside = fs::path(o.table).parent_path() / input;
      if (fs::exists(beside)) input = beside.string();
    }
    if (!fs::exists(input))
      throw std::invalid_argument("the true shear: " + o.table + "'s first input '" + plus.first_input +
                                  "' is not found here: give it (--shear G1,G2)");
    io::FitsFile in = io::FitsFile::open_read(input);
    out.true_shear = {in.key_double("G1"), in.key_double("G2")};
  }
  out.has_bias = true;
  out.bias = metadetect_pair_bias(ps, ms, out.true_shear[0], out.true_shear[1], plus.step, o.resamples, o.seed,
                                  o.estimator);
  return out;
}

}  // namespace stampede::app
