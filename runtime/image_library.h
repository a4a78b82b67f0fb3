// The image library: Relief's OpenImageIO half (texture lookups, image formats other than PNG and
// PNM), built as a plugin and loaded on first use. Debian's OpenImageIO brings about 260 shared
// libraries into any process that links it: binding them costs every run 0.2 s and ~125 MB of
// resident memory before main(), which a scene without textures, written to PNG, never needs.
// The table below is the whole interface, plain C so that no C++ type crosses the boundary.
// Used by builtins_texture.cpp and renderer/film.cpp; implemented in runtime/oiio/.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "runtime/builtins_texture.h"

#ifdef __cplusplus
extern "C" {
#endif

// Bumped whenever the table changes; a plugin of another version is refused (a stale build).
#define RLF_IMAGE_LIBRARY_VERSION 3

typedef struct RlfImageLibrary {
  uint32_t version;  // RLF_IMAGE_LIBRARY_VERSION
  uint32_t size;     // sizeof(RlfImageLibrary)
  // Filtered lookup through one process-wide TextureSystem (thread-safe). Returns 0 on failure
  // and then writes a one-line reason (truncated) to why[0..whySize).
  int32_t (*texture)(const char* filename, float s, float t, float dsdx, float dtdx, float dsdy, float dtdy,
                     const RlfTextureOptions* options, int32_t nchannels, float* out, float* dout_ds,
                     float* dout_dt, char* why, size_t whySize);
  // ':'-separated directories tried for relative texture names after the working directory.
  void (*setTextureSearchPath)(const char* joined);
  // Writes width x height pixels of `channels` interleaved values (float if floatPixels, else
  // uint8) to `path`, whose extension names the format. alphaChannel < 0: none. colorSpace:
  // "sRGB" or "linear". channelNames: null or `channels` names. metadata: null or name, value
  // pairs ending with a null name. Returns 0 with a message in error[0..errorSize) on failure.
  int32_t (*writeImage)(const char* path, int32_t width, int32_t height, int32_t channels, int32_t floatPixels,
                        const void* pixels, int32_t alphaChannel, int32_t unassociatedAlpha, const char* colorSpace,
                        const char* const* channelNames, const char* const* metadata, char* error,
                        size_t errorSize);
  // Whether an image format writer exists for `path`'s extension (nothing is created) and, if
  // `alpha`, whether that format stores an alpha channel. Returns 0 with the reason in
  // error[0..errorSize) if not.
  int32_t (*canWrite)(const char* path, int32_t alpha, char* error, size_t errorSize);
} RlfImageLibrary;

// The plugin's one exported symbol.
const RlfImageLibrary* rlf_image_library(void);

#ifdef __cplusplus
}
#endif

#ifdef __cplusplus
#include <string>
namespace relief::runtime {
// Loads the plugin once per process (thread-safe) and returns its table, or null with *why set
// (on every call) when it cannot be loaded. Looked for at $RELIEF_IMAGE_LIBRARY if set, else
// where `cmake --install` puts it relative to the executable (<libdir>/relief/), else in the
// build tree.
const RlfImageLibrary* imageLibrary(std::string* why = nullptr);
// Whether imageLibrary() has loaded it (tests: a PNG render must not).
bool imageLibraryLoaded();
}  // namespace relief::runtime
#endif
