// Tests of adaptive crack-free subdivision: edge-length target and depth guard, conforming micro-
// meshes, shared input edges split identically from both sides, non-finite fallback, determinism.
#include "renderer/subdivide.h"

#include <map>
#include <set>
#include <tuple>

#include <gtest/gtest.h>

#include "geometry_test_util.h"

namespace relief {
namespace {

// A unit quad in the z = 0 plane as two triangles sharing the diagonal (0, 2), with uv = xy.
Mesh makeQuad() {
  Mesh mesh;
  mesh.P = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  mesh.N.assign(4, glm::vec3(0, 0, 1));
  mesh.uv = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  return mesh;
}

Displacement makeDisplacement(RlfShaderEntry entry, float km, float freq, float edgeLength,
                              int maxDepth) {
  Displacement d;
  d.shader = testing::makeShader(entry, km, freq);
  d.boundWorld = km;
  d.edgeLength = edgeLength;
  d.maxDepth = maxDepth;
  return d;
}

using Key = std::tuple<float, float, float>;
Key key(glm::vec3 p) { return {p.x, p.y, p.z}; }

// Directed micro-edges by position.
std::map<std::pair<Key, Key>, int> directedEdges(const MicroMesh& mm) {
  std::map<std::pair<Key, Key>, int> edges;
  for (uint32_t t = 0; t < mm.numTriangles(); ++t)
    for (int e = 0; e < 3; ++e)
      ++edges[{key(mm.P[mm.indices[3 * t + e]]), key(mm.P[mm.indices[3 * t + (e + 1) % 3]])}];
  return edges;
}

TEST(Subdivide, WithoutShaderReturnsTheInputTriangle) {
  const Mesh quad = makeQuad();
  MicroMesh mm;
  SubdivideCounters counters;
  subdivideTriangle(quad, 1, nullptr, mm, counters);
  ASSERT_EQ(mm.numTriangles(), 1u);
  EXPECT_EQ(mm.P[mm.indices[0]], quad.P[0]);
  EXPECT_EQ(mm.P[mm.indices[1]], quad.P[2]);
  EXPECT_EQ(mm.P[mm.indices[2]], quad.P[3]);
  EXPECT_EQ(counters.shaderPoints, 0u);
}

// P += Km * N, and Nout = Ng: what a shader sees as the surface's normals.
void liftEntry(const RlfShadingBatch* b, const void* params, RlfStatus*) {
  float km;
  std::memcpy(&km, params, 4);
  for (uint32_t i = 0; i < b->count; ++i) {
    b->Pout.x[i] = b->P.x[i] + km * b->N.x[i];
    b->Pout.y[i] = b->P.y[i] + km * b->N.y[i];
    b->Pout.z[i] = b->P.z[i] + km * b->N.z[i];
    b->Nout.x[i] = b->Ng.x[i], b->Nout.y[i] = b->Ng.y[i], b->Nout.z[i] = b->Ng.z[i];
  }
}

TEST(Subdivide, AReversedOrientationTurnsTheShadersNormalsInward) {
  const Mesh quad = makeQuad();
  for (bool reversed : {false, true}) {
    Displacement d = makeDisplacement(liftEntry, 0.25f, 1.0f, 0.5f, 12);
    d.reverseOrientation = reversed;
    MicroMesh mm;
    SubdivideCounters counters;
    subdivideTriangle(quad, 0, &d, mm, counters);
    ASSERT_GT(mm.numTriangles(), 0u);
    for (const glm::vec3& p : mm.P) EXPECT_FLOAT_EQ(p.z, reversed ? -0.25f : 0.25f);
    // The winding stays the input's: only the side the shader displaces towards changes.
    const glm::vec3 n = glm::cross(mm.P[mm.indices[1]] - mm.P[mm.indices[0]], mm.P[mm.indices[2]] - mm.P[mm.indices[0]]);
    EXPECT_GT(n.z, 0.0f);
  }
  // Normals the scene gave stay as given (the RI spec flips only the surface's own).
  Mesh given = makeQuad();
  given.givenNormals = true;
  Displacement reversed = makeDisplacement(liftEntry, 0.25f, 1.0f, 0.5f, 12);
  reversed.reverseOrientation = true;
  MicroMesh mm;
  SubdivideCounters counters;
  subdivideTriangle(given, 0, &reversed, mm, counters);
  for (const glm::vec3& p : mm.P) EXPECT_FLOAT_EQ(p.z, 0.25f);
  // Ng is the surface's own: it turns, also without normals (the face normal stands in for N).
  Mesh bare = makeQuad();
  bare.N.clear();
  Displacement d = makeDisplacement(liftEntry, 0.25f, 1.0f, 0.5f, 12);
  d.reverseOrientation = true;
  glm::vec3 shadingN;
  ASSERT_TRUE(displacedShadingNormal(bare, 0, d, glm::vec2(0.25f, 0.25f), &shadingN));
  EXPECT_LT(shadingN.z, -0.99f);
}

TEST(Subdivide, FlatShaderMeetsEdgeLengthAndKeepsArea) {
  const Mesh quad = makeQuad();
  const Displacement d = makeDisplacement(testing::bumpyEntry, 0.0f, 1.0f, 0.1f, 12);
  MicroMesh mm;
  SubdivideCounters counters;
  subdivideTriangle(quad, 0, &d, mm, counters);
  float area = 0.0f;
  for (uint32_t t = 0; t < mm.numTriangles(); ++t) {
    const glm::vec3 a = mm.P[mm.indices[3 * t]], b = mm.P[mm.indices[3 * t + 1]],
                    c = mm.P[mm.indices[3 * t + 2]];
    EXPECT_LE(glm::length(b - a), 0.1f);
    EXPECT_LE(glm::length(c - b), 0.1f);
    EXPECT_LE(glm::length(a - c), 0.1f);
    const glm::vec3 n = glm::cross(b - a, c - a);
    EXPECT_GT(n.z, 0.0f);  // wound as the input triangle
    area += 0.5f * glm::length(n);
  }
  EXPECT_NEAR(area, 0.5f, 1e-4f);
  EXPECT_EQ(counters.shaderPoints, mm.P.size());  // each vertex displaced exactly once
}

TEST(Subdivide, FlatnessMergesFlatGeometry) {
  const Mesh quad = makeQuad();
  Displacement d = makeDisplacement(testing::bumpyEntry, 0.0f, 1.0f, 0.1f, 12);
  d.flatness = 1e-4f;
  MicroMesh mm, unsimplified;
  SubdivideCounters counters;
  subdivideTriangle(quad, 0, &d, mm, counters);
  d.flatness = 0.0f;
  subdivideTriangle(quad, 0, &d, unsimplified, counters);
  // A flat triangle merges all the way back to itself (the paper's full recursive merge).
  EXPECT_EQ(mm.numTriangles(), 1u);
  EXPECT_EQ(unsimplified.numTriangles(), 256u);
  d = makeDisplacement(testing::bumpyEntry, 0.1f, 2.0f, 0.05f, 12);
  MicroMesh full, simple;
  subdivideTriangle(quad, 0, &d, full, counters);
  d.flatness = 0.002f;
  subdivideTriangle(quad, 0, &d, simple, counters);
  EXPECT_LT(simple.numTriangles(), full.numTriangles());
  EXPECT_GT(simple.numTriangles(), 8u);
}

TEST(Subdivide, DepthGuardStopsSplitting) {
  const Mesh quad = makeQuad();
  const Displacement d = makeDisplacement(testing::bumpyEntry, 0.0f, 1.0f, 1e-6f, 3);
  MicroMesh mm;
  SubdivideCounters counters;
  subdivideTriangle(quad, 0, &d, mm, counters);
  EXPECT_EQ(*std::max_element(mm.level.begin(), mm.level.end()), 3);
  EXPECT_EQ(mm.numTriangles(), 64u);  // 4^3: every edge wants splitting, uniform 1-to-4
}

// Conforming: inside one input triangle every micro-edge is shared by exactly two micro-triangles
// in opposite directions; edges on the input triangle's border appear once.
TEST(Subdivide, MicroMeshIsConforming) {
  const Mesh quad = makeQuad();
  const Displacement d = makeDisplacement(testing::bumpyEntry, 0.2f, 2.0f, 0.07f, 10);
  MicroMesh mm;
  SubdivideCounters counters;
  subdivideTriangle(quad, 0, &d, mm, counters);
  std::map<int, int> childCounts;
  const auto edges = directedEdges(mm);
  int border = 0;
  for (const auto& [edge, count] : edges) {
    EXPECT_EQ(count, 1);
    if (!edges.count({edge.second, edge.first})) ++border;
  }
  EXPECT_GT(border, 0);
  // Non-uniform: different parts reach different levels.
  std::set<int> levels(mm.level.begin(), mm.level.end());
  EXPECT_GE(levels.size(), 4u);
  // All border edges lie on the input triangle's border (barycentric coordinate zero).
  for (uint32_t t = 0; t < mm.numTriangles(); ++t)
    for (int e = 0; e < 3; ++e) {
      const uint32_t a = mm.indices[3 * t + e], b = mm.indices[3 * t + (e + 1) % 3];
      if (edges.count({key(mm.P[b]), key(mm.P[a])})) continue;
      const glm::vec2 ba = mm.bary[a], bb = mm.bary[b];
      const bool onBorder = (ba.x == 0 && bb.x == 0) || (ba.y == 0 && bb.y == 0) ||
                            (ba.x + ba.y == 1 && bb.x + bb.y == 1);
      EXPECT_TRUE(onBorder);
    }
}

// Crack-free across input triangles: the shared diagonal is split into the same displaced
// micro-edges, bit for bit, from both triangles.
TEST(Subdivide, SharedEdgeSplitIdenticallyFromBothSides) {
  const Mesh quad = makeQuad();
  const Displacement d = makeDisplacement(testing::bumpyEntry, 0.2f, 2.0f, 0.05f, 10);
  MicroMesh m0, m1;
  SubdivideCounters counters;
  subdivideTriangle(quad, 0, &d, m0, counters);
  subdivideTriangle(quad, 1, &d, m1, counters);
  const auto e1 = directedEdges(m1);
  // Pieces of the diagonal (0, 2): in triangle 0 = (0, 1, 2) corner 1 has weight zero (bary.x),
  // in triangle 1 = (0, 2, 3) corner 2 does (bary.y). Each piece of one must be a piece of the
  // other, reversed, with bit-identical displaced end points.
  auto pieces = [](const MicroMesh& mm, bool useX) {
    std::vector<std::pair<Key, Key>> out;
    for (uint32_t t = 0; t < mm.numTriangles(); ++t)
      for (int e = 0; e < 3; ++e) {
        const uint32_t a = mm.indices[3 * t + e], b = mm.indices[3 * t + (e + 1) % 3];
        const float wa = useX ? mm.bary[a].x : mm.bary[a].y, wb = useX ? mm.bary[b].x : mm.bary[b].y;
        if (wa == 0.0f && wb == 0.0f) out.push_back({key(mm.P[a]), key(mm.P[b])});
      }
    return out;
  };
  const auto diagonal0 = pieces(m0, true), diagonal1 = pieces(m1, false);
  EXPECT_GT(diagonal0.size(), 4u);
  EXPECT_EQ(diagonal0.size(), diagonal1.size());
  for (const auto& [a, b] : diagonal0) EXPECT_TRUE(e1.count({b, a}));
}

TEST(Subdivide, NonFiniteDisplacementFallsBackToUndisplaced) {
  const Mesh quad = makeQuad();
  const Displacement d = makeDisplacement(testing::nanEntry, 0.0f, 0.0f, 0.2f, 6);
  MicroMesh mm;
  SubdivideCounters counters;
  subdivideTriangle(quad, 0, &d, mm, counters);
  for (const glm::vec3& p : mm.P) {
    EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    EXPECT_EQ(p.z, 0.0f);
  }
  // Counted once per replaced point (u = x here, and NaN was returned where u > 0.5).
  uint32_t expected = 0;
  for (const glm::vec3& p : mm.P) expected += p.x > 0.5f;
  EXPECT_GT(expected, 0u);
  EXPECT_EQ(counters.status.nonFinite, expected);
  EXPECT_GT(mm.numTriangles(), 1u);
}

// Moves every point to (dsdu, dtdv, dsdv) + dPdu + 10 * dNdu: the host's seeds become visible.
void seedEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  for (uint32_t i = 0; i < b->count; ++i) {
    b->Pout.x[i] = b->dsdu[i] + b->dPdu.x[i] + 10 * b->dNdu.x[i];
    b->Pout.y[i] = b->dtdv[i] + b->dPdu.y[i] + 10 * b->dNdu.y[i];
    b->Pout.z[i] = b->dsdv[i] + b->dPdu.z[i] + 10 * b->dNdu.z[i];
    b->Nout.x[i] = b->N.x[i], b->Nout.y[i] = b->N.y[i], b->Nout.z[i] = b->N.z[i];
  }
}

TEST(Subdivide, HostSuppliesDerivativeSeeds) {
  Mesh quad = makeQuad();
  for (glm::vec2& uv : quad.uv) uv *= 0.5f;  // u, v over [0, 0.5]: dP/du = (2, 0, 0)
  quad.st = {{0, 0}, {2, 0}, {2, 4}, {0, 4}};  // in uv units: ds/du = 4, dt/dv = 8
  quad.N = {{0, 0, 1}, {0.1f, 0, 1}, {0.1f, 0, 1}, {0, 0, 1}};  // N.x grows with u: 0.2 per unit u
  const Displacement d = makeDisplacement(seedEntry, 0.0f, 0.0f, 10.0f, 4);
  MicroMesh mm;
  SubdivideCounters counters;
  subdivideTriangle(quad, 0, &d, mm, counters);
  ASSERT_EQ(mm.numTriangles(), 1u);
  EXPECT_NEAR(mm.P[0].x, 4.0f + 2.0f + 10 * 0.2f, 1e-5f);
  EXPECT_NEAR(mm.P[0].y, 8.0f, 1e-5f);
  EXPECT_NEAR(mm.P[0].z, 0.0f, 1e-5f);
}

TEST(Subdivide, DeterministicAcrossCalls) {
  const Mesh quad = makeQuad();
  const Displacement d = makeDisplacement(testing::bumpyEntry, 0.2f, 3.0f, 0.04f, 10);
  MicroMesh a, b, other;
  SubdivideCounters counters;
  subdivideTriangle(quad, 0, &d, a, counters);
  subdivideTriangle(quad, 1, &d, other, counters);  // interleave another triangle
  subdivideTriangle(quad, 0, &d, b, counters);
  EXPECT_EQ(a.P, b.P);
  EXPECT_EQ(a.indices, b.indices);
}

TEST(Subdivide, DegeneratePoleTrianglesStayFinite) {
  testing::SphereOptions o;
  o.edgeLength = 0.05f;
  const Scene scene = testing::makeSphereScene(o);
  const Mesh& mesh = scene.meshes[0];
  MicroMesh mm;
  SubdivideCounters counters;
  for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
    subdivideTriangle(mesh, t, &scene.displacements[0], mm, counters);
    for (const glm::vec3& p : mm.P) ASSERT_TRUE(std::isfinite(p.x + p.y + p.z)) << "triangle " << t;
  }
  EXPECT_EQ(counters.status.nonFinite, 0u);
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// Culling to a box keeps exactly the full subdivision's triangles that reach it, with the same
// ids and bit-identical positions, and ids are unique.
// With simplification too: its decisions are per edge and per triangle, never per box.
class SubdivideCulling : public ::testing::TestWithParam<float> {};

TEST_P(SubdivideCulling, KeepsIdsAndGeometry) {
  const Mesh quad = makeQuad();
  Displacement d = makeDisplacement(testing::bumpyEntry, 0.05f, 2.0f, 0.02f, 10);
  d.flatness = GetParam();
  MicroMesh full, culled;
  SubdivideCounters fullCounters, culledCounters;
  subdivideTriangle(quad, 0, &d, full, fullCounters);
  const CullBox box{{0.6f, 0.1f, -1.0f}, {0.8f, 0.3f, 1.0f}};
  subdivideTriangle(quad, 0, &d, culled, culledCounters, &box);
  // Simplification's lookahead runs along whole edges, also out of the box: it culls less.
  EXPECT_LT(culledCounters.shaderPoints * (GetParam() > 0 ? 1 : 3), fullCounters.shaderPoints);
  using Tri = std::tuple<Key, Key, Key>;
  auto triangleOf = [](const MicroMesh& mm, uint32_t i) {
    return Tri{key(mm.P[mm.indices[3 * i]]), key(mm.P[mm.indices[3 * i + 1]]),
               key(mm.P[mm.indices[3 * i + 2]])};
  };
  std::map<uint32_t, Tri> byId;
  for (uint32_t i = 0; i < full.numTriangles(); ++i)
    EXPECT_TRUE(byId.emplace(full.ids[i], triangleOf(full, i)).second) << "duplicate id";
  auto reaches = [&](const MicroMesh& mm, uint32_t i) {
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (int c = 0; c < 3; ++c) lo = glm::min(lo, mm.P[mm.indices[3 * i + c]]), hi = glm::max(hi, mm.P[mm.indices[3 * i + c]]);
    return lo.x <= box.hi.x && box.lo.x <= hi.x && lo.y <= box.hi.y && box.lo.y <= hi.y &&
           lo.z <= box.hi.z && box.lo.z <= hi.z;
  };
  std::set<uint32_t> culledIds;
  for (uint32_t i = 0; i < culled.numTriangles(); ++i) {
    auto it = byId.find(culled.ids[i]);
    ASSERT_NE(it, byId.end());
    EXPECT_EQ(it->second, triangleOf(culled, i));
    culledIds.insert(culled.ids[i]);
  }
  int reaching = 0;
  for (uint32_t i = 0; i < full.numTriangles(); ++i)
    if (reaches(full, i)) {
      ++reaching;
      EXPECT_TRUE(culledIds.count(full.ids[i]));
    }
  EXPECT_GT(reaching, 10);
}

INSTANTIATE_TEST_SUITE_P(Flatness, SubdivideCulling, ::testing::Values(0.0f, 0.002f));

}  // namespace
}  // namespace relief
