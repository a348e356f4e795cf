// The metadetect run's inputs; see metadetect_input.hpp.
#include "app/metadetect_input.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <string_view>

#include "app/metadetect_option_keys.hpp"
#include "app/version.hpp"
#include "io/cell_image_reader.hpp"
#include "io/config_error.hpp"
#include "io/file_digest.hpp"
#include "io/option_text.hpp"
#include "io/output_check.hpp"
#include "io/result_columns.hpp"
#include "io/star_catalogue.hpp"

namespace stampede::app {
namespace {

// What stands for the band's name in an image path or --psfex.
constexpr std::string_view kBandField = "{band}";

bool has_band_field(const std::string& path) { return path.find(kBandField) != std::string::npos; }


// What every image records alike of its scene (SHEAR1, SHEAR2, SCNSEED, SCNROT), by which metrics
// checks a shear pair (app/metadetect_metrics); a key some image lacks or records otherwise is left
// out. Derived from the inputs, whose digests the fingerprint holds.
void record_scene(const std::vector<std::string>& files, io::MetadetectWriterOptions* table) {
  if (files.empty()) return;
  io::SceneRecord common = io::read_scene_record(files[0]);
  for (std::size_t k = 1; k < files.size(); ++k) {
    const io::SceneRecord r = io::read_scene_record(files[k]);
    if (!(r.g1 == common.g1 && r.g2 == common.g2)) common.g1 = common.g2 = NAN;
    if (r.seed != common.seed) common.seed.clear();
    if (r.rotated != common.rotated) common.rotated.clear();
  }
  if (std::isfinite(common.g1) && std::isfinite(common.g2)) {
    table->header.emplace_back("SHEAR1", io::format_double(common.g1));
    table->header.emplace_back("SHEAR2", io::format_double(common.g2));
    table->header_types["SHEAR1"] = table->header_types["SHEAR2"] = io::HeaderValueType::kReal;
  }
  for (const auto& [key, value] : {std::pair{"SCNSEED", &common.seed}, std::pair{"SCNROT", &common.rotated}})
    if (!value->empty()) {
      table->header.emplace_back(key, *value);
      table->header_types[key] = io::HeaderValueType::kInteger;
    }
}

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

io::CellSource open_cell_source(const MetadetectRunOptions& options, const MetadetectOptions& measure,
                                const MetadetectFiles& read) {
  io::CellSource source = options.tile ? io::CellSource(io::CellSource::Tile{options.inputs}, measure)
                                       : io::CellSource(read.images, measure);
  if (!(options.star_margin >= 0 && options.star_margin <= 1000))
    throw io::ConfigError("--star-margin " + io::format_double(options.star_margin) + ": must be in [0, 1000] pixels");
  if (!options.star_mask.empty() && !options.star_hdu.empty())
    throw io::ConfigError("--star-mask and --star-mask-hdu exclude each other: one catalogue for every input, or each "
                          "image's own");
  if (!options.star_hdu.empty() && options.tile)
    throw io::ConfigError("--star-mask-hdu reads each image file's own star table: a --meds cell tile has none");
  if (!options.star_mask.empty()) source.set_stars(io::read_star_table(options.star_mask, options.star_margin));
  if (!options.star_hdu.empty()) source.set_star_hdu(options.star_hdu, options.star_margin);
  return source;
}

io::MetadetectWriterOptions metadetect_table_options(const MetadetectRunOptions& options,
                                                     const std::vector<std::string>& bands,
                                                     const MetadetectOptions& measure, const MetadetectFiles& read,
                                                     long long cells) {
  io::MetadetectWriterOptions writer_options;
  writer_options.path = options.output;
  writer_options.bands = bands;
  writer_options.header_types = metadetect_header_types();
  writer_options.header_types["NCELLS"] = io::HeaderValueType::kInteger;
  std::string& fingerprint = writer_options.fingerprint;
  fingerprint = "stampede " + std::string(program_version()) + " metadetect\n";
  const auto record = [&](const std::string& key, const std::string& value, const std::string& line) {
    writer_options.header.emplace_back(key, value);
    fingerprint += line + "\n";
  };
  record("INPUTS", options.tile ? "cell tile" : "images", options.tile ? "cell tile" : "images");
  if (!bands.empty()) record("BANDS", io::comma_list(bands), "bands " + io::comma_list(bands));
  for (const auto& [key, role] : {std::pair{"DETBANDS", &options.detect_bands}, std::pair{"SHRBANDS", &options.shear_bands}})
    if (!role->empty()) record(key, io::comma_list(*role), std::string(key) + " " + io::comma_list(*role));
  for (const auto& [key, value] : metadetect_header_keys(measure)) record(key, value, key + "=" + value);
  const auto record_files = [&](const std::vector<std::string>& files, const char* path_key, const char* digest_key,
                                const char* role, bool each_once) {
    std::map<std::string, std::string> seen;  // digest -> the file that has it
    for (std::size_t i = 0; i < files.size(); ++i) {
      const std::string d = io::digest_file(files[i]).text(), n = std::to_string(i + 1);
      // The same image twice (a repeated list line, a link, another spelling, a copy) would be
      // measured twice, with other fixnoise, as if its cells were independent.
      if (const auto [at, added] = seen.emplace(d, files[i]); each_once && !added)
        throw io::ConfigError(std::string(role) + " '" + files[i] + "' holds the same bytes as '" + at->second + "' (" +
                              d + "): each image once");
      writer_options.header.emplace_back(path_key + n, files[i]);
      record(digest_key + n, d, role + (" " + files[i]) + " " + d);
    }
  };
  record_files(read.files, "INPUT", "DIGEST", "input", true);
  record_files(read.images.psfex, "PSFEX", "PSFEXD", "psfex", false);  // bands may share a model
  if (!options.star_hdu.empty()) record("STARHDU", options.star_hdu, "star tables " + options.star_hdu);
  if (!options.star_mask.empty()) {
    const std::string d = io::digest_file(options.star_mask).text();
    writer_options.header.emplace_back("STARCAT", options.star_mask);
    record("STARCATD", d, "star mask " + options.star_mask + " " + d);
  }
  if (!options.star_hdu.empty() || !options.star_mask.empty()) {
    record("STARMARG", io::format_double(options.star_margin), "star margin " + io::format_double(options.star_margin));
    writer_options.header_types["STARMARG"] = io::HeaderValueType::kReal;
  }
  if (!options.tile) record_scene(read.files, &writer_options);
  writer_options.header.emplace_back("NCELLS", std::to_string(cells));
  return writer_options;
}

}  // namespace stampede::app
