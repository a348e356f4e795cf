// Counter-based random numbers that are identical on every platform and independent of thread
// count: a stream is keyed by what it is for (seed, set, object, purpose), never by who draws it.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <numbers>
#include <span>

namespace stampede {

// splitmix64 (Steele, Lea & Flood 2014): advances `state` and returns a well-mixed 64-bit value.
inline std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

class RandomStream {
 public:
  // The keys are folded in order, so (7, 0, 3) and (7, 3, 0) are unrelated streams.
  explicit RandomStream(std::initializer_list<std::uint64_t> keys) {
    for (std::uint64_t k : keys) {
      state_ ^= k;
      state_ = splitmix64(state_);
    }
  }
  std::uint64_t next() { return splitmix64(state_); }
  // Uniform on [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Standard normal by Box-Muller (one value per call: no hidden state between calls).
  double normal() {
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }
  // A field of standard normals, two at a time by Marsaglia's polar method (one log, no
  // trigonometry, per pair; a pair's uniforms outside the unit disc are drawn again): 4x faster
  // than normal() per value, which a metacal image's fixnoise field draws for every pixel. Not
  // normal()'s values.
  void normals(std::span<double> out) {
    const std::size_t n = out.size();
    std::size_t i = 0;
    while (i < n) {
      const double x = 2.0 * uniform() - 1.0, y = 2.0 * uniform() - 1.0, r2 = x * x + y * y;
      if (r2 >= 1.0 || r2 == 0.0) continue;
      const double f = std::sqrt(-2.0 * std::log(r2) / r2);
      out[i++] = x * f;
      if (i < n) out[i++] = y * f;
    }
  }

 private:
  std::uint64_t state_ = 0x5eed5eed5eed5eedull;
};

}  // namespace stampede
