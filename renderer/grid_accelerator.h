// The grid accelerator behind makeGridAccelerator (accel.h): 3D DDA through the contributor grid,
// per-voxel geometry from the geometry cache, watertight intersection. Exposed beyond accel.h only
// for tests and statistics; the integrator uses the Accelerator interface.
//
// Traversal and determinism: voxels are visited front to back and every hit found in a visited
// voxel is a real intersection, so the nearest (t, key) over the visited voxels is kept; traversal
// stops once that t lies before the current voxel's exit. This is rule 2 in its exact form: a far
// hit in one voxel can never hide a nearer one in the next, since the next is still visited. As a
// voxel's content is a pure function of the voxel, the visited set and the answer depend only on
// the ray, never on the cache state, budget or threads. Ties in t go to the smaller key
// (global input triangle id, micro-triangle index).
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <optional>
#include <vector>

#include "renderer/accel.h"
#include "renderer/contributor_grid.h"
#include "renderer/triangle_bvh.h"
#include "renderer/geometry_cache.h"
#include "renderer/subdivide.h"

namespace relief {

class GridAccelerator final : public Accelerator {
 public:
  GridAccelerator(const Scene& scene, const AccelOptions& options);
  ~GridAccelerator() override;

  std::optional<Hit> intersect(const Ray& ray) override;
  bool occluded(const Ray& ray) override;
  AccelStats stats() const override;
  bool filling(uint32_t voxel) const override { return cache_->filling(voxel); }

  const ContributorGrid& grid() const { return grid_; }
  // Never null: undisplaced input triangles are cached whole (statistics leave them out).
  const GeometryCache* cache() const { return cache_.get(); }
  // The largest triangle count of any voxel filled so far (bounds the budget overshoot).
  uint64_t maxVoxelTriangles() const { return maxVoxelTriangles_.load(std::memory_order_relaxed); }
  // Shader problems summed over all fills (for one-time warnings by the caller).
  RlfStatus shaderStatus() const;
  // The step of the lattice displaced vertices are snapped to (snapToLattice; 0: none).
  float positionStep() const { return positionStep_; }
  // Builds voxel `voxel`'s geometry exactly as a fill does, without caching it (bench/fill_rate.cpp
  // measures the whole fill: subdivision, shader, culling, the voxel's BVH).
  std::unique_ptr<VoxelGeometry> buildVoxelUncached(uint32_t voxel) { return buildVoxel(voxel); }

  struct SlabRay;  // a ray's slab-test set-up, shared by the voxel BVHs and their proxies

 private:
  struct Best;
  template <bool kAnyHit>
  void traverse(const Ray& ray, Best& best);
  void intersectVoxel(uint32_t voxel, const struct WatertightRay& wr, const SlabRay& sr, const Ray& ray,
                      uint64_t stamp, bool anyHit, Best& best);
  std::unique_ptr<VoxelGeometry> buildVoxel(uint32_t voxel);
  struct SideCache;
  // The whole micro-mesh of contributor `id` from the shared side cache, subdividing on a miss.
  std::shared_ptr<const MicroMesh> sideCached(uint32_t id, SubdivideCounters& counters);
  // The subtree memo of contributor `id`, created on first use with slots for `rounds` rounds;
  // null once the memos reach AccelOptions::memoBytesLimit.
  SubtreeMemo* subtreeMemo(uint32_t id, int rounds);
  void addCounters(const SubdivideCounters& counters);
  float choosePositionStep() const;
  void addTraverseTime(uint64_t startTicks);

  const Scene& scene_;
  AccelOptions options_;
  ContributorGrid grid_;
  TriangleBvh outside_;  // the undisplaced triangles the grid leaves out (contributor_grid.h)
  std::unique_ptr<GeometryCache> cache_;
  // LRU stamps (nextStamp): one per ray, from a shared clock in blocks per thread. id_ tells
  // accelerators apart in the thread's block (a new one may reuse an old one's address).
  static constexpr uint64_t kStampBlock = 256;
  uint64_t nextStamp();
  std::atomic<uint64_t> clock_{1};
  const uint64_t id_ = [] {
    static std::atomic<uint64_t> next{1};
    return next.fetch_add(1, std::memory_order_relaxed);
  }();
  float positionStep_ = 0.0f;
  std::vector<std::atomic<uint8_t>> voxelCounted_;  // per voxel: its unique triangles counted
  std::vector<std::atomic<uint8_t>> knownEmpty_;    // per voxel: filled once with no triangles
  // Per input triangle: kShared when listed in 2+ voxels, kMemoWorthy when also subdivided finely
  // enough for a subtree memo to pay, kSideWorthy when also small enough for the side cache to
  // keep its whole subdivision (at most an eighth of its capacity).
  static constexpr uint8_t kShared = 1, kMemoWorthy = 2, kSideWorthy = 4;
  std::vector<uint8_t> sharedContributor_;
  std::atomic<uint64_t> uniqueTriangles_{0}, shaderPoints_{0}, fillNanos_{0}, displaceTicks_{0};
  std::atomic<uint64_t> maxVoxelTriangles_{0};
  std::atomic<uint64_t> droppedContributors_{0};
  std::atomic<uint64_t> simplifyBefore_{0}, simplifyAfter_{0};
  std::unique_ptr<SideCache> side_;
  std::vector<std::atomic<SubtreeMemo*>> subtreeMemos_;  // per input triangle, owned; or null
  std::atomic<uint64_t> subtreeBytes_{0};
  // Per voxel, once filled with a BVH: the top two levels of its nodes and its lattice, kept when
  // the voxel is evicted. nodes[0] is the root; its children that are nodes follow, and the
  // root's child references point at them (leaves keep their leaf references).
  struct VoxelProxy {
    glm::vec3 origin, step;
    VoxelGeometry::BvhFrame root;
    VoxelGeometry::BvhNode nodes[5];
  };
  // Whether `ray` passes the voxel of proxy `p` without testing a triangle (see intersectVoxel).
  // base and scale: the ray's slab set-up on the proxy's lattice.
  static bool passes(const VoxelProxy& p, const Ray& ray, const SlabRay& sr, const glm::vec3& base,
                     const glm::vec3& scale, float limit);
  std::vector<std::atomic<const VoxelProxy*>> proxies_;  // owned; null until the first fill
  std::atomic<uint64_t> proxyBytes_{0};
  std::atomic<uint64_t> sideHits_{0}, sideMisses_{0}, sidePeak_{0};
  // Traversal time per ray, fills included (they are subtracted in stats()), summed per thread
  // shard so that the two clock reads per ray (readTicks, ticks.h) are the only cost on the ray
  // path.
  static constexpr int kTimeShards = 16;
  struct alignas(64) TimeShard {
    std::atomic<uint64_t> ticks{0};
    std::atomic<uint64_t> proxySkips{0};  // voxels a ray passed on their proxy alone
  };
  TimeShard traverseNanos_[kTimeShards];
  std::atomic<uint32_t> nonFinite_{0}, loopLimit_{0}, indexClamped_{0}, unknownSpace_{0},
      textureErrors_{0};
};

}  // namespace relief
