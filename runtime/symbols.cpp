// The explicit list of host functions compiled shader code may call: libm entry points LLVM
// lowers intrinsics to and the rlf_* built-ins. Both ways of loading shader code resolve against
// it and nothing else (never the whole process): the in-process JIT (compiler/jit.cpp) and the
// shader-object loader (shader_object.h).
#include "runtime/symbols.h"

#include <math.h>

#include <cmath>
#include <cstring>

#include "runtime/builtins_noise.h"
#include "runtime/builtins_print.h"
#include "runtime/builtins_space.h"
#include "runtime/builtins_texture.h"

namespace relief::runtime {
namespace {

// libm entry points LLVM lowers intrinsics to; resolved explicitly, never from the whole process.
// Most are libm's own functions (no wrapper frame on the hot path).
void* libm1(float (*f)(float)) { return reinterpret_cast<void*>(f); }
void* libm2(float (*f)(float, float)) { return reinterpret_cast<void*>(f); }
float exp10fImpl(float x) { return std::pow(10.0f, x); }
float ldexpfImpl(float x, int e) { return std::ldexp(x, e); }
float fmafImpl(float a, float b, float c) { return std::fma(a, b, c); }
void* memsetImpl(void* d, int c, size_t n) { return std::memset(d, c, n); }
void* memcpyImpl(void* d, const void* s, size_t n) { return std::memcpy(d, s, n); }
void* memmoveImpl(void* d, const void* s, size_t n) { return std::memmove(d, s, n); }
int strcmpImpl(const char* a, const char* b) { return std::strcmp(a, b); }

const RuntimeSymbol kSymbols[] = {
    {"sinf", libm1(&::sinf)},
    {"cosf", libm1(&::cosf)},
    {"tanf", libm1(&::tanf)},
    {"asinf", libm1(&::asinf)},
    {"acosf", libm1(&::acosf)},
    {"atanf", libm1(&::atanf)},
    {"atan2f", libm2(&::atan2f)},
    {"expf", libm1(&::expf)},
    {"exp2f", libm1(&::exp2f)},
    {"logf", libm1(&::logf)},
    {"log2f", libm1(&::log2f)},
    {"log10f", libm1(&::log10f)},
    {"powf", libm2(&::powf)},
    {"floorf", libm1(&::floorf)},
    {"ceilf", libm1(&::ceilf)},
    {"truncf", libm1(&::truncf)},
    {"roundf", libm1(&::roundf)},
    {"fmodf", libm2(&::fmodf)},
    {"sqrtf", libm1(&::sqrtf)},
    {"sincosf", reinterpret_cast<void*>(&::sincosf)},  // glibc: one call for LLVM's merged sin+cos
    {"exp10f", reinterpret_cast<void*>(&exp10fImpl)},
    {"ldexpf", reinterpret_cast<void*>(&ldexpfImpl)},
    {"fminf", libm2(&::fminf)},
    {"fmaxf", libm2(&::fmaxf)},
    {"fmaf", reinterpret_cast<void*>(&fmafImpl)},
    {"memset", reinterpret_cast<void*>(&memsetImpl)},
    {"memcpy", reinterpret_cast<void*>(&memcpyImpl)},
    {"memmove", reinterpret_cast<void*>(&memmoveImpl)},
    {"strcmp", reinterpret_cast<void*>(&strcmpImpl)},
    {"rlf_noise1", reinterpret_cast<void*>(&rlf_noise1)},
    {"rlf_noise2", reinterpret_cast<void*>(&rlf_noise2)},
    {"rlf_noise3", reinterpret_cast<void*>(&rlf_noise3)},
    {"rlf_noise4", reinterpret_cast<void*>(&rlf_noise4)},
    {"rlf_cellnoise", reinterpret_cast<void*>(&rlf_cellnoise)},
    {"rlf_random", reinterpret_cast<void*>(&rlf_random)},
    {"rlf_pnoise", reinterpret_cast<void*>(&rlf_pnoise)},
    {"rlf_texture", reinterpret_cast<void*>(&rlf_texture)},
    {"rlf_printf", reinterpret_cast<void*>(&rlf_printf)},
    {"rlf_format", reinterpret_cast<void*>(&rlf_format)},
    {"rlf_concat", reinterpret_cast<void*>(&rlf_concat)},
    {"rlf_strings_reset", reinterpret_cast<void*>(&rlf_strings_reset)},
    {"rlf_space_matrices", reinterpret_cast<void*>(&rlf_space_matrices)},
};

}  // namespace

std::span<const RuntimeSymbol> runtimeSymbols() { return kSymbols; }

void* findRuntimeSymbol(std::string_view name) {
  for (const RuntimeSymbol& s : kSymbols)
    if (name == s.name) return s.address;
  return nullptr;
}

}  // namespace relief::runtime
