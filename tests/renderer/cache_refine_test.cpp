// Contributor refinement (AccelOptions::refineContributors): a fill drops from its voxel's list the
// input triangles that reached nothing there. Checked directly (no dropped contributor has a
// micro-triangle overlapping the voxel, by full, unculled subdivision) and by its effect (the same
// hits with refinement on and off, at any budget, and fewer shader points on refills).
#include <tuple>

#include <gtest/gtest.h>

#include "geometry_test_util.h"
#include "renderer/grid_accelerator.h"

namespace relief {
namespace {

using testing::makeSphereScene;
using testing::SphereOptions;

using HitKey = std::tuple<bool, float, uint32_t, uint32_t, uint32_t>;

std::vector<HitKey> run(Accelerator& accel, const std::vector<Ray>& rays) {
  std::vector<HitKey> keys;
  for (const Ray& ray : rays) {
    const std::optional<Hit> hit = accel.intersect(ray);
    keys.push_back(hit ? HitKey{true, hit->t, hit->meshIndex, hit->triangleIndex, hit->microIndex}
                       : HitKey{false, 0.0f, 0, 0, 0});
  }
  return keys;
}

SphereOptions sphere() {
  SphereOptions o;
  o.nu = 24, o.nv = 12;
  o.edgeLength = 0.05f;
  return o;
}

bool overlaps(const Bounds3& box, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  Bounds3 t;
  t.extend(a), t.extend(b), t.extend(c);
  return box.overlaps(t);
}

TEST(CacheRefine, DroppedContributorsNeverReachTheirVoxel) {
  const Scene scene = makeSphereScene(sphere());
  AccelOptions options;
  options.gridResolution = 10;
  GridAccelerator accel(scene, options);
  run(accel, testing::randomRays(4000, 3, 3.0f, 1.2f));
  const ContributorGrid& grid = accel.grid();
  uint64_t dropped = 0, kept = 0;
  MicroMesh mm;
  SubdivideCounters counters;
  for (uint32_t v = 0; v < grid.numVoxels(); ++v) {
    const auto all = grid.allContributors(v);
    const size_t live = grid.contributors(v).size();
    ASSERT_LE(live, all.size());
    const Bounds3 box = grid.voxelBounds(v);
    for (size_t k = live; k < all.size(); ++k) {
      const auto [m, t] = grid.split(all[k]);
      subdivideTriangle(scene.meshes[m], t, grid.displacement(m), mm, counters);  // unculled
      for (uint32_t i = 0; i < mm.numTriangles(); ++i) {
        const uint32_t* tri = &mm.indices[3 * size_t(i)];
        ASSERT_FALSE(overlaps(box, mm.P[tri[0]], mm.P[tri[1]], mm.P[tri[2]]))
            << "voxel " << v << " dropped contributor " << all[k] << " whose micro-triangle " << i
            << " overlaps it";
      }
      ++dropped;
    }
    kept += live;
  }
  // Refinement really happened, and the accelerator counted it.
  EXPECT_GT(dropped, 100u);
  EXPECT_GT(kept, 0u);
  EXPECT_EQ(accel.stats().droppedContributors, dropped);
  EXPECT_EQ(accel.stats().contributorEntries, dropped + kept);
}

TEST(CacheRefine, SameHitsWithRefinementOnAndOffAtAnyBudget) {
  const Scene scene = makeSphereScene(sphere());
  const std::vector<Ray> rays = testing::randomRays(3000, 7, 3.0f, 1.2f);
  AccelOptions off;
  off.gridResolution = 16;
  off.refineContributors = false;
  GridAccelerator reference(scene, off);
  const std::vector<HitKey> expected = run(reference, rays);
  const AccelStats full = reference.stats();
  EXPECT_EQ(full.droppedContributors, 0u);
  for (uint64_t budget : {UINT64_MAX, full.residentTriangles / 20}) {
    for (bool refine : {false, true}) {
      AccelOptions o = off;
      o.cacheBudgetTriangles = budget;
      o.refineContributors = refine;
      GridAccelerator accel(scene, o);
      EXPECT_EQ(run(accel, rays), expected) << "budget " << budget << " refine " << refine;
      // A second pass: refills now run on refined lists.
      EXPECT_EQ(run(accel, rays), expected) << "budget " << budget << " refine " << refine;
      const AccelStats s = accel.stats();
      EXPECT_EQ(s.uniqueDisplacedTriangles, full.uniqueDisplacedTriangles);
      if (refine) {
        EXPECT_GT(s.droppedContributors, 0u);
      }
    }
  }
}

TEST(CacheRefine, RefillsOfRefinedVoxelsEvaluateFewerShaderPoints) {
  const Scene scene = makeSphereScene(sphere());
  const std::vector<Ray> rays = testing::randomRays(3000, 9, 3.0f, 1.2f);
  AccelOptions o;
  o.gridResolution = 16;
  o.cacheBudgetTriangles = 2000;  // nearly every access refills
  uint64_t points[2];
  for (int refine = 0; refine < 2; ++refine) {
    o.refineContributors = refine == 1;
    GridAccelerator accel(scene, o);
    run(accel, rays);
    run(accel, rays);
    EXPECT_GT(accel.stats().capacityMisses, 0u);
    points[refine] = accel.stats().shaderPoints;
  }
  EXPECT_LT(points[1], points[0]);
}

}  // namespace
}  // namespace relief
