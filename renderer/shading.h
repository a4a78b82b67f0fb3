// The Whitted ray-tracing integrator: RenderMan's standard light sources (ambient, distant, point,
// spot, area) and surfaces (matte, plastic, metal, mirror/shinymetal, glass, constant), shadow rays
// through coloured glass, and reflection/refraction rays up to a depth limit. Pure function of the
// scene, the ray and a seed (area-light samples are seeded, never drawn from shared state), so the
// image cannot depend on thread scheduling or cache state. Reaches geometry only through
// Accelerator. Used by the render loop (render.*) and tests.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "renderer/accel.h"
#include "renderer/scene.h"

namespace relief {

struct RenderStats {
  double seconds = 0;
  int threads = 0;
  int samplesPerPixel = 0;
  uint64_t cameraRays = 0, shadowRays = 0, cameraHits = 0;
  uint64_t reflectionRays = 0, refractionRays = 0;
  // Pixels put aside because they needed a voxel another thread was filling, counted each time
  // (RenderOptions::sharedWalk); their rays are counted once, when traced to the end.
  uint64_t deferredPixels = 0;
  bool sharedWalk = false;  // the threads shared one walk over the pixels (RenderOptions)
  // Most bytes of traced samples held at once while they waited for filtering (render.cpp).
  uint64_t peakSampleBytes = 0;
  // The render stopped before every pixel was traced: a subdivision ran away (subdivide.h,
  // setSubdivisionLimits). The film is then incomplete and must not be written.
  bool stopped = false;
};

inline constexpr int kDefaultMaxDepth = 5;

// SplitMix64 finaliser: decorrelates consecutive pixel, sample and light indices for seeding.
inline uint64_t mix64(uint64_t z) {
  z += 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// The top 24 bits of a hash as a float in [0, 1).
inline float unitFloat(uint64_t bits) { return float(bits >> 40) * (1.0f / 16777216.0f); }

// Stratum pair of sample `index` of `count` for 2D stratification of any count: x in stratum
// `index`, y in stratum (index * k) mod count with k coprime to count near count / golden ratio,
// so both axes are stratified (n-rooks) and the pattern spreads like a rank-1 lattice. Jittered
// within the cell by `jitter` in [0, 1)^2; returns a point in [0, 1)^2.
glm::vec2 stratifiedSample(int index, int count, glm::vec2 jitter);

struct ShadingOptions {
  int maxDepth = kDefaultMaxDepth;  // reflection/refraction bounces after the camera ray
  // False when the accelerator renders the undisplaced surfaces: then every mesh with normals is
  // shaded with them, displaced ones included.
  bool displaced = true;
};

// What one camera ray saw: colour (premultiplied by alpha), alpha (coverage times the opacity
// accumulated through partly transparent surfaces, as RenderMan's Oi), and the first visible
// surface's camera-ray parameter (camera-space depth) and world normal for the AOVs.
struct SampleResult {
  glm::vec3 color{0.0f};
  float alpha = 0.0f;
  bool hit = false;         // a surface was hit, even a fully transparent one
  float depth = 0.0f;       // 0 where nothing was hit
  glm::vec3 normal{0.0f};   // outward shading normal; 0 where nothing was hit
};

class Integrator {
 public:
  Integrator(const Scene& scene, Accelerator& accel, const ShadingOptions& options = {});

  // Traces a camera ray. `seed` decorrelates area-light samples; the render loop derives it from
  // the pixel and sample index only.
  SampleResult trace(const Ray& ray, uint64_t seed, RenderStats* stats) const;

  // Colour along a camera ray; *hit (optional) says whether the ray hit anything.
  glm::vec3 radiance(const Ray& ray, RenderStats* stats, bool* hit = nullptr) const;

  // Fraction of light (per channel) that passes along `ray` between tMin and tMax: 0 behind an
  // opaque surface, the transmit colour through glass, 1 - Os through partly transparent surfaces.
  glm::vec3 transmittance(const Ray& ray, RenderStats* stats) const;

  // Distance a secondary ray starts off a surface hit at P by a ray from `origin`. Large enough
  // to clear the float error of the hit point (16 ulps of the larger coordinate of P and origin
  // at least), small against any feature a displacement shader can make: 2e-5 of the scene's
  // extent, as long as that is at most 2^-13 (1024 ulps) of the local scale. A fraction of the
  // extent alone pushed shadow rays 56 units off a unit sphere standing on a 1e6-unit ground
  // plane, and its shadow vanished; 16 ulps alone left speckles of self-shadowing on the
  // facade's micro-triangles.
  float epsilonAt(const glm::vec3& P, const glm::vec3& origin) const;

  // The lights in use: Scene::lights, or for readers that only fill the older fields, distant
  // lights and one ambient light made from Scene::distantLights and ambientColor.
  const std::vector<Light>& lights() const { return lights_; }

  // Cs at a hit: the per-vertex colour interpolated over the input triangle if the mesh has one,
  // else the material's colour.
  static glm::vec3 surfaceColor(const Mesh& mesh, const Material& material, const Hit& hit);

  // Unpolarised Fresnel reflectance of a dielectric interface for a ray arriving with
  // cos(incidence) `cosI` (> 0), where `etaRatio` = n(incident side) / n(far side); 1 under total
  // internal reflection.
  static float fresnel(float cosI, float etaRatio);

  // Snell refraction of unit `incident` through a surface with unit normal `n` facing against it;
  // false under total internal reflection.
  static bool refract(const glm::vec3& incident, const glm::vec3& n, float etaRatio,
                      glm::vec3* transmitted);

 private:
  struct Surface;  // a resolved hit: material, normals, colours
  struct LightSample {
    glm::vec3 L;   // unit, towards the light
    glm::vec3 Cl;  // arriving colour, shadowing included
  };

  // Nearest hit that is not a culled back face of a one-sided surface.
  std::optional<Hit> findHit(Ray ray) const;
  bool resolve(const Ray& ray, const Hit& hit, Surface* s) const;
  // `weight`: the largest factor by which what this ray returns reaches the pixel (1 for a camera
  // ray). Secondary rays whose weight would fall below kMinRayWeight are not traced.
  // `opacity` (may be null) receives the opacity accumulated along the ray through partly
  // transparent surfaces (0 where it hits nothing): the camera sample's alpha is its mean.
  // `layers`: the partly transparent surfaces this ray has already passed (kMaxTransparentLayers);
  // compositing through them is the hider's work, not ray recursion, so it does not use `depth`.
  glm::vec3 radianceAt(const Ray& ray, int depth, uint64_t seed, RenderStats* stats,
                       SampleResult* first, float weight = 1.0f, glm::vec3* opacity = nullptr,
                       int layers = 0) const;
  glm::vec3 shade(const Ray& ray, const Surface& s, int depth, uint64_t seed,
                  RenderStats* stats, float weight, glm::vec3* opacity, int layers) const;
  // Ambient light reaching the surface (unshadowed) and shadowed samples of every other light
  // whose direction lies in the hemisphere around Nf.
  glm::vec3 ambient(const Surface& s) const;
  // The lights that reach a mesh: its own list when the reader set one (even empty), every light
  // for meshes built without one, and for scenes that only fill the older light fields.
  const std::vector<uint32_t>& lightsOf(const Mesh& mesh) const {
    if (scene_.lights.empty()) return allLights_;
    return mesh.lightsSet || !mesh.lights.empty() ? mesh.lights : allLights_;
  }
  void illuminate(const Surface& s, uint64_t seed, RenderStats* stats,
                  std::vector<LightSample>* out) const;

  const Scene& scene_;
  Accelerator& accel_;
  ShadingOptions options_;
  std::vector<Light> lights_;
  std::vector<uint32_t> allLights_;  // 0 .. lights_.size() - 1: for meshes without a light list
  float sceneEpsilon_ = 0;  // 2e-5 of the extent of the scene's geometry (epsilonAt)
  bool throughShadows_ = false;  // some surface lets shadow rays through (glass, Os < 1, Sides 1)
  bool anyOneSided_ = false;     // some surface is culled from behind (Sides 1, not glass)
};

}  // namespace relief
