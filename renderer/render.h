// The render loop: pixel orders, and the thread pool that traces every sample (through the
// integrator of shading.h) into a sample buffer, then filters it into a Film in a separate gather
// pass. Each pixel's value depends only on the scene and the pixel (per-pixel seeded jitter, fixed
// sample and gather order), never on the order or the thread count. Used by tools/relief and
// tests; reaches geometry only through Accelerator.
#pragma once

#include <cstdint>
#include <functional>
#include <string_view>
#include <vector>

#include "renderer/accel.h"
#include "renderer/film.h"
#include "renderer/filter.h"
#include "renderer/scene.h"
#include "renderer/shading.h"

namespace relief {

enum class PixelOrder { Scanline, Bucket, Hilbert };

// Parses "scanline", "bucket" or "hilbert".
bool parsePixelOrder(std::string_view text, PixelOrder* order);
std::string_view pixelOrderName(PixelOrder order);

// Every pixel index (y * width + x) exactly once, in the given order. Bucket: 16 x 16 tiles in
// scanline order, scanline inside each tile. Hilbert: a generalised Hilbert curve that covers any
// width x height with (almost always) unit steps, so consecutive pixels stay close and the
// geometry cache sees coherent rays.
std::vector<uint32_t> pixelOrder(PixelOrder order, int width, int height);

inline constexpr int kBucketSize = 16;

struct RenderOptions {
  PixelOrder order = PixelOrder::Hilbert;
  int threads = 0;          // 0: all hardware threads
  int samplesPerPixel = 0;  // 0: the scene's PixelSamples
  int maxDepth = -1;        // reflection/refraction depth; -1: the scene's, else kDefaultMaxDepth
  FilterType filter = FilterType::Gaussian;
  bool displaced = true;    // false: the accelerator renders undisplaced surfaces (see shading.h)
  // Threads share one walk over the pixel order, putting aside pixels that need a voxel another
  // thread is filling, instead of each walking its own stretch (render.cpp). No influence on
  // the image.
  bool sharedWalk = false;
  // A crop of a larger image (RI CropWindow): the film holds pixels [cropX, cropX + film width) x
  // [cropY, cropY + film height) of a fullWidth x fullHeight image, each exactly as the whole
  // render gives it (the camera, the sample positions and the filter's neighbours are the whole
  // image's). fullWidth 0: the film is the whole image.
  int fullWidth = 0, fullHeight = 0;
  int cropX = 0, cropY = 0;
  // Called with the percentage of pixels done whenever it grows; serialized by the render loop,
  // so it may print. Has no influence on the image.
  std::function<void(int percent)> progress;
};

// Arbitrary output variables, each the size of the main film; null entries are not computed.
// Not filtered: each pixel holds what its own samples saw.
struct AovFilms {
  Film* depth = nullptr;      // "z": nearest camera-space depth of the pixel's samples (0: none)
  Film* normal = nullptr;     // "N": outward world normal of that nearest hit
  Film* cacheMiss = nullptr;  // "cachemiss": geometry-cache misses while tracing the pixel
};

// Renders `scene` into `film` (whose size is the output resolution, or the crop's: RenderOptions).
RenderStats render(const Scene& scene, Accelerator& accel, const RenderOptions& options, Film* film,
                   const AovFilms& aovs = {});

// Where sample `index` of `count` falls inside pixel `pixel`, in [0, 1)^2: the centre for one
// sample, stratified jitter otherwise. Seeded by (pixel, index) only.
glm::vec2 pixelSampleOffset(uint64_t pixel, int index, int count);

}  // namespace relief
