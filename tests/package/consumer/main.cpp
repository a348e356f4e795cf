// Draws four noise-free GREAT08-like galaxies with the installed engine and fits them through the
// application layer; exits 0 when every fit recovers its observed ellipticity to 1e-4.
#include <cmath>
#include <cstdio>
#include <vector>

#include "app/array_fit.hpp"
#include "app/version.hpp"
#include "engine/model/parameters.hpp"
#include "engine/sim/great08_sim.hpp"

int main() {
  stampede::Great08SimOptions o;
  o.grid = 2;
  o.noise_free = true;
  const stampede::SimSet set = stampede::Great08Simulator(o).simulate_set(0);
  std::vector<double> stamps;
  for (int k = 0; k < 4; ++k)
    for (int y = 0; y < o.stamp_size; ++y)
      for (int x = 0; x < o.stamp_size; ++x)
        stamps.push_back(set.image[((k / 2) * o.stamp_size + y) * set.width + (k % 2) * o.stamp_size + x]);
  stampede::app::RunConfig cfg;
  stampede::app::set_option(cfg, "renderer", "exact");
  stampede::app::set_option(cfg, "psf_e2", "0.05");
  stampede::app::ArrayStamps in;
  in.count = 4;
  in.stamp_size = o.stamp_size;
  in.pixels = stamps;
  const auto rows = stampede::app::fit_array_stamps(cfg, in, 1);
  int bad = 0;
  for (int k = 0; k < 4; ++k) {
    const double d = std::hypot(rows[k].fit.params[int(stampede::Param::kE1)] - set.truth[k].e1_obs,
                                rows[k].fit.params[int(stampede::Param::kE2)] - set.truth[k].e2_obs);
    std::printf("stampede %s: object %d |e - e_obs| = %.2e\n", std::string(stampede::app::program_version()).c_str(), k, d);
    bad += !(d < 1e-4);
  }
  return bad == 0 ? 0 : 1;
}
