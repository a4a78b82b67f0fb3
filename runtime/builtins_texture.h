// Texture lookups called by JIT-compiled shaders (language.md §6.7): extern "C", noexcept. Uses the
// host's RlfHostServices::texture when given, else a process-wide OpenImageIO TextureSystem.
// Registered with the JIT by compiler/builtins.cpp.
#pragma once

#include <stdint.h>

#include "runtime/abi.h"

#ifdef __cplusplus
extern "C" {
#endif

// What the `options` pointer of a texture lookup points to (also RlfHostServices::texture's
// `options`). Filled by generated code from a call's "name", value pairs.
typedef struct RlfTextureOptions {
  float sblur, tblur;    // texture-coordinate units
  float swidth, twidth;  // footprint multipliers
  float fill;            // value of absent channels
  float missingcolor[3];
  int32_t hasMissingColor;  // 0: an unreadable file yields `fill` and counts an error
  int32_t firstchannel;
  const char* swrap;  // "default" "black" "clamp" "periodic" "mirror"; null: default
  const char* twrap;
} RlfTextureOptions;

// Looks up `nchannels` (1..4) channels; writes values and their derivatives with respect to s and t.
// Returns 0 on failure (out then holds missingcolor or fill).
int32_t rlf_texture(const RlfHostServices* services, const char* filename, float s, float t, float dsdx,
                    float dtdx, float dsdy, float dtdy, const RlfTextureOptions* options, int32_t nchannels,
                    float* out, float* dout_ds, float* dout_dt);

#ifdef __cplusplus
}
#endif

#ifdef __cplusplus
#include <string>
#include <vector>
namespace relief::runtime {
// Names of texture files that failed to read through the shared TextureSystem since the last call,
// each at most once per process (its first failure is also printed to stderr).
std::vector<std::string> takeTextureFailures();
// The program named at the start of the message printed for an unreadable texture, as every other
// message of that program starts ("relief: error: ..."); "relief" until set.
void setTextureMessageProgram(const std::string& name);
// Directories searched, in order, for texture names that are relative and not found from the
// working directory (the renderer passes the scene's Option "searchpath" "texture").
void setTextureSearchPath(const std::vector<std::string>& dirs);
}  // namespace relief::runtime
#endif
