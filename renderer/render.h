// The render loop: pixel orders, the Lambert integrator with shadow rays, and the thread pool that
// fills a Film. Each pixel's value depends only on the scene and the pixel (per-pixel seeded
// jitter, fixed sample order), never on the order or the thread count. Used by tools/relief and
// tests; reaches geometry only through Accelerator.
#pragma once

#include <cstdint>
#include <functional>
#include <string_view>
#include <vector>

#include "renderer/accel.h"
#include "renderer/film.h"
#include "renderer/scene.h"

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
  // Called with the percentage of pixels done whenever it grows; serialized by the render loop,
  // so it may print. Has no influence on the image.
  std::function<void(int percent)> progress;
};

struct RenderStats {
  double seconds = 0;
  int threads = 0;
  int samplesPerPixel = 0;
  uint64_t cameraRays = 0, shadowRays = 0, cameraHits = 0;
};

// Shades camera rays: matte (Ka * ambient + Kd * sum over distant lights of max(0, N.L), each
// light tested with one shadow ray) times the material colour; black where nothing is hit.
class Integrator {
 public:
  Integrator(const Scene& scene, Accelerator& accel);

  // *hit (optional) says whether the ray hit anything (for coverage / alpha).
  glm::vec3 radiance(const Ray& ray, RenderStats* stats, bool* hit = nullptr) const;

  // Distance a shadow ray starts off the surface, scaled to the scene's extent.
  float shadowEpsilon() const { return epsilon_; }

  // Cs at a hit: the per-vertex colour interpolated over the input triangle if the mesh has one,
  // else the material's colour.
  static glm::vec3 surfaceColor(const Mesh& mesh, const Material& material, const Hit& hit);

 private:
  const Scene& scene_;
  Accelerator& accel_;
  float epsilon_;
};

// Renders `scene` into `film` (whose size is the output resolution).
RenderStats render(const Scene& scene, Accelerator& accel, const RenderOptions& options, Film* film);

}  // namespace relief
