// The metadetect run's serial reader (io/cell_source): an image cut into the layout's cells, each
// cell's pixels and weights the image's at its place, its PSF the image's; skip_to and set_end (a
// resume, a shard) give exactly the whole run's cells in that range; bands of a scene that do not
// share its pixels are refused naming both files.
#include "io/cell_source.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "engine/metadetect/cell_layout.hpp"
#include "engine/sim/cell_sim.hpp"
#include "io/cell_image_writer.hpp"
#include "io/config_error.hpp"
#include "support/scratch_dir.hpp"

namespace stampede::io {
namespace {

CellImage numbered_image(long width, long height) {
  CellImage im;
  im.width = width, im.height = height, im.pixel_scale = 0.2;
  for (long i = 0; i < width * height; ++i) {
    im.pixels.push_back(static_cast<double>(i));
    im.weight.push_back(1.0 + static_cast<double>(i % 7));
  }
  auto psf = std::make_shared<PsfImage>();
  psf->nx = psf->ny = 3;
  psf->pixels = {0, 1, 0, 1, 4, 1, 0, 1, 0};
  im.psf = psf;
  return im;
}

struct ReadCell {
  long long id;
  CellPlacement place;
  std::vector<double> pixels, weights;
};

std::vector<ReadCell> read_all(CellSource& source) {
  std::vector<ReadCell> out;
  StampBatch batch(2);
  while (source.fill(batch)) {
    const CellBatch& data = batch.payload<CellBatch>();
    EXPECT_EQ(static_cast<int>(data.cells.size()), batch.count);
    for (int k = 0; k < batch.count; ++k) {
      const CellBatch::Cell& c = data.cells[static_cast<std::size_t>(k)];
      const ArenaObservation& o = batch.observations[c.first_observation];
      EXPECT_EQ(c.bands, 1);
      EXPECT_EQ(c.pixel_scale, 0.2);
      EXPECT_TRUE(o.psf.image != nullptr);
      const auto p = batch.observations.pixels(o), w = batch.observations.weights(o);
      out.push_back({batch.records[k].id, c.place, {p.begin(), p.end()}, {w.begin(), w.end()}});
    }
  }
  return out;
}

TEST(CellSource, CutsAnImageIntoTheLayoutsCellsAndReadsARangeAsTheWholeRunDoes) {
  MetadetectOptions options;
  options.cell_size = 40, options.cell_buffer = 8;
  const CellImage image = numbered_image(100, 70);
  std::string why;
  const std::vector<CellPlacement> layout = cell_layout(100, 70, 40, 8, &why);
  ASSERT_GT(layout.size(), 3u) << why;
  CellSource whole({&image, 1}, options);
  EXPECT_EQ(whole.total_objects(), static_cast<long long>(layout.size()));
  EXPECT_EQ(whole.max_cell_pixels(), 40 * 40);
  const std::vector<ReadCell> cells = read_all(whole);
  ASSERT_EQ(cells.size(), layout.size());
  for (std::size_t k = 0; k < cells.size(); ++k) {
    const ReadCell& c = cells[k];
    EXPECT_EQ(c.id, static_cast<long long>(k));
    EXPECT_EQ(c.place.x0, layout[k].x0);
    EXPECT_EQ(c.place.y0, layout[k].y0);
    ASSERT_EQ(c.pixels.size(), 40u * 40u);
    for (int y = 0; y < 40; y += 13)
      for (int x = 0; x < 40; x += 11) {
        const long i = (c.place.y0 + y) * 100L + c.place.x0 + x;
        EXPECT_EQ(c.pixels[static_cast<std::size_t>(y * 40 + x)], image.pixels[static_cast<std::size_t>(i)]);
        EXPECT_EQ(c.weights[static_cast<std::size_t>(y * 40 + x)], image.weight[static_cast<std::size_t>(i)]);
      }
  }
  CellSource part({&image, 1}, options);  // cells [1, 3): a resume at 1 of a shard ending at 3
  part.skip_to(1);
  part.set_end(3);
  const std::vector<ReadCell> range = read_all(part);
  ASSERT_EQ(range.size(), 2u);
  for (std::size_t k = 0; k < range.size(); ++k) {
    EXPECT_EQ(range[k].id, cells[k + 1].id);
    EXPECT_EQ(range[k].pixels, cells[k + 1].pixels);
  }
}

TEST(CellSource, BandsThatDoNotShareTheScenesPixelsAreRefusedNamingBoth) {
  testing::ScratchDir dir("stampede_cell_source_");
  auto write = [&](const std::string& name, int size) {
    CellSimOptions o;
    o.size = size, o.buffer = 10, o.grid = 2, o.psf_size = 25, o.seed = 3;
    const CellSimulator sim(o);
    auto ws = sim.make_workspace();
    write_cell_image(dir.path(name), sim, sim.simulate(0, 0.0, 0.0, *ws), 0, "r", false);
    return dir.path(name);
  };
  const std::string g = write("g.fits", 64), r = write("r.fits", 72);
  MetadetectOptions options;
  options.cell_size = 60, options.cell_buffer = 10;
  try {
    CellSource source(CellSource::Images{{"scene_{band}.fits"}, {{g, r}}, {}}, options);
    ADD_FAILURE() << "bands of two sizes were accepted";
  } catch (const ConfigError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(r + " is 72 x 72 pixels, " + g + " 64 x 64"), std::string::npos) << m;
  }
}

}  // namespace
}  // namespace stampede::io
