// The contributor grid (paper, phase 1): for each voxel of a regular grid over the scene, the input
// triangles whose displaced geometry may reach it. Built once by the grid accelerator from the
// immutable Scene. Afterwards only refinement changes it (a voxel's filler drops contributors that
// reached nothing there, see refine()); everything else is safe to read from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "renderer/accel.h"
#include "renderer/scene.h"

namespace relief {

// A world-space box.
struct Bounds3 {
  glm::vec3 lo{1e30f}, hi{-1e30f};
  void extend(glm::vec3 p) { lo = glm::min(lo, p), hi = glm::max(hi, p); }
  bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  bool overlaps(const Bounds3& o) const {
    return lo.x <= o.hi.x && o.lo.x <= hi.x && lo.y <= o.hi.y && o.lo.y <= hi.y && lo.z <= o.hi.z &&
           o.lo.z <= hi.z;
  }
};

// Triangle `triangle` of `mesh` grown by `grow` (a displacement bound): what the grid lists it
// under, and what its displaced geometry may reach. Empty when a corner is missing or not finite.
Bounds3 triangleReach(const Mesh& mesh, uint32_t triangle, float grow);

// Heuristic for AccelOptions::gridResolution == 0: voxels along the longest axis =
// round(kAutoGridFactor * cbrt(numTriangles)), clamped to [1, kMaxAutoGridResolution]. With cubic
// voxels this gives about kAutoGridFactor^3 = 8 voxels per input triangle on a compact scene, so a
// voxel holds a small piece of a few input triangles: big enough that per-voxel fills rarely
// re-subdivide one triangle for many voxels, small enough that a voxel's displaced triangles stay
// cheap to fill and evict.
//
// Displaced scenes also cap the resolution so that a voxel is at least kVoxelsPerBound times the
// largest displacement bound: a per-voxel fill re-subdivides every part of its contributors within
// the bound of the voxel, so the repeated work grows like ((size + 2 * bound) / size)^2. Measured
// on a bumpy sphere (4096 input triangles, bound 0.05, 600K micro-triangles, 160K rays): 32^3
// voxels evaluated 5.2M shader points in 1.37 s, 8^3 voxels 1.0M points in 0.54 s.
//
// Finely displaced scenes need more voxels than their input triangles say: a voxel's fill costs
// subdivision scratch and time in proportion to the micro-triangles it holds, so few large input
// triangles at a fine edge length made voxels of 50-60K micro-triangles, fills that held tens of
// megabytes of scratch, and budgets that thrashed. So the resolution is also at least
// cbrt(E / kMicroTrianglesPerCell), E the micro-triangles the undisplaced surfaces ask for
// (estimatedMicroTriangles, before simplification), which may take voxels down to kMinVoxelBounds
// displacement bounds: with subtree memos the margin a fill repeats is small. The constant keeps
// the example scenes at or near their measured best (the facade at 18 voxels); at a 4x finer edge
// length (E 57M, 4.5-5M micro-triangles made) the rule gives 37, where 18 took 12.4 s and 115 MB
// at a 10% budget and 36 took 10.3 s and 93 MB (docs/cache.md).
//
// Under a cache budget, the automatic resolution is also raised (up to kMaxBudgetGridResolution)
// until the heaviest voxel's estimated micro-triangles (each input triangle's 4^k spread over the
// voxels of its undisplaced box, capped for slivers by what its area and longest edge ask for)
// fit the budget kVoxelsPerBudget times, the bound caps above notwithstanding; the entry limit
// below still wins. Heavy voxels otherwise make a budget thrash: the example sphere with a bound
// of 0.5 got 3 voxels across, 134K micro-triangles in the heaviest, and rendered in 258 s at a
// budget of 60K against 0.66 s unlimited (8 across now: 5.2 s); the facade at a budget of 20K
// took 60-67 s (37 across now: 2.1 s). Explicit resolutions are left as asked (docs/cache.md).
constexpr float kAutoGridFactor = 2.0f;
constexpr double kVoxelsPerBudget = 4.0;
constexpr int kMaxBudgetGridResolution = 64;
constexpr float kVoxelsPerBound = 4.0f;
constexpr double kMicroTrianglesPerCell = 800.0;
constexpr float kMinVoxelBounds = 2.0f;
constexpr int kMaxAutoGridResolution = 128;
// Explicit resolutions are clamped too: beyond this the per-voxel arrays alone exceed memory.
constexpr int kMaxGridResolution = 1024;
// And so is the whole grid's voxel count (about 30 bytes a voxel before any geometry: 1 GB here;
// 1024 voxels along each axis made 19 GB): a resolution asking for more is lowered until it fits.
constexpr uint64_t kMaxGridVoxels = uint64_t(1) << 25;
// An automatic resolution is halved until the grid lists at most this many entries per
// triangle on average, or kMinEntryLimit in all (a few big triangles may cover many voxels).
constexpr int kMaxEntriesPerTriangle = 64;
constexpr size_t kMinEntryLimit = size_t(1) << 22;
// An explicit resolution is lowered (with a warning) only past a limit made for memory, not
// speed: 2^24 entries (64 MB, and three times that while building) or 256 per triangle.
constexpr int kMaxExplicitEntriesPerTriangle = 256;
constexpr size_t kMinExplicitEntryLimit = size_t(1) << 24;

// Undisplaced triangles outside the displaced geometry. A scene with displaced geometry gets a
// grid over the displaced triangles' neighbourhood: their reach grown on every side by
// kOutsideMargin times its longest extent. An undisplaced triangle not entirely inside it (a floor
// a kilometre wide, a sky dome, one vertex far away) is left out of the grid and listed in
// outside(), for the accelerator to intersect through a plain BVH (triangle_bvh.h). Otherwise
// such a triangle stretches the grid, and the displaced object ends up in a handful of voxels:
// every fill subdivides most of it, and a budget cannot work (the sphere example with a
// 2000-unit floor: 877 first fills became 4, the render 3.1x slower). The margin keeps the small
// undisplaced things around the displaced ones (sphere_box's table and glass) in the grid, whose
// voxel BVHs test them faster than the plain BVH does (with no margin sphere_box's render was
// 1.25x slower). Scenes without displaced geometry take the neighbourhood of their triangles of
// ordinary size instead: those at most kOrdinaryTriangles times the median triangle's extent
// (a huge ground plane under small objects goes to the plain BVH, whose test is in double).
constexpr float kOutsideMargin = 1.0f;
constexpr float kOrdinaryTriangles = 64.0f;

class ContributorGrid {
 public:
  ContributorGrid(const Scene& scene, const AccelOptions& options);

