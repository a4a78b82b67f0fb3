// Pixel reconstruction filters (see filter.h). Separable except the Gaussian, which RenderMan
// defines radially: exp(-2 (x'^2 + y'^2)) with x' = 2x / width.
#include "renderer/filter.h"

#include <cmath>

namespace relief {

bool parseFilter(std::string_view text, FilterType* filter) {
  if (text == "gaussian") *filter = FilterType::Gaussian;
  else if (text == "blackman-harris") *filter = FilterType::BlackmanHarris;
  else if (text == "box") *filter = FilterType::Box;
  else return false;
  return true;
}

std::string_view filterName(FilterType filter) {
  switch (filter) {
    case FilterType::Gaussian: return "gaussian";
    case FilterType::BlackmanHarris: return "blackman-harris";
    case FilterType::Box: return "box";
  }
  return "?";
}

PixelFilter PixelFilter::make(FilterType type) {
  PixelFilter f;
  f.type = type;
  f.width = type == FilterType::Gaussian ? 2.0f : type == FilterType::BlackmanHarris ? 3.0f : 1.0f;
  return f;
}

namespace {

// The 4-term Blackman-Harris window over [-width/2, width/2]; never negative.
float blackmanHarris(float x, float width) {
  constexpr float kTwoPi = 6.28318530717959f;
  const float t = x / width + 0.5f;  // 0 .. 1 across the support
  return 0.35875f - 0.48829f * std::cos(kTwoPi * t) + 0.14128f * std::cos(2.0f * kTwoPi * t) -
         0.01168f * std::cos(3.0f * kTwoPi * t);
}

}  // namespace

float PixelFilter::weight(float dx, float dy) const {
  const float r = radius();
  if (!(std::fabs(dx) < r && std::fabs(dy) < r)) return 0.0f;
  switch (type) {
    case FilterType::Gaussian: {
      const float x = dx / r, y = dy / r;
      return std::exp(-2.0f * (x * x + y * y));
    }
    case FilterType::BlackmanHarris:
      return blackmanHarris(dx, width) * blackmanHarris(dy, width);
    case FilterType::Box:
      return 1.0f;
  }
  return 0.0f;
}

}  // namespace relief
