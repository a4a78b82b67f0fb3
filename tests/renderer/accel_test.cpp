// Tests of the grid accelerator: hits equal a brute-force search over every (displaced) triangle,
// occlusion agrees with intersection, and hit attributes are consistent.
#include "renderer/grid_accelerator.h"

#include <cmath>
#include <limits>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "geometry_test_util.h"

namespace relief {
namespace {

using testing::BruteForce;
using testing::makeSphereScene;
using testing::randomRays;
using testing::SphereOptions;

void expectMatchesBruteForce(const Scene& scene, const AccelOptions& options, int numRays,
                             float jitter) {
  auto accel = std::make_unique<GridAccelerator>(scene, options);
  BruteForce reference(scene, accel->positionStep());
  int numHits = 0;
  for (const Ray& ray : randomRays(numRays, 7, 3.0f, jitter)) {
    auto hit = accel->intersect(ray);
    auto expected = reference.intersect(ray);
    ASSERT_EQ(hit.has_value(), expected.has_value());
    EXPECT_EQ(accel->occluded(ray), expected.has_value());
    if (!hit) continue;
    ++numHits;
    EXPECT_EQ(hit->t, expected->t);  // bit-identical: the same triangles and the same test
    EXPECT_EQ(hit->meshIndex, expected->mesh);
    EXPECT_EQ(hit->triangleIndex, expected->triangle);
    EXPECT_EQ(hit->microIndex, expected->micro);
    EXPECT_NEAR(glm::length(hit->Ng), 1.0f, 1e-4f);
    EXPECT_LT(glm::dot(hit->Ng, ray.direction), 0.0f);  // outward faces seen from outside
    EXPECT_GE(hit->st.x, -1e-4f);
    EXPECT_LE(hit->st.x, 1.0001f);
    // The hit point lies at t along the ray.
    const glm::vec3 p = ray.origin + hit->t * ray.direction;
    EXPECT_LT(glm::length(p - hit->P), 1e-5f);
    // bary locates the hit on the input triangle: on it when undisplaced, within the
    // displacement bound of it otherwise.
    const Mesh& mesh = scene.meshes[hit->meshIndex];
    const uint32_t* idx = &mesh.indices[3 * size_t(hit->triangleIndex)];
    const glm::vec3 onInput = (1.0f - hit->bary.x - hit->bary.y) * mesh.P[idx[0]] +
                              hit->bary.x * mesh.P[idx[1]] + hit->bary.y * mesh.P[idx[2]];
    const bool displaced = options.displace && mesh.displacementIndex != UINT32_MAX;
    EXPECT_LT(glm::length(onInput - hit->P),
              displaced ? scene.displacements[0].boundWorld * 1.01f + 1e-4f : 1e-4f);
  }
  EXPECT_GT(numHits, numRays / 4);
  const AccelStats stats = accel->stats();
  EXPECT_EQ(stats.capacityMisses, 0u);  // unlimited budget
  if (scene.meshes[0].displacementIndex != UINT32_MAX && options.displace) {
    // Unique counts each micro-triangle of the filled voxels once; created counts it per voxel.
    EXPECT_GT(stats.uniqueDisplacedTriangles, 0u);
    EXPECT_LE(stats.uniqueDisplacedTriangles, stats.displacedTrianglesCreated);
  }
}

TEST(GridAccelerator, UndisplacedMatchesBruteForce) {
  SphereOptions o;
  o.displaced = false;
  expectMatchesBruteForce(makeSphereScene(o), AccelOptions{}, 500, 1.5f);
}

TEST(GridAccelerator, DisplaceFalseIgnoresShader) {
  Scene scene = makeSphereScene(SphereOptions{});
  AccelOptions options;
  options.displace = false;
  auto accel = makeGridAccelerator(scene, options);
  Scene flat = scene;
  flat.meshes[0].displacementIndex = UINT32_MAX;
  BruteForce reference(flat);
  for (const Ray& ray : randomRays(200, 3, 3.0f, 0.5f)) {
    auto hit = accel->intersect(ray);
    auto expected = reference.intersect(ray);
    ASSERT_EQ(hit.has_value(), expected.has_value());
    if (hit) {
      EXPECT_EQ(hit->t, expected->t);
    }
  }
  EXPECT_EQ(accel->stats().shaderPoints, 0u);
}

TEST(GridAccelerator, DisplacedMatchesBruteForce) {
  SphereOptions o;
  o.edgeLength = 0.08f;
  expectMatchesBruteForce(makeSphereScene(o), AccelOptions{}, 300, 1.5f);
}

TEST(GridAccelerator, DisplacedMatchesBruteForceAtEveryResolution) {
  SphereOptions o;
  o.edgeLength = 0.1f;
  for (int resolution : {1, 3, 7, 20}) {
    AccelOptions options;
    options.gridResolution = resolution;
    expectMatchesBruteForce(makeSphereScene(o), options, 100, 1.5f);
  }
}

// Dense voxels get a BVH by default or the paper's sub-voxel grid: both find exactly the
// brute-force hits (one voxel holds everything at resolution 1).
TEST(GridAccelerator, EitherDenseVoxelStructureMatchesBruteForce) {
  SphereOptions o;
  o.edgeLength = 0.08f;
  for (bool subVoxelGrid : {false, true})
    for (int resolution : {1, 4}) {
      SCOPED_TRACE(::testing::Message() << "subVoxelGrid " << subVoxelGrid << ", resolution " << resolution);
      AccelOptions options;
      options.subVoxelGrid = subVoxelGrid;
      options.gridResolution = resolution;
      expectMatchesBruteForce(makeSphereScene(o), options, 150, 1.5f);
    }
}

// Flat, axis-aligned geometry gives zero-thickness boxes and rays parallel to box faces: the
// BVH's quantized boxes must still hold their triangles. A floor of 2048 triangles at z = 0 and
// a wall at x = 0.25, hit by axis-parallel rays, rays grazing at tiny angles, and rays lying in
// the floor's plane, each compared with brute force.
TEST(GridAccelerator, FlatAxisAlignedGeometryMatchesBruteForceForGrazingRays) {
  Scene scene;
  Mesh mesh;
  constexpr int kCells = 32;
  auto quad = [&](glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
    const uint32_t base = uint32_t(mesh.P.size());
    mesh.P.insert(mesh.P.end(), {a, b, c, d});
    mesh.indices.insert(mesh.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  };
  for (int i = 0; i < kCells; ++i)
    for (int j = 0; j < kCells; ++j) {
      const float x0 = -1 + 2.0f * float(i) / kCells, x1 = -1 + 2.0f * float(i + 1) / kCells;
      const float y0 = -1 + 2.0f * float(j) / kCells, y1 = -1 + 2.0f * float(j + 1) / kCells;
      quad({x0, y0, 0}, {x1, y0, 0}, {x1, y1, 0}, {x0, y1, 0});
    }
  for (int j = 0; j < 8; ++j)
    quad({0.25f, -1, 0.125f * float(j)}, {0.25f, 1, 0.125f * float(j)}, {0.25f, 1, 0.125f * float(j + 1)},
         {0.25f, -1, 0.125f * float(j + 1)});
  scene.meshes.push_back(mesh);
  BruteForce reference(scene);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> pos(-1.2f, 1.2f), tiny(-1e-3f, 1e-3f);
  std::vector<Ray> rays;
  for (int i = 0; i < 300; ++i) {
    const float x = pos(rng), y = pos(rng);
    rays.push_back(Ray{{x, y, 2}, {0, 0, -1}, 0.0f, 1e30f});                  // straight down
    rays.push_back(Ray{{-2, y, 0.5f}, {1, 0, 0}, 0.0f, 1e30f});               // into the wall
    rays.push_back(Ray{{-2, y, 1e-4f}, {1, tiny(rng), -1e-4f}, 0.0f, 1e30f});  // grazing the floor
    rays.push_back(Ray{{x, -2, 0}, {tiny(rng), 1, 0}, 0.0f, 1e30f});           // in its plane
  }
  // Directions far from unit length: the slab arithmetic must not depend on it.
  for (float length : {1e-22f, 1e-12f, 1e12f}) {
    rays.push_back(Ray{{-2, 0.3f, 0.5f}, {length, 0, 0}, 0.0f, 1e30f});
    rays.push_back(Ray{{0.1f, 0.2f, 2}, {0, 0, -length}, 0.0f, 1e30f});
  }
  for (int resolution : {1, 3}) {
    AccelOptions options;
    options.gridResolution = resolution;
    auto accel = makeGridAccelerator(scene, options);
    int hits = 0;
    for (const Ray& ray : rays) {
      const auto hit = accel->intersect(ray);
      const auto expected = reference.intersect(ray);
      ASSERT_EQ(hit.has_value(), expected.has_value()) << "from " << ray.origin.x << " " << ray.origin.y << " " << ray.origin.z;
      EXPECT_EQ(accel->occluded(ray), expected.has_value());
      if (!hit) continue;
      ++hits;
      EXPECT_EQ(hit->t, expected->t);
      EXPECT_EQ(hit->triangleIndex, expected->triangle);
    }
    EXPECT_GT(hits, 600);
  }
}

TEST(GridAccelerator, RespectsRayInterval) {
  SphereOptions o;
  o.displaced = false;
  Scene scene = makeSphereScene(o);
  auto accel = makeGridAccelerator(scene, AccelOptions{});
  Ray ray{{0, 0, -5}, {0, 0, 1}, 0.0f, 1e30f};
  auto near = accel->intersect(ray);
  ASSERT_TRUE(near);
  EXPECT_NEAR(near->t, 4.0f, 1e-2f);
  ray.tMin = near->t + 1e-3f;
  auto far = accel->intersect(ray);
  ASSERT_TRUE(far);
  EXPECT_NEAR(far->t, 6.0f, 1e-2f);
  ray.tMax = 5.5f;
  EXPECT_FALSE(accel->intersect(ray));
  EXPECT_FALSE(accel->occluded(ray));
  // Rays that miss the grid entirely, and axis-parallel rays starting inside it.
  EXPECT_FALSE(accel->intersect(Ray{{5, 5, 5}, {1, 0, 0}, 0.0f, 1e30f}));
  auto inside = accel->intersect(Ray{{0, 0, 0}, {0, 1, 0}, 0.0f, 1e30f});
  ASSERT_TRUE(inside);
  EXPECT_NEAR(inside->t, 1.0f, 1e-2f);
}

TEST(GridAccelerator, MalformedRaysNeverHit) {
  SphereOptions o;
  Scene scene = makeSphereScene(o);
  auto accel = makeGridAccelerator(scene, AccelOptions{});
  const float nan = std::nanf(""), inf = std::numeric_limits<float>::infinity();
  for (Ray ray : {Ray{{0, 0, -5}, {0, 0, 0}, 0.0f, 1e30f}, Ray{{nan, 0, -5}, {0, 0, 1}, 0.0f, 1e30f},
                  Ray{{0, 0, -5}, {0, inf, 1}, 0.0f, 1e30f}}) {
    EXPECT_FALSE(accel->intersect(ray));
    EXPECT_FALSE(accel->occluded(ray));
  }
}

// The contributor grid lists every triangle in every voxel its box, grown by the displacement
// bound, overlaps; an explicit resolution is honoured along the longest axis.
// Each triangle is listed in every voxel its shape, grown by the displacement bound, may reach
// (checked on a lattice of points on the triangle: a point within the grown voxel means listed),
// never in a voxel its grown box misses, and not in every voxel of its box: the diagonal triangles
// of a coarse sphere skip voxels their box covers but their plane does not.
TEST(ContributorGrid, ListsTrianglesInEveryVoxelTheirShapeMayReach) {
  SphereOptions o;
  o.nu = 12, o.nv = 6;
  const Scene scene = makeSphereScene(o);
  AccelOptions options;
  options.gridResolution = 7;
  const ContributorGrid grid(scene, options);
  EXPECT_EQ(std::max({grid.resolution().x, grid.resolution().y, grid.resolution().z}), 7);
  const Mesh& mesh = scene.meshes[0];
  const float bound = scene.displacements[0].boundWorld;
  uint64_t expectedEntries = 0, boxEntries = 0;
  for (uint32_t v = 0; v < grid.numVoxels(); ++v) {
    const Bounds3 box = grid.voxelBounds(v);
    Bounds3 reach = box;  // shrunk a little: shapes that merely touch may go either way
    reach.lo -= glm::vec3(bound - 1e-3f), reach.hi += glm::vec3(bound - 1e-3f);
    std::set<uint32_t> listed(grid.contributors(v).begin(), grid.contributors(v).end());
    for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
      const glm::vec3 a = mesh.P[mesh.indices[3 * t]], b = mesh.P[mesh.indices[3 * t + 1]],
                      c = mesh.P[mesh.indices[3 * t + 2]];
      bool reaches = false;
      constexpr int kSteps = 24;
      for (int i = 0; i <= kSteps && !reaches; ++i)
        for (int j = 0; i + j <= kSteps && !reaches; ++j) {
          const glm::vec3 p = a + (b - a) * (float(i) / kSteps) + (c - a) * (float(j) / kSteps);
          reaches = glm::all(glm::greaterThanEqual(p, reach.lo)) && glm::all(glm::lessThanEqual(p, reach.hi));
        }
      if (reaches) {
        EXPECT_TRUE(listed.count(grid.globalId(0, t))) << "voxel " << v << " triangle " << t;
      }
      Bounds3 tb;
      for (const glm::vec3& p : {a, b, c}) tb.extend(p);
      Bounds3 grown = tb;
      grown.lo -= glm::vec3(bound + 0.01f), grown.hi += glm::vec3(bound + 0.01f);
      if (!grown.overlaps(box)) {
        EXPECT_FALSE(listed.count(grid.globalId(0, t)));
      }
      tb.lo -= glm::vec3(bound), tb.hi += glm::vec3(bound);
      boxEntries += tb.overlaps(box);  // what listing by boxes gives
    }
    expectedEntries += listed.size();
  }
  EXPECT_EQ(expectedEntries, grid.numEntries());
  EXPECT_LT(grid.numEntries(), boxEntries);  // fewer than listing by boxes
  // Automatic resolution: bounded, and at least 4 displacement bounds per voxel.
  const ContributorGrid automatic(scene, AccelOptions{});
  EXPECT_GE(automatic.voxelSize(), 4.0f * bound * 0.99f);
}

// A few input triangles displaced finely get voxels by their micro-triangles (a voxel's fill
// holds scratch and time in proportion to them), never narrower than kMinVoxelBounds bounds.
TEST(ContributorGrid, FineDisplacementGetsVoxelsForItsMicroTriangles) {
  auto longestResolution = [](const ContributorGrid& g) {
    return std::max({g.resolution().x, g.resolution().y, g.resolution().z});
  };
  SphereOptions o;
  o.nu = 8, o.nv = 4;
  o.km = 0.01f;
  o.edgeLength = 0.05f;
  const Scene coarse = makeSphereScene(o);
  const int byInput = longestResolution(ContributorGrid(coarse, AccelOptions{}));
  EXPECT_EQ(byInput, int(std::lround(kAutoGridFactor * std::cbrt(double(coarse.meshes[0].numTriangles())))));

  o.edgeLength = 0.005f;  // 4^8 micro-triangles per input triangle at the depth limit
  const Scene fine = makeSphereScene(o);
  const double micro = estimatedMicroTriangles(fine.meshes[0], fine.displacements[0]);
  EXPECT_EQ(micro, 65536.0 * fine.meshes[0].numTriangles());
  const ContributorGrid fineGrid(fine, AccelOptions{});
  EXPECT_EQ(longestResolution(fineGrid), int(std::lround(std::cbrt(micro / kMicroTrianglesPerCell))));
  EXPECT_GT(longestResolution(fineGrid), byInput);
  AccelOptions undisplaced;
  undisplaced.displace = false;  // no micro-triangles: the input rule alone
  EXPECT_EQ(longestResolution(ContributorGrid(fine, undisplaced)), byInput);

  o.km = 0.1f;  // a large bound caps it: 2 bounds a voxel, not 4
  const Scene bumpy = makeSphereScene(o);
  const ContributorGrid capped(bumpy, AccelOptions{});
  EXPECT_GE(capped.voxelSize(), kMinVoxelBounds * o.km * 0.99f);
  EXPECT_LT(capped.voxelSize(), kVoxelsPerBound * o.km);
}

// The automatic resolution depends on the scene's shape, not its units: a sphere scaled by 1e-11
// gets the grid of the unscaled one (an absolute floor of 1e-6 units made it one voxel), and a
// scene 2^31 bounds across is capped, not overflowed into a single voxel (a floor of +-1e9
// under a bound of 0.06 held 34M micro-triangles in its one voxel).
TEST(ContributorGrid, AutomaticResolutionIsTheSameInAnyUnits) {
  SphereOptions o;
  o.nu = 32, o.nv = 16;
  o.km = 0.02f;
  o.edgeLength = 0.03f;
  const Scene unit = makeSphereScene(o);
  const glm::ivec3 expected = ContributorGrid(unit, AccelOptions{}).resolution();
  ASSERT_GT(expected.x, 4);
  for (float scale : {1e-11f, 1e-20f, 1e6f}) {
    Scene scaled = makeSphereScene(o);
    for (glm::vec3& p : scaled.meshes[0].P) p *= scale;
    scaled.displacements[0].boundWorld *= scale;
    scaled.displacements[0].edgeLength *= scale;
    EXPECT_EQ(ContributorGrid(scaled, AccelOptions{}).resolution(), expected) << scale;
  }
  Scene floor;
  Mesh square;
  square.P = {{-1e9f, 0, -1e9f}, {1e9f, 0, -1e9f}, {1e9f, 0, 1e9f}, {-1e9f, 0, 1e9f}};
  square.indices = {0, 1, 2, 0, 2, 3};
  floor.meshes.push_back(square);
  Displacement d = unit.displacements[0];
  d.boundWorld = 0.06f;
  d.edgeLength = 1e8f;
  floor.displacements.push_back(d);
  floor.meshes[0].displacementIndex = 0;
  const ContributorGrid wide(floor, AccelOptions{});
  EXPECT_GT(wide.resolution().x, 1);
  EXPECT_GT(wide.resolution().z, 1);
}

// A budget that holds only a few voxels makes every refill a heavy one, and a generous
// displacement bound makes heavy voxels (the automatic grid keeps a voxel several bounds wide). So
// under a budget the automatic resolution is raised, past the bound's cap, until the heaviest
// voxel's estimate fits the budget kVoxelsPerBudget times: a sphere with a bound of 0.5 got 3
// voxels across and rendered 390 times slower at a 7% budget than unlimited.
TEST(ContributorGrid, ATightBudgetGetsVoxelsItCanHoldWhateverTheBound) {
  SphereOptions o;
  o.nu = 32, o.nv = 16;
  o.km = 0.02f;
  o.edgeLength = 0.03f;
  Scene scene = makeSphereScene(o);
  scene.displacements[0].boundWorld = 0.4f;  // 20 times what the shader needs
  const std::vector<Ray> rays = randomRays(400, 11, 3.0f, 1.2f);
  auto keysOf = [&](GridAccelerator& accel) { return testing::hitKeys(accel, rays); };
  GridAccelerator unlimited(scene, AccelOptions{});
  const auto expected = keysOf(unlimited);
  const AccelStats full = unlimited.stats();
  EXPECT_EQ(unlimited.grid().budgetRefinements(), 0);
  const int capped = unlimited.grid().resolution().x;
  ASSERT_LE(capped, 4);  // the bound's cap: a few voxels across

  AccelOptions tight;
  tight.cacheBudgetTriangles = full.uniqueDisplacedTriangles / 12;
  GridAccelerator raised(scene, tight);
  EXPECT_GT(raised.grid().budgetRefinements(), 0);
  EXPECT_GT(raised.grid().resolution().x, capped);
  EXPECT_LE(raised.grid().resolution().x, kMaxBudgetGridResolution);
  EXPECT_EQ(keysOf(raised), expected);
  // Voxels the budget holds (the estimate is about half of what a bumpy surface stores), so a
  // refill remakes a fraction of what the capped grid's refills do.
  EXPECT_LT(raised.maxVoxelTriangles(), tight.cacheBudgetTriangles);
  AccelOptions sameGrid = tight;
  sameGrid.gridResolution = capped;  // explicit resolutions are left as asked
  GridAccelerator thrashing(scene, sameGrid);
  EXPECT_EQ(thrashing.grid().resolution().x, capped);
  EXPECT_EQ(keysOf(thrashing), expected);
  EXPECT_GT(thrashing.maxVoxelTriangles(), tight.cacheBudgetTriangles);
  EXPECT_LT(2 * raised.stats().displacedTrianglesCreated, thrashing.stats().displacedTrianglesCreated)
      << raised.grid().resolution().x << " voxels across against " << capped;
}

// An explicit resolution is lowered until the grid has at most kMaxGridVoxels voxels: 1024 along
// each axis of a sphere's box made a billion voxels (19 GB before any geometry).
TEST(ContributorGrid, ExplicitResolutionsStayWithinTheVoxelBudget) {
  SphereOptions o;
  o.nu = 8, o.nv = 4;
  const Scene scene = makeSphereScene(o);
  AccelOptions options;
  options.gridResolution = 1024;
  const ContributorGrid grid(scene, options);
  const glm::ivec3 r = grid.resolution();
  EXPECT_LE(uint64_t(r.x) * uint64_t(r.y) * uint64_t(r.z), kMaxGridVoxels);
  EXPECT_GT(uint64_t(r.x) * uint64_t(r.y) * uint64_t(r.z), kMaxGridVoxels / 2);  // lowered, not collapsed
  options.gridResolution = 64;  // within the budget: as asked
  EXPECT_EQ(ContributorGrid(scene, options).resolution().x, 64);
}

// Nor may an explicit resolution list more than kMinExplicitEntryLimit entries (or 256 per
// triangle): a bound large against the voxels lists each triangle in a volume of them (819M
// entries and 9.6 GB at 128 voxels across).
TEST(ContributorGrid, ExplicitResolutionsStayWithinTheEntryLimit) {
  SphereOptions o;
  o.nu = 16, o.nv = 8;
  Scene generous = makeSphereScene(o);
  generous.displacements[0].boundWorld = 0.4f;
  AccelOptions options;
  options.gridResolution = 128;
  const ContributorGrid lowered(generous, options);
  EXPECT_LT(lowered.resolution().x, 128);
  EXPECT_GT(lowered.resolution().x, 16);
  EXPECT_LE(lowered.numEntries(), kMinExplicitEntryLimit);
}

// Big triangles stacked on one another would each be listed in thousands of voxels of a
// resolution chosen by their count: the automatic resolution is halved until the entries are
// bounded, and the coarser grid still finds them.
TEST(ContributorGrid, StackedBigTrianglesKeepTheEntriesBounded) {
  SphereOptions o;
  o.nu = 8, o.nv = 4;
  o.km = 0.001f;  // a bound too small to cap the resolution
  Scene scene = makeSphereScene(o);
  Mesh stack;
  constexpr uint32_t kCopies = 10000;
  stack.P = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  for (uint32_t k = 0; k < kCopies; ++k) stack.indices.insert(stack.indices.end(), {0, 1, 2, 0, 2, 3});
  scene.meshes.push_back(stack);
  const uint32_t triangles = scene.meshes[0].numTriangles() + 2 * kCopies;
  const ContributorGrid grid(scene, AccelOptions{});
  EXPECT_GT(grid.coarsenings(), 0);
  size_t entries = 0;
  for (uint32_t v = 0; v < grid.numVoxels(); ++v) entries += grid.contributors(v).size();
  EXPECT_LE(entries, std::max(kMinEntryLimit, size_t(kMaxEntriesPerTriangle) * triangles));
  EXPECT_GT(entries, size_t(2 * kCopies));  // each copy is still listed, in several voxels
  // An explicit resolution is the user's to choose: it is kept.
  AccelOptions fine;
  fine.gridResolution = 8;
  const ContributorGrid kept(scene, fine);
  EXPECT_EQ(kept.coarsenings(), 0);
  EXPECT_EQ(std::max({kept.resolution().x, kept.resolution().y, kept.resolution().z}), 8);
  // And the stack is found through the coarse grid, from inside the sphere.
  auto accel = makeGridAccelerator(scene, AccelOptions{});
  const std::optional<Hit> hit = accel->intersect(Ray{{0.3f, 0.2f, -0.5f}, {0, 0, 1}, 0.0f, 1e30f});
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->meshIndex, 1u);
  EXPECT_NEAR(hit->t, 0.5f, 1e-5f);
}

TEST(GridAccelerator, EmptySceneNeverHits) {
  Scene scene;
  auto accel = makeGridAccelerator(scene, AccelOptions{});
  EXPECT_FALSE(accel->intersect(Ray{{0, 0, -5}, {0, 0, 1}, 0.0f, 1e30f}));
  EXPECT_FALSE(accel->occluded(Ray{{0, 0, -5}, {0, 0, 1}, 0.0f, 1e30f}));
}

}  // namespace
}  // namespace relief
