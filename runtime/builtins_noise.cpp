// Perlin-type gradient noise with analytic gradient (language.md §6.5) for JIT-compiled shaders.
// Lattice gradients come from an integer hash (no tables, no state), so results are identical
// across runs, threads and entry points. The 3D noise, which fBm and its kin call once per octave,
// also has an AVX2 twin that agrees with it to the bit, so results do not depend on the CPU either.
#include "runtime/builtins_noise.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace {

[[gnu::always_inline]] inline uint32_t mix32(uint32_t h) {
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
  // Inside int32 range the wrap below is the identity; skipping its double fmod saves a few
  // percent of a whole noise-heavy render.
  if (std::fabs(x) < 2147483648.0f) return int32_t(std::floor(x));
  const double f = std::floor(double(x));
  const double wrapped = std::fmod(f, 4294967296.0);
  return int32_t(uint32_t(int64_t(wrapped)));
}

constexpr uint32_t kHashPrimes[4] = {0x8da6b343u, 0xd8163841u, 0xcb1ab31fu, 0x9e3779b1u};
constexpr uint32_t kHashSeed = 0x27d4eb2du;

// The hash seed of channel `channel` of a triple noise. Channels differ in their lattice gradients,
// not in a shifted domain, so every channel is 0.5 at the lattice points (§6.5); channel 0 is the
// float noise.
uint32_t channelSeed(int channel) {
  return channel == 0 ? kHashSeed : mix32(kHashSeed ^ (uint32_t(channel) * 0x9e3779b9u));
}

// The hash of a lattice corner is a chain over the axes, h = mix(...mix(seed ^ c0 P0) ^ c1 P1...),
// so the 2^D corners of a cell share prefixes: computed level by level, a cell costs 2 + 4 + ... +
// 2^D finalizers instead of D 2^D (14 instead of 24 in 3D). Corner k's bit i selects cell[i][1].
// Always inlined: out of line, the call and the copies out of `level` cost a third of the noise.
template <int D>
[[gnu::always_inline]] inline void hashCorners(const int32_t (*cell)[2], uint32_t* out, uint32_t seed) {
  uint32_t level[1 << D];
  level[0] = seed;
  int count = 1;
  for (int i = 0; i < D; ++i) {
    // Corners with bit i clear keep their slot; their bit-i twins go `count` slots up.
    for (int k = count - 1; k >= 0; --k) {
      const uint32_t prefix = level[k];
      level[k] = mix32(prefix ^ (uint32_t(cell[i][0]) * kHashPrimes[i]));
      level[k + count] = mix32(prefix ^ (uint32_t(cell[i][1]) * kHashPrimes[i]));
    }
    count *= 2;
  }
  for (int k = 0; k < (1 << D); ++k) out[k] = level[k];
}

// The 3D gradients: the twelve edge midpoints of a cube, as in improved noise.
constexpr float kDirs3[12][3] = {{1, 1, 0},  {-1, 1, 0}, {1, -1, 0}, {-1, -1, 0},
                                 {1, 0, 1},  {-1, 0, 1}, {1, 0, -1}, {-1, 0, -1},
                                 {0, 1, 1},  {0, -1, 1}, {0, 1, -1}, {0, -1, -1}};

// The 4D gradients: direction k has component k >> 3 zero and the others -1 where k's next bit
// (bits 0, 1, 2 in turn) is set, else 1.
constexpr auto kDirs4 = [] {
  std::array<std::array<float, 4>, 32> dirs{};
  for (uint32_t k = 0; k < 32; ++k) {
    const int zero = int(k >> 3);
    int bit = 0;
    for (int i = 0; i < 4; ++i) dirs[k][size_t(i)] = i == zero ? 0.0f : ((k >> bit++) & 1 ? -1.0f : 1.0f);
  }
  return dirs;
}();

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
    const auto& d = kDirs3[(h >> 8) % 12];
    for (int i = 0; i < 3; ++i) g[i] = d[i];
  } else {
    // 32 vectors with one zero component and ±1 elsewhere, from a table: choosing each component
    // by its bits took four unpredictable branches per corner, sixteen corners a call.
    const auto& d = kDirs4[(h >> 8) & 31];
    for (int i = 0; i < 4; ++i) g[i] = d[i];
  }
}

