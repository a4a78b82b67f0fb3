// Invariants of the geometry cache: answers independent of budget, order and threads; the
// resident set bounded by the budget plus one voxel; statistics that add up.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <thread>
#include <tuple>

#include <gtest/gtest.h>

#include "geometry_test_util.h"
#include "renderer/grid_accelerator.h"
#include "renderer/intersect.h"

namespace relief {
namespace {

using testing::HitKey;
using testing::hitKeys;
using testing::hitKeysOnTwoThreads;

using testing::makeSphereScene;
using testing::SphereOptions;

SphereOptions cacheOptions() {
  SphereOptions o;
  o.nu = 24, o.nv = 12;
  o.edgeLength = 0.05f;
  return o;
}

// Rays in a scattered order (each ray far from the previous one), so a small cache thrashes.
std::vector<Ray> scatteredRays() { return testing::randomRays(3000, 5, 3.0f, 1.2f); }

TEST(GeometryCache, HitsIndependentOfBudgetAndThreads) {
  const Scene scene = makeSphereScene(cacheOptions());
  const std::vector<Ray> rays = scatteredRays();

  // Many small voxels, so that a 5% budget holds a good number of them.
  AccelOptions unlimitedOptions;
  unlimitedOptions.gridResolution = 16;
  GridAccelerator unlimited(scene, unlimitedOptions);
  const std::vector<HitKey> expected = hitKeys(unlimited, rays);
  const AccelStats full = unlimited.stats();
  ASSERT_GT(full.residentTriangles, 10000u);
  EXPECT_EQ(full.capacityMisses, 0u);
  EXPECT_EQ(full.residentTriangles, full.displacedTrianglesCreated);

  // A second pass over the same rays is served entirely from the cache.
  EXPECT_EQ(hitKeys(unlimited, rays), expected);
  const AccelStats again = unlimited.stats();
  EXPECT_EQ(again.compulsoryMisses, full.compulsoryMisses);
  EXPECT_EQ(again.hits - full.hits, again.accesses - full.accesses);

  AccelOptions small = unlimitedOptions;
  small.cacheBudgetTriangles = full.residentTriangles / 20;  // 5%
  GridAccelerator limited(scene, small);
  EXPECT_EQ(hitKeys(limited, rays), expected);
  const AccelStats ls = limited.stats();
  EXPECT_GT(ls.capacityMisses, 0u);
  EXPECT_EQ(ls.compulsoryMisses, full.compulsoryMisses);
  // The same rays in the same order visit the same voxels, whatever is resident.
  EXPECT_EQ(ls.accesses, full.accesses);
  EXPECT_GT(ls.displacedTrianglesCreated, full.displacedTrianglesCreated);
  EXPECT_LE(ls.peakResidentTriangles, small.cacheBudgetTriangles + limited.maxVoxelTriangles());
  EXPECT_LE(ls.residentTriangles, small.cacheBudgetTriangles);
  EXPECT_EQ(ls.uniqueDisplacedTriangles, full.uniqueDisplacedTriangles);

  // Two threads sharing one small cache, each taking every other ray.
  GridAccelerator shared(scene, small);
  EXPECT_EQ(hitKeysOnTwoThreads(shared, rays), expected);
  const AccelStats ts = shared.stats();
  EXPECT_EQ(ts.compulsoryMisses, full.compulsoryMisses);  // every voxel is filled once first
  // Each thread pins at most one voxel at a time, so at most one voxel per thread overshoots.
  EXPECT_LE(ts.peakResidentTriangles, small.cacheBudgetTriangles + 2 * shared.maxVoxelTriangles());
}

TEST(GeometryCache, OcclusionIndependentOfBudget) {
  const Scene scene = makeSphereScene(cacheOptions());
  const std::vector<Ray> rays = scatteredRays();
  AccelOptions tiny;
  tiny.gridResolution = 16;
  GridAccelerator unlimited(scene, tiny);
  tiny.cacheBudgetTriangles = 1;  // every fill evicts everything unpinned
  GridAccelerator limited(scene, tiny);
  for (const Ray& ray : rays) {
    const bool expected = unlimited.intersect(ray).has_value();
    EXPECT_EQ(unlimited.occluded(ray), expected);
    EXPECT_EQ(limited.occluded(ray), expected);
  }
  EXPECT_LE(limited.stats().residentTriangles, limited.maxVoxelTriangles());
}

TEST(GeometryCache, StorageUsesNarrowIndicesAndSubGrids) {
  const Scene scene = makeSphereScene(cacheOptions());
  AccelOptions options;
  options.gridResolution = 4;  // large voxels: dense enough for sub-voxel grids
  GridAccelerator accel(scene, options);
  auto expected = testing::BruteForce(scene, accel.positionStep());
  for (const Ray& ray : testing::randomRays(200, 11, 3.0f, 1.2f)) {
    auto hit = accel.intersect(ray);
    auto ref = expected.intersect(ray);
    ASSERT_EQ(hit.has_value(), ref.has_value());
    if (hit) {
      EXPECT_EQ(hit->t, ref->t);
      EXPECT_EQ(hit->microIndex, ref->micro);
    }
  }
  EXPECT_GT(accel.maxVoxelTriangles(), kSubGridThreshold);
}

// The cache on its own: lookup-or-fill, pins and eviction with a synthetic builder.
TEST(GeometryCache, FillsOnceAndNeverEvictsPinnedVoxels) {
  GeometryCache cache(8, 10);
  int builds = 0;
  auto build = [&](uint32_t voxel) {
    ++builds;
    auto g = std::make_unique<VoxelGeometry>();
    for (uint32_t i = 0; i < 6; ++i) g->appendKey(voxel, i);
    return g;
  };
  const VoxelGeometry* g0 = cache.acquire(0, 1, build);
  ASSERT_NE(g0, nullptr);
  EXPECT_EQ(cache.acquire(0, 2, build), g0);  // second pin, no rebuild
  EXPECT_EQ(builds, 1);
  // Over budget while voxel 0 is pinned: it must survive.
  const VoxelGeometry* g1 = cache.acquire(1, 3, build);
  EXPECT_EQ(builds, 2);
  EXPECT_EQ(g0->key(0).first, 0u);
  EXPECT_EQ(g1->key(0).first, 1u);
  cache.release(0), cache.release(0), cache.release(1);
  // Now voxel 0 is the least recently used and unpinned: filling voxel 2 evicts it.
  cache.acquire(2, 4, build);
  cache.release(2);
  const CacheStats s = cache.stats();
  EXPECT_LE(s.residentTriangles, 10u);
  EXPECT_EQ(s.compulsoryMisses, 3u);
  cache.acquire(0, 5, build);
  cache.release(0);
  EXPECT_EQ(cache.stats().capacityMisses, 1u);
  EXPECT_EQ(builds, 4);
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// The compact per-voxel storage returns exactly what was put in: keys across segment boundaries
// (input triangle changes) and micro ids of every width, barycentrics in every encoding.
// Undisplaced input triangles dense in a voxel go through the cache (stored whole, with a
// sub-voxel grid); the nearest hit, its triangle and its barycentrics must be what testing every
// triangle gives (with vertices shared between triangles), and none of it may show in the
// displaced-geometry statistics.
TEST(GeometryCache, DenseUndisplacedVoxelsMatchBruteForce) {
  SphereOptions o;
  o.nu = 96, o.nv = 48;  // 9,216 triangles in one voxel
  o.displaced = false;
  const Scene scene = makeSphereScene(o);
  AccelOptions options;
  options.gridResolution = 1;
  GridAccelerator accel(scene, options);
  const Mesh& mesh = scene.meshes[0];
  int hits = 0;
  for (const Ray& ray : scatteredRays()) {
    const std::optional<Hit> hit = accel.intersect(ray);
    const WatertightRay wr(ray);
    float bestT = ray.tMax;
    uint32_t bestTriangle = UINT32_MAX;
    TriangleHit th, best{};
    for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
      const glm::vec3 a = mesh.P[mesh.indices[3 * t]], b = mesh.P[mesh.indices[3 * t + 1]],
                      c = mesh.P[mesh.indices[3 * t + 2]];
      if (intersectTriangle(wr, a, b, c, ray.tMin, bestT, th)) bestT = th.t, bestTriangle = t, best = th;
    }
    ASSERT_EQ(hit.has_value(), bestTriangle != UINT32_MAX);
    if (!hit) continue;
    ++hits;
    EXPECT_EQ(hit->t, bestT);
    EXPECT_EQ(hit->triangleIndex, bestTriangle);
    EXPECT_EQ(hit->bary, glm::vec2(best.b1, best.b2));
  }
  EXPECT_GT(hits, 1000);
  const AccelStats s = accel.stats();
  EXPECT_EQ(s.accesses, 0u);
  EXPECT_EQ(s.uniqueDisplacedTriangles, 0u);
  EXPECT_EQ(s.peakResidentTriangles, 0u);
  // Whole input triangles share their vertices in a voxel (their barycentrics are their corners'),
  // so the closed mesh keeps about one vertex per two triangles, not three per triangle.
  const auto g = accel.buildVoxelUncached(0);
  EXPECT_EQ(g->numTriangles(), mesh.numTriangles());
  EXPECT_LT(g->numVertices(), g->numTriangles() * 6 / 10);
}

TEST(VoxelStorage, KeysAndBarycentricsRoundTrip) {
  if constexpr (std::endian::native != std::endian::little) GTEST_SKIP() << "the packed forms are little-endian";
  VoxelGeometry g;
  const std::pair<uint32_t, uint32_t> keys[] = {
      {7, 1}, {7, 2}, {7, 0x12345}, {7, 0x12346}, {9, 0x12346}, {9, 3}, {4000000000u, 0xffffffffu}};
  for (auto [t, m] : keys) g.appendKey(t, m);
  ASSERT_EQ(g.numTriangles(), 7u);
  for (uint32_t i = 0; i < 7; ++i) EXPECT_EQ(g.key(i), keys[i]) << i;
  for (uint32_t m : {0u, 1u, 0x12345u, 0xdeadbeefu, 0xffffffffu})
    EXPECT_EQ(VoxelGeometry::unpackMicro(VoxelGeometry::packMicro(m)), m);
  // Ids of one input triangle share a segment, whatever their path codes and ranks.
  const uint32_t rank = 1u << kMicroRankBits;
  const size_t before = g.segments.size();
  for (uint32_t path = 1; path < 512; path += 37)
    for (uint32_t r = 0; r < 20; ++r) g.appendKey(11, path * rank + r);
  EXPECT_EQ(g.segments.size(), before + 1);
  for (uint32_t i = 7, path = 1; path < 512; path += 37)
    for (uint32_t r = 0; r < 20; ++r, ++i) ASSERT_EQ(g.key(i), std::make_pair(11u, path * rank + r));
  // Packed, the keys read back the same, the micro ids in as many bits as the largest needs.
  const uint32_t total = g.numTriangles();
  std::vector<std::pair<uint32_t, uint32_t>> unpacked;
  for (uint32_t i = 0; i < total; ++i) unpacked.push_back(g.key(i));
  g.packKeys();
  EXPECT_EQ(g.microBits, 32u);  // 0xffffffff
  EXPECT_TRUE(g.micro32.empty());
  for (uint32_t i = 0; i < total; ++i) ASSERT_EQ(g.key(i), unpacked[i]) << i;
  // A voxel of small ranks and short path codes (packed: rank << 9 | code) takes few bits.
  VoxelGeometry small;
  for (uint32_t t = 0; t < 100; ++t) small.appendKey(t / 7, (((t % 5) + 16) << kMicroRankBits) | (t % 3));
  small.packKeys();
  EXPECT_EQ(small.microBits, 11u);  // rank < 4 above a 9-bit code slot
  EXPECT_EQ(small.packedMicro.size(), (11 * 100 + 7) / 8 + 8);
  // 15 input triangles in runs of 7: 15 segments would take 120 bytes, the ids in 4 bits each 58.
  EXPECT_TRUE(small.segments.empty());
  EXPECT_EQ(small.idBits, 4u);
  EXPECT_EQ(small.packedIds.size(), (4 * 100 + 7) / 8 + 8);
  for (uint32_t t = 0; t < 100; ++t)
    ASSERT_EQ(small.key(t), std::make_pair(t / 7, (((t % 5) + 16) << kMicroRankBits) | (t % 3))) << t;
  // Long runs keep their segments: 3 of them against 300 ids of 20 bits.
  VoxelGeometry runs;
  for (uint32_t t = 0; t < 300; ++t) runs.appendKey(1000000 + (t / 100) * 500000, t);
  runs.packKeys();
  EXPECT_EQ(runs.segments.size(), 3u);
  EXPECT_TRUE(runs.packedIds.empty());
  for (uint32_t t = 0; t < 300; ++t) ASSERT_EQ(runs.key(t), std::make_pair(1000000 + (t / 100) * 500000, t)) << t;

  // Dyadic barycentrics up to level 15 use 16 bits and decode exactly.
  const std::vector<glm::vec2> dyadic = {{0, 0}, {1, 0}, {0, 1}, {0.5f, 0.25f}, {1.0f / 32768, 0.75f}};
  g.setBary(dyadic);
  EXPECT_EQ(g.bary16.size(), 2 * dyadic.size());
  EXPECT_TRUE(g.baryF.empty());
  for (uint32_t v = 0; v < dyadic.size(); ++v) EXPECT_EQ(g.bary(v), dyadic[v]);
  g.packBary();
  EXPECT_TRUE(g.bary16.empty());
  EXPECT_EQ(g.baryShift, 0u);  // 2^-15 needs every bit
  for (uint32_t v = 0; v < dyadic.size(); ++v) EXPECT_EQ(g.bary(v), dyadic[v]);
  // Packed, a voxel whose barycentrics are multiples of 2^-l keeps l + 1 bits each and decodes
  // them exactly, at every level (level 16: all zero, no bits).
  std::mt19937 rng(5);
  for (int level = 0; level <= 16; ++level) {
    std::vector<glm::vec2> b;
    const int steps = level == 16 ? 0 : 1 << level;
    std::uniform_int_distribution<int> k(0, steps);
    for (int v = 0; v < 300; ++v) b.push_back(glm::vec2(float(k(rng)), float(k(rng))) / float(std::max(steps, 1)));
    if (steps) b[7] = glm::vec2(1.0f / float(steps), 1.0f);  // the finest value occurs
    g.setBary(b);
    g.packBary();
    const uint32_t bits = level == 16 ? 0 : uint32_t(level) + 1;
    EXPECT_EQ(g.baryShift, 16u - bits) << level;
    EXPECT_EQ(g.packedBary.size(), (2 * bits * b.size() + 7) / 8 + 8) << level;
    for (uint32_t v = 0; v < b.size(); ++v) ASSERT_EQ(g.bary(v), b[v]) << level << " " << v;
  }
  // Finer values (deeper levels, the thirds of centre splits) round to the nearest 2^-15.
  const std::vector<glm::vec2> fine = {{0.5f, 0.5f}, {1.0f / 65536, 0.0f}, {1.0f / 3, 1.0f / 3}, {0.3f, 0.1f}};
  g.setBary(fine);
  EXPECT_EQ(g.bary16.size(), 2 * fine.size());
  for (uint32_t v = 0; v < fine.size(); ++v) {
    EXPECT_LE(std::fabs(g.bary(v).x - fine[v].x), 1.0f / 65536) << v;
    EXPECT_LE(std::fabs(g.bary(v).y - fine[v].y), 1.0f / 65536) << v;
  }
  EXPECT_EQ(g.bary(0), fine[0]);  // dyadic: exact
  // A value outside the triangle (or NaN) falls back to floats, exact.
  const std::vector<glm::vec2> outside = {{0.25f, 0.5f}, {1.5f, -0.25f}};
  g.setBary(outside);
  EXPECT_TRUE(g.bary16.empty());
  for (uint32_t v = 0; v < outside.size(); ++v) EXPECT_EQ(g.bary(v), outside[v]);
}

// Positions pack into lattice steps around the voxel (as many bits per axis as the packed
// vertices' extent needs, at most 19) where they decode to their own bits; the rest stay floats,
// and triangles and barycentrics follow the renumbering.
void expectPackingKeepsEveryCorner(bool wideIndices, bool floatBary) {
  const float step = 1.0f / 1024.0f;
  const glm::vec3 centre(0.3f, -0.2f, 5.1f);
  const glm::vec3 c = snapToLattice(centre, step);
  std::vector<glm::vec3> P;
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> near(-30000, 30000);
  uint32_t expectPacked = 0;
  for (int i = 0; i < 300; ++i) {
    const int kind = i % 10;
    glm::vec3 p = c + glm::vec3(float(near(rng)), float(near(rng)), float(near(rng))) * step;
    if (kind == 3) p.y = c.y + 300000.0f * step;  // outside the window
    if (kind == 5) p.x += 0.3f * step;               // not a lattice point
    if (kind == 7) p.z = c.z - 262145.0f * step;     // one step below the window
    if (kind == 8) p.x = c.x + 262143.0f * step;     // the window's last step
    if (kind == 9) p.z = c.z - 262144.0f * step;     // its first
    expectPacked += kind != 3 && kind != 5 && kind != 7;
    P.push_back(p);
  }
  P.push_back(glm::vec3(-0.0f, 0.0f, 0.0f));  // -0 would decode as +0: must stay a float
  VoxelGeometry g;
  g.P = P;
  std::vector<uint32_t> indices;
  for (uint32_t t = 0; t + 2 < uint32_t(P.size()); ++t) indices.insert(indices.end(), {t, t + 2, uint32_t(P.size()) - 1 - t});
  if (wideIndices) g.indices32 = indices;
  else g.indices16.assign(indices.begin(), indices.end());
  std::vector<glm::vec2> bary;
  for (uint32_t v = 0; v < P.size(); ++v)
    bary.push_back(glm::vec2(float(v % 64), float(v / 64)) / 128.0f + (floatBary ? 1.25f : 0.0f));  // > 1: floats
  g.setBary(bary);
  ASSERT_EQ(g.baryF.empty(), !floatBary);
  const uint32_t numTriangles = uint32_t(indices.size() / 3);
  for (uint32_t t = 0; t < numTriangles; ++t) g.appendKey(0, t);

  g.packPositions(step, centre);
  EXPECT_EQ(g.numPacked(), expectPacked);
  EXPECT_EQ(g.numVertices(), P.size());
  for (uint32_t t = 0; t < numTriangles; ++t) {
    const glm::uvec3 tri = g.triangle(t);
    for (int k = 0; k < 3; ++k) {
      const glm::vec3 want = P[indices[3 * t + k]], got = g.vertex(tri[k]);
      ASSERT_EQ(std::memcmp(&want, &got, sizeof want), 0) << "triangle " << t << " corner " << k;
      ASSERT_EQ(g.bary(tri[k]), bary[indices[3 * t + k]]);
    }
  }
  // Packed vertices take 19 + 16 + 19 bits here (the extents of x, y and z): 7 bytes, not 12.
  EXPECT_EQ(int(g.pBits[0]), 19);
  EXPECT_EQ(int(g.pBits[1]), 16);
  EXPECT_EQ(int(g.pBits[2]), 19);
  EXPECT_EQ(g.pBytes, 7u);
  EXPECT_EQ(g.packedP.size(), 7 * expectPacked + 8);
  EXPECT_LT(g.bytes(), sizeof(VoxelGeometry) + 12 * P.size() + 2 * indices.size() * (wideIndices ? 2 : 1) +
                           bary.size() * (floatBary ? 8 : 4) + 4 * numTriangles + g.segments.size() * 8);
  // A step of 0 (an undisplaced scene) packs nothing.
  VoxelGeometry h;
  h.P = P;
  h.packPositions(0.0f, centre);
  EXPECT_EQ(h.numPacked(), 0u);
  EXPECT_EQ(h.P.size(), P.size());
}

TEST(VoxelStorage, PackedPositionsDecodeToTheirOwnBits) {
  if constexpr (std::endian::native != std::endian::little) GTEST_SKIP() << "the packed forms are little-endian";
  expectPackingKeepsEveryCorner(false, false);
  expectPackingKeepsEveryCorner(true, true);
  // A voxel of vertices in one axis-aligned plane spends no bits on that axis, and narrow
  // extents few on the others: 3 + 0 + 5 bits, one byte a vertex.
  const float step = 1.0f / 4096.0f;
  VoxelGeometry g;
  for (int i = 0; i < 40; ++i) g.P.push_back(glm::vec3(-2.0f + float(i % 8) * step, 0.75f, 3.0f + float(i * 3 / 4) * step));
  g.packPositions(step, glm::vec3(-2.0f, 1.0f, 3.0f));
  ASSERT_EQ(g.numPacked(), 40u);
  EXPECT_EQ(int(g.pBits[0]), 3);
  EXPECT_EQ(int(g.pBits[1]), 0);
  EXPECT_EQ(int(g.pBits[2]), 5);
  EXPECT_EQ(g.pBytes, 1u);
  EXPECT_EQ(g.packedP.size(), 40u + 8);
  for (uint32_t i = 0; i < 40; ++i) {
    const glm::vec3 got = g.vertex(i), want(-2.0f + float(i % 8) * step, 0.75f, 3.0f + float(i * 3 / 4) * step);
    ASSERT_EQ(std::memcmp(&got, &want, sizeof got), 0) << i;
  }
}

// Every BVH node's child boxes, decoded through the frames their ancestors' 8-bit codes give,
// hold the triangles below them grown by the grid's padding (the traversal culls on them), and
// nodes are 40 bytes: 8 bits a plane.
void expectBoxesHold(const VoxelGeometry& g, uint32_t ref, const VoxelGeometry::BvhFrame& frame, float padding,
                     glm::vec3 lo, glm::vec3 hi, int& leaves) {
  if (ref & VoxelGeometry::kBvhLeafFlag) {
    const uint32_t first = ref & 0xffffffu, count = (ref >> 24) & 0x7fu;
    for (uint32_t t = first; t < first + count; ++t) {
      const glm::uvec3 tri = g.triangle(t);
      for (int c = 0; c < 3; ++c) {
        const glm::vec3 p = g.vertex(tri[c]);
        for (int k = 0; k < 3; ++k) {
          // The root's box is the padded triangles' own, so their extremes meet its planes (to
          // float rounding); every box below adds at least a lattice step outwards. `lo`, `hi`:
          // the boxes of every ancestor, intersected.
          ASSERT_LE(lo[k], p[k] - 0.5f * padding) << "triangle " << t;
          ASSERT_GE(hi[k], p[k] + 0.5f * padding) << "triangle " << t;
        }
      }
    }
    ++leaves;
    return;
  }
  const VoxelGeometry::BvhNode& node = g.bvhNodes[ref];
  for (int i = 0; i < 4; ++i) {
    if (node.child[i] == VoxelGeometry::kBvhLeafFlag) continue;  // unused slot
    glm::vec3 clo, chi;
    for (int k = 0; k < 3; ++k) {
      clo[k] = g.bvhOrigin[k] + (frame.lo[k] + float(node.lo[k][i]) * frame.step[k]) * g.bvhStep[k];
      chi[k] = g.bvhOrigin[k] + (frame.lo[k] + float(node.hi[k][i]) * frame.step[k]) * g.bvhStep[k];
    }
    expectBoxesHold(g, node.child[i], frame.child(node, i), padding, glm::max(lo, clo), glm::min(hi, chi), leaves);
  }
}

TEST(VoxelStorage, HierarchicalNodeBoxesHoldTheirTriangles) {
  static_assert(sizeof(VoxelGeometry::BvhNode) == 40);
  SphereOptions o = cacheOptions();
  o.edgeLength = 0.01f;  // dense voxels: trees several levels deep
  const Scene scene = makeSphereScene(o);
  GridAccelerator accel(scene, AccelOptions{});
  int deep = 0, leaves = 0;
  for (uint32_t v = 0; v < accel.grid().numVoxels(); ++v) {
    if (!accel.grid().hasContributors(v)) continue;
    const auto g = accel.buildVoxelUncached(v);
    if (g->bvhNodes.empty()) continue;
    deep += g->bvhNodes.size() > 5;
    const glm::vec3 inf(std::numeric_limits<float>::infinity());
    expectBoxesHold(*g, 0, g->bvhRoot, accel.grid().padding(), -inf, inf, leaves);
    if (::testing::Test::HasFatalFailure()) return;
  }
  EXPECT_GT(deep, 10);
  EXPECT_GT(leaves, 1000);
}

// Indices pack into 3 x (bits of the largest vertex number) per triangle and read back the same,
// at widths from 1 to 19 bits and at their edges; wider voxels keep 32-bit indices.
TEST(VoxelStorage, PackedIndicesReadBackAtEveryWidth) {
  std::mt19937 rng(17);
  for (uint32_t vertices : {1u, 2u, 3u, 4u, 5u, 255u, 256u, 257u, 1000u, 4096u, 4097u, 65536u, 65537u, 300000u,
                            524288u, 524289u}) {
    VoxelGeometry g;
    g.P.resize(vertices);
    std::uniform_int_distribution<uint32_t> pick(0, vertices - 1);
    std::vector<uint32_t> indices;
    for (uint32_t t = 0; t < 301; ++t) {
      // The extremes at every position of a triangle, then random corners.
      if (t < 3) indices.insert(indices.end(), {vertices - 1, t % 2 ? 0u : vertices - 1, 0u});
      else indices.insert(indices.end(), {pick(rng), pick(rng), pick(rng)});
      g.appendKey(0, t);
    }
    if (vertices <= 65536) g.indices16.assign(indices.begin(), indices.end());
    else g.indices32 = indices;
    const uint64_t before = g.bytes();
    g.packIndices();
    const uint32_t width = std::max(1, int(std::bit_width(vertices - 1)));
    if (width <= 19 && !(width == 16 && vertices <= 65536)) {  // 16 bits in 16: nothing to gain
      EXPECT_EQ(g.indexBits, width) << vertices;
      EXPECT_TRUE(g.indices16.empty() && g.indices32.empty());
      EXPECT_LT(g.bytes(), before) << vertices;
    } else {
      EXPECT_EQ(g.indexBits, 0u) << vertices;
      EXPECT_EQ(g.indices16.size() + g.indices32.size(), indices.size());
    }
    for (uint32_t t = 0; t < 301; ++t)
      ASSERT_EQ(g.triangle(t), glm::uvec3(indices[3 * t], indices[3 * t + 1], indices[3 * t + 2]))
          << vertices << " vertices, triangle " << t;
  }
}

TEST(VoxelStorage, SnappingIsAPureFunctionOntoThePowerOfTwoLattice) {
  const float step = std::ldexp(1.0f, -16);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> pos(-8.0f, 8.0f);
  for (int i = 0; i < 1000; ++i) {
    const glm::vec3 p(pos(rng), pos(rng), pos(rng));
    const glm::vec3 s = snapToLattice(p, step);
    for (int k = 0; k < 3; ++k) {
      EXPECT_LE(std::fabs(s[k] - p[k]), 0.5f * step);
      EXPECT_EQ(s[k] / step, std::floor(s[k] / step));  // a lattice point
    }
    EXPECT_EQ(snapToLattice(s, step), s);  // idempotent
  }
  EXPECT_FALSE(std::signbit(snapToLattice(glm::vec3(-1e-9f), step).x));  // -0 made +0
  EXPECT_EQ(snapToLattice(glm::vec3(0.1f), 0.0f), glm::vec3(0.1f));      // no lattice
  // Where the floats are coarser than the lattice, and for infinities, a coordinate is kept.
  EXPECT_EQ(snapToLattice(glm::vec3(3.0e5f + 0.03125f, 1e30f, -std::numeric_limits<float>::infinity()), step),
            glm::vec3(3.0e5f + 0.03125f, 1e30f, -std::numeric_limits<float>::infinity()));
  EXPECT_TRUE(std::isnan(snapToLattice(glm::vec3(std::nanf("")), step).x));
}

// The lattice the accelerator chooses: a power of two fine against the micro-triangles, the same
// for every grid resolution, and none for an undisplaced scene.
TEST(GridAccelerator, PositionStepIsAPowerOfTwoFineAgainstTheEdgeLength) {
  SphereOptions o = cacheOptions();
  const Scene scene = makeSphereScene(o);
  GridAccelerator accel(scene, AccelOptions{});
  const float step = accel.positionStep();
  ASSERT_GT(step, 0.0f);
  int e = 0;
  EXPECT_EQ(std::frexp(step, &e), 0.5f);
  const float wanted = std::min(o.edgeLength / 1024.0f, 0.5f * accel.grid().padding());
  EXPECT_LE(step, wanted);
  EXPECT_GT(step, 0.5f * wanted);
  // Whatever the grid: the voxel size is no part of it.
  for (int resolution : {2, 40}) {
    AccelOptions gridded;
    gridded.gridResolution = resolution;
    EXPECT_EQ(GridAccelerator(scene, gridded).positionStep(), step) << resolution;
  }
  AccelOptions flat;
  flat.displace = false;
  EXPECT_EQ(GridAccelerator(scene, flat).positionStep(), 0.0f);
  // Far from the origin along x, y and z keep the fine lattice.
  Scene far = scene;
  for (Mesh& m : far.meshes)
    for (glm::vec3& p : m.P) p += glm::vec3(3.0e5f, 0.0f, 0.0f);
  GridAccelerator farAccel(far, AccelOptions{});
  const float farStep = farAccel.positionStep();
  const Bounds3& b = farAccel.grid().bounds();
  const float largest = std::max({std::fabs(b.lo.x), std::fabs(b.hi.x), std::fabs(b.lo.y), std::fabs(b.hi.y),
                                  std::fabs(b.lo.z), std::fabs(b.hi.z)});
  // The lattice stays as fine as near the origin: snapping keeps x where floats are coarser.
  EXPECT_EQ(farStep, step);
  EXPECT_GT(largest / farStep, 16777216.0f);
  const auto hit = farAccel.intersect(Ray{{3.0e5f, 0.0f, -5.0f}, {0.0f, 0.0f, 1.0f}, 0.0f, 1e30f});
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->P.z, -1.0f, 0.2f);  // the displaced sphere's near side
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// Hits of `accel` against brute force on the same lattice, for rays moved by `offset`.
void expectHitsMatchBruteForce(GridAccelerator& accel, const Scene& scene, int numRays, uint32_t seed,
                               const glm::vec3& offset = glm::vec3(0.0f)) {
  testing::BruteForce expected(scene, accel.positionStep());
  for (uint32_t id : accel.grid().outside()) {
    const auto [m, t] = accel.grid().split(id);
    expected.intersectInDouble(m, t);
  }
  int hits = 0;
  for (Ray ray : testing::randomRays(numRays, seed, 3.0f, 1.2f)) {
    ray.origin += offset;
    const auto hit = accel.intersect(ray);
    const auto ref = expected.intersect(ray);
    ASSERT_EQ(hit.has_value(), ref.has_value());
    if (!hit) continue;
    ++hits;
    EXPECT_EQ(hit->t, ref->t);
    EXPECT_EQ(hit->meshIndex, ref->mesh);
    EXPECT_EQ(hit->triangleIndex, ref->triangle);
    EXPECT_EQ(hit->microIndex, ref->micro);
  }
  EXPECT_GT(hits, numRays / 4);
}

// An undisplaced mesh in a displaced scene: its triangles are kept whole and share vertices
// (snapped and packed like the displaced ones) with their neighbours in a voxel, and a hit on one
// still reports its own triangle and barycentrics.
TEST(VoxelStorage, WholeTrianglesSharingVerticesMatchBruteForce) {
  Scene scene = makeSphereScene(cacheOptions());
  Mesh plane;
  constexpr int kCells = 16;
  for (int j = 0; j <= kCells; ++j)
    for (int i = 0; i <= kCells; ++i)
      plane.P.push_back(glm::vec3(-0.9f + 1.8f * float(i) / kCells, -0.9f + 1.8f * float(j) / kCells,
                                  1.25f + 0.1f * std::sin(float(i * j))));
  for (int j = 0; j < kCells; ++j)
    for (int i = 0; i < kCells; ++i) {
      const uint32_t a = uint32_t(j * (kCells + 1) + i), b = a + 1, c = a + kCells + 1, d = c + 1;
      plane.indices.insert(plane.indices.end(), {a, b, d, a, d, c});
    }
  scene.meshes.push_back(plane);
  GridAccelerator accel(scene, AccelOptions{});
  EXPECT_EQ(accel.grid().outside().size(), 0u);  // every plane triangle is in the grid
  testing::BruteForce expected(scene, accel.positionStep());
  int planeHits = 0;
  for (const Ray& ray : testing::randomRays(2000, 43, 3.0f, 1.2f)) {
    const auto hit = accel.intersect(ray);
    const auto ref = expected.intersect(ray);
    ASSERT_EQ(hit.has_value(), ref.has_value());
    if (!hit) continue;
    EXPECT_EQ(hit->t, ref->t);
    EXPECT_EQ(hit->meshIndex, ref->mesh);
    EXPECT_EQ(hit->triangleIndex, ref->triangle);
    EXPECT_EQ(hit->microIndex, ref->micro);
    EXPECT_EQ(hit->bary, ref->bary);
    planeHits += hit->meshIndex == 1;
  }
  EXPECT_GT(planeHits, 100);
  // The plane's voxels hold fewer vertices than three per whole triangle.
  uint64_t wholeTriangles = 0, vertices = 0;
  for (uint32_t v = 0; v < accel.grid().numVoxels(); ++v) {
    if (!accel.grid().hasContributors(v)) continue;
    const auto g = accel.buildVoxelUncached(v);
    uint32_t whole = 0;
    for (uint32_t i = 0; i < g->numTriangles(); ++i) whole += g->key(i).second == kWholeTriangleId;
    if (whole == g->numTriangles() && whole > 0) wholeTriangles += whole, vertices += g->numVertices();
  }
  EXPECT_GT(wholeTriangles, 100u);
  EXPECT_LT(vertices, 2 * wholeTriangles);
}

// One voxel holding everything: more than 65536 vertices (indices as a 17-bit stream), triangles
// and sub-grid references (32-bit sub-grid offsets and references), with the BVH and with the
// sub-voxel grid, still in exact agreement with brute force.
TEST(VoxelStorage, WideVoxelsUseTheir32BitFormsCorrectly) {
  SphereOptions o;
  o.nu = 24, o.nv = 12;
  o.edgeLength = 0.02f;
  const Scene scene = makeSphereScene(o);
  for (bool grid : {false, true}) {
    AccelOptions options;
    options.gridResolution = 1;
    options.subVoxelGrid = grid;
    GridAccelerator accel(scene, options);
    expectHitsMatchBruteForce(accel, scene, 60, 13);
    EXPECT_GT(accel.maxVoxelTriangles(), 100000u);
  }
}

// A displaced sphere on a large undisplaced floor: the floor's far corners fall outside every
// voxel's 16-bit window and stay floats, so groups of four mix packed and float vertices; grids of
// 1 to 3 voxels across make the lattice as coarse as the padding allows; and the same scene far
// from the origin snaps only where the floats are finer than the lattice. Hits agree exactly
// with brute force on the same lattice everywhere.
TEST(VoxelStorage, MixedPackedAndFloatVerticesAndCoarseLatticesMatchBruteForce) {
  SphereOptions o = cacheOptions();
  Scene scene = makeSphereScene(o);
  Mesh floor;
  floor.P = {{-40, -40, -1.3f}, {40, -40, -1.3f}, {40, 40, -1.3f}, {-40, 40, -1.3f}, {0.5f, 0.5f, -1.3f}};
  floor.indices = {0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4};
  scene.meshes.push_back(floor);
  // Two tiny displaced triangles at the floor's far corners stretch the displaced geometry over
  // the floor, so the floor is in the grid (not outside it, contributor_grid.h).
  Mesh markers;
  markers.P = {{-40, -40, -1.3f}, {-39.99f, -40, -1.3f}, {-40, -39.99f, -1.3f},
               {40, 40, -1.3f}, {39.99f, 40, -1.3f}, {40, 39.99f, -1.3f}};
  markers.indices = {0, 1, 2, 3, 4, 5};
  markers.displacementIndex = 0;
  scene.meshes.push_back(markers);
  for (int resolution : {0, 1, 2, 3}) {
    AccelOptions options;
    options.gridResolution = resolution;  // 0: automatic
    GridAccelerator accel(scene, options);
    ASSERT_TRUE(accel.grid().outside().empty());
    ASSERT_GT(accel.positionStep(), 0.0f);
    EXPECT_LE(accel.positionStep(), accel.grid().padding());
    expectHitsMatchBruteForce(accel, scene, 200, 21);
    if (HasFatalFailure()) return;
  }
  const glm::vec3 offset(3.0e5f, 0.0f, 0.0f);
  Scene far = scene;
  for (Mesh& m : far.meshes)
    for (glm::vec3& p : m.P) p += offset;
  GridAccelerator accel(far, AccelOptions{});
  expectHitsMatchBruteForce(accel, far, 200, 23, offset);
}

// contributor_grid.h, "outside": with displaced geometry in the scene, the grid spans its reach
// only; undisplaced triangles reaching beyond it (a wide floor, one far vertex) are intersected
// through their own BVH, and hits, occlusion and the nearest-hit ties agree exactly with brute
// force. An undisplaced triangle inside the reach stays in the grid; without displaced geometry
// nothing is outside.
TEST(VoxelStorage, UndisplacedTrianglesOutsideTheDisplacedGeometryMatchBruteForce) {
  Scene scene = makeSphereScene(cacheOptions());
  Mesh floor;
  floor.P = {{-40, -40, -1.3f}, {40, -40, -1.3f}, {40, 40, -1.3f}, {-40, 40, -1.3f}, {0.5f, 0.5f, -1.3f},
             {0.2f, 0.1f, 0.0f}, {0.3f, 0.1f, 0.0f}, {0.2f, 0.2f, 0.0f},     // inside the sphere's reach
             {-0.9f, 0.0f, 0.2f}, {0.9f, 0.0f, 0.2f}, {0.0f, 900.0f, 0.3f}};  // one vertex far away
  floor.indices = {0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4, 5, 6, 7, 8, 9, 10};
  scene.meshes.push_back(floor);
  GridAccelerator accel(scene, AccelOptions{});
  const uint32_t first = accel.grid().globalId(1, 0);
  const std::vector<uint32_t> outside = {first, first + 1, first + 2, first + 3, first + 5};
  EXPECT_EQ(std::vector<uint32_t>(accel.grid().outside().begin(), accel.grid().outside().end()), outside);
  EXPECT_LT(accel.grid().bounds().hi.x, 2.0f);  // the grid fits the sphere, not the floor
  expectHitsMatchBruteForce(accel, scene, 400, 31);
  testing::BruteForce expected(scene, accel.positionStep());
  for (uint32_t id : outside) {
    const auto [m, t] = accel.grid().split(id);
    expected.intersectInDouble(m, t);
  }
  int floorHits = 0;
  for (const Ray& ray : testing::randomRays(400, 37, 3.0f, 1.2f)) {
    const auto ref = expected.intersect(ray);
    floorHits += ref && ref->mesh == 1;
    EXPECT_EQ(accel.occluded(ray), ref.has_value());
  }
  EXPECT_GT(floorHits, 20);
  // Segments (shadow rays) and rays starting past the first hit agree too.
  for (Ray ray : testing::randomRays(300, 41, 3.0f, 1.2f)) {
    const auto first = expected.intersect(ray);
    if (!first) continue;
    Ray shorter = ray, later = ray;
    shorter.tMax = first->t * 0.999f;
    later.tMin = first->t * 1.001f;
    EXPECT_FALSE(accel.occluded(shorter));
    EXPECT_FALSE(accel.intersect(shorter).has_value());
    const auto beyond = expected.intersect(later);
    const auto got = accel.intersect(later);
    ASSERT_EQ(got.has_value(), beyond.has_value());
    if (got) {
      EXPECT_EQ(got->t, beyond->t);
    }
    EXPECT_EQ(accel.occluded(later), beyond.has_value());
  }

  // Undisplaced, the neighbourhood is that of the triangles of ordinary size (the sphere's): the
  // same floor triangles are outside, and the hits still match.
  Scene plain = scene;
  for (Mesh& m : plain.meshes) m.displacementIndex = UINT32_MAX;
  GridAccelerator undisplaced(plain, AccelOptions{});
  EXPECT_EQ(std::vector<uint32_t>(undisplaced.grid().outside().begin(), undisplaced.grid().outside().end()), outside);
  testing::BruteForce plainExpected(plain, undisplaced.positionStep());
  for (uint32_t id : outside) {
    const auto [m, t] = undisplaced.grid().split(id);
    plainExpected.intersectInDouble(m, t);
  }
  for (const Ray& ray : testing::randomRays(300, 43, 3.0f, 1.2f)) {
    const auto ref = plainExpected.intersect(ray);
    const auto got = undisplaced.intersect(ray);
    ASSERT_EQ(got.has_value(), ref.has_value());
    if (got) {
      EXPECT_EQ(got->t, ref->t);
      EXPECT_EQ(got->meshIndex, ref->mesh);
    }
  }
}

}  // namespace
}  // namespace relief
