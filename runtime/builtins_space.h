// Coordinate spaces named at run time (language.md §2.3: a non-literal space name). extern "C",
// noexcept; registered with the JIT by compiler/builtins.cpp.
#pragma once

#include <stdint.h>

#include "runtime/abi.h"

#ifdef __cplusplus
extern "C" {
#endif

// Writes the row-major matrices currentFromSpace and spaceFromCurrent of `name`. Returns 0 (and
// writes identities) for an unknown name, which the caller counts in RlfStatus::unknownSpace.
int32_t rlf_space_matrices(const RlfSpaces* spaces, const char* name, float* currentFromSpace,
                           float* spaceFromCurrent);

#ifdef __cplusplus
}
#endif
