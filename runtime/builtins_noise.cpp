// Perlin-type gradient noise with analytic gradient (language.md §6.5) for JIT-compiled shaders.
// Lattice gradients come from an integer hash (no tables, no state), so results are identical
// across runs, threads and entry points.
#include "runtime/builtins_noise.h"

#include <cmath>
#include <cstdint>
#include <cstring>

namespace {

uint32_t mix32(uint32_t h) {
  // Murmur3 finalizer: every input bit affects every output bit.
  h ^= h >> 16;
  h *= 0x85ebca6bu;
  h ^= h >> 13;
  h *= 0xc2b2ae35u;
  h ^= h >> 16;
  return h;
}

// Lattice coordinate of a finite float; far-away inputs wrap, which only matters past 2^31.
int32_t cellOf(float x) {
  const double f = std::floor(double(x));
  const double wrapped = std::fmod(f, 4294967296.0);
  return int32_t(uint32_t(int64_t(wrapped)));
}

template <int D>
uint32_t hashCorner(const int32_t* cell) {
  static constexpr uint32_t kPrimes[4] = {0x8da6b343u, 0xd8163841u, 0xcb1ab31fu, 0x9e3779b1u};
  uint32_t h = 0x27d4eb2du;
  for (int i = 0; i < D; ++i) h = mix32(h ^ (uint32_t(cell[i]) * kPrimes[i]));
  return h;
}

// Gradient vectors of the improved-noise family: unit-ish, evenly spread.
template <int D>
void gradient(uint32_t h, float* g) {
  if constexpr (D == 1) {
    g[0] = float(int32_t(h >> 16) - 32768) / 32768.0f;  // [-1, 1)
  } else if constexpr (D == 2) {
    static constexpr float kS = 0.70710678f;
    static constexpr float kDirs[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1},
                                          {kS, kS}, {-kS, kS}, {kS, -kS}, {-kS, -kS}};
    const auto& d = kDirs[(h >> 8) & 7];
    g[0] = d[0];
    g[1] = d[1];
  } else if constexpr (D == 3) {
    static constexpr float kDirs[12][3] = {{1, 1, 0},  {-1, 1, 0}, {1, -1, 0}, {-1, -1, 0},
                                           {1, 0, 1},  {-1, 0, 1}, {1, 0, -1}, {-1, 0, -1},
                                           {0, 1, 1},  {0, -1, 1}, {0, 1, -1}, {0, -1, -1}};
    const auto& d = kDirs[(h >> 8) % 12];
    for (int i = 0; i < 3; ++i) g[i] = d[i];
  } else {
    // 32 vectors with one zero component and ±1 elsewhere.
    const uint32_t k = (h >> 8) & 31;
    const int zero = int(k >> 3);
    int bit = 0;
    for (int i = 0; i < 4; ++i) g[i] = i == zero ? 0.0f : ((k >> bit++) & 1 ? -1.0f : 1.0f);
  }
}

// Quintic fade: C2 at lattice points, so the noise is C1 with continuous gradient.
float fade(float t) { return t * t * t * (t * (t * 6 - 15) + 10); }
float fadeDeriv(float t) { return 30 * t * t * (t * (t - 2) + 1); }

// Output scale so the signed noise fills about [-1, 1] for each dimension.
template <int D>
constexpr float kScale = D == 1 ? 2.0f : D == 2 ? 1.41421356f : 1.0f;

