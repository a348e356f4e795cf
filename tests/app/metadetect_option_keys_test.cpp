// The metadetection options' one table (app/metadetect_option_keys): fields, flags and header keys
// each named once; the header records the keys a table has always carried, in order; every
// option reads back what it records; the core's refusals, which name fields, read in
// the command line's flags once translated.
#include "app/metadetect_option_keys.hpp"

#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

namespace stampede::app {
namespace {

TEST(MetadetectOptionKeys, EachNameOnceAndTheHeaderKeysInTheirOrder) {
  std::set<std::string> fields, flags, headers;
  std::vector<std::string> order;
  for (const MetadetectOptionKey& k : metadetect_option_keys()) {
    EXPECT_TRUE(fields.insert(k.field).second) << k.field;
    if (!k.flag.empty()) {
      EXPECT_TRUE(flags.insert(k.flag).second) << k.flag;
    }
    EXPECT_TRUE(headers.insert(k.header).second) << k.header;
    EXPECT_LE(k.header.size(), 8u) << k.header;
    order.push_back(k.header);
  }
  const std::vector<std::string> recorded = {"CELLSIZE", "CELLBUF", "MCSTEP",  "MCPSFDIL", "MCRECONV", "FIXNOISE",
                                             "MASKSYM",  "MASKFILL", "MFRACFW",
                                             "IMGPREC",  "PEROBJMC", "NOISEPLN", "MCSEED",  "MEASURE",  "WFWHM",
                                             "RECENTRE", "KEEPUNL", "DETECTOR", "DETTHR",  "DETMINA",  "DBLCONT",
                                             "DBLNTHR",  "FILTFWHM", "FILTSIZE", "CLEAN",   "CLEANPAR", "STAMPSZ",
                                             "BOXRFAC",  "BOXRMIN", "BOXPAD",   "BOXMIN",  "BOXMAX"};
  EXPECT_EQ(order, recorded);
}

TEST(MetadetectOptionKeys, EveryOptionReadsBackWhatItRecords) {
  MetadetectOptions changed;
  changed.cell_size = 201, changed.cell_buffer = 40, changed.step = 0.02, changed.psf_dilation = 1.25;
  changed.reconvolution = ReconvolutionRule::kMoffat, changed.fixnoise = false, changed.double_images = true;
  changed.noise_plane = false, changed.seed = 77, changed.measurement = MetadetectMeasurement::kPgauss;
  changed.weight_fwhm = 1.7, changed.recentre = true, changed.keep_unlensed = true;
  changed.detection.detector = DetectorKind::kSep, changed.detection.threshold = 1.1, changed.detection.min_area = 6;
  changed.detection.deblend_contrast = 0.002, changed.detection.deblend_thresholds = 16;
  changed.detection.filter_fwhm = 2.5, changed.detection.filter_size = 9, changed.detection.clean = false;
  changed.stamp.size = 0, changed.stamp.box_min = 35, changed.stamp.box_max = 101;
  changed.detection.clean_param = 1.5, changed.stamp.radius_factor = 2.5, changed.stamp.radius_min = 3.0;
  changed.stamp.padding = 1.0;  // the options recorded without a flag
  std::string why;
  ASSERT_TRUE(changed.IsValid(&why)) << why;
  // The recorded text as it is (what an MPI worker reads), and a switch's words as the command line
  // and Python give them.
  MetadetectOptions read, said;
  for (const MetadetectOptionKey& k : metadetect_option_keys()) {
    const std::string text = k.recorded(changed);
    EXPECT_EQ(k.set(read, text), "") << k.field << " '" << text << "'";
    if (k.kind != MetadetectOptionKey::Kind::kSwitch) continue;
    const std::string word = text == "T" || text == "double" ? "true" : "false";
    EXPECT_EQ(k.set(said, word), "") << k.field << " '" << word << "'";
    EXPECT_EQ(k.recorded(said), text) << k.field;
  }
  EXPECT_EQ(metadetect_header_keys(read), metadetect_header_keys(changed));
  EXPECT_NE(metadetect_header_keys(read), metadetect_header_keys(MetadetectOptions()));
  EXPECT_EQ(metadetect_header_types().at("CELLSIZE"), io::HeaderValueType::kInteger);
  EXPECT_EQ(metadetect_header_types().at("WFWHM"), io::HeaderValueType::kReal);
  EXPECT_EQ(metadetect_header_types().count("MEASURE"), 0u);
}

TEST(MetadetectOptionKeys, TheCoresFieldsBecomeTheCommandLinesFlags) {
  auto refusal = [](MetadetectOptions o) {
    std::string why;
    EXPECT_FALSE(o.IsValid(&why));
    return why;
  };
  MetadetectOptions o;
  o.cell_size = 3;
  EXPECT_EQ(refusal(o).substr(0, 14), "cell_size = 3:");
  EXPECT_EQ(with_metadetect_flags(refusal(o)).substr(0, 16), "--cell-size = 3:");
  o = MetadetectOptions();
  o.stamp.box_max = 31;
  EXPECT_EQ(with_metadetect_flags(refusal(o)), "--box-max = 31: must be odd, >= --box-min (33) and <= 4095");
  o = MetadetectOptions();
  o.per_object_metacal = true, o.measurement = MetadetectMeasurement::kPgauss;
  EXPECT_EQ(with_metadetect_flags(refusal(o)), "--measurement = pgauss: --per-object-metacal measures with wmom only");
  o = MetadetectOptions();
  o.step = 0.5;  // a one-word field is translated where the message opens with it
  EXPECT_EQ(with_metadetect_flags(refusal(o)), "--step = 0.5: must be in [0.001, 0.1]");
  // Inside a message only a field standing as a word: never part of a path.
  EXPECT_EQ(with_metadetect_flags("/data/cell_size/a.fits: 40 x 40 pixels, smaller than one cell (cell_size 64)"),
            "/data/cell_size/a.fits: 40 x 40 pixels, smaller than one cell (--cell-size 64)");
  EXPECT_EQ(with_metadetect_flags("cell_buffer.fits: no step (cell_size must exceed twice cell_buffer)"),
            "cell_buffer.fits: no step (--cell-size must exceed twice --cell-buffer)");
}

}  // namespace
}  // namespace stampede::app
