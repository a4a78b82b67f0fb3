// Gradient noise called by JIT-compiled shaders (language.md §6.5): extern "C", noexcept, pure and
// deterministic. Each returns a value in [0,1] and writes its analytic gradient. Registered with the
// JIT by compiler/builtins.cpp.
#pragma once

#ifdef __cplusplus
extern "C" {
#endif

// `channel` (0, 1, 2) picks one of three uncorrelated noises with the same lattice (a triple
// noise's components); every one is 0.5 at the lattice points. Channel 0 is the float noise.
float rlf_noise1(float x, float* dx, int channel);
float rlf_noise2(float x, float y, float* grad2, int channel);
float rlf_noise3(float x, float y, float z, float* grad3, int channel);
float rlf_noise4(float x, float y, float z, float w, float* grad4, int channel);
// Constant per integer cell of the `dims` (1..4) coordinates in p, uncorrelated across cells and
// channels, in [0, 1).
float rlf_cellnoise(const float* p, int dims, int channel);
// Periodic noise: like rlf_noiseN with the lattice wrapped every round(periods[i]) (>= 1) cells.
float rlf_pnoise(const float* p, const float* periods, int dims, float* grad, int channel);
// random(): a hash in [0, 1) of an invocation's inputs (P.xyz, u, v), the call's ordinal and channel.
float rlf_random(const float* inputs5, int ordinal, int channel);

#ifdef __cplusplus
}
#endif

#ifdef __cplusplus
// The 3D noise's two implementations, for the test that holds them bit-identical and the benchmark
// that compares them; rlf_noise3 picks one by CPU.
namespace relief::noise_detail {
float noise3Portable(const float* p, float* grad, int channel = 0);
bool noise3Avx2Available();
float noise3Avx2(const float* p, float* grad, int channel = 0);  // only where noise3Avx2Available()
}  // namespace relief::noise_detail
#endif
