// The metadetect run's inputs; see metadetect_input.hpp.
#include "app/metadetect_input.hpp"

#include <algorithm>
#include <string_view>

#include "io/config_error.hpp"
#include "io/option_text.hpp"
#include "io/output_check.hpp"
#include "io/result_columns.hpp"

namespace stampede::app {
namespace {

// What stands for the band's name in an image path or --psfex.
constexpr std::string_view kBandField = "{band}";

bool has_band_field(const std::string& path) { return path.find(kBandField) != std::string::npos; }

}  // namespace

std::string expand_band(const std::string& path, const std::string& band) {
  std::string out = path;
  for (std::size_t at = out.find(kBandField); at != std::string::npos; at = out.find(kBandField, at + band.size()))
    out.replace(at, kBandField.size(), band);
  return out;
}

namespace {

// Image files' bands: --bands names what `{band}` stands for in every path.
std::vector<std::string> image_bands(const MetadetectRunOptions& options) {
  std::vector<std::pair<std::string, std::string>> templates;  // (what, path)
  for (const std::string& in : options.inputs) templates.emplace_back("image path", in);
  if (!options.psfex.empty()) templates.emplace_back("--psfex", options.psfex);
  const std::vector<std::string>& names = options.bands;
  const std::size_t n = names.size();
  if (n == 0) {
    for (const auto& [what, path] : templates)
      if (has_band_field(path))
        throw io::ConfigError(what + " '" + path + "' holds '{band}' but no --bands names the bands it stands for");
    return {};
  }
  if (n > static_cast<std::size_t>(kMaxMetadetectBands))
    throw io::ConfigError("--bands names " + std::to_string(n) + " bands: at most " + std::to_string(kMaxMetadetectBands));
  if (std::string why; !io::are_band_names(names, &why)) throw io::ConfigError("--bands: " + why);
  if (n > 1) {
    for (const auto& [what, path] : templates)
      if (!has_band_field(path))
        throw io::ConfigError("--bands names " + std::to_string(n) + " bands but " + what + " '" + path +
                              "' holds no '{band}': each is a template, read once per band with {band} its name");
    for (const std::string& in : options.inputs)
      for (std::size_t b = 0; b < n; ++b)
        for (std::size_t a = 0; a < b; ++a)
          if (io::same_file(expand_band(in, names[a]), expand_band(in, names[b])))
            throw io::ConfigError("image " + expand_band(in, names[b]) + " is bands " + names[a] + " and " + names[b] +
                                  " of '" + in + "'");
  }
  return names;
}

// What measures one band only, whichever input carries the bands; `give` says how to give one.
void refuse_bands_for_one_band_measurements(const MetadetectOptions& o, std::size_t bands, const std::string& give) {
  if (bands < 2) return;
  if (o.per_object_metacal) throw io::ConfigError("--per-object-metacal measures one band: " + give);
  if (is_model_fit(o.measurement))
    throw io::ConfigError(std::string("--measurement ") + metadetect_measurement_name(o.measurement) +
                          " fits one band: " + give + ", or measure the bands with wmom or pgauss");
}

}  // namespace

std::vector<std::string> metadetect_bands(const MetadetectRunOptions& options) {
  if (!options.tile) {
    std::vector<std::string> names = image_bands(options);
    refuse_bands_for_one_band_measurements(options.metadetect, names.size(), "give --bands one band");
    return names;
  }
  if (!options.psfex.empty())
    throw io::ConfigError("--psfex gives image files' PSF: a --meds cell tile has its own PSF cutouts");
  const std::size_t n = options.inputs.size();
  if (n > static_cast<std::size_t>(kMaxMetadetectBands))
    throw io::ConfigError(std::to_string(n) + " --meds tiles: at most " + std::to_string(kMaxMetadetectBands) + " bands");
  if (!options.bands.empty() && options.bands.size() != n)
    throw io::ConfigError("--bands names " + std::to_string(options.bands.size()) + " band" +
                          (options.bands.size() == 1 ? "" : "s") + " but " + std::to_string(n) + " --meds tile" +
                          (n == 1 ? " is" : "s are") + " given: one tile per band, in the order of --bands");
  if (options.bands.empty() && n == 1) return {};
  std::vector<std::string> names = options.bands;
  if (names.empty())
    for (std::size_t b = 0; b < n; ++b) {
      // Appended, not "b" + to_string(b): GCC 12 warns (-Wrestrict) falsely on that concatenation.
      std::string name = "b";
      name += std::to_string(b);
      names.push_back(std::move(name));
    }
  if (std::string why; !io::are_band_names(names, &why)) throw io::ConfigError("--bands: " + why);
  for (std::size_t b = 0; b < n; ++b)
    for (std::size_t a = 0; a < b; ++a)
      if (io::same_file(options.inputs[a], options.inputs[b]))
        throw io::ConfigError("--meds " + options.inputs[b] + " is given twice (bands " + names[a] + " and " + names[b] + ")");
  refuse_bands_for_one_band_measurements(options.metadetect, n, "give one --meds tile");
  return names;
}

std::uint32_t band_role_mask(const std::vector<std::string>& role, const std::vector<std::string>& bands,
                             const std::string& flag) {
  if (role.empty()) return 0;
  if (bands.size() < 2)
    throw io::ConfigError(flag + " gives bands a role: it needs several bands (--bands, or a --meds tile per band)");
  std::uint32_t mask = 0;
  for (const std::string& name : role) {
    const auto at = std::find(bands.begin(), bands.end(), name);
    if (at == bands.end()) {
      throw io::ConfigError(flag + ": '" + name + "' is not one of the run's bands (" + io::comma_list(bands) + ")");
    }
    const std::uint32_t bit = 1u << (at - bands.begin());
    if (mask & bit) throw io::ConfigError(flag + ": band '" + name + "' is given twice");
    mask |= bit;
  }
  return mask;
}

MetadetectFiles metadetect_files(const MetadetectRunOptions& options, const std::vector<std::string>& bands) {
  MetadetectFiles out;
  if (options.tile) {
    out.files = options.inputs;
    return out;
  }
  const std::vector<std::string> names = bands.empty() ? std::vector<std::string>{""} : bands;
  for (const std::string& in : options.inputs) {
    out.images.names.push_back(in);
    out.images.files.emplace_back();
    for (const std::string& b : names) out.images.files.back().push_back(expand_band(in, b));
    out.files.insert(out.files.end(), out.images.files.back().begin(), out.images.files.back().end());
  }
  if (!options.psfex.empty())
    for (const std::string& b : names) out.images.psfex.push_back(expand_band(options.psfex, b));
  return out;
}

}  // namespace stampede::app