template <int D>
float noise(const float* p, float* grad, const int32_t* period = nullptr) {
  for (int i = 0; i < D; ++i) {
    if (!std::isfinite(p[i])) {
      for (int k = 0; k < D; ++k) grad[k] = 0;
      return 0.5f;
    }
  }
  int32_t base[D];
  float f[D], s[D], ds[D];
  for (int i = 0; i < D; ++i) {
    base[i] = cellOf(p[i]);
    f[i] = p[i] - std::floor(p[i]);
    s[i] = fade(f[i]);
    ds[i] = fadeDeriv(f[i]);
  }
  float value = 0;
  float dvalue[D] = {};
  for (int corner = 0; corner < (1 << D); ++corner) {
    int32_t cell[D];
    float d[D], w[D], dw[D];
    for (int i = 0; i < D; ++i) {
      const int c = (corner >> i) & 1;
      cell[i] = int32_t(uint32_t(base[i]) + uint32_t(c));
      if (period) cell[i] = int32_t(((int64_t(cell[i]) % period[i]) + period[i]) % period[i]);
      d[i] = f[i] - float(c);
      w[i] = c ? s[i] : 1 - s[i];
      dw[i] = c ? ds[i] : -ds[i];
    }
    float g[D];
    gradient<D>(hashCorner<D>(cell), g);
    float dot = 0, weight = 1;
    for (int i = 0; i < D; ++i) {
      dot += g[i] * d[i];
      weight *= w[i];
    }
    value += weight * dot;
    for (int k = 0; k < D; ++k) {
      float partial = dw[k];
      for (int i = 0; i < D; ++i)
        if (i != k) partial *= w[i];
      dvalue[k] += g[k] * weight + dot * partial;
    }
  }
  const float signedValue = value * kScale<D>;
  if (signedValue <= -1 || signedValue >= 1) {  // rare overshoot: flat at the clamp
    for (int k = 0; k < D; ++k) grad[k] = 0;
    return signedValue <= -1 ? 0.0f : 1.0f;
  }
  for (int k = 0; k < D; ++k) grad[k] = 0.5f * kScale<D> * dvalue[k];
  return 0.5f + 0.5f * signedValue;
}

}  // namespace

extern "C" {

float rlf_noise1(float x, float* dx) { return noise<1>(&x, dx); }

float rlf_noise2(float x, float y, float* grad2) {
  const float p[2] = {x, y};
  return noise<2>(p, grad2);
}

float rlf_noise3(float x, float y, float z, float* grad3) {
  const float p[3] = {x, y, z};
  return noise<3>(p, grad3);
}

float rlf_noise4(float x, float y, float z, float w, float* grad4) {
  const float p[4] = {x, y, z, w};
  return noise<4>(p, grad4);
}

float rlf_pnoise(const float* p, const float* periods, int dims, float* grad) {
  int32_t period[4];
  for (int i = 0; i < dims && i < 4; ++i) {
    // Periods are rounded to integers >= 1 (language.md §6.5).
    const float r = std::isfinite(periods[i]) ? std::round(periods[i]) : 1.0f;
    period[i] = r < 1 ? 1 : r > 1e9f ? 1000000000 : int32_t(r);
  }
  switch (dims) {
    case 1: return noise<1>(p, grad, period);
    case 2: return noise<2>(p, grad, period);
    case 3: return noise<3>(p, grad, period);
    default: return noise<4>(p, grad, period);
  }
}

float rlf_random(const float* inputs5, int ordinal, int channel) {
  uint32_t h = mix32(0x3c6ef372u ^ uint32_t(ordinal) * 0x9e3779b9u ^ uint32_t(channel) * 0x85ebca77u);
  for (int i = 0; i < 5; ++i) {
    uint32_t bits;
    std::memcpy(&bits, &inputs5[i], 4);
    h = mix32(h ^ bits);
  }
  return float(h >> 8) * (1.0f / 16777216.0f);
}

float rlf_cellnoise(const float* p, int dims, int channel) {
  uint32_t h = mix32(0x5bd1e995u ^ uint32_t(channel) * 0x68e31da4u);
  for (int i = 0; i < dims && i < 4; ++i) {
    const int32_t cell = std::isfinite(p[i]) ? cellOf(p[i]) : 0;
    h = mix32(h ^ (uint32_t(cell) * 0x9e3779b1u + uint32_t(i)));
  }
  return float(h >> 8) * (1.0f / 16777216.0f);  // 24 bits: exactly representable, < 1
}

}  // extern "C"