// Quintic fade: C2 at lattice points, so the noise is C1 with continuous gradient.
float fade(float t) { return t * t * t * (t * (t * 6 - 15) + 10); }
float fadeDeriv(float t) { return 30 * t * t * (t * (t - 2) + 1); }

// Output scale so the signed noise fills about [-1, 1] for each dimension.
template <int D>
constexpr float kScale = D == 1 ? 2.0f : D == 2 ? 1.41421356f : 1.0f;

template <int D>
float noise(const float* p, float* grad, uint32_t seed, const int32_t* period = nullptr) {
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
  int32_t cells[D][2];
  for (int i = 0; i < D; ++i)
    for (int c = 0; c < 2; ++c) {
      int32_t cell = int32_t(uint32_t(base[i]) + uint32_t(c));
      if (period) {
        // The cell modulo the period, in [0, period): one 32-bit division (period >= 1) instead of
        // two 64-bit ones, the same values (3D pnoise: 105 -> 97 ns a call).
        cell %= period[i];
        if (cell < 0) cell += period[i];
      }
      cells[i][c] = cell;
    }
  uint32_t hashes[1 << D];
  hashCorners<D>(cells, hashes, seed);
  float value = 0;
  float dvalue[D] = {};
  // Unrolled, the corners' arrays live in registers (4D noise: 167 -> 133 ns a call).
#pragma GCC unroll 16
  for (int corner = 0; corner < (1 << D); ++corner) {
    float d[D], w[D], dw[D];
    for (int i = 0; i < D; ++i) {
      const int c = (corner >> i) & 1;
      d[i] = f[i] - float(c);
      w[i] = c ? s[i] : 1 - s[i];
      dw[i] = c ? ds[i] : -ds[i];
    }
    float g[D];
    gradient<D>(hashes[corner], g);
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

// The signed 3D noise value and its gradient as rlf_noise3 returns them: [0, 1], gradient halved.
float noise3Result(float value, const float dvalue[3], float* grad) {
  if (value <= -1 || value >= 1) {  // rare overshoot: flat at the clamp
    grad[0] = grad[1] = grad[2] = 0;
    return value <= -1 ? 0.0f : 1.0f;
  }
  for (int k = 0; k < 3; ++k) grad[k] = 0.5f * dvalue[k];
  return 0.5f + 0.5f * value;
}

// The 3D case, which fBm and every spatial noise use, written out: eight corner dot products, then
// three rounds of lerps for the value, with the weights' derivatives giving the analytic gradient.
// The generic loop above spent about 1,100 instructions a call on index bookkeeping; this is the
// same function (same lattice, gradients and fade), rounded differently in the last bits.
// noise3Avx2 below computes the very same operations eight corners at a time; the two must stay
// bit-identical (tests/runtime/noise_test.cpp), since which one runs depends on the CPU.
float noise3Portable(const float* p, float* grad, uint32_t seed) {
  if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
    grad[0] = grad[1] = grad[2] = 0;
    return 0.5f;
  }
  int32_t cells[3][2];
  float f[3], s[3], ds[3];
  for (int i = 0; i < 3; ++i) {
    const int32_t base = cellOf(p[i]);
    cells[i][0] = base;
    cells[i][1] = int32_t(uint32_t(base) + 1u);
    f[i] = p[i] - std::floor(p[i]);
    s[i] = fade(f[i]);
    ds[i] = fadeDeriv(f[i]);
  }
  uint32_t hashes[8];
  hashCorners<3>(cells, hashes, seed);
  float n[8], gx[8], gy[8], gz[8];
  for (int k = 0; k < 8; ++k) {
    const float* g = kDirs3[(hashes[k] >> 8) % 12];
    const float dx = f[0] - float(k & 1), dy = f[1] - float((k >> 1) & 1), dz = f[2] - float(k >> 2);
    gx[k] = g[0];
    gy[k] = g[1];
    gz[k] = g[2];
    n[k] = g[0] * dx + g[1] * dy + g[2] * dz;
  }
  auto lerp = [](float a, float b, float t) { return a + t * (b - a); };
  // Trilinear interpolation of eight corner values, x first (corner bit 0), then y, then z.
  auto tri = [&](const float* v) {
    return lerp(lerp(lerp(v[0], v[1], s[0]), lerp(v[2], v[3], s[0]), s[1]),
                lerp(lerp(v[4], v[5], s[0]), lerp(v[6], v[7], s[0]), s[1]), s[2]);
  };
  const float y0 = lerp(n[0], n[1], s[0]), y1 = lerp(n[2], n[3], s[0]);
  const float y2 = lerp(n[4], n[5], s[0]), y3 = lerp(n[6], n[7], s[0]);
  const float z0 = lerp(y0, y1, s[1]), z1 = lerp(y2, y3, s[1]);
  const float value = lerp(z0, z1, s[2]);
  const float ddx = lerp(lerp(n[1] - n[0], n[3] - n[2], s[1]), lerp(n[5] - n[4], n[7] - n[6], s[1]), s[2]);
  const float ddy = lerp(y1 - y0, y3 - y2, s[2]);
  const float ddz = z1 - z0;
  const float dvalue[3] = {tri(gx) + ds[0] * ddx, tri(gy) + ds[1] * ddy, tri(gz) + ds[2] * ddz};
  return noise3Result(value, dvalue, grad);
}

#if defined(__x86_64__) || defined(__i386__)
#define RELIEF_NOISE_AVX2 1
// noise3Portable, eight lattice corners to a vector: the corner hashes in three rounds of eight
// lanes instead of fourteen scalar finalizers, the gradients by table permutes instead of a
// division and loads, the lerp trees on [value, gx, gy, gz] columns, and the three axes' fades
// side by side. Every floating-point operation is the one noise3Portable does, in the same order
// (and the build forbids contraction into FMA), so the two agree to the bit.
[[gnu::target("avx2")]] inline __m256i mix32x8(__m256i h) {
  h = _mm256_xor_si256(h, _mm256_srli_epi32(h, 16));
  h = _mm256_mullo_epi32(h, _mm256_set1_epi32(int32_t(0x85ebca6bu)));
  h = _mm256_xor_si256(h, _mm256_srli_epi32(h, 13));
  h = _mm256_mullo_epi32(h, _mm256_set1_epi32(int32_t(0xc2b2ae35u)));
  return _mm256_xor_si256(h, _mm256_srli_epi32(h, 16));
}

// kDirs3 column by column for lane permutes: [0][c][k] is direction k's component c (k < 8),
// [1][c][k] direction 8 + k % 4's.
constexpr auto kDirColumns = [] {
  std::array<std::array<std::array<float, 8>, 3>, 2> columns{};
  for (size_t c = 0; c < 3; ++c)
    for (size_t k = 0; k < 8; ++k) {
      columns[0][c][k] = kDirs3[k][c];
      columns[1][c][k] = kDirs3[8 + k % 4][c];
    }
  return columns;
}();

// lerp(a, b, t) = a + t * (b - a), as in noise3Portable.
[[gnu::target("avx2")]] inline __m128 lerp4(__m128 a, __m128 b, __m128 t) {
  return _mm_add_ps(a, _mm_mul_ps(t, _mm_sub_ps(b, a)));
}

[[gnu::target("avx2")]] float noise3Avx2(const float* p, float* grad, uint32_t seed) {
  if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
    grad[0] = grad[1] = grad[2] = 0;
    return 0.5f;
  }
  // The three axes side by side: fractions, fades and cells, operation for operation as fade(),
  // fadeDeriv() and cellOf().
  const __m128 pv = _mm_setr_ps(p[0], p[1], p[2], 0.0f);
  const __m128 floorv = _mm_floor_ps(pv);
  const __m128 t = _mm_sub_ps(pv, floorv);
  const __m128 sv = _mm_mul_ps(
      _mm_mul_ps(_mm_mul_ps(t, t), t),
      _mm_add_ps(_mm_mul_ps(t, _mm_sub_ps(_mm_mul_ps(t, _mm_set1_ps(6)), _mm_set1_ps(15))), _mm_set1_ps(10)));
  const __m128 dsv = _mm_mul_ps(_mm_mul_ps(_mm_mul_ps(_mm_set1_ps(30), t), t),
                                _mm_add_ps(_mm_mul_ps(t, _mm_sub_ps(t, _mm_set1_ps(2))), _mm_set1_ps(1)));
  alignas(16) float f[4], s[4], ds[4];
  _mm_store_ps(f, t);
  _mm_store_ps(s, sv);
  _mm_store_ps(ds, dsv);
  const __m128 magnitude = _mm_andnot_ps(_mm_set1_ps(-0.0f), pv);
  const bool inRange = (_mm_movemask_ps(_mm_cmplt_ps(magnitude, _mm_set1_ps(2147483648.0f))) & 7) == 7;
  const __m128i base =
      inRange ? _mm_cvttps_epi32(floorv) : _mm_setr_epi32(cellOf(p[0]), cellOf(p[1]), cellOf(p[2]), 0);
  // Lane k is corner k: bit 0 picks the x cell, bit 1 the y cell, bit 2 the z cell.
  const __m256i base8 = _mm256_broadcastsi128_si256(base);
  const __m256i cx = _mm256_add_epi32(_mm256_permutevar8x32_epi32(base8, _mm256_set1_epi32(0)),
                                      _mm256_setr_epi32(0, 1, 0, 1, 0, 1, 0, 1));
  const __m256i cy = _mm256_add_epi32(_mm256_permutevar8x32_epi32(base8, _mm256_set1_epi32(1)),
                                      _mm256_setr_epi32(0, 0, 1, 1, 0, 0, 1, 1));
  const __m256i cz = _mm256_add_epi32(_mm256_permutevar8x32_epi32(base8, _mm256_set1_epi32(2)),
                                      _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1));
  __m256i h = _mm256_set1_epi32(int32_t(seed));
  h = mix32x8(_mm256_xor_si256(h, _mm256_mullo_epi32(cx, _mm256_set1_epi32(int32_t(kHashPrimes[0])))));
  h = mix32x8(_mm256_xor_si256(h, _mm256_mullo_epi32(cy, _mm256_set1_epi32(int32_t(kHashPrimes[1])))));
  h = mix32x8(_mm256_xor_si256(h, _mm256_mullo_epi32(cz, _mm256_set1_epi32(int32_t(kHashPrimes[2])))));
  // (h >> 8) % 12: the quotient by 12 is the high word of x * 0xaaaaaaab shifted by 3, taken on the
  // even lanes and then on the odd ones.
  const __m256i x = _mm256_srli_epi32(h, 8);
  const __m256i magic = _mm256_set1_epi32(int32_t(0xaaaaaaabu));
  const __m256i qEven = _mm256_srli_epi64(_mm256_mul_epu32(x, magic), 35);
  const __m256i qOdd = _mm256_srli_epi64(_mm256_mul_epu32(_mm256_srli_epi64(x, 32), magic), 35);
  const __m256i q = _mm256_or_si256(qEven, _mm256_slli_epi64(qOdd, 32));
  const __m256i q12 = _mm256_add_epi32(_mm256_slli_epi32(q, 3), _mm256_slli_epi32(q, 2));
  const __m256i dir = _mm256_sub_epi32(x, q12);
  // kDirs3 by column: directions 0-7 permute from one table, 8-11 from another.
  const __m256i high = _mm256_cmpgt_epi32(dir, _mm256_set1_epi32(7));
  __m256 g[3];
  for (int c = 0; c < 3; ++c)
    g[c] = _mm256_blendv_ps(_mm256_permutevar8x32_ps(_mm256_loadu_ps(kDirColumns[0][c].data()), dir),
                            _mm256_permutevar8x32_ps(_mm256_loadu_ps(kDirColumns[1][c].data()), dir),
                            _mm256_castsi256_ps(high));
  const __m256 dx = _mm256_sub_ps(_mm256_set1_ps(f[0]), _mm256_setr_ps(0, 1, 0, 1, 0, 1, 0, 1));
  const __m256 dy = _mm256_sub_ps(_mm256_set1_ps(f[1]), _mm256_setr_ps(0, 0, 1, 1, 0, 0, 1, 1));
  const __m256 dz = _mm256_sub_ps(_mm256_set1_ps(f[2]), _mm256_setr_ps(0, 0, 0, 0, 1, 1, 1, 1));
  const __m256 n = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(g[0], dx), _mm256_mul_ps(g[1], dy)),
                                 _mm256_mul_ps(g[2], dz));
  // Columns c[k] = [n, gx, gy, gz] of corner k.
  __m128 c0 = _mm256_castps256_ps128(n), c1 = _mm256_castps256_ps128(g[0]);
  __m128 c2 = _mm256_castps256_ps128(g[1]), c3 = _mm256_castps256_ps128(g[2]);
  __m128 c4 = _mm256_extractf128_ps(n, 1), c5 = _mm256_extractf128_ps(g[0], 1);
  __m128 c6 = _mm256_extractf128_ps(g[1], 1), c7 = _mm256_extractf128_ps(g[2], 1);
  _MM_TRANSPOSE4_PS(c0, c1, c2, c3);
  _MM_TRANSPOSE4_PS(c4, c5, c6, c7);
  const __m128 s0 = _mm_set1_ps(s[0]), s1 = _mm_set1_ps(s[1]), s2 = _mm_set1_ps(s[2]);
  // x first, then y, then z, as tri() and the value in noise3Portable.
  const __m128 y0 = lerp4(c0, c1, s0), y1 = lerp4(c2, c3, s0);
  const __m128 y2 = lerp4(c4, c5, s0), y3 = lerp4(c6, c7, s0);
  const __m128 z0 = lerp4(y0, y1, s1), z1 = lerp4(y2, y3, s1);
  const __m128 v = lerp4(z0, z1, s2);  // [value, tri(gx), tri(gy), tri(gz)]
  // Lane 0 of each is the n-column's derivative term.
  const __m128 ddx = lerp4(lerp4(_mm_sub_ps(c1, c0), _mm_sub_ps(c3, c2), s1),
                           lerp4(_mm_sub_ps(c5, c4), _mm_sub_ps(c7, c6), s1), s2);
  const __m128 ddy = lerp4(_mm_sub_ps(y1, y0), _mm_sub_ps(y3, y2), s2);
  const __m128 ddz = _mm_sub_ps(z1, z0);
  alignas(16) float out[4];
  _mm_store_ps(out, v);
  const float value = out[0];
  const float dvalue[3] = {out[1] + ds[0] * _mm_cvtss_f32(ddx), out[2] + ds[1] * _mm_cvtss_f32(ddy),
                           out[3] + ds[2] * _mm_cvtss_f32(ddz)};
  return noise3Result(value, dvalue, grad);
}
#endif

