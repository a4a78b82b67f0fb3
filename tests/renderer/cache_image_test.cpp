// Determinism of whole images through the geometry cache: bit-identical films at cache budgets of
// 5%, 20% and unlimited, for every pixel order and for one and two threads (each walk of render.h),
// with the budget check mode on (no fill may leave more than the budget resident, apart from pinned
// voxels).
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "geometry_test_util.h"
#include "render_test_util.h"
#include "renderer/grid_accelerator.h"
#include "renderer/render.h"
#include "renderer/rib_reader.h"

namespace relief {
namespace {

// A bumpy displaced sphere over a floor, lit from the side (shadow rays reach other voxels).
Scene bumpyScene() {
  test::TestShaderProvider shaders;
  RibReadOptions options;
  options.shaders = &shaders;
  SceneError error;
  std::optional<Scene> scene = readRibString(
      "Format 40 30 1\nProjection \"perspective\" \"fov\" [40]\n"
      "Translate 0 0 5\nRotate -20 1 0 0\nWorldBegin\n"
      "LightSource \"distantlight\" 1 \"from\" [-2 3 -1.5] \"to\" [0 0 0]\n"
      "LightSource \"ambientlight\" 2 \"intensity\" [0.1]\n"
      "AttributeBegin\nAttribute \"displacementbound\" \"float sphere\" [0.1]\n"
      "Attribute \"relief\" \"float edgelength\" [0.04]\n"
      "Displacement \"push\" \"Km\" [0.0]\nSphere 1 -1 1 360\nAttributeEnd\n"
      "Polygon \"P\" [-4 -1.3 -4  -4 -1.3 4  4 -1.3 4  4 -1.3 -4]\nWorldEnd\n",
      "bumpy.rib", options, &error);
  EXPECT_TRUE(scene) << error.format();
  if (!scene) return Scene{};
  // Swap in the bumpy test displacement (Km 0.1, freq 4) for an interesting surface.
  scene->displacements.at(0).shader = testing::makeShader(testing::bumpyEntry, 0.1f, 4.0f);
  return std::move(*scene);
}

struct Result {
  Film film{1, 1};
  AccelStats stats;
  RenderStats render;
};

Result renderWith(const Scene& scene, PixelOrder order, int threads, uint64_t budget, bool refine,
                  bool sharedWalk = false, int gridResolution = 12) {
  AccelOptions accelOptions;
  accelOptions.cacheBudgetTriangles = budget;
  accelOptions.gridResolution = gridResolution;
  accelOptions.refineContributors = refine;
  accelOptions.checkBudget = true;
  GridAccelerator accel(scene, accelOptions);
  Result r;
  r.film = Film(scene.width, scene.height);
  RenderOptions renderOptions;
  renderOptions.order = order;
  renderOptions.threads = threads;
  renderOptions.sharedWalk = sharedWalk;
  r.render = render(scene, accel, renderOptions, &r.film);
  r.stats = accel.stats();
  return r;
}

TEST(CacheImage, BitIdenticalAcrossBudgetsOrdersAndThreads) {
  const Scene scene = bumpyScene();
  ASSERT_FALSE(scene.meshes.empty());
  const Result reference = renderWith(scene, PixelOrder::Hilbert, 1, UINT64_MAX, false);
  const uint64_t unique = reference.stats.uniqueDisplacedTriangles;
  ASSERT_GT(unique, 10000u);
  EXPECT_GT(reference.film.pixel(20, 15).r, 0.05f);  // the sphere is there and lit
  for (uint64_t budget : {UINT64_MAX, unique / 5, unique / 20}) {
    for (PixelOrder order : {PixelOrder::Scanline, PixelOrder::Bucket, PixelOrder::Hilbert}) {
      for (auto [threads, shared] : {std::pair{1, false}, std::pair{2, false}, std::pair{2, true}}) {
        SCOPED_TRACE(std::string(pixelOrderName(order)) + ", " + std::to_string(threads) +
                     " threads, budget " + std::to_string(budget) + (shared ? ", shared walk" : ""));
        const Result r = renderWith(scene, order, threads, budget, true, shared);
        EXPECT_EQ(r.render.cameraRays, reference.render.cameraRays);
        EXPECT_EQ(r.render.shadowRays, reference.render.shadowRays);
        EXPECT_TRUE(r.film.data() == reference.film.data());
        EXPECT_EQ(r.stats.budgetViolations, 0u);
        EXPECT_EQ(r.stats.uniqueDisplacedTriangles, unique);
        EXPECT_EQ(r.stats.hits + r.stats.compulsoryMisses + r.stats.capacityMisses,
                  r.stats.accesses);
        if (budget != UINT64_MAX) {
          EXPECT_GT(r.stats.capacityMisses, 0u);
          EXPECT_LE(r.stats.peakResidentTriangles,
                    budget + uint64_t(threads) * r.stats.maxVoxelTriangles);
          EXPECT_LE(r.stats.residentTriangles, budget + uint64_t(threads) * r.stats.maxVoxelTriangles);
        } else {
          EXPECT_EQ(r.stats.capacityMisses, 0u);
        }
      }
    }
  }
}

// The grid is a means, not part of the picture: a coarse grid, the test's usual one and grids far
// finer than the automatic choice give the same bits (vertices used to be snapped to a lattice of
// 1/16384 of a voxel, so grids finer than 16 voxels across moved them).
TEST(CacheImage, BitIdenticalAcrossGridResolutions) {
  const Scene scene = bumpyScene();
  ASSERT_FALSE(scene.meshes.empty());
  const Result reference = renderWith(scene, PixelOrder::Hilbert, 1, UINT64_MAX, true);
  for (int resolution : {3, 17, 40}) {
    SCOPED_TRACE(std::to_string(resolution) + " voxels across");
    const Result r = renderWith(scene, PixelOrder::Hilbert, 1, UINT64_MAX, true, false, resolution);
    EXPECT_EQ(r.render.shadowRays, reference.render.shadowRays);
    EXPECT_TRUE(r.film.data() == reference.film.data());
  }
}

// The smallest threaded case on its own (one reference, one two-thread render at a 5% budget), so
// that tools/tsan.sh can run it under ThreadSanitizer in reasonable time.
TEST(CacheThreads, TwoThreadsAtASmallBudgetMatchOneThreadUnlimited) {
  const Scene scene = bumpyScene();
  ASSERT_FALSE(scene.meshes.empty());
  const Result reference = renderWith(scene, PixelOrder::Hilbert, 1, UINT64_MAX, false);
  for (bool shared : {false, true}) {
    SCOPED_TRACE(shared ? "shared walk" : "stretches");
    const Result r = renderWith(scene, PixelOrder::Scanline, 2,
                                reference.stats.uniqueDisplacedTriangles / 20, true, shared);
    EXPECT_TRUE(r.film.data() == reference.film.data());
    EXPECT_EQ(r.render.shadowRays, reference.render.shadowRays);
    EXPECT_GT(r.stats.capacityMisses, 0u);
    EXPECT_GT(r.stats.droppedContributors, 0u);
    EXPECT_EQ(r.stats.budgetViolations, 0u);
  }
}

// The check counts only what eviction could have freed: a pinned voxel may keep the resident set
// over budget, and the next fill after it is released evicts it.
TEST(CacheImage, BudgetCheckAllowsPinnedOvershootOnly) {
  GeometryCache cache(4, 10);
  cache.setCheckBudget(true);
  auto build = [](uint32_t voxel) {
    auto g = std::make_unique<VoxelGeometry>();
    for (uint32_t i = 0; i < 8; ++i) g->appendKey(voxel, i);
    return g;
  };
  cache.acquire(0, 1, build);  // kept pinned
  cache.acquire(1, 2, build);  // 16 resident, voxel 0 pinned: allowed
  cache.release(1);
  EXPECT_EQ(cache.stats().budgetViolations, 0u);
  cache.acquire(2, 3, build);  // voxel 1 evictable: evicted, 16 resident again
  cache.release(2);
  EXPECT_EQ(cache.stats().budgetViolations, 0u);
  EXPECT_EQ(cache.stats().evictions, 1u);
  cache.release(0);
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// The "cachemiss" AOV through the real geometry cache: every fill is charged to the pixel whose
// ray caused it, so the map sums to the cache's misses, and a tight budget adds capacity misses.
TEST(CacheImage, CacheMissAovSumsToTheCacheMisses) {
  const Scene scene = bumpyScene();
  ASSERT_FALSE(scene.meshes.empty());
  for (uint64_t budget : {UINT64_MAX, uint64_t(3000)}) {
    AccelOptions accelOptions;
    accelOptions.cacheBudgetTriangles = budget;
    accelOptions.gridResolution = 12;
    GridAccelerator accel(scene, accelOptions);
    Film film(scene.width, scene.height), misses(scene.width, scene.height);
    AovFilms aovs;
    aovs.cacheMiss = &misses;
    RenderOptions renderOptions;
    renderOptions.threads = 2;
    renderOptions.sharedWalk = budget != UINT64_MAX;  // pixels put aside keep their misses
    render(scene, accel, renderOptions, &film, aovs);
    double total = 0;
    for (int y = 0; y < scene.height; ++y)
      for (int x = 0; x < scene.width; ++x) total += misses.pixel(x, y).r;
    const AccelStats s = accel.stats();
    EXPECT_GT(s.compulsoryMisses, 10u);
    EXPECT_EQ(total, double(s.compulsoryMisses + s.capacityMisses)) << budget;
    if (budget != UINT64_MAX) {
      EXPECT_GT(s.capacityMisses, 0u);
    }
    // No flatness in this scene: nothing simplified, every micro-triangle counted on both sides.
    EXPECT_GT(s.trianglesBeforeSimplification, 0u);
    EXPECT_EQ(s.trianglesAfterSimplification, s.trianglesBeforeSimplification);
  }
}

}  // namespace
}  // namespace relief
