// Tolerance-based image comparison for reference-image tests (see docs/testing.md): a pixel fails
// when any channel differs by more than `pixelThreshold` (0..1 units), and the test fails when more
// than `maxFailFraction` of the pixels fail. Small differences in shading noise pass; a shifted or
// missing object does not.
#pragma once

#include <string>

namespace relief::test {

struct ImageDiff {
  bool loaded = false;
  std::string error;
  int width = 0, height = 0;
  long failingPixels = 0;
  double failFraction = 0;
  double maxDifference = 0;
  double meanDifference = 0;
};

ImageDiff compareImages(const std::string& actual, const std::string& reference,
                        float pixelThreshold);

}  // namespace relief::test
