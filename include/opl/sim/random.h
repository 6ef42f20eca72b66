// Portable seeded random numbers for simulation and Monte Carlo.
//
// The C++ standard fully specifies the engines (std::mt19937_64 gives the same
// sequence everywhere) but not the distributions: std::uniform_int_distribution
// and std::normal_distribution differ between standard libraries. These
// helpers are written out so that a seed gives the same draws with any
// standard library (up to the last bits of std::log/std::cos/std::sin of the C
// library, for the normal draws).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

namespace opl {

// SplitMix64 (Steele, Lea, Flood 2014; Vigna): turns one 64-bit seed into a
// stream of well-mixed, independent-looking 64-bit seeds for other engines.
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }

 private:
  uint64_t state_;
};

// Uniform double in [0, 1) with 53 random bits.
inline double Uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

// Uniform integer in [0, n), n >= 1, unbiased (rejection of the top remainder).
inline uint64_t UniformIndex(uint64_t n, std::mt19937_64& rng) {
  const uint64_t threshold = (0 - n) % n;  // 2^64 mod n
  uint64_t x = rng();
  while (x < threshold) x = rng();
  return x % n;
}

// k distinct indices of [0, n) chosen uniformly (partial Fisher-Yates), in the
// order drawn. Requires k <= n.
inline std::vector<size_t> SampleWithoutReplacement(size_t n, size_t k, std::mt19937_64& rng) {
  std::vector<size_t> index(n);
  for (size_t i = 0; i < n; ++i) index[i] = i;
  for (size_t i = 0; i < k && i < n; ++i) {
    const size_t j = i + static_cast<size_t>(UniformIndex(n - i, rng));
    std::swap(index[i], index[j]);
  }
  index.resize(k < n ? k : n);
  return index;
}

// Standard normal draws by the Box-Muller transform; keeps the second value of
// each pair for the next call.
class NormalGenerator {
 public:
  double operator()(std::mt19937_64& rng) {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double u1 = 1.0 - Uniform01(rng);  // (0, 1]: log is finite
    const double u2 = Uniform01(rng);
    const double r = std::sqrt(-2.0 * std::log(u1));
    const double phi = 2.0 * 3.14159265358979323846 * u2;
    spare_ = r * std::sin(phi);
    has_spare_ = true;
    return r * std::cos(phi);
  }

 private:
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace opl
