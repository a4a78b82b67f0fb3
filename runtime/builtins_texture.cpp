// Texture lookups for JIT-compiled shaders (see builtins_texture.h). The fallback TextureSystem is
// shared by all threads (OIIO's is thread-safe) and lives for the whole process.
#include "runtime/builtins_texture.h"

#include <OpenImageIO/texture.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace {

OIIO::TextureSystem* textureSystem() {
  static OIIO::TextureSystem* ts = [] {
    OIIO::TextureSystem* t = OIIO::TextureSystem::create(true);
    t->attribute("automip", 1);
    return t;
  }();
  return ts;
}

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
void recordFailure(const char* filename, const std::string& why) {
  FailureLog& log = failureLog();
  std::lock_guard lock(log.mutex);
  if (!log.seen.insert(filename).second) return;
  log.pending.push_back(filename);
  std::fprintf(stderr, "%s: error: cannot read texture '%s'%s%s; using the fill value\n",
               log.program.c_str(), filename, why.empty() ? "" : ": ", why.c_str());
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
  if (!filename || !*filename) {
    fillMissing(options, nchannels, out, dout_ds, dout_dt);
    return 0;
  }
  if (services && services->texture) {
    const int ok = services->texture(services->context, filename, s, t, dsdx, dtdx, dsdy, dtdy, options, nchannels,
                                     out, dout_ds, dout_dt);
    if (!ok) fillMissing(options, nchannels, out, dout_ds, dout_dt);
    return ok ? 1 : 0;
  }
  try {
    OIIO::TextureOpt opt;
    if (options) {
      opt.sblur = options->sblur;
      opt.tblur = options->tblur;
      opt.swidth = options->swidth;
      opt.twidth = options->twidth;
      opt.fill = options->fill;
      opt.firstchannel = options->firstchannel;
      if (options->swrap) opt.swrap = OIIO::TextureOpt::decode_wrapmode(options->swrap);
      if (options->twrap) opt.twrap = OIIO::TextureOpt::decode_wrapmode(options->twrap);
    }
    const bool ok = textureSystem()->texture(OIIO::ustring(filename), opt, s, t, dsdx, dtdx, dsdy, dtdy, nchannels,
                                             out, dout_ds, dout_dt);
    if (!ok) {
      // Clear the per-thread message; the host counts failures, the first one per file is printed.
      std::string why = textureSystem()->geterror();
      if (const size_t nl = why.find('\n'); nl != std::string::npos) why.resize(nl);
      if (!options || !options->hasMissingColor) recordFailure(filename, why);
      fillMissing(options, nchannels, out, dout_ds, dout_dt);
      return 0;
    }
    return 1;
  } catch (...) {
    // Nothing may unwind through JIT frames.
    fillMissing(options, nchannels, out, dout_ds, dout_dt);
    return 0;
  }
}

namespace relief::runtime {

void setTextureSearchPath(const std::vector<std::string>& dirs) {
  std::string joined;
  for (const std::string& d : dirs) joined += (joined.empty() ? "" : ":") + d;
  // OIIO tries a relative name against the working directory first, then these directories.
  textureSystem()->attribute("searchpath", joined);
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
