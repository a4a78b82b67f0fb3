// printf(), format() and concat() for JIT-compiled shaders (language.md §6.8): formats on the host side and hands the text
// to RlfHostServices::print (dropped without one). extern "C", noexcept; registered by
// compiler/builtins.cpp.
#pragma once

#include <stdint.h>

#include "runtime/abi.h"

#ifdef __cplusplus
extern "C" {
#endif

// Kinds of the arguments after the format, one per argument.
enum { kRlfPrintInt = 0, kRlfPrintFloat = 1, kRlfPrintTriple = 2, kRlfPrintString = 3, kRlfPrintMatrix = 4 };

// `floats` holds the float and triple components in order, `ints` the ints, `strings` the strings.
void rlf_printf(const RlfHostServices* services, const char* format, const int32_t* kinds, int32_t count,
                const float* floats, const int32_t* ints, const char* const* strings);

// format(): the same formatting as rlf_printf, returned as a string that stays valid until the
// calling thread's next rlf_strings_reset (the generated code resets once per shading point).
const char* rlf_format(const char* format, const int32_t* kinds, int32_t count, const float* floats,
                       const int32_t* ints, const char* const* strings);
// concat(): the `count` strings joined, valid like rlf_format's result.
const char* rlf_concat(const char* const* parts, int32_t count);
// Frees the calling thread's strings built by rlf_format/rlf_concat.
void rlf_strings_reset(void);

#ifdef __cplusplus
}
#endif
