// Run-time lookup of named coordinate spaces (see builtins_space.h).
#include "runtime/builtins_space.h"

#include <cstring>

extern "C" int32_t rlf_space_matrices(const RlfSpaces* spaces, const char* name, float* currentFromSpace,
                                      float* spaceFromCurrent) {
  const float* to = nullptr;
  const float* from = nullptr;
  bool known = true;
  if (spaces && name) {
    if (!std::strcmp(name, "object")) {
      to = spaces->currentFromObject;
      from = spaces->objectFromCurrent;
    } else if (!std::strcmp(name, "shader")) {
      to = spaces->currentFromShader;
      from = spaces->shaderFromCurrent;
    } else if (!std::strcmp(name, "camera")) {
      to = spaces->currentFromCamera;
      from = spaces->cameraFromCurrent;
    } else {
      known = !std::strcmp(name, "current") || !std::strcmp(name, "world") || !std::strcmp(name, "common");
    }
  } else {
    known = false;
  }
  if (to && from) {
    std::memcpy(currentFromSpace, to, 16 * sizeof(float));
    std::memcpy(spaceFromCurrent, from, 16 * sizeof(float));
    return 1;
  }
  for (int i = 0; i < 16; ++i) currentFromSpace[i] = spaceFromCurrent[i] = (i % 5 == 0) ? 1.0f : 0.0f;
  return known ? 1 : 0;
}
