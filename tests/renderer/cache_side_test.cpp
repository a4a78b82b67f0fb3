// The side cache of whole contributor subdivisions (AccelOptions::sideCacheTriangles): fills that
// take micro-triangles from it store exactly what culled per-voxel subdivision stores, so hits are
// identical with it on or off, at any budget and on two threads; it really is used, within its
// capacity, and saves shader work on a coherent ray order.
#include <thread>
#include <tuple>

#include <gtest/gtest.h>

#include "geometry_test_util.h"
#include "renderer/grid_accelerator.h"

namespace relief {
namespace {

using testing::HitKey;
using testing::hitKey;
using testing::hitKeys;
using testing::hitKeysOnTwoThreads;

// Rays from one point sweeping across the sphere row by row: neighbouring rays need neighbouring
// voxels, as in a coherent pixel order.
std::vector<Ray> sweep() {
  std::vector<Ray> rays;
  for (int y = 0; y < 60; ++y)
    for (int x = 0; x < 60; ++x) {
      Ray r;
      r.origin = glm::vec3(0, 0, 4);
      r.direction = glm::vec3(-0.35f + 0.7f * float(x) / 59, -0.35f + 0.7f * float(y) / 59, -1);
      rays.push_back(r);
    }
  return rays;
}

// The displaced sphere both tests use: 288 input triangles, each spanning a few voxels at grid 12.
Scene sideScene() {
  testing::SphereOptions o;
  o.nu = 24, o.nv = 12;
  return testing::makeSphereScene(o);
}

TEST(CacheSide, SameHitsWithTheSideCacheAtAnyBudgetAndOnTwoThreads) {
  const Scene scene = sideScene();
  const std::vector<Ray> rays = sweep();
  AccelOptions base;
  base.gridResolution = 12;
  GridAccelerator reference(scene, base);
  const std::vector<HitKey> expected = hitKeys(reference, rays);
  const AccelStats plain = reference.stats();
  ASSERT_GT(plain.uniqueDisplacedTriangles, 10000u);

  for (uint64_t budget : {UINT64_MAX, plain.residentTriangles / 10}) {
    AccelOptions o2 = base;
    o2.cacheBudgetTriangles = budget;
    o2.sideCacheTriangles = 20000;
    GridAccelerator side(scene, o2);
    for (size_t i = 0; i < rays.size(); ++i) ASSERT_EQ(hitKey(side.intersect(rays[i])), expected[i]) << i;
    const AccelStats s = side.stats();
    EXPECT_GT(s.sideCacheHits, 0u);
    EXPECT_GT(s.sideCacheMisses, 0u);
    EXPECT_EQ(s.uniqueDisplacedTriangles, plain.uniqueDisplacedTriangles);
    // One thread: the capacity plus at most the one entry that did not fit (an input triangle of
    // this sphere subdivides into far fewer micro-triangles than the capacity).
    EXPECT_LE(s.sideCachePeakTriangles, 2 * o2.sideCacheTriangles);
    EXPECT_GT(s.sideCachePeakTriangles, o2.sideCacheTriangles / 2);
    if (budget == UINT64_MAX) {
      EXPECT_LT(s.shaderPoints, plain.shaderPoints);
    }

    GridAccelerator shared(scene, o2);
    EXPECT_EQ(hitKeysOnTwoThreads(shared, rays), expected);
  }
}

// A contributor listed in one voxel only is subdivided by that voxel's fills alone, so the side
// cache leaves it out: with a single voxel nothing is shared and nothing is kept, and the hits are
// those of per-voxel fills.
TEST(CacheSide, ContributorsOfOneVoxelOnlyBypassTheSideCache) {
  const Scene scene = sideScene();
  const std::vector<Ray> rays = sweep();
  AccelOptions base;
  base.gridResolution = 1;
  GridAccelerator reference(scene, base);
  AccelOptions withSide = base;
  withSide.sideCacheTriangles = 20000;
  GridAccelerator side(scene, withSide);
  const std::vector<HitKey> expected = hitKeys(reference, rays);
  for (size_t i = 0; i < rays.size(); ++i) ASSERT_EQ(hitKey(side.intersect(rays[i])), expected[i]) << i;
  const AccelStats s = side.stats();
  EXPECT_EQ(s.sideCacheHits + s.sideCacheMisses, 0u);
  EXPECT_EQ(s.sideCachePeakTriangles, 0u);
  EXPECT_EQ(s.shaderPoints, reference.stats().shaderPoints);
}

// A contributor whose whole subdivision would not fit an eighth of the capacity bypasses the side
// cache (it is subdivided per voxel, culled), so the cache stays within its capacity: a coarse
// sphere of big triangles at a small capacity keeps nothing, with the same hits.
TEST(CacheSide, ContributorsTooBigForTheSideCacheBypassIt) {
  testing::SphereOptions o;
  o.nu = 8, o.nv = 4;  // 64 input triangles of 4^4 micro-triangles each, before displacement
  const Scene scene = testing::makeSphereScene(o);
  const std::vector<Ray> rays = sweep();
  AccelOptions base;
  base.gridResolution = 12;
  GridAccelerator reference(scene, base);
  const std::vector<HitKey> expected = hitKeys(reference, rays);
  AccelOptions small = base;
  small.sideCacheTriangles = 2000;  // under 8 x 4^4
  GridAccelerator side(scene, small);
  for (size_t i = 0; i < rays.size(); ++i) ASSERT_EQ(hitKey(side.intersect(rays[i])), expected[i]) << i;
  const AccelStats s = side.stats();
  EXPECT_EQ(s.sideCachePeakTriangles, 0u);
  EXPECT_EQ(s.sideCacheHits + s.sideCacheMisses, 0u);
  // With room for them, the same triangles are kept and shared.
  AccelOptions roomy = base;
  roomy.sideCacheTriangles = 200000;
  GridAccelerator kept(scene, roomy);
  for (size_t i = 0; i < rays.size(); ++i) ASSERT_EQ(hitKey(kept.intersect(rays[i])), expected[i]) << i;
  EXPECT_GT(kept.stats().sideCacheHits, 0u);
  EXPECT_LE(kept.stats().sideCachePeakTriangles, roomy.sideCacheTriangles);
}

}  // namespace
}  // namespace relief
