// The image-library plugin (librelief_oiio.so): everything Relief asks of OpenImageIO, behind the C
// table of runtime/image_library.h. The only file of the project that includes OpenImageIO
// headers outside tests and benchmarks. Exceptions never leave it.
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <OpenImageIO/texture.h>

#include "runtime/image_library.h"

namespace {

OIIO::TextureSystem* textureSystem() {
  static OIIO::TextureSystem* ts = [] {
    OIIO::TextureSystem* t = OIIO::TextureSystem::create(true);
    t->attribute("automip", 1);
    // Texture channels are data (heights, masks): an RGBA file's colour comes back as stored, not
    // multiplied by its alpha (OpenImageIO associates alpha by default, so a height under alpha
    // 0.5 read as half of itself).
    t->attribute("unassociatedalpha", 1);
    return t;
  }();
  return ts;
}

void copyMessage(const std::string& message, char* buffer, size_t size) {
  if (!buffer || size == 0) return;
  std::snprintf(buffer, size, "%s", message.c_str());
}

// Runs `body` (which returns 1 or 0), turning any exception into 0 and its message: none may
// cross the C table into the host.
template <typename Body>
int32_t guarded(char* error, size_t errorSize, Body&& body) {
  try {
    return body();
  } catch (const std::exception& e) {
    copyMessage(e.what(), error, errorSize);
  } catch (...) {
    copyMessage("internal error in OpenImageIO", error, errorSize);
  }
  return 0;
}

// The texture search path as last set (setTextureSearchPath), for nameInfo.
std::mutex searchPathMutex;
std::string searchPathJoined;
std::atomic<uint64_t> searchPathGeneration{0};  // bumped by every setTextureSearchPath

// What is known of a texture name on this thread, by the ustring text pointer that identifies
// it; dropped when the search path changes (a new frame's may resolve the name elsewhere).
struct NameInfo {
  bool regular = true;  // no device or pipe where OpenImageIO would look (its probes read /dev/zero for ever)
  bool found = false;   // some candidate exists
  std::string path;     // the first candidate that exists
  std::string searched; // the search path's directories, for "not found"
  int channels = -2;    // the file's channel count once asked (channelCount); -1: unreadable
};
NameInfo& nameInfo(OIIO::ustring name) {
  thread_local std::unordered_map<const char*, NameInfo> known;
  thread_local uint64_t knownGeneration = 0;
  if (const uint64_t g = searchPathGeneration.load(std::memory_order_acquire); g != knownGeneration)
    known.clear(), knownGeneration = g;
  const auto [it, added] = known.try_emplace(name.c_str());
  if (!added) return it->second;
  std::vector<std::filesystem::path> candidates{std::filesystem::path(name.string())};
  if (!candidates[0].is_absolute()) {
    std::string joined;
    {
      std::lock_guard lock(searchPathMutex);
      joined = searchPathJoined;
    }
    std::stringstream dirs(joined);
    for (std::string dir; std::getline(dirs, dir, ':');)
      if (!dir.empty()) candidates.push_back(std::filesystem::path(dir) / name.string());
    it->second.searched = joined;
  }
  for (const std::filesystem::path& candidate : candidates) {
    std::error_code ec;
    const std::filesystem::file_status status = std::filesystem::status(candidate, ec);
    if (ec || !std::filesystem::exists(status)) continue;
    it->second.regular = std::filesystem::is_regular_file(status);
    it->second.found = true;
    it->second.path = candidate.string();
    break;
  }
  return it->second;
}

// Why a lookup of a file that exists failed, the same on every thread: OpenImageIO tells only the
// first thread to fail on a broken file, so the thread whose failure was reported first could
// have no reason to give. Asked once per file, of the file itself.
std::string failureReason(const NameInfo& info, const std::string& message) {
  static std::mutex mutex;
  static std::unordered_map<std::string, std::string> reasons;
  std::lock_guard lock(mutex);
  std::string& reason = reasons[info.path];
  if (reason.empty()) {
    if (!message.empty()) {
      reason = message;
    } else if (auto in = OIIO::ImageInput::open(info.path)) {
      reason = "OpenImageIO could not read it as a texture";
    } else {
      reason = OIIO::geterror();
      if (const size_t nl = reason.find('\n'); nl != std::string::npos) reason.resize(nl);
      if (reason.empty()) reason = "OpenImageIO could not read it";
    }
  }
  return reason;
}

// The file's channel count, or -1 when it cannot be read (the lookup itself then reports why).
int channelCount(OIIO::ustring name, NameInfo& info) {
  if (info.channels == -2) {
    int channels = 0;
    if (!textureSystem()->get_texture_info(name, 0, OIIO::ustring("channels"), OIIO::TypeDesc::INT, &channels)) {
      (void)textureSystem()->geterror();
      channels = -1;
    }
    info.channels = channels;
  }
  return info.channels;
}

int32_t texture(const char* filename, float s, float t, float dsdx, float dtdx, float dsdy, float dtdy,
                const RlfTextureOptions* options, int32_t nchannels, float* out, float* dout_ds, float* dout_dt,
                char* why, size_t whySize) {
  return guarded(why, whySize, [&]() -> int32_t {
    const OIIO::ustring name(filename);
    NameInfo& info = nameInfo(name);
    if (!info.regular) {
      copyMessage("not a regular file", why, whySize);
      return 0;
    }
    if (!info.found) {
      copyMessage(info.searched.empty() ? "no such file" : "no such file (texture search path '" + info.searched + "')", why,
                  whySize);
      return 0;
    }
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
    // A lookup with no footprint ("width" 0, or coordinates that do not vary) and no blur is a
    // point sample, as in RenderMan: bilinear between texels, so a texel's centre returns it.
    // OpenImageIO's default would magnify with a B-spline, which blurs even there.
    const bool noS = opt.swidth == 0.0f || (dsdx == 0.0f && dsdy == 0.0f);
    const bool noT = opt.twidth == 0.0f || (dtdx == 0.0f && dtdy == 0.0f);
    if (noS && noT && opt.sblur == 0.0f && opt.tblur == 0.0f) opt.interpmode = OIIO::TextureOpt::InterpBilinear;
    // Channels the file lacks are `fill` (language.md 6.7). OpenImageIO handles that past the
    // first channel, but a first channel beyond the file's, or a negative one, asserts (and reads
    // out of bounds), so such a lookup is answered here; the first channel is 0 in most lookups
    // and needs no count.
    if (opt.firstchannel != 0) {
      const int channels = channelCount(name, info);
      if (channels < 0 && opt.firstchannel < 0) opt.firstchannel = 0;  // unreadable: let the lookup say why
      if (channels >= 0 && (opt.firstchannel < 0 || opt.firstchannel >= channels)) {
        for (int32_t c = 0; c < nchannels; ++c) {
          out[c] = opt.fill;
          if (dout_ds) dout_ds[c] = 0.0f;
          if (dout_dt) dout_dt[c] = 0.0f;
        }
        return 1;
      }
    }
    if (textureSystem()->texture(name, opt, s, t, dsdx, dtdx, dsdy, dtdy, nchannels, out, dout_ds,
                                 dout_dt))
      return 1;
    // Taking the message also clears it from this thread's error state.
    std::string message = textureSystem()->geterror();
    if (const size_t nl = message.find('\n'); nl != std::string::npos) message.resize(nl);
    copyMessage(failureReason(info, message), why, whySize);
    return 0;
  });
}

void setTextureSearchPath(const char* joined) {
  try {
    {
      std::lock_guard lock(searchPathMutex);
      searchPathJoined = joined ? joined : "";
    }
    searchPathGeneration.fetch_add(1, std::memory_order_acq_rel);
    textureSystem()->attribute("searchpath", std::string(joined ? joined : ""));
  } catch (...) {
  }
}

int32_t writeImage(const char* path, int32_t width, int32_t height, int32_t channels, int32_t floatPixels,
                   const void* pixels, int32_t alphaChannel, int32_t unassociatedAlpha, const char* colorSpace,
                   const char* const* channelNames, const char* const* metadata, char* error, size_t errorSize) {
  return guarded(error, errorSize, [&]() -> int32_t {
    auto out = OIIO::ImageOutput::create(path);
    if (!out) {
      copyMessage(OIIO::geterror(), error, errorSize);
      return 0;
    }
    const OIIO::TypeDesc format = floatPixels ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
    OIIO::ImageSpec spec(width, height, channels, format);
    spec.attribute("oiio:ColorSpace", colorSpace ? colorSpace : "sRGB");
    spec.attribute("Software", "relief");
    for (const char* const* m = metadata; m && m[0]; m += 2) {
      // The pixel aspect ratio (RI Format's third value) is the formats' own float attribute.
      float aspect = 0.0f;
      if (std::string_view(m[0]) == "relief:pixelAspectRatio" && m[1] && std::sscanf(m[1], "%f", &aspect) == 1 &&
          aspect > 0.0f) {
        spec.attribute("PixelAspectRatio", aspect);
        continue;
      }
      spec.attribute(m[0], m[1] ? m[1] : "");
      // "x y fullWidth fullHeight": the image is that crop of a larger one (RI CropWindow).
      int x = 0, y = 0, fullWidth = 0, fullHeight = 0;
      if (std::string_view(m[0]) == "relief:dataWindow" && m[1] &&
          std::sscanf(m[1], "%d %d %d %d", &x, &y, &fullWidth, &fullHeight) == 4) {
        spec.x = x, spec.y = y;
        spec.full_x = 0, spec.full_y = 0;
        spec.full_width = fullWidth, spec.full_height = fullHeight;
      }
    }
    if (channelNames) spec.channelnames.assign(channelNames, channelNames + channels);
    if (alphaChannel >= 0) {
      spec.alpha_channel = alphaChannel;
      if (unassociatedAlpha) spec.attribute("oiio:UnassociatedAlpha", 1);
    }
    if (!out->open(path, spec)) {
      copyMessage(out->geterror(), error, errorSize);
      return 0;
    }
    const bool ok = out->write_image(format, pixels);
    std::string message = ok ? std::string() : out->geterror();
    if (!out->close() && ok) message = out->geterror();
    if (!ok || !message.empty()) {
      copyMessage(message.empty() ? "write failed" : message, error, errorSize);
      return 0;
    }
    return 1;
  });
}

int32_t canWrite(const char* path, int32_t alpha, char* error, size_t errorSize) {
  return guarded(error, errorSize, [&]() -> int32_t {
    auto out = OIIO::ImageOutput::create(path);
    if (!out) {
      copyMessage(OIIO::geterror(), error, errorSize);
      return 0;
    }
    // A JPEG asked for rgba would be written as rgb in silence.
    if (alpha && !out->supports("alpha")) {
      copyMessage(std::string("the ") + out->format_name() +
                      " format has no alpha channel (use png, tif or exr for \"rgba\")",
                  error, errorSize);
      return 0;
    }
    return 1;
  });
}

const RlfImageLibrary kTable = {
    RLF_IMAGE_LIBRARY_VERSION, sizeof(RlfImageLibrary), texture, setTextureSearchPath, writeImage, canWrite,
};

}  // namespace

extern "C" __attribute__((visibility("default"))) const RlfImageLibrary* rlf_image_library(void) { return &kTable; }
