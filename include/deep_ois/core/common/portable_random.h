// Random numbers that are the same on every machine: std::mt19937 is specified bit for bit, but
// the std:: distributions are not (each standard library picks its own algorithm), so every
// seeded component of deep_ois draws through these formulas instead.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <random>

namespace deep_ois {

// Uniform double in [0, 1) from two raw outputs (53 bits).
inline double uniform01(std::mt19937& rng) {
  const std::uint64_t high = rng() >> 5;  // 27 bits
  const std::uint64_t low = rng() >> 6;   // 26 bits
  return (static_cast<double>(high) * 67108864.0 + static_cast<double>(low)) / 9007199254740992.0;
}

inline double uniform(std::mt19937& rng, double lo, double hi) { return lo + (hi - lo) * uniform01(rng); }

// Standard normal by Box-Muller.
inline double gaussian(std::mt19937& rng) {
  const double u1 = 1.0 - uniform01(rng);  // (0, 1]: log is finite
  const double u2 = uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * 3.14159265358979323846 * u2);
}

// A generator per purpose (e.g. shake, pans, noise), so that changing one component of a seeded
// sequence leaves the others' random streams as they were. SplitMix64's finaliser spreads
// (seed, stream) over the 32-bit seed space.
inline std::uint32_t streamSeed(std::uint32_t seed, std::uint32_t stream) {
  std::uint64_t z = (static_cast<std::uint64_t>(seed) << 32) + 0x9E3779B97F4A7C15ull * (stream + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return static_cast<std::uint32_t>((z ^ (z >> 31)) & 0xFFFFFFFFu);
}

inline std::mt19937 streamGenerator(std::uint32_t seed, std::uint32_t stream) {
  return std::mt19937(streamSeed(seed, stream));
}

// Three independent standard normals, drawn x, y, z in that order.
inline Eigen::Vector3d gaussian3(std::mt19937& rng) {
  const double x = gaussian(rng);
  const double y = gaussian(rng);
  return Eigen::Vector3d(x, y, gaussian(rng));
}

}  // namespace deep_ois