using Noise3Fn = float (*)(const float*, float*, uint32_t);

Noise3Fn pickNoise3() {
#ifdef RELIEF_NOISE_AVX2
  __builtin_cpu_init();  // may run before the CPU-model constructor
  if (__builtin_cpu_supports("avx2")) return noise3Avx2;
#endif
  return noise3Portable;
}

}  // namespace

extern "C" {

float rlf_noise1(float x, float* dx, int channel) { return noise<1>(&x, dx, channelSeed(channel)); }

float rlf_noise2(float x, float y, float* grad2, int channel) {
  const float p[2] = {x, y};
  return noise<2>(p, grad2, channelSeed(channel));
}

float rlf_noise3(float x, float y, float z, float* grad3, int channel) {
  static const Noise3Fn impl = pickNoise3();
  const float p[3] = {x, y, z};
  return impl(p, grad3, channelSeed(channel));
}

float rlf_noise4(float x, float y, float z, float w, float* grad4, int channel) {
  const float p[4] = {x, y, z, w};
  return noise<4>(p, grad4, channelSeed(channel));
}

float rlf_pnoise(const float* p, const float* periods, int dims, float* grad, int channel) {
  int32_t period[4];
  for (int i = 0; i < dims && i < 4; ++i) {
    // Periods are rounded to integers >= 1 (language.md §6.5).
    const float r = std::isfinite(periods[i]) ? std::round(periods[i]) : 1.0f;
    period[i] = r < 1 ? 1 : r > 1e9f ? 1000000000 : int32_t(r);
  }
  const uint32_t seed = channelSeed(channel);
  switch (dims) {
    case 1: return noise<1>(p, grad, seed, period);
    case 2: return noise<2>(p, grad, seed, period);
    case 3: return noise<3>(p, grad, seed, period);
    default: return noise<4>(p, grad, seed, period);
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

namespace relief::noise_detail {

float noise3Portable(const float* p, float* grad, int channel) { return ::noise3Portable(p, grad, channelSeed(channel)); }

bool noise3Avx2Available() { return pickNoise3() != ::noise3Portable; }

float noise3Avx2(const float* p, float* grad, int channel) {
#ifdef RELIEF_NOISE_AVX2
  return ::noise3Avx2(p, grad, channelSeed(channel));
#else
  return ::noise3Portable(p, grad, channelSeed(channel));
#endif
}

}  // namespace relief::noise_detail
