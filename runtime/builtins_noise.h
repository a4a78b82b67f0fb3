// Gradient noise called by JIT-compiled shaders (language.md §6.5): extern "C", noexcept, pure and
// deterministic. Each returns a value in [0,1] and writes its analytic gradient. Registered with the
// JIT by compiler/builtins.cpp.
#pragma once

#ifdef __cplusplus
extern "C" {
#endif

float rlf_noise1(float x, float* dx);
float rlf_noise2(float x, float y, float* grad2);
float rlf_noise3(float x, float y, float z, float* grad3);
float rlf_noise4(float x, float y, float z, float w, float* grad4);
// Constant per integer cell of the `dims` (1..4) coordinates in p, uncorrelated across cells and
// channels, in [0, 1).
float rlf_cellnoise(const float* p, int dims, int channel);
// Periodic noise: like rlf_noiseN with the lattice wrapped every round(periods[i]) (>= 1) cells.
float rlf_pnoise(const float* p, const float* periods, int dims, float* grad);
// random(): a hash in [0, 1) of an invocation's inputs (P.xyz, u, v), the call's ordinal and channel.
float rlf_random(const float* inputs5, int ordinal, int channel);

#ifdef __cplusplus
}
#endif

#ifdef __cplusplus
// The 3D noise's two implementations, for the test that holds them bit-identical and the benchmark
// that compares them; rlf_noise3 picks one by CPU.
namespace relief::noise_detail {
float noise3Portable(const float* p, float* grad);
bool noise3Avx2Available();
float noise3Avx2(const float* p, float* grad);  // only where noise3Avx2Available()
}  // namespace relief::noise_detail
#endif
