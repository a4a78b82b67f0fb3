// Image formats Relief writes itself: PNG (the default output) and binary PNM. Every other format
// goes through the image-library plugin (runtime/image_library.h), so that rendering a scene to
// PNG never loads OpenImageIO. Used by film.cpp.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace relief {

// 8-bit interleaved pixels, rows top to bottom.
struct Image8 {
  int width = 0, height = 0;
  int channels = 3;  // 1 grey, 2 grey + alpha, 3 RGB, 4 RGBA (alpha unassociated, as PNG wants)
  const uint8_t* pixels = nullptr;
};

// PNG with zlib compression and per-row adaptive filters. `srgb`: a colour image (sRGB, gAMA and
// cHRM chunks); otherwise values encoded with the power 1/`gamma` (gAMA 1/gamma: 1 for data
// already mapped to [0, 1], 1/2.2 for a colour image under RiExposure's gamma 2.2). `text` pairs become
// tEXt chunks (keywords PNG cannot store are skipped). Returns false with the reason in *error.
// The rows are compressed in bands of fixed height, up to `threads` bands at once: the file's
// bytes depend on the image alone, never on the thread count.
bool writePng(const std::string& path, const Image8& image, bool srgb, float gamma,
              const std::vector<std::pair<std::string, std::string>>& text, std::string* error,
              int threads = 1);

// Binary PGM (1 channel) or PPM (3 channels); PNM has no alpha. False with the reason in *error.
bool writePnm(const std::string& path, const Image8& image, std::string* error);

}  // namespace relief
