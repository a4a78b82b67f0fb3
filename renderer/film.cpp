// Image storage and output (see film.h): PNG and PNM by image_formats.cpp, every other format
// through the image-library plugin (runtime/image_library.h), loaded only then.
#include "renderer/film.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <thread>

#include "renderer/image_formats.h"
#include "runtime/image_library.h"

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

namespace {
std::string lowerExtension(const std::string& path) {
  std::string extension = fs::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return extension;
}
// PNG and PNM are written here (image_formats.cpp), everything else by the image library.
bool ownFormat(const std::string& extension) {
  return extension == ".png" || extension == ".ppm" || extension == ".pgm" || extension == ".pnm";
}
}  // namespace

bool isFloatFormat(const std::string& path) {
  const std::string extension = lowerExtension(path);
  return extension == ".exr" || extension == ".hdr";
}

Film alphaForDisplay(const Film& film) {
  Film out(film.width(), film.height());
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x) out.setPixel(x, y, glm::vec3(film.alpha(x, y)), 1.0f);
  return out;
}

Film depthForDisplay(const Film& depth) {
  float lo = 0.0f, hi = 0.0f;
  bool any = false;
  for (int y = 0; y < depth.height(); ++y)
    for (int x = 0; x < depth.width(); ++x) {
      const float z = depth.pixel(x, y).r;
      if (!(z > 0.0f) || !std::isfinite(z)) continue;
      lo = any ? std::min(lo, z) : z;
      hi = any ? std::max(hi, z) : z;
      any = true;
    }
  Film out(depth.width(), depth.height());
  for (int y = 0; y < depth.height(); ++y)
    for (int x = 0; x < depth.width(); ++x) {
      const float z = depth.pixel(x, y).r;
      if (!(z > 0.0f) || !std::isfinite(z)) continue;
      const float v = hi > lo ? 1.0f - 0.8f * (z - lo) / (hi - lo) : 1.0f;
      out.setPixel(x, y, glm::vec3(v), 1.0f);
    }
  return out;
}

Film normalForDisplay(const Film& normal) {
  Film out(normal.width(), normal.height());
  for (int y = 0; y < normal.height(); ++y)
    for (int x = 0; x < normal.width(); ++x)
      if (normal.alpha(x, y) > 0.0f)
        out.setPixel(x, y, 0.5f + 0.5f * normal.pixel(x, y), 1.0f);
  return out;
}

Film heatMapForDisplay(const Film& counts) {
  float most = 0.0f;
  for (int y = 0; y < counts.height(); ++y)
    for (int x = 0; x < counts.width(); ++x) most = std::max(most, counts.pixel(x, y).r);
  Film out(counts.width(), counts.height());
  for (int y = 0; y < counts.height(); ++y)
    for (int x = 0; x < counts.width(); ++x) {
      const float t = most > 0.0f ? counts.pixel(x, y).r / most : 0.0f;
      // Three equal ramps: black to red, red to yellow, yellow to white.
      const glm::vec3 c(std::clamp(3.0f * t, 0.0f, 1.0f), std::clamp(3.0f * t - 1.0f, 0.0f, 1.0f),
                        std::clamp(3.0f * t - 2.0f, 0.0f, 1.0f));
      out.setPixel(x, y, c, 1.0f);
    }
  return out;
}

bool canWriteFormat(const std::string& path, bool alpha, std::string* error) {
  const std::string extension = lowerExtension(path);
  if (extension.empty()) {
    *error = "cannot write '" + path + "': no file extension to choose the image format";
    return false;
  }
  if (ownFormat(extension)) {
    if (!alpha || extension == ".png") return true;
    *error = "cannot write '" + path + "': PNM has no alpha channel (use png, tif or exr for \"rgba\")";
    return false;
  }
  std::string why;
  const RlfImageLibrary* library = runtime::imageLibrary(&why);
  char message[1024];
  message[0] = 0;
  if (library && library->canWrite(path.c_str(), alpha ? 1 : 0, message, sizeof message)) return true;
  *error = "cannot write '" + path + "': " + (library ? std::string(message) : why);
  return false;
}

bool Film::write(const std::string& path, std::string* error, bool withAlpha) const {
  ImageWriteOptions options;
  options.alpha = withAlpha;
  return write(path, error, options);
}

bool Film::write(const std::string& path, std::string* error, const ImageWriteOptions& options) const {
  std::string staged;
  return writeStaged(path, &staged, error, options) && commitStagedImage(staged, path, error);
}

bool commitStagedImage(const std::string& stagedPath, const std::string& path, std::string* error) {
  std::error_code ec;
  const fs::file_status target = fs::status(path, ec);
  if (!ec && fs::exists(target) && !fs::is_regular_file(target) && !fs::is_directory(target)) {
    // A device or a pipe (/dev/null, a FIFO): written through, as compilers do. Renaming over it
    // would replace it with a regular file (as root, even /dev/null).
    std::ifstream in(stagedPath, std::ios::binary);
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    if (out) out << in.rdbuf();
    const bool ok = in && out.good();
    std::error_code ignored;
    fs::remove(stagedPath, ignored);
    if (!ok) *error = "cannot write '" + path + "': " + std::strerror(errno);
    return ok;
  }
  fs::rename(stagedPath, path, ec);
  if (!ec) return true;
  std::error_code ignored;
  fs::remove(stagedPath, ignored);
  *error = "cannot write '" + path + "': " + ec.message();
  return false;
}

void Film::applyExposure(float gain, float gamma) {
  if (gain == 1.0f && gamma == 1.0f) return;
  const float power = 1.0f / gamma;
  for (size_t i = 0; i < alpha_.size(); ++i) {
    const float a = alpha_[i];
    for (int c = 0; c < 3; ++c) {
      float& v = rgb_[3 * i + size_t(c)];
      const float straight = a > 0.0f && a < 1.0f ? v / a : v;
      const float exposed = straight > 0.0f ? std::pow(straight * gain, power) : straight * gain;
      v = a > 0.0f && a < 1.0f ? exposed * a : exposed;
    }
  }
}

