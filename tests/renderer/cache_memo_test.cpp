// What the cache keeps beyond its voxels (docs/cache.md, "Subtree memo" and "Voxel proxies"): a
// culled subdivision that reads and feeds the subtree memo keeps exactly the micro-triangles of the
// whole subdivision that reach its box, with less shader work once the memo knows the triangle;
// memo boxes are rounded outwards; an accelerator with memos and proxies gives the hits of one
// without, at any budget and on two threads, with fewer shader points and capacity misses; and
// memos stop at their byte limit; sparse voxels are passed on their proxies too.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <random>
#include <thread>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "geometry_test_util.h"
#include "renderer/grid_accelerator.h"
#include "renderer/subdivide.h"

namespace relief {
namespace {

using testing::HitKey;
using testing::hitKey;
using testing::hitKeys;
using testing::hitKeysOnTwoThreads;

// Bumps on the half x > 0 of the plane, nothing on the other half: simplification then finds flat
// edges and flat interiors (decisions to memoize) beside edges and interiors that are not flat.
void halfBumpsEntry(const RlfShadingBatch* b, const void* params, RlfStatus*) {
  float km, freq;
  std::memcpy(&km, params, 4);
  std::memcpy(&freq, static_cast<const char*>(params) + 4, 4);
  for (uint32_t i = 0; i < b->count; ++i) {
    const float x = b->P.x[i], y = b->P.y[i];
    const float h = x > 0.0f ? km * std::sin(freq * x) * std::sin(freq * y) : 0.0f;
    b->Pout.x[i] = x + h * b->N.x[i];
    b->Pout.y[i] = y + h * b->N.y[i];
    b->Pout.z[i] = b->P.z[i] + h * b->N.z[i];
    b->Nout.x[i] = b->N.x[i], b->Nout.y[i] = b->N.y[i], b->Nout.z[i] = b->N.z[i];
  }
}

// The square [-1, 1]^2 in 6x6 quads: input triangles a dozen edge lengths across, as in the
// paper's facade (the memo's subtrees are those of the first kCullRounds rounds, so each then
// holds a few micro-triangles and its decisions fit one word).
Mesh square() {
  Mesh m;
  constexpr int n = 6;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) m.P.push_back({-1.0f + 2.0f * float(x) / n, -1.0f + 2.0f * float(y) / n, 0.0f});
  m.N.assign(m.P.size(), glm::vec3(0, 0, 1));
  for (uint32_t y = 0; y < n; ++y)
    for (uint32_t x = 0; x < n; ++x) {
      const uint32_t a = y * (n + 1) + x, b = a + 1, c = a + n + 2, d = a + n + 1;
      m.indices.insert(m.indices.end(), {a, b, c, a, c, d});
    }
  return m;
}

Displacement halfBumps() {
  Displacement d;
  d.shader = testing::makeShader(halfBumpsEntry, 0.04f, 14.0f);
  d.boundWorld = 0.04f;
  d.edgeLength = 0.02f;
  d.maxDepth = 12;
  d.flatness = 0.0005f;
  return d;
}

using TriangleKey = std::tuple<uint32_t, float, float, float, float, float, float, float, float, float>;

bool overlaps(const CullBox& box, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 lo = glm::min(a, glm::min(b, c)), hi = glm::max(a, glm::max(b, c));
  return lo.x <= box.hi.x && box.lo.x <= hi.x && lo.y <= box.hi.y && box.lo.y <= hi.y &&
         lo.z <= box.hi.z && box.lo.z <= hi.z;
}

// The micro-triangles of `mm` overlapping `box`, by id and exact corner positions.
std::vector<TriangleKey> reaching(const MicroMesh& mm, const CullBox& box) {
  std::vector<TriangleKey> keys;
  for (uint32_t i = 0; i < mm.numTriangles(); ++i) {
    const glm::vec3 a = mm.P[mm.indices[3 * i]], b = mm.P[mm.indices[3 * i + 1]], c = mm.P[mm.indices[3 * i + 2]];
    if (overlaps(box, a, b, c)) keys.emplace_back(mm.ids[i], a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z);
  }
  std::sort(keys.begin(), keys.end());
  return keys;
}

// Voxel-like boxes over the square, in row order.
std::vector<CullBox> columns(int n) {
  std::vector<CullBox> boxes;
  const float step = 2.2f / float(n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      boxes.push_back({{-1.1f + step * float(x), -1.1f + step * float(y), -0.05f},
                       {-1.1f + step * float(x + 1), -1.1f + step * float(y + 1), 0.05f}});
  return boxes;
}

TEST(SubtreeMemo, CulledSubdivisionsKeepExactlyTheWholeSubdivisionsTriangles) {
  const Mesh mesh = square();
  const Displacement disp = halfBumps();
  const std::vector<CullBox> boxes = columns(13);
  SubdivideCounters wholeCounters;
  uint64_t withoutMemo = 0, firstPass = 0, secondPass = 0;
  for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
    MicroMesh whole, culled;
    subdivideTriangle(mesh, t, &disp, whole, wholeCounters);
    CullBox reference{glm::vec3(-1.1f), glm::vec3(1.1f)};
    SubtreeMemo memo(reference);
    std::vector<LearntSubtree> learnt;
    // Without a memo, then twice with one (the second pass reverses the order, so each box is
    // filled with what its successors, not its predecessors, taught the memo).
    for (int pass = 0; pass < 3; ++pass) {
      for (size_t k = 0; k < boxes.size(); ++k) {
        const CullBox& box = boxes[pass == 2 ? boxes.size() - 1 - k : k];
        SubdivideCounters c;
        if (pass == 0) {
          subdivideTriangle(mesh, t, &disp, culled, c, &box);
        } else {
          subdivideTriangle(mesh, t, &disp, culled, c, &box, &memo, &learnt);
          for (const LearntSubtree& l : learnt) memo.learn(l.code, l.hasBox ? &l.box : nullptr, l.decisions);
        }
        (pass == 0 ? withoutMemo : pass == 1 ? firstPass : secondPass) += c.shaderPoints;
        ASSERT_EQ(reaching(culled, box), reaching(whole, box)) << "triangle " << t << " pass " << pass << " box " << k;
      }
    }
  }
  // The shape the test needs: simplification has flat and non-flat decisions to memoize.
  ASSERT_GT(wholeCounters.trianglesBeforeSimplification, 2 * wholeCounters.trianglesAfterSimplification);
  ASSERT_GT(wholeCounters.trianglesAfterSimplification, 1000u);
  // The memo is used: boxes learnt by neighbours save work in the first pass, and a memo that has
  // seen every box leaves the second pass little beyond the kept subtrees' own vertices.
  EXPECT_LT(2 * firstPass, withoutMemo);
  EXPECT_LT(secondPass, firstPass);
  EXPECT_LT(3 * secondPass, withoutMemo) << secondPass << " vs " << withoutMemo;
}

// Decisions replayed from the memo are the ones the subdivision would make: a memo whose every
// decision is inverted changes the micro-triangles (so the replay is really taken), and a memo
// learnt from the same triangle changes nothing.
TEST(SubtreeMemo, ReplayedDecisionsAreTheSubdivisionsOwn) {
  const Mesh mesh = square();
  const Displacement disp = halfBumps();
  const CullBox all{glm::vec3(-2.0f), glm::vec3(2.0f)};
  CullBox reference{glm::vec3(-1.1f), glm::vec3(1.1f)};
  SubtreeMemo memo(reference), inverted(reference);
  MicroMesh first, again, wrong;
  SubdivideCounters c1, c2, c3;
  std::vector<LearntSubtree> learnt, ignored;
  const uint32_t t = 21;  // in the bumpy half, next to the flat one
  subdivideTriangle(mesh, t, &disp, first, c1, &all, nullptr, &learnt);
  size_t decisions = 0;
  for (const LearntSubtree& l : learnt) {
    memo.learn(l.code, l.hasBox ? &l.box : nullptr, l.decisions);
    const uint64_t count = l.decisions ? (l.decisions >> 56) & 127u : 0;
    decisions += count;
    const uint64_t flipped = count ? l.decisions ^ ((uint64_t(1) << count) - 1) : 0;
    inverted.learn(l.code, l.hasBox ? &l.box : nullptr, flipped);
  }
  ASSERT_GT(decisions, 100u);
  subdivideTriangle(mesh, t, &disp, again, c2, &all, &memo, &ignored);
  EXPECT_EQ(reaching(again, all), reaching(first, all));
  EXPECT_LT(c2.shaderPoints, c1.shaderPoints / 2) << c2.shaderPoints << " vs " << c1.shaderPoints;
  subdivideTriangle(mesh, t, &disp, wrong, c3, &all, &inverted, &ignored);
  EXPECT_NE(reaching(wrong, all), reaching(first, all));
  // Replayed in culled fills too (the memo complete, every box of a fine grid).
  for (const CullBox& box : columns(13)) {
    MicroMesh culled;
    SubdivideCounters c;
    subdivideTriangle(mesh, t, &disp, culled, c, &box, &memo, &ignored);
    ASSERT_EQ(reaching(culled, box), reaching(first, box));
  }
}

// Boxes are held on a byte lattice over the reference, rounded outwards: what comes back contains
// what was learnt, and a box the lattice cannot hold (outside the reference, or not finite) is
// not kept at all.
TEST(SubtreeMemo, BoxesAreRoundedOutwardsOrNotKept) {
  const CullBox reference{{-3.0f, 0.5f, 10.0f}, {7.0f, 0.5f, 10.3f}};  // flat in y
  SubtreeMemo memo(reference);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> ux(-3.0f, 7.0f), uz(10.0f, 10.3f);
  for (uint32_t code = 4; code < 8; ++code)
    for (int i = 0; i < 200; ++i) {
      float x0 = ux(rng), x1 = ux(rng), z0 = uz(rng), z1 = uz(rng);
      const CullBox box{{std::min(x0, x1), 0.5f, std::min(z0, z1)}, {std::max(x0, x1), 0.5f, std::max(z0, z1)}};
      memo.learn(code, &box, 0);
      CullBox got;
      ASSERT_TRUE(memo.box(code, got));
      for (int a = 0; a < 3; ++a) {
        EXPECT_LE(got.lo[a], box.lo[a]);
        EXPECT_GE(got.hi[a], box.hi[a]);
        // One lattice step at most (a tenth of a millimetre of slack here would be 1/255 of 10).
        EXPECT_LE(box.lo[a] - got.lo[a], 10.0f / 255.0f * 1.01f);
        EXPECT_LE(got.hi[a] - box.hi[a], 10.0f / 255.0f * 1.01f);
      }
    }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  CullBox got;
  const CullBox outside{{-3.5f, 0.5f, 10.0f}, {0.0f, 0.5f, 10.1f}}, offFlat{{0.0f, 0.5f, 10.0f}, {1.0f, 0.6f, 10.1f}},
      notFinite{{nan, 0.5f, 10.0f}, {1.0f, 0.5f, 10.1f}}, top{{0.0f, 0.5f, 10.1f}, {7.0f, 0.5f, 10.3f}};
  memo.learn(1, &outside, 0);
  EXPECT_FALSE(memo.box(1, got));
  memo.learn(16, &offFlat, 0);
  EXPECT_FALSE(memo.box(16, got));
  memo.learn(17, &notFinite, 0);
  EXPECT_FALSE(memo.box(17, got));
  memo.learn(18, &top, 0);  // touching the reference's top corner
  ASSERT_TRUE(memo.box(18, got));
  EXPECT_GE(got.hi.x, 7.0f);
  EXPECT_GE(got.hi.z, 10.3f);
  EXPECT_EQ(memo.decisions(18), 0u);
  // Decisions alone, without a box.
  memo.learn(19, nullptr, (uint64_t(1) << 63) | (uint64_t(3) << 56) | 5u);
  EXPECT_FALSE(memo.box(19, got));
  EXPECT_EQ(memo.decisions(19), (uint64_t(1) << 63) | (uint64_t(3) << 56) | 5u);

  // A memo of one round holds the root and its four children only: deeper codes are ignored.
  SubtreeMemo small(reference, 1);
  small.learn(4, &top, 1u | (uint64_t(1) << 56) | (uint64_t(1) << 63));
  small.learn(16, &top, 1u | (uint64_t(1) << 56) | (uint64_t(1) << 63));
  EXPECT_TRUE(small.box(4, got));
  EXPECT_FALSE(small.box(16, got));
  EXPECT_EQ(small.decisions(16), 0u);
  EXPECT_LT(small.bytes(), memo.bytes());

  // An infinite reference has no lattice: nothing is kept.
  const float inf = std::numeric_limits<float>::infinity();
  SubtreeMemo unbounded(CullBox{glm::vec3(-inf), glm::vec3(inf)});
  unbounded.learn(1, &top, 0);
  EXPECT_FALSE(unbounded.box(1, got));
}

// Two sweeps of rays from one point across the sphere and past its silhouette, row by row
// (neighbouring rays need neighbouring voxels, as in a coherent pixel order); under a budget the
// second sweep refills what the first evicted.
std::vector<Ray> sweeps() {
  std::vector<Ray> rays;
  for (int pass = 0; pass < 2; ++pass)
    for (int y = 0; y < 50; ++y)
      for (int x = 0; x < 50; ++x) {
        Ray r;
        r.origin = glm::vec3(0.3f, -0.2f, 4);
        r.direction = glm::vec3(-0.45f + 0.9f * float(x) / 49, -0.45f + 0.9f * float(y) / 49, -1);
        rays.push_back(r);
      }
  return rays;
}

TEST(CacheMemo, SameHitsWithMemosAndProxiesAtAnyBudgetAndOnTwoThreads) {
  testing::SphereOptions so;
  so.nu = 24, so.nv = 12;
  so.edgeLength = 0.02f;
  so.flatness = 0.001f;
  const Scene scene = testing::makeSphereScene(so);
  const std::vector<Ray> rays = sweeps();
  AccelOptions base;
  base.gridResolution = 6;  // voxels of a few hundred triangles: dense enough for a BVH
  base.learnSubtrees = false, base.voxelProxies = false;
  GridAccelerator reference(scene, base);
  const std::vector<HitKey> expected = hitKeys(reference, rays);
  const AccelStats plain = reference.stats();
  ASSERT_GT(plain.uniqueDisplacedTriangles, 2000u);
  EXPECT_EQ(plain.memoBytes, 0u);
  EXPECT_EQ(plain.proxySkips, 0u);

  for (uint64_t budget : {UINT64_MAX, plain.residentTriangles / 10}) {
    std::map<std::pair<bool, bool>, AccelStats> stats;
    for (bool memo : {false, true})
      for (bool proxies : {false, true}) {
        AccelOptions o = base;
        o.cacheBudgetTriangles = budget;
        o.learnSubtrees = memo, o.voxelProxies = proxies;
        GridAccelerator accel(scene, o);
        for (size_t i = 0; i < rays.size(); ++i)
          ASSERT_EQ(hitKey(accel.intersect(rays[i])), expected[i]) << i << " memo " << memo << " proxies " << proxies;
        stats[std::make_pair(memo, proxies)] = accel.stats();
      }
    const AccelStats& none = stats[std::make_pair(false, false)];
    const AccelStats& both = stats[std::make_pair(true, true)];
    const AccelStats& onlyProxies = stats[std::make_pair(false, true)];
    const AccelStats& onlyMemo = stats[std::make_pair(true, false)];
    EXPECT_GT(onlyProxies.proxySkips, 0u);
    // Each structure reports its bytes.
    EXPECT_GT(onlyMemo.memoBytes, none.memoBytes);
    EXPECT_GT(onlyProxies.memoBytes, none.memoBytes);
    EXPECT_GT(both.memoBytes, onlyMemo.memoBytes);
    // Proxies take accesses off the cache; memos take shader work off the fills.
    EXPECT_LT(onlyProxies.accesses, none.accesses);
    EXPECT_LT(onlyMemo.shaderPoints, none.shaderPoints);
    if (budget != UINT64_MAX) {
      ASSERT_GT(none.capacityMisses, 10u);
      EXPECT_LT(both.capacityMisses, none.capacityMisses);
      EXPECT_LT(3 * both.shaderPoints, 2 * none.shaderPoints) << both.shaderPoints << " vs " << none.shaderPoints;
      EXPECT_LE(both.peakResidentTriangles, budget + both.maxVoxelTriangles);
    }

    // Memos stop at their byte limit: with none allowed, fills work as without memos.
    AccelOptions capped = base;
    capped.cacheBudgetTriangles = budget;
    capped.learnSubtrees = true, capped.memoBytesLimit = 0;
    GridAccelerator cappedAccel(scene, capped);
    for (size_t i = 0; i < rays.size(); ++i) ASSERT_EQ(hitKey(cappedAccel.intersect(rays[i])), expected[i]) << i;
    EXPECT_EQ(cappedAccel.stats().shaderPoints, none.shaderPoints);
    EXPECT_LT(cappedAccel.stats().memoBytes, onlyMemo.memoBytes);

    AccelOptions o = base;
    o.cacheBudgetTriangles = budget;
    o.learnSubtrees = true, o.voxelProxies = true;
    GridAccelerator shared(scene, o);
    EXPECT_EQ(hitKeysOnTwoThreads(shared, rays), expected);
  }
}

// Memos are kept only for triangles subdivided three or more levels deep: the memo of a triangle of
// a few micro-triangles costs more bytes than the fill it saves. A sphere of 0.26-wide triangles
// at edge length 0.1 (two levels) keeps none; at 0.02 (four levels) it keeps some.
TEST(CacheMemo, TrianglesOfFewMicroTrianglesKeepNoMemo) {
  for (float edge : {0.1f, 0.02f}) {
    testing::SphereOptions so;
    so.nu = 24, so.nv = 12;
    so.edgeLength = edge;
    so.flatness = 0.001f;
    const Scene scene = testing::makeSphereScene(so);
    const std::vector<Ray> rays = sweeps();
    AccelOptions base;
    base.gridResolution = 6;  // most triangles listed in two or more voxels
    base.voxelProxies = false, base.learnSubtrees = false;
    GridAccelerator reference(scene, base);
    const std::vector<HitKey> expected = hitKeys(reference, rays);
    const AccelStats plain = reference.stats();
    AccelOptions o = base;
    o.cacheBudgetTriangles = plain.residentTriangles / 10;
    GridAccelerator forgetful(scene, o);
    o.learnSubtrees = true;
    GridAccelerator accel(scene, o);
    for (size_t i = 0; i < rays.size(); ++i) {
      ASSERT_EQ(hitKey(forgetful.intersect(rays[i])), expected[i]) << i;
      ASSERT_EQ(hitKey(accel.intersect(rays[i])), expected[i]) << i;
    }
    const AccelStats without = forgetful.stats(), got = accel.stats();
    ASSERT_GT(got.capacityMisses, 10u) << edge;  // refills, where a memo would be read
    // Memo bytes beyond the per-triangle table of memo pointers (8 bytes a triangle).
    const uint64_t table = 8 * uint64_t(scene.meshes[0].indices.size() / 3);
    if (edge > 0.05f) {
      EXPECT_LE(got.memoBytes, without.memoBytes + table) << got.memoBytes << " vs " << without.memoBytes;
      EXPECT_EQ(got.shaderPoints, without.shaderPoints);
    } else {
      EXPECT_GT(got.memoBytes, without.memoBytes + table + 10000) << got.memoBytes << " vs " << without.memoBytes;
      EXPECT_LT(got.shaderPoints, without.shaderPoints);
    }
  }
}

// Sparse voxels (fewer than kSubGridThreshold triangles) get a BVH root too, one leaf under the
// box of their triangles, so their proxies let rays that pass beside the triangles skip the voxel
// (on sphere_box, 58% of the visits to sparse voxels missed that box). The hits stay those of an
// accelerator without proxies.
TEST(CacheMemo, SparseVoxelsArePassedOnTheirProxies) {
  testing::SphereOptions so;
  so.nu = 24, so.nv = 12;
  so.edgeLength = 0.1f;
  const Scene scene = testing::makeSphereScene(so);
  // Rays past the sphere's silhouette cross voxels its triangles only touch at a corner.
  const std::vector<Ray> rays = sweeps();
  AccelOptions base;
  base.gridResolution = 48;
  base.voxelProxies = false;
  GridAccelerator reference(scene, base);
  const std::vector<HitKey> expected = hitKeys(reference, rays);
  const AccelStats plain = reference.stats();
  ASSERT_LT(plain.maxVoxelTriangles, kSubGridThreshold);  // every voxel is sparse
  ASSERT_GT(plain.compulsoryMisses, 100u);
  EXPECT_EQ(plain.proxySkips, 0u);
  AccelOptions o = base;
  o.voxelProxies = true;
  GridAccelerator withProxies(scene, o);
  for (size_t i = 0; i < rays.size(); ++i) ASSERT_EQ(hitKey(withProxies.intersect(rays[i])), expected[i]) << i;
  const AccelStats got = withProxies.stats();
  EXPECT_GT(got.proxySkips, plain.accesses / 50) << got.proxySkips << " of " << plain.accesses;
  EXPECT_EQ(got.accesses + got.proxySkips, plain.accesses);
  EXPECT_EQ(got.compulsoryMisses, plain.compulsoryMisses);
}

}  // namespace
}  // namespace relief
