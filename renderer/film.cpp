// Image storage and OpenImageIO output (see film.h).
#include "renderer/film.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <system_error>

#include <OpenImageIO/imageio.h>

namespace relief {

namespace fs = std::filesystem;

Film::Film(int width, int height)
    : width_(std::max(width, 1)),
      height_(std::max(height, 1)),
      rgb_(size_t(width_) * size_t(height_) * 3, 0.0f),
      alpha_(size_t(width_) * size_t(height_), 0.0f) {}

float linearToSrgb(float v) {
  if (!(v > 0.0f)) return 0.0f;  // also maps NaN to black
  if (v >= 1.0f) return 1.0f;
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

bool Film::write(const std::string& path, std::string* error, bool withAlpha) const {
  std::string extension = fs::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  if (extension.empty()) {
    *error = "cannot write '" + path + "': no file extension to choose the image format";
    return false;
  }
  auto out = OIIO::ImageOutput::create(path);
  if (!out) {
    *error = "cannot write '" + path + "': " + OIIO::geterror();
    return false;
  }
  const bool floatOutput = extension == ".exr" || extension == ".hdr";
  const int channels = withAlpha ? 4 : 3;
  OIIO::ImageSpec spec(width_, height_, channels,
                       floatOutput ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", floatOutput ? "linear" : "sRGB");
  spec.attribute("Software", "relief");
  if (withAlpha) {
    spec.alpha_channel = 3;
    if (!floatOutput) spec.attribute("oiio:UnassociatedAlpha", 1);
  }

  const size_t numPixels = size_t(width_) * size_t(height_);
  std::vector<float> floats;
  std::vector<uint8_t> bytes;
  const void* pixels;
  if (floatOutput) {
    floats.resize(numPixels * size_t(channels));
    for (size_t i = 0; i < numPixels; ++i)
      for (int c = 0; c < channels; ++c) {
        const float v = c < 3 ? rgb_[3 * i + size_t(c)] : alpha_[i];
        floats[i * size_t(channels) + size_t(c)] = std::isfinite(v) ? v : 0.0f;
      }
    pixels = floats.data();
  } else {
    bytes.resize(numPixels * size_t(channels));
    for (size_t i = 0; i < numPixels; ++i) {
      const float a = std::clamp(alpha_[i], 0.0f, 1.0f);
      // Colour is premultiplied; PNG wants it straight, and encoded after the division.
      const float scale = withAlpha && a > 0.0f ? 1.0f / a : 1.0f;
      for (int c = 0; c < 3; ++c)
        bytes[i * size_t(channels) + size_t(c)] =
            uint8_t(std::lround(linearToSrgb(rgb_[3 * i + size_t(c)] * scale) * 255.0f));
      if (withAlpha) bytes[i * 4 + 3] = uint8_t(std::lround(a * 255.0f));
    }
    pixels = bytes.data();
  }

  // Same directory, so the final rename is atomic; same extension, in case a plugin checks it.
  const fs::path target(path);
  std::string tempName = ".";
  tempName += target.stem().string();
  tempName += ".tmp";
  tempName += std::to_string(::getpid());
  tempName += target.extension().string();
  const fs::path temp = target.parent_path() / tempName;
  if (!out->open(temp.string(), spec)) {
    *error = "cannot write '" + path + "': " + out->geterror();
    return false;
  }
  const bool ok = out->write_image(floatOutput ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8, pixels);
  std::string writeError = ok ? std::string() : out->geterror();
  if (!out->close() && ok) writeError = out->geterror();
  if (!ok || !writeError.empty()) {
    std::error_code ignored;
    fs::remove(temp, ignored);
    *error = "cannot write '" + path + "': " + (writeError.empty() ? "write failed" : writeError);
    return false;
  }
  std::error_code ec;
  fs::rename(temp, target, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(temp, ignored);
    *error = "cannot write '" + path + "': " + ec.message();
    return false;
  }
  return true;
}

}  // namespace relief
