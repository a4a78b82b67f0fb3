// The ray-query interface over the displaced scene: contributor grid + lazily filled geometry cache.
// The integrator sees only this; how geometry is subdivided, cached and intersected lives behind it.
// Thread-safe: intersect/occluded may be called from many threads (the cache is the only shared
// mutable state in the renderer).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>

#include <glm/glm.hpp>

#include "renderer/scene.h"

namespace relief {

struct Ray {
  glm::vec3 origin;
  glm::vec3 direction;  // need not be unit; t is in units of |direction|
  float tMin = 0.0f;
  float tMax = 1e30f;
};

struct Hit {
  float t = 0.0f;
  glm::vec3 P{0};   // world-space hit point
  glm::vec3 Ng{0};  // unit face normal of the (micro-)triangle hit, facing as the input triangle
  glm::vec2 st{0};  // interpolated texture coordinates
  glm::vec2 bary{0};  // weights of input corners 1 and 2 at the hit (exact even where displaced P
                     // lies off the input triangle): interpolate per-vertex data with these
  uint32_t meshIndex = 0;
  uint32_t triangleIndex = 0;  // input triangle within the mesh
  uint32_t microIndex = 0;     // micro-triangle within the input triangle's displaced geometry
};

struct AccelOptions {
  uint64_t cacheBudgetTriangles = UINT64_MAX;  // UINT64_MAX: unlimited
  int gridResolution = 0;                      // voxels along the longest axis; 0: automatic
  bool displace = true;                        // false: the undisplaced scene
  // Contributor refinement: a fill drops from the voxel's contributor list every input triangle
  // none of whose micro-triangles reached the voxel, so refills skip it (never changes the image).
  bool refineContributors = true;
  // Debug check after every fill: the resident set minus the voxel just filled stays within the
  // budget, except for voxels other threads hold pinned. Violations are counted in
  // AccelStats::budgetViolations. Also switched on by the environment variable
  // RELIEF_CHECK_BUDGET=1.
  bool checkBudget = false;
  // Side cache (docs/cache.md): the fill threads share the whole subdivisions of the contributors
  // subdivided last, up to this many micro-triangles in all, so that neighbouring voxel fills
  // reuse them instead of re-subdividing. 0: off (each fill subdivides its contributors culled to
  // the voxel). Never changes the image: culled and whole subdivisions agree triangle for triangle.
  uint64_t sideCacheTriangles = 0;
  // Subtree memos (subdivide.h, SubtreeMemo; docs/cache.md): culled fills learn the exact
  // displaced box of every subtree they keep whole and the simplification decisions of the
  // subtrees they process, so later fills skip subtrees that miss their voxel and replay the
  // decisions instead of sampling. One memo per input triangle listed in two or more voxels,
  // two words per subtree of the rounds it reaches (at most 5.5 KB). Never changes the image.
  bool learnSubtrees = true;
  // The subtree memos' total size, beyond which input triangles get none (the facade needs 5 MB:
  // about 2.3 bytes per displaced triangle of the input triangles fills reach).
  uint64_t memoBytesLimit = uint64_t(64) << 20;
  // Voxel proxies: a voxel's first fill keeps the top two levels of its BVH (at most 248 bytes)
  // for the rest of the render, and rays that would enter no leaf there pass the voxel without
  // the cache (after an eviction, a refill avoided). Never changes the image.
  bool voxelProxies = true;
  // Undisplaced triangles reaching beyond the displaced geometry are left out of the grid and
  // intersected through their own BVH (contributor_grid.h). Off: every triangle in the grid (for
  // measurement; RELIEF_OUTSIDE=0).
  bool outsideTriangles = true;
  // Dense voxels get a BVH (default) or, when set, the paper's uniform sub-voxel grid; kept to
  // measure one against the other (docs/cache.md). Never changes the image. relief sets it from
  // the environment variable RELIEF_SUBVOXEL=grid.
  bool subVoxelGrid = false;
};

struct AccelStats {
  uint64_t accesses = 0, hits = 0, compulsoryMisses = 0, capacityMisses = 0;
  uint64_t displacedTrianglesCreated = 0, uniqueDisplacedTriangles = 0;
  uint64_t peakResidentTriangles = 0, residentTriangles = 0;
  uint64_t peakResidentBytes = 0, residentBytes = 0;  // the same resident sets, in bytes
  uint64_t shaderPoints = 0;
  double subdivideSeconds = 0, displaceSeconds = 0;
  // Additions for the statistics interface (docs/statistics.md). Times are summed over threads.
  uint64_t budgetTriangles = UINT64_MAX;    // UINT64_MAX: unlimited
  uint64_t createdBytes = 0;                // bytes of all filled voxels, refills included
  uint64_t evictions = 0;
  uint64_t contributorEntries = 0;          // contributor-grid entries at build time
  uint64_t outsideTriangles = 0;            // undisplaced triangles left out of the grid
  uint64_t droppedContributors = 0;         // entries removed by refinement
  uint64_t budgetViolations = 0;            // only counted with AccelOptions::checkBudget
  uint64_t maxVoxelTriangles = 0;           // largest voxel filled (bounds budget overshoot)
  double intersectSeconds = 0;              // traversal + triangle tests, fills excluded
  glm::ivec3 gridResolution{0};
  uint64_t sideCacheHits = 0, sideCacheMisses = 0;
  uint64_t sideCachePeakTriangles = 0;
  // Voxel visits decided on a voxel proxy alone (no cache access), and the bytes of the subtree
  // memos and voxel proxies, which outlive the voxels (outside the budget and bytes per triangle).
  uint64_t proxySkips = 0, memoBytes = 0;
  // Micro-triangles of every subdivision (refills included) before and after the paper's 3.1
  // simplification; equal when nothing is simplified.
  uint64_t trianglesBeforeSimplification = 0, trianglesAfterSimplification = 0;
  // Whether the displaced geometry was made before the render (the Embree baseline): its
  // subdivision and shader times are then part of the build, not of the render.
  bool upFront = false;
};

class Accelerator {
 public:
  virtual ~Accelerator() = default;
  // Nearest hit with t in (ray.tMin, ray.tMax); ties broken by (mesh, triangle, micro) index so the
  // answer never depends on cache state, order or threads.
  virtual std::optional<Hit> intersect(const Ray& ray) = 0;
  // Any hit with t in (ray.tMin, ray.tMax).
  virtual bool occluded(const Ray& ray) = 0;
  virtual AccelStats stats() const = 0;
  // Whether `voxel` is being filled by some thread right now (see VoxelBusy).
  virtual bool filling(uint32_t /*voxel*/) const { return false; }
};

// Thrown out of intersect() and occluded() instead of waiting, on a thread that has set
// threadDefersBusyVoxels(), when the ray needs a voxel another thread is filling. Nothing is
// pinned when it is thrown, and a trace is a pure function of the scene, so the render loop can
// drop the pixel's partial work and trace it again once filling(voxel) turns false, with the same
// result. It lets threads that share one walk over the pixels do other pixels while a neighbour
// fills the voxel they need.
struct VoxelBusy {
  uint32_t voxel;
};
inline bool& threadDefersBusyVoxels() {
  thread_local bool defers = false;
  return defers;
}

// Geometry-cache misses (voxel fills) caused by the calling thread so far. Accelerators increment
// it on every miss; the integrator reads it around a pixel for the "cachemiss" AOV. Per thread, so
// it needs no synchronisation and cannot disturb the image.
inline uint64_t& threadCacheMisses() {
  thread_local uint64_t misses = 0;
  return misses;
}

// Builds the contributor grid over `scene` (which must outlive the accelerator).
std::unique_ptr<Accelerator> makeGridAccelerator(const Scene& scene, const AccelOptions& options);

// The Embree baseline (embree_accelerator.h): the whole scene displaced up front into one BVH.
// Throws EmbreeOutOfMemory when memory runs out, std::runtime_error in a build without Embree.
struct EmbreeOptions;
std::unique_ptr<Accelerator> makeEmbreeAccelerator(const Scene& scene, const AccelOptions& options,
                                                   const EmbreeOptions& embree);

}  // namespace relief
