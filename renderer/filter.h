// Pixel reconstruction filters (RenderMan's PixelFilter): Gaussian (the default, RenderMan's
// 2 x 2 "gaussian"), Blackman-Harris (3 x 3) and box (1 x 1). The render loop weights every
// sample within the filter's support of a pixel centre and normalises by the weight sum.
#pragma once

#include <string_view>

namespace relief {

enum class FilterType { Gaussian, BlackmanHarris, Box };

// Parses "gaussian", "blackman-harris" or "box".
bool parseFilter(std::string_view text, FilterType* filter);
std::string_view filterName(FilterType filter);

struct PixelFilter {
  FilterType type = FilterType::Gaussian;
  float width = 2.0f;  // full support, in pixels; samples count when |dx|, |dy| < width / 2

  static PixelFilter make(FilterType type);
  float radius() const { return 0.5f * width; }
  // Weight of a sample at offset (dx, dy) pixels from the pixel centre; 0 outside the support.
  float weight(float dx, float dy) const;
};

}  // namespace relief
