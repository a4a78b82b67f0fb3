// Texture lookups for JIT-compiled shaders (see builtins_texture.h). The fallback TextureSystem is
// the image library's (image_library.h), shared by all threads and alive for the whole process;
// the first lookup loads that library.
#include "runtime/builtins_texture.h"

#include "runtime/image_library.h"

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace {

// Files that failed to read, each reported once per process (language.md §6.7: one runtime error per
// file name); `pending` holds those the host has not taken yet.
struct FailureLog {
  std::mutex mutex;
  std::set<std::string> seen;
  std::vector<std::string> pending;
  std::string program = "relief";  // prefixes the printed message
};
FailureLog& failureLog() {
  static FailureLog log;
  return log;
}
// Said at the scene line that bound the shader when the host tells it (the first shader to miss
// the file is named), else under the program's name.
void recordFailure(const char* filename, const std::string& why, const RlfHostServices* services) {
  FailureLog& log = failureLog();
  std::lock_guard lock(log.mutex);
  if (!log.seen.insert(filename).second) return;
  log.pending.push_back(filename);
  const char* origin = services && services->origin ? services->origin : log.program.c_str();
  const bool subject = services && services->subject;
  std::fprintf(stderr, "%s: error: %s%scannot read texture '%s'%s%s; using the fill value\n", origin,
               subject ? services->subject : "", subject ? ": " : "", filename, why.empty() ? "" : ": ",
               why.c_str());
}

// A wrap mode named at run time (a string parameter) that is none of the modes: said once per
// name, as a failed file is, and the lookup uses "default" (a literal one is a compile error).
void checkWrapModes(const RlfTextureOptions* options, const RlfHostServices* services) {
  if (!options) return;
  for (const char* mode : {options->swrap, options->twrap}) {
    if (!mode) continue;
    const std::string_view m(mode);
    if (m == "default" || m == "black" || m == "clamp" || m == "periodic" || m == "mirror") continue;
    FailureLog& log = failureLog();
    std::lock_guard lock(log.mutex);
    if (!log.seen.insert("\x01wrap:" + std::string(m)).second) continue;
    const char* origin = services && services->origin ? services->origin : log.program.c_str();
    const bool subject = services && services->subject;
    std::fprintf(stderr,
                 "%s: warning: %s%sunknown texture wrap mode '%s' (the modes are \"default\", \"black\", "
                 "\"clamp\", \"periodic\" and \"mirror\"); \"default\" used\n",
                 origin, subject ? services->subject : "", subject ? ": " : "", mode);
  }
}

// The texture search path, handed to the library when it is loaded and whenever it changes after.
struct SearchPath {
  std::mutex mutex;
  std::string joined;
  std::atomic<uint64_t> generation{0};  // bumped by every setTextureSearchPath
  std::atomic<uint64_t> applied{0};     // the generation the library has
};
SearchPath& searchPath() {
  static SearchPath path;
  return path;
}

const RlfImageLibrary* textureLibrary(std::string* why) {
  const RlfImageLibrary* library = relief::runtime::imageLibrary(why);
  SearchPath& path = searchPath();
  if (library && path.applied.load(std::memory_order_acquire) != path.generation.load(std::memory_order_acquire)) {
    std::lock_guard lock(path.mutex);
    const uint64_t generation = path.generation.load(std::memory_order_relaxed);
    if (path.applied.load(std::memory_order_relaxed) != generation) {  // another thread may have
      library->setTextureSearchPath(path.joined.c_str());
      path.applied.store(generation, std::memory_order_release);
    }
  }
  return library;
}

void fillMissing(const RlfTextureOptions* o, int32_t n, float* out, float* ds, float* dt) {
  for (int32_t c = 0; c < n; ++c) {
    out[c] = o && o->hasMissingColor && c < 3 ? o->missingcolor[c] : (o ? o->fill : 0.0f);
    ds[c] = dt[c] = 0;
  }
}

}  // namespace

extern "C" int32_t rlf_texture(const RlfHostServices* services, const char* filename, float s, float t, float dsdx,
                               float dtdx, float dsdy, float dtdy, const RlfTextureOptions* options,
                               int32_t nchannels, float* out, float* dout_ds, float* dout_dt) {
  nchannels = std::clamp<int32_t>(nchannels, 1, 4);
  const bool named = filename && *filename;
  if (options && (options->swrap || options->twrap)) {
    try {
      checkWrapModes(options, services);
    } catch (...) {
    }
  }
  if (named && services && services->texture) {
    const int ok = services->texture(services->context, filename, s, t, dsdx, dtdx, dsdy, dtdy, options, nchannels,
                                     out, dout_ds, dout_dt);
    if (!ok) fillMissing(options, nchannels, out, dout_ds, dout_dt);
    return ok ? 1 : 0;
  }
  // Nothing may unwind through JIT frames. The host counts failures; the first per file is printed.
  try {
    // An empty name is unreadable like any missing file (language.md 6.7: one runtime error per
    // file name).
    std::string why = named ? "" : "the file name is empty";
    if (const RlfImageLibrary* library = named ? textureLibrary(&why) : nullptr) {
      char message[512];
      message[0] = 0;
      if (library->texture(filename, s, t, dsdx, dtdx, dsdy, dtdy, options, nchannels, out, dout_ds, dout_dt,
                           message, sizeof message))
        return 1;
      why = message;
    }
    if (!options || !options->hasMissingColor) recordFailure(named ? filename : "", why, services);
  } catch (...) {
  }
  fillMissing(options, nchannels, out, dout_ds, dout_dt);
  return 0;
}

namespace relief::runtime {

void setTextureSearchPath(const std::vector<std::string>& dirs) {
  std::string joined;
  for (const std::string& d : dirs) joined += (joined.empty() ? "" : ":") + d;
  // OpenImageIO tries a relative name against the working directory first, then these directories.
  // The library may not be loaded yet (it is on the first lookup): the next lookup hands it over.
  SearchPath& path = searchPath();
  std::lock_guard lock(path.mutex);
  path.joined = joined;
  path.generation.fetch_add(1, std::memory_order_release);
}

void setTextureMessageProgram(const std::string& name) {
  FailureLog& log = failureLog();
  std::lock_guard lock(log.mutex);
  log.program = name;
}

std::vector<std::string> takeTextureFailures() {
  FailureLog& log = failureLog();
  std::lock_guard lock(log.mutex);
  return std::exchange(log.pending, {});
}

}  // namespace relief::runtime
