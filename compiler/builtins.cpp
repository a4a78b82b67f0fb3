// The built-in function table and the explicit list of runtime symbols the JIT may resolve.
#include "compiler/builtins.h"

#include <cmath>
#include <cstring>
#include <unordered_map>

#include "runtime/builtins_noise.h"
#include "runtime/builtins_print.h"
#include "runtime/builtins_space.h"
#include "runtime/builtins_texture.h"

namespace relief::compiler {

namespace {
constexpr BuiltinInfo kBuiltins[] = {
#define RELIEF_BUILTIN(Id, Name, Shape) {BuiltinId::Id, Name, BuiltinShape::Shape},
#include "compiler/builtins.def"
};

// libm entry points LLVM lowers intrinsics to; resolved explicitly, never from the whole process.
float sinfImpl(float x) { return std::sin(x); }
float cosfImpl(float x) { return std::cos(x); }
float tanfImpl(float x) { return std::tan(x); }
float asinfImpl(float x) { return std::asin(x); }
float acosfImpl(float x) { return std::acos(x); }
float atanfImpl(float x) { return std::atan(x); }
float atan2fImpl(float y, float x) { return std::atan2(y, x); }
float expfImpl(float x) { return std::exp(x); }
float exp2fImpl(float x) { return std::exp2(x); }
float logfImpl(float x) { return std::log(x); }
float log2fImpl(float x) { return std::log2(x); }
float log10fImpl(float x) { return std::log10(x); }
float powfImpl(float x, float y) { return std::pow(x, y); }
float floorfImpl(float x) { return std::floor(x); }
float ceilfImpl(float x) { return std::ceil(x); }
float truncfImpl(float x) { return std::trunc(x); }
float roundfImpl(float x) { return std::round(x); }
float fmodfImpl(float x, float y) { return std::fmod(x, y); }
float sqrtfImpl(float x) { return std::sqrt(x); }
void sincosfImpl(float x, float* s, float* c) {
  *s = std::sin(x);
  *c = std::cos(x);
}
float exp10fImpl(float x) { return std::pow(10.0f, x); }
float ldexpfImpl(float x, int e) { return std::ldexp(x, e); }
float fminfImpl(float a, float b) { return std::fmin(a, b); }
float fmaxfImpl(float a, float b) { return std::fmax(a, b); }
float fmafImpl(float a, float b, float c) { return std::fma(a, b, c); }
void* memsetImpl(void* d, int c, size_t n) { return std::memset(d, c, n); }
void* memcpyImpl(void* d, const void* s, size_t n) { return std::memcpy(d, s, n); }
void* memmoveImpl(void* d, const void* s, size_t n) { return std::memmove(d, s, n); }
int strcmpImpl(const char* a, const char* b) { return std::strcmp(a, b); }

const RuntimeSymbol kSymbols[] = {
    {"sinf", reinterpret_cast<void*>(&sinfImpl)},
    {"cosf", reinterpret_cast<void*>(&cosfImpl)},
    {"tanf", reinterpret_cast<void*>(&tanfImpl)},
    {"asinf", reinterpret_cast<void*>(&asinfImpl)},
    {"acosf", reinterpret_cast<void*>(&acosfImpl)},
    {"atanf", reinterpret_cast<void*>(&atanfImpl)},
    {"atan2f", reinterpret_cast<void*>(&atan2fImpl)},
    {"expf", reinterpret_cast<void*>(&expfImpl)},
    {"exp2f", reinterpret_cast<void*>(&exp2fImpl)},
    {"logf", reinterpret_cast<void*>(&logfImpl)},
    {"log2f", reinterpret_cast<void*>(&log2fImpl)},
    {"log10f", reinterpret_cast<void*>(&log10fImpl)},
    {"powf", reinterpret_cast<void*>(&powfImpl)},
    {"floorf", reinterpret_cast<void*>(&floorfImpl)},
    {"ceilf", reinterpret_cast<void*>(&ceilfImpl)},
    {"truncf", reinterpret_cast<void*>(&truncfImpl)},
    {"roundf", reinterpret_cast<void*>(&roundfImpl)},
    {"fmodf", reinterpret_cast<void*>(&fmodfImpl)},
    {"sqrtf", reinterpret_cast<void*>(&sqrtfImpl)},
    {"sincosf", reinterpret_cast<void*>(&sincosfImpl)},
    {"exp10f", reinterpret_cast<void*>(&exp10fImpl)},
    {"ldexpf", reinterpret_cast<void*>(&ldexpfImpl)},
    {"fminf", reinterpret_cast<void*>(&fminfImpl)},
    {"fmaxf", reinterpret_cast<void*>(&fmaxfImpl)},
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

const BuiltinInfo* findBuiltin(std::string_view name) {
  static const std::unordered_map<std::string_view, const BuiltinInfo*> table = [] {
    std::unordered_map<std::string_view, const BuiltinInfo*> t;
    for (const BuiltinInfo& b : kBuiltins) t.emplace(b.name, &b);
    return t;
  }();
  auto it = table.find(name);
  return it == table.end() ? nullptr : it->second;
}

std::span<const RuntimeSymbol> runtimeSymbols() { return kSymbols; }

}  // namespace relief::compiler
