// OpenImageIO-based implementation of the reference-image comparison in image_compare.h.
#include "image_compare.h"

#include <algorithm>
#include <cmath>

#include <OpenImageIO/imagebuf.h>

namespace relief::test {

ImageDiff compareImages(const std::string& actual, const std::string& reference,
                        float pixelThreshold) {
  ImageDiff d;
  OIIO::ImageBuf a(actual), r(reference);
  if (!a.read(0, 0, true, OIIO::TypeDesc::FLOAT)) {
    d.error = "cannot read " + actual + ": " + a.geterror();
    return d;
  }
  if (!r.read(0, 0, true, OIIO::TypeDesc::FLOAT)) {
    d.error = "cannot read " + reference + ": " + r.geterror();
    return d;
  }
  const OIIO::ImageSpec& sa = a.spec();
  const OIIO::ImageSpec& sr = r.spec();
  if (sa.width != sr.width || sa.height != sr.height) {
    d.error = "size differs: " + std::to_string(sa.width) + "x" + std::to_string(sa.height) +
              " vs " + std::to_string(sr.width) + "x" + std::to_string(sr.height);
    return d;
  }
  d.loaded = true;
  d.width = sa.width;
  d.height = sa.height;
  const int channels = std::min({sa.nchannels, sr.nchannels, 3});
  double sum = 0;
  for (int y = 0; y < sa.height; ++y) {
    for (int x = 0; x < sa.width; ++x) {
      double worst = 0;
      for (int c = 0; c < channels; ++c)
        worst = std::max(worst, double(std::fabs(a.getchannel(x, y, 0, c) - r.getchannel(x, y, 0, c))));
      sum += worst;
      d.maxDifference = std::max(d.maxDifference, worst);
      if (worst > pixelThreshold) ++d.failingPixels;
    }
  }
  const double n = double(sa.width) * sa.height;
  d.failFraction = d.failingPixels / n;
  d.meanDifference = sum / n;
  return d;
}

}  // namespace relief::test
