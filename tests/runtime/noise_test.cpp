// The noise functions' values, pinned: the 3D noise's vectorised implementation against the
// portable one (images must not depend on which CPU rendered them, so the two have to agree to the
// bit, value and gradient, everywhere), and every noise against fingerprints of its values taken
// before it was last made faster, so that no speed-up changes a shader's look unnoticed.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "runtime/builtins_noise.h"

namespace {

using relief::noise_detail::noise3Avx2;
using relief::noise_detail::noise3Avx2Available;
using relief::noise_detail::noise3Portable;

uint32_t bits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  return b;
}

// Points where rounding, lattice cells and the clamp are most likely to tell two implementations
// apart: lattice points and their float neighbours, both signs of zero, large and wrapping
// coordinates, non-finite values, and plain random points at several scales.
std::vector<std::array<float, 3>> probePoints() {
  std::vector<std::array<float, 3>> points;
  std::mt19937 rng(11);
  const float scales[] = {1e-3f, 1.0f, 50.0f, 1e4f, 3e9f};
  for (float scale : scales) {
    std::uniform_real_distribution<float> dist(-scale, scale);
    for (int i = 0; i < 40000; ++i) points.push_back({dist(rng), dist(rng), dist(rng)});
  }
  const float inf = std::numeric_limits<float>::infinity();
  const float special[] = {0.0f, -0.0f, 1.0f, -1.0f, 0.5f, std::nextafter(1.0f, 0.0f),
                           std::nextafter(-1.0f, 0.0f), std::nextafter(0.0f, 1.0f), 2147483520.0f,
                           -2147483648.0f, 4294967296.0f, 1e30f, -1e30f, inf, -inf,
                           std::numeric_limits<float>::quiet_NaN()};
  for (float a : special)
    for (float b : special)
      for (float c : special) points.push_back({a, b, c});
  std::uniform_int_distribution<int> cell(-100, 100);
  for (int i = 0; i < 20000; ++i) {
    std::array<float, 3> p;
    for (float& v : p) {
      const float k = float(cell(rng));
      const int nudge = int(rng() % 3);
      v = nudge == 0 ? k : nudge == 1 ? std::nextafter(k, -inf) : std::nextafter(k, inf);
    }
    points.push_back(p);
  }
  return points;
}

TEST(Noise3, VectorisedAgreesWithPortableToTheBit) {
  if (!noise3Avx2Available()) GTEST_SKIP() << "this CPU has no AVX2; only the portable noise runs";
  size_t compared = 0, clamped = 0;
  for (const auto& p : probePoints()) {
    float ga[3] = {-7, -7, -7}, gb[3] = {-9, -9, -9};
    const int channel = int(compared % 3);
    const float a = noise3Portable(p.data(), ga, channel);
    const float b = noise3Avx2(p.data(), gb, channel);
    ASSERT_EQ(bits(a), bits(b)) << p[0] << ' ' << p[1] << ' ' << p[2];
    for (int k = 0; k < 3; ++k) ASSERT_EQ(bits(ga[k]), bits(gb[k])) << k << ": " << p[0] << ' ' << p[1] << ' ' << p[2];
    ++compared;
    if (a == 0.0f || a == 1.0f) ++clamped;
  }
  EXPECT_GT(compared, 200000u);
  EXPECT_LT(clamped, compared / 100);  // the values compared are real noise, not the clamp
}

TEST(Noise3, ShadersGetOneOfTheTwo) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> dist(-20, 20);
  for (int i = 0; i < 1000; ++i) {
    const float p[3] = {dist(rng), dist(rng), dist(rng)};
    float g[3], gp[3];
    const float n = rlf_noise3(p[0], p[1], p[2], g, i % 3);
    ASSERT_EQ(bits(n), bits(noise3Portable(p, gp, i % 3)));
    for (int k = 0; k < 3; ++k) ASSERT_EQ(bits(g[k]), bits(gp[k]));
  }
}

// SplitMix64: the points must not depend on the standard library's distributions.
struct SplitMix {
  uint64_t state;
  uint64_t next() {
    uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
};

// FNV-1a over the bits of the value and gradient of 20,000 calls (a seventh of them with a
// coordinate on the lattice), per function. The fingerprints were taken with the code of commit
// 8bf5236, before the AVX2 3D noise and the 4D gradient table. A deliberate change of the noise
// must update them, and say so.
TEST(Noise, ValuesAreUnchangedBySpeedUps) {
  const struct {
    const char* name;
    uint64_t fingerprint;
  } expected[] = {{"noise1", 0x4b14b186f4903b0dull},  {"noise2", 0xbecb74198d174e08ull},
                  {"noise3", 0x23f8d9892122214bull},  {"noise4", 0x8a297fa01d37c861ull},
                  {"pnoise1", 0xf55f98a320ed5102ull}, {"pnoise2", 0x5f676bf29ec6eab6ull},
                  {"pnoise3", 0xe8941e93303954ddull}, {"pnoise4", 0xec14463a4e6e1fe0ull},
                  {"cellnoise", 0xe6260351d6dd9fe6ull}};
  for (int which = 0; which < 9; ++which) {
    SplitMix rng{uint64_t(which) + 1};
    uint64_t h = 1469598103934665603ull;
    auto mix = [&](float f) {
      const uint32_t b = bits(f);
      for (int i = 0; i < 4; ++i) h = (h ^ ((b >> (8 * i)) & 255)) * 1099511628211ull;
    };
    for (int i = 0; i < 20000; ++i) {
      float p[4], g[4] = {0, 0, 0, 0};
      for (float& c : p) c = float(int32_t(rng.next() % 140000u) - 70000) / 1000.0f;
      if (i % 7 == 0) p[i % 4] = float(int32_t(p[i % 4]));
      const float periods[4] = {3, 5.4f, 8, 2.6f};
      float v;
      switch (which) {
        case 0: v = rlf_noise1(p[0], g, 0); break;
        case 1: v = rlf_noise2(p[0], p[1], g, 0); break;
        case 2: v = rlf_noise3(p[0], p[1], p[2], g, 0); break;
        case 3: v = rlf_noise4(p[0], p[1], p[2], p[3], g, 0); break;
        case 8: v = rlf_cellnoise(p, 1 + i % 4, i % 3); break;
        default: v = rlf_pnoise(p, periods, which - 3, g, 0); break;
      }
      mix(v);
      for (float x : g) mix(x);
    }
    EXPECT_EQ(h, expected[which].fingerprint) << expected[which].name;
  }
}

}  // namespace
