// Texture lookups for JIT-compiled shaders (see builtins_texture.h). The fallback TextureSystem is
// shared by all threads (OIIO's is thread-safe) and lives for the whole process.
#include "runtime/builtins_texture.h"

#include <OpenImageIO/texture.h>

#include <algorithm>
#include <cstring>

namespace {

OIIO::TextureSystem* textureSystem() {
  static OIIO::TextureSystem* ts = [] {
    OIIO::TextureSystem* t = OIIO::TextureSystem::create(true);
    t->attribute("automip", 1);
    return t;
  }();
  return ts;
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
      (void)textureSystem()->geterror();  // clear the per-thread message; the host counts failures
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