  // Global triangle ids number the triangles of all meshes consecutively, mesh by mesh.
  uint32_t numTriangles() const { return meshOffsets_.back(); }
  uint32_t globalId(uint32_t mesh, uint32_t triangle) const { return meshOffsets_[mesh] + triangle; }
  // (mesh, triangle) of a global id.
  std::pair<uint32_t, uint32_t> split(uint32_t globalId) const;
  // The displacement of a mesh, or null when it is drawn undisplaced.
  const Displacement* displacement(uint32_t mesh) const { return displacements_[mesh]; }
  bool anyDisplaced() const { return anyDisplaced_; }

  const Bounds3& bounds() const { return bounds_; }
  glm::ivec3 resolution() const { return resolution_; }
  float voxelSize() const { return voxelSize_; }
  uint32_t numVoxels() const { return uint32_t(offsets_.size() - 1); }
  uint32_t voxelIndex(glm::ivec3 cell) const {
    return uint32_t((cell.z * resolution_.y + cell.y) * resolution_.x + cell.x);
  }
  // The voxel's box, grown by `padding()` so triangles touching a face are found from both sides.
  Bounds3 voxelBounds(uint32_t voxel) const;
  // Slack added to every overlap test: absorbs the rounding of boxes and of the traversal.
  float padding() const { return padding_; }
  // Times the automatic resolution was halved to keep the entries in bounds (kMaxEntriesPerTriangle).
  int coarsenings() const { return coarsenings_; }
  // Times the automatic resolution was raised to fit the cache budget (kVoxelsPerBudget).
  int budgetRefinements() const { return budgetRefinements_; }
  // The voxel's contributors, less those refinement dropped. Reading the ids (not just the size)
  // while another thread may refine the voxel is a race: only the voxel's filler (which the
  // geometry cache makes exclusive) and single-threaded callers may do it.
  std::span<const uint32_t> contributors(uint32_t voxel) const {
    return {ids_.data() + offsets_[voxel], live_[voxel].load(std::memory_order_acquire)};
  }
  bool hasContributors(uint32_t voxel) const {
    return live_[voxel].load(std::memory_order_relaxed) != 0;
  }
  // Every contributor found at build time: the live ones (in their original order) followed by
  // the dropped ones.
  std::span<const uint32_t> allContributors(uint32_t voxel) const {
    return {ids_.data() + offsets_[voxel], ids_.data() + offsets_[voxel + 1]};
  }
  uint64_t numEntries() const { return ids_.size(); }
  // Global ids of the undisplaced triangles left out of the grid (above), in id order.
  std::span<const uint32_t> outside() const { return outside_; }

  // Contributor refinement (paper, section 3): drops the live contributors i of `voxel` with
  // !keep[i] (keep parallels contributors(voxel)), keeping the others' order. Only the voxel's
  // filler may call it. Returns how many were dropped.
  uint32_t refine(uint32_t voxel, const std::vector<uint8_t>& keep);

 private:
  std::vector<uint32_t> meshOffsets_;  // numMeshes + 1
  std::vector<const Displacement*> displacements_;
  bool anyDisplaced_ = false;
  Bounds3 bounds_;
  glm::ivec3 resolution_{1};
  float voxelSize_ = 1.0f;
  float padding_ = 0.0f;
  std::vector<uint32_t> offsets_;  // numVoxels + 1, into ids_ (compressed rows)
  std::vector<uint32_t> ids_;
  std::vector<uint32_t> outside_;
  int coarsenings_ = 0;
  int budgetRefinements_ = 0;
  // The largest per-voxel sum of estimated micro-triangles at the current layout (see above).
  double heaviestVoxelEstimate(const Scene& scene) const;
  // Per voxel: how many of its row's ids are live (refinement shrinks it).
  std::unique_ptr<std::atomic<uint32_t>[]> live_;
};

}  // namespace relief
