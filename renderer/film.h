// The image being rendered: linear float RGB per pixel, written as PNG/PNM by Relief itself and in
// other formats through OpenImageIO (the image-library plugin, runtime/image_library.h). Pixels are
// written by exactly one thread each (the render loop owns a pixel until it is done), so the film
// needs no locking. Used by render.* and tools/relief.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

namespace relief {

// Largest image we accept (16 bytes a pixel: 2 GiB of film). Checked where resolutions come in
// (Format, --resolution) so a typo fails with a message rather than an allocation failure.
inline constexpr uint64_t kMaxPixels = uint64_t(1) << 27;

// How Film::write stores the pixels.
class Film;

struct ImageWriteOptions {
  bool alpha = false;  // a fourth channel with coverage (see Film::write)
  int channels = 3;    // 1: only the first colour channel (depth, counts), or 3
  std::vector<std::string> channelNames;  // empty: the format's defaults (R, G, B, A)
  // 8-bit formats: sRGB-encode (colour images) or scale linearly (data already mapped to [0, 1]).
  bool srgb = true;
  // Without srgb, the power the values were encoded with (RiExposure's gamma; 1 for data): PNG
  // records it (gAMA 1/gamma).
  float gamma = 1.0f;
  // String attributes stored in the file's header where the format has one (EXR, TIFF).
  std::vector<std::pair<std::string, std::string>> metadata;
  // Threads that may convert to 8 bits and compress a PNG (the bytes do not depend on how many).
  int threads = 1;
  // A last channel holding this film's first channel (camera depth for RenderMan's "rgbz" and
  // "rgbaz" modes); float formats only.
  const Film* depth = nullptr;
};

class Film {
 public:
  Film(int width, int height);

  int width() const { return width_; }
  int height() const { return height_; }

  // `alpha` is the pixel's coverage; rgb is premultiplied by it (misses contribute black).
  void setPixel(int x, int y, const glm::vec3& rgb, float alpha = 1.0f) {
    const size_t i = size_t(y) * size_t(width_) + size_t(x);
    float* p = &rgb_[3 * i];
    p[0] = rgb.r, p[1] = rgb.g, p[2] = rgb.b;
    alpha_[i] = alpha;
  }
  float alpha(int x, int y) const { return alpha_[size_t(y) * size_t(width_) + size_t(x)]; }
  glm::vec3 pixel(int x, int y) const {
    const float* p = &rgb_[3 * (size_t(y) * size_t(width_) + size_t(x))];
    return {p[0], p[1], p[2]};
  }
  const std::vector<float>& data() const { return rgb_; }
  // RI Exposure: each colour becomes (colour * gain)^(1 / gamma), on the unpremultiplied colour.
  void applyExposure(float gain, float gamma);

  // Writes the image; the format follows the extension (png, exr, tif, jpg, ...). Float formats
  // (exr, hdr) keep linear values; the others are sRGB-encoded 8-bit. The file appears atomically:
  // it is written under a temporary name in the same directory and renamed into place, so a failed
  // or interrupted render never leaves a partial image. Returns false with *error set.
  // With `withAlpha`, a fourth channel holds coverage (EXR: premultiplied colour, as EXR expects;
  // 8-bit formats: unpremultiplied before sRGB encoding, as PNG expects).
  bool write(const std::string& path, std::string* error, bool withAlpha = false) const;
  bool write(const std::string& path, std::string* error, const ImageWriteOptions& options) const;
  // The first half of write(), for several images that must appear together or not at all: the
  // image is complete under the temporary name *stagedPath (in path's directory) and the caller
  // renames it into place (commitStagedImage) or removes it. Nothing is left behind on failure.
  bool writeStaged(const std::string& path, std::string* stagedPath, std::string* error,
                   const ImageWriteOptions& options) const;

 private:
  int width_, height_;
  std::vector<float> rgb_;
  std::vector<float> alpha_;
};

// Renames an image written by Film::writeStaged to its final path (atomic within a directory);
// on failure removes the staged file and returns false with *error set.
bool commitStagedImage(const std::string& stagedPath, const std::string& path, std::string* error);

// True for formats written as linear floats (exr, hdr), judged by the extension.
bool isFloatFormat(const std::string& path);

// Whether write() can produce `path`'s format, checked before a render so that a mistyped
// extension fails at once rather than after the render. Loads the image library for formats
// other than PNG and PNM. Returns false with *error set ("cannot write 'path': ...").
// `alpha`: the image would have a coverage channel (mode "rgba").
bool canWriteFormat(const std::string& path, bool alpha, std::string* error);

// Arbitrary output variables mapped for viewing in 8-bit formats (float formats keep raw values):
// depth as grey, near white to far black over the range of hits (misses black); normals as
// 0.5 + 0.5 N; cache misses as a black-red-yellow-white heat map scaled to the largest count.
// The film's alpha as grey (alpha 1): RenderMan's "a" display mode.
Film alphaForDisplay(const Film& film);
Film depthForDisplay(const Film& depth);
Film normalForDisplay(const Film& normal);
Film heatMapForDisplay(const Film& counts);

// Linear to sRGB transfer for one channel, clamped to [0, 1].
float linearToSrgb(float v);

}  // namespace relief