bool Film::writeStaged(const std::string& path, std::string* stagedPath, std::string* error,
                       const ImageWriteOptions& options) const {
  const bool withAlpha = options.alpha;
  if (!canWriteFormat(path, withAlpha, error)) return false;
  const std::string extension = lowerExtension(path);
  const bool floatOutput = isFloatFormat(path);
  // A PGM holds grey: colour becomes its luminance (Rec. 709 weights, on linear values).
  const bool grey = options.channels != 1 && extension == ".pgm";
  const int colourChannels = options.channels == 1 || grey ? 1 : 3;
  const bool withDepth = options.depth != nullptr;
  if (withDepth && (!floatOutput || options.depth->width() != width_ || options.depth->height() != height_)) {
    *error = "cannot write '" + path + "': a depth channel needs a float format (exr)";
    return false;
  }
  const int channels = colourChannels + (withAlpha ? 1 : 0) + (withDepth ? 1 : 0);
  const size_t numPixels = size_t(width_) * size_t(height_);
  std::vector<float> floats;
  std::vector<uint8_t> bytes;
  const void* pixels;
  if (floatOutput) {
    floats.resize(numPixels * size_t(channels));
    for (size_t i = 0; i < numPixels; ++i)
      for (int c = 0; c < channels; ++c) {
        const float v = c < colourChannels                  ? rgb_[3 * i + size_t(c)]
                        : withAlpha && c == colourChannels ? alpha_[i]
                                                           : options.depth->rgb_[3 * i];
        floats[i * size_t(channels) + size_t(c)] = std::isfinite(v) ? v : 0.0f;
      }
    pixels = floats.data();
  } else {
    bytes.resize(numPixels * size_t(channels));
    auto encode = [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) {
        const float a = std::clamp(alpha_[i], 0.0f, 1.0f);
        // Colour is premultiplied; PNG wants it straight, and encoded after the division.
        const float scale = withAlpha && a > 0.0f ? 1.0f / a : 1.0f;
        for (int c = 0; c < colourChannels; ++c) {
          const float* p = &rgb_[3 * i];
          const float v = (grey ? 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2] : p[c]) * scale;
          const float encoded = options.srgb ? linearToSrgb(v) : (v > 0.0f ? std::min(v, 1.0f) : 0.0f);
          bytes[i * size_t(channels) + size_t(c)] = uint8_t(std::lround(encoded * 255.0f));
        }
        if (withAlpha)
          bytes[i * size_t(channels) + size_t(colourChannels)] = uint8_t(std::lround(a * 255.0f));
      }
    };
    // The sRGB curve's pow per channel is most of this loop: split the pixels among the threads
    // (each pixel's bytes are its own, so the split changes nothing).
    const size_t parts = size_t(std::clamp<int64_t>(options.threads, 1, int64_t(numPixels / 65536) + 1));
    std::vector<std::thread> helpers;
    for (size_t k = 1; k < parts; ++k) helpers.emplace_back(encode, numPixels * k / parts, numPixels * (k + 1) / parts);
    encode(0, numPixels / parts);
    for (std::thread& h : helpers) h.join();
    pixels = bytes.data();
  }

  // Same directory, so the final rename is atomic; same extension, in case a plugin checks it. The
  // counter keeps two staged images of one process apart (two displays may name one file).
  static std::atomic<uint64_t> stagedCount{0};
  const fs::path target(path);
  std::string tempName = ".";
  tempName += target.stem().string();
  tempName += ".tmp";
  tempName += std::to_string(::getpid());
  tempName += "-";
  tempName += std::to_string(stagedCount++);
  tempName += target.extension().string();
  const fs::path temp = target.parent_path() / tempName;
  std::string writeError;
  bool ok;
  if (ownFormat(extension)) {
    const Image8 image{width_, height_, channels, bytes.data()};
    ok = extension == ".png" ? writePng(temp.string(), image, options.srgb, options.gamma, options.metadata, &writeError, options.threads)
                             : writePnm(temp.string(), image, &writeError);
  } else if (const RlfImageLibrary* library = runtime::imageLibrary(&writeError)) {
    std::vector<const char*> names, metadata;
    if (!options.channelNames.empty() && int(options.channelNames.size()) == channels)
      for (const std::string& n : options.channelNames) names.push_back(n.c_str());
    for (const auto& [name, value] : options.metadata) metadata.push_back(name.c_str()), metadata.push_back(value.c_str());
    metadata.push_back(nullptr);
    char message[1024];
    message[0] = 0;
    ok = library->writeImage(temp.string().c_str(), width_, height_, channels, floatOutput ? 1 : 0, pixels,
                             withAlpha ? colourChannels : -1, withAlpha && !floatOutput ? 1 : 0,
                             floatOutput || !options.srgb ? "linear" : "sRGB", names.empty() ? nullptr : names.data(),
                             metadata.data(), message, sizeof message) != 0;
    writeError = message;
    // OpenImageIO names the file it was given, the staged one; the user knows the final name.
    for (size_t at = 0; (at = writeError.find(temp.string(), at)) != std::string::npos; at += path.size())
      writeError.replace(at, temp.string().size(), path);
  } else {
    ok = false;
  }
  if (!ok) {
    std::error_code ignored;
    fs::remove(temp, ignored);
    *error = "cannot write '" + path + "': " + (writeError.empty() ? "write failed" : writeError);
    return false;
  }
  *stagedPath = temp.string();
  return true;
}

}  // namespace relief
