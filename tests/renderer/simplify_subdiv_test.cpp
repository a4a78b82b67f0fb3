// Tests of simplification (paper 3.1) and of the depth guard: removed geometry stays within the
// flatness tolerance of the simplified surface, the bevelled box loses most of its triangles, the
// saved-fraction counters agree with the meshes, and runaway shaders stop at maxDepth.
#include <algorithm>
#include <array>
#include <map>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <tuple>

#include <gtest/gtest.h>

#include "geometry_test_util.h"
#include "renderer/subdivide.h"

namespace relief {
namespace {

// The bevel of examples/shaders/roundedbox.disp, in world space (object = world here): the point
// moves to the nearest point of the shrunken box, pushed out by `radius` along the way it came.
void roundedBoxEntry(const RlfShadingBatch* b, const void* params, RlfStatus*) {
  float radius, half;
  std::memcpy(&radius, params, 4);
  std::memcpy(&half, static_cast<const char*>(params) + 4, 4);
  for (uint32_t i = 0; i < b->count; ++i) {
    const glm::vec3 p(b->P.x[i], b->P.y[i], b->P.z[i]);
    const glm::vec3 q = glm::clamp(p, glm::vec3(radius - half), glm::vec3(half - radius));
    const glm::vec3 d = p - q;
    const float len = glm::length(d);
    const glm::vec3 out = len > 0.0f ? q + radius * (d / len) : p;
    b->Pout.x[i] = out.x, b->Pout.y[i] = out.y, b->Pout.z[i] = out.z;
    b->Nout.x[i] = b->N.x[i], b->Nout.y[i] = b->N.y[i], b->Nout.z[i] = b->N.z[i];
  }
}

// Never settles: each point moves by a large pseudo-random amount, so every edge always wants
// splitting.
void runawayEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  for (uint32_t i = 0; i < b->count; ++i) {
    uint32_t h;
    std::memcpy(&h, &b->u[i], 4);
    uint32_t k;
    std::memcpy(&k, &b->v[i], 4);
    h = (h ^ (k * 0x9E3779B9u)) * 0x85EBCA6Bu;
    h ^= h >> 13;
    const float jump = float(h % 1000u);
    b->Pout.x[i] = b->P.x[i], b->Pout.y[i] = b->P.y[i], b->Pout.z[i] = b->P.z[i] + jump;
    b->Nout.x[i] = b->N.x[i], b->Nout.y[i] = b->N.y[i], b->Nout.z[i] = b->N.z[i];
  }
}

// A narrow bump (height p0, width p1) along N around (15/32, 6/32, 0): on makeQuad's triangle 0
// that is the point with barycentric weights (17, 9, 6) / 32, a sample of the finest interior
// lattice (32 steps) that no coarser lattice has, and far from the triangle's edges and centre.
void narrowBumpEntry(const RlfShadingBatch* b, const void* params, RlfStatus*) {
  float height, width;
  std::memcpy(&height, params, 4);
  std::memcpy(&width, static_cast<const char*>(params) + 4, 4);
  for (uint32_t i = 0; i < b->count; ++i) {
    const glm::vec3 p(b->P.x[i], b->P.y[i], b->P.z[i]), n(b->N.x[i], b->N.y[i], b->N.z[i]);
    const glm::vec3 d = p - glm::vec3(15.0f / 32, 6.0f / 32, 0.0f);
    const glm::vec3 out = p + n * (height * std::exp(-glm::dot(d, d) / (width * width)));
    b->Pout.x[i] = out.x, b->Pout.y[i] = out.y, b->Pout.z[i] = out.z;
    b->Nout.x[i] = n.x, b->Nout.y[i] = n.y, b->Nout.z[i] = n.z;
  }
}

// Records (u, v, du) of every point it is asked to displace, and displaces nothing.
std::vector<std::array<float, 3>> recordedPoints;
void recordingEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  for (uint32_t i = 0; i < b->count; ++i) {
    recordedPoints.push_back({b->u[i], b->v[i], b->du[i]});
    b->Pout.x[i] = b->P.x[i], b->Pout.y[i] = b->P.y[i], b->Pout.z[i] = b->P.z[i];
    b->Nout.x[i] = b->N.x[i], b->Nout.y[i] = b->N.y[i], b->Nout.z[i] = b->N.z[i];
  }
}

// The 12 triangles of the cube [-1, 1]^3, wound outward, corners shared between faces.
Mesh makeCube() {
  Mesh mesh;
  mesh.P = {{-1, -1, -1}, {1, -1, -1}, {1, -1, 1}, {-1, -1, 1},
            {-1, 1, -1},  {1, 1, -1},  {1, 1, 1},  {-1, 1, 1}};
  const uint32_t quads[6][4] = {{0, 1, 2, 3}, {4, 7, 6, 5}, {0, 4, 5, 1},
                                {1, 5, 6, 2}, {2, 6, 7, 3}, {3, 7, 4, 0}};
  for (const auto& q : quads)
    for (uint32_t i : {q[0], q[1], q[2], q[0], q[2], q[3]}) mesh.indices.push_back(i);
  return mesh;
}

Mesh makeQuad() {
  Mesh mesh;
  mesh.P = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  mesh.N.assign(4, glm::vec3(0, 0, 1));
  mesh.uv = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  return mesh;
}

Displacement makeDisplacement(RlfShaderEntry entry, float p0, float p1, float edgeLength,
                              int maxDepth, float flatness) {
  Displacement d;
  d.shader = testing::makeShader(entry, p0, p1);
  d.boundWorld = 1.0f;
  d.edgeLength = edgeLength;
  d.maxDepth = maxDepth;
  d.flatness = flatness;
  return d;
}

float segmentDistance(glm::vec3 p, glm::vec3 a, glm::vec3 b) {
  const glm::vec3 e = b - a;
  const float t = std::clamp(glm::dot(p - a, e) / glm::dot(e, e), 0.0f, 1.0f);
  return glm::length(p - (a + t * e));
}

// Distance from p to a triangle (double-checked by brute force: plane if the projection is inside,
// else the nearest edge).
float triangleDistance(glm::vec3 p, glm::vec3 a, glm::vec3 b, glm::vec3 c) {
  const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
  const float h = glm::dot(p - a, n);
  const glm::vec3 q = p - h * n;
  if (glm::dot(glm::cross(b - a, q - a), n) >= 0 && glm::dot(glm::cross(c - b, q - b), n) >= 0 &&
      glm::dot(glm::cross(a - c, q - c), n) >= 0)
    return std::fabs(h);
  return std::min({segmentDistance(p, a, b), segmentDistance(p, b, c), segmentDistance(p, c, a)});
}

float meshDistance(glm::vec3 p, const MicroMesh& mm) {
  float best = std::numeric_limits<float>::infinity();
  for (uint32_t t = 0; t < mm.numTriangles(); ++t)
    best = std::min(best, triangleDistance(p, mm.P[mm.indices[3 * t]], mm.P[mm.indices[3 * t + 1]],
                                           mm.P[mm.indices[3 * t + 2]]));
  return best;
}

// Every vertex of the unsimplified micro-mesh (what simplification removes) lies within the
// tolerance of the simplified surface, for several tolerances and shapes.
TEST(Simplify, RemovedVerticesLieWithinTolerance) {
  const Mesh quad = makeQuad();
  for (float flatness : {0.001f, 0.005f, 0.02f}) {
    for (float freq : {1.0f, 2.0f}) {
      const Displacement full = makeDisplacement(testing::bumpyEntry, 0.1f, freq, 0.03f, 10, 0.0f);
      const Displacement simple =
          makeDisplacement(testing::bumpyEntry, 0.1f, freq, 0.03f, 10, flatness);
      MicroMesh a, b;
      SubdivideCounters counters;
      subdivideTriangle(quad, 0, &full, a, counters);
      subdivideTriangle(quad, 0, &simple, b, counters);
      EXPECT_LT(b.numTriangles(), a.numTriangles());
      std::vector<bool> used(a.P.size(), false);
      for (uint32_t i : a.indices) used[i] = true;
      float worst = 0.0f;
      for (size_t i = 0; i < a.P.size(); ++i)
        if (used[i]) worst = std::max(worst, meshDistance(a.P[i], b));
      EXPECT_LE(worst, flatness * 1.001f + 1e-6f) << "flatness " << flatness << " freq " << freq;
    }
  }
}

// Interior flatness is judged on every point of the finest sampling lattice: a bump that only
// one of those points sees (the coarser lattices, the centre and the edges miss it) keeps the
// triangle from being final. Without the bump the same triangle merges back into one.
TEST(Simplify, InteriorDetailSeenByOneFineSampleIsKept) {
  const Mesh quad = makeQuad();
  MicroMesh mm;
  SubdivideCounters counters;
  const Displacement flat = makeDisplacement(narrowBumpEntry, 0.0f, 0.008f, 0.03f, 10, 0.002f);
  subdivideTriangle(quad, 0, &flat, mm, counters);
  EXPECT_EQ(mm.numTriangles(), 1u);
  const Displacement bump = makeDisplacement(narrowBumpEntry, 0.1f, 0.008f, 0.03f, 10, 0.002f);
  subdivideTriangle(quad, 0, &bump, mm, counters);
  EXPECT_GT(mm.numTriangles(), 1u);
}

// A flat triangle is only final once every point of its finest interior lattice was found flat:
// the coarse-to-fine stages together evaluate each of those points exactly once, each seen by the
// shader with the same spacing (du: the edge length over the mesh's scale, 1 here), as a single
// batch of them all would be.
TEST(Simplify, FlatInteriorIsSampledOnEveryPointOfTheFinestLatticeOnce) {
  const Mesh quad = makeQuad();
  recordedPoints.clear();
  MicroMesh mm;
  SubdivideCounters counters;
  const Displacement flat = makeDisplacement(recordingEntry, 0.0f, 0.0f, 0.03f, 10, 0.002f);
  subdivideTriangle(quad, 0, &flat, mm, counters);
  ASSERT_EQ(mm.numTriangles(), 1u);
  // Triangle 0 is (0, 1, 2) with uv (0,0), (1,0), (1,1); its longest edge (1.41) asks for the
  // deepest lattice, 32 steps, sampled at level 5.
  const glm::vec2 uv[3] = {quad.uv[0], quad.uv[1], quad.uv[2]};
  std::map<std::pair<float, float>, std::vector<float>> seen;
  for (const auto& r : recordedPoints) seen[{r[0], r[1]}].push_back(r[2]);
  const int steps = 32;
  int missing = 0, repeated = 0, wrongSpacing = 0, expected = 0;
  for (int i = 1; i < steps; ++i)
    for (int j = 1; i + j < steps; ++j) {
      ++expected;
      const float wa = float(steps - i - j) / float(steps), wb = float(i) / float(steps),
                  wc = float(j) / float(steps);
      const glm::vec2 p = wa * uv[0] + wb * uv[1] + wc * uv[2];  // as the subdivider computes it
      const auto found = seen.find({p.x, p.y});
      if (found == seen.end()) {
        ++missing;
        continue;
      }
      repeated += found->second.size() > 1;
      wrongSpacing += found->second[0] != 0.03f;
    }
  EXPECT_EQ(expected, 465);
  EXPECT_EQ(missing, 0);
  EXPECT_EQ(repeated, 0);
  EXPECT_EQ(wrongSpacing, 0);
}

// The paper's bevelled box: flat faces merge back to their input triangles; only the bevels keep
// fine triangles. Most of the geometry is saved, and the counters say so.
TEST(Simplify, BevelledBoxSavesMostGeometry) {
  const Mesh cube = makeCube();
  const Displacement full = makeDisplacement(roundedBoxEntry, 0.25f, 1.0f, 0.05f, 12, 0.0f);
  const Displacement simple = makeDisplacement(roundedBoxEntry, 0.25f, 1.0f, 0.05f, 12, 0.002f);
  uint64_t fullCount = 0, simpleCount = 0;
  SubdivideCounters fullCounters, simpleCounters;
  MicroMesh mm;
  for (uint32_t t = 0; t < cube.numTriangles(); ++t) {
    subdivideTriangle(cube, t, &full, mm, fullCounters);
    fullCount += mm.numTriangles();
    subdivideTriangle(cube, t, &simple, mm, simpleCounters);
    simpleCount += mm.numTriangles();
  }
  EXPECT_EQ(fullCounters.trianglesBeforeSimplification, fullCount);
  EXPECT_EQ(fullCounters.trianglesAfterSimplification, fullCount);
  EXPECT_EQ(simpleCounters.trianglesAfterSimplification, simpleCount);
  const double saved = 1.0 - double(simpleCount) / double(fullCount);
  EXPECT_GT(saved, 0.5) << simpleCount << " of " << fullCount;
  // The estimate of the unsimplified count is close to the real one.
  const double estimate = double(simpleCounters.trianglesBeforeSimplification);
  EXPECT_GT(estimate, 0.5 * double(fullCount));
  EXPECT_LT(estimate, 2.0 * double(fullCount));
}

// Shared cube edges are decided from the edge alone: the micro-vertices on a cube edge are the
// same from both faces, with simplification on.
TEST(Simplify, SharedEdgesAgreeAcrossInputTriangles) {
  const Mesh cube = makeCube();
  const Displacement simple = makeDisplacement(roundedBoxEntry, 0.25f, 1.0f, 0.05f, 12, 0.002f);
  // Triangles 0 (face y = -1: 0,1,2) and 7 (face x = 1: 1,6,2) share the cube edge (1, 2).
  auto edgePoints = [&](uint32_t t) {
    MicroMesh mm;
    SubdivideCounters counters;
    subdivideTriangle(cube, t, &simple, mm, counters);
    std::set<std::tuple<float, float, float>> points;
    for (uint32_t i : mm.indices) {
      const glm::vec3 p = mm.P[i];
      // The cube edge x = 1, y = -1 maps to the middle of the bevel's arc.
      if (std::fabs(p.x - (1.0f - 0.25f + 0.25f * std::sqrt(0.5f))) < 1e-4f &&
          std::fabs(p.y + (1.0f - 0.25f + 0.25f * std::sqrt(0.5f))) < 1e-4f)
        points.insert({p.x, p.y, p.z});
    }
    return points;
  };
  const auto a = edgePoints(0), b = edgePoints(7);
  EXPECT_GT(a.size(), 4u);
  EXPECT_EQ(a, b);
}

// A shader that never settles still stops at maxDepth, with and without simplification.
TEST(Simplify, DepthGuardStopsRunawayShaders) {
  const Mesh quad = makeQuad();
  for (float flatness : {0.0f, 0.5f}) {
    const Displacement d = makeDisplacement(runawayEntry, 0.0f, 0.0f, 0.01f, 5, flatness);
    MicroMesh mm;
    SubdivideCounters counters;
    subdivideTriangle(quad, 0, &d, mm, counters);
    for (uint32_t i : mm.indices) EXPECT_LE(mm.level[i], 5);
    EXPECT_LE(mm.numTriangles(), 1024u);  // 4^5
    EXPECT_GT(mm.numTriangles(), 64u);
  }
}

// subdivide.h, work guard: the estimate is 4^k per triangle (k halvings of the longest edge to
// reach the edge length); a subdivision that evaluates more than kRunawayAllowance times that
// counts the rest as excess, and past the limit the Displacement is marked runaway and its
// subdivisions stop early. A surface that meets its edge length never counts, however often it is
// subdivided again (refills under a budget).
TEST(Simplify, WorkGuardStopsRunawaySubdivisionsOnly) {
  Scene scene;
  scene.meshes.push_back(makeQuad());  // longest edges sqrt(2): 2 halvings to 0.5, 8 to 0.01
  scene.meshes[0].displacementIndex = 0;
  scene.displacements.push_back(makeDisplacement(runawayEntry, 0.0f, 0.0f, 0.5f, 8, 0.0f));
  Displacement& d = scene.displacements[0];
  MicroMesh unguarded;
  SubdivideCounters counters;
  subdivideTriangle(scene.meshes[0], 0, &d, unguarded, counters);  // not armed yet: no guard
  EXPECT_FALSE(d.problems->runaway.load());
  EXPECT_EQ(d.problems->excessPoints.load(), 0u);

  const std::vector<double> estimate = setSubdivisionLimits(scene);
  ASSERT_EQ(estimate.size(), 1u);
  EXPECT_EQ(estimate[0], 2 * 16.0);
  EXPECT_EQ(d.problems->pointLimit, kRunawayPoints);
  // One subdivision past the limit (small, to keep the test quick) stops at once.
  d.problems->pointLimit = 1000;
  MicroMesh guarded;
  subdivideTriangle(scene.meshes[0], 0, &d, guarded, counters);
  EXPECT_TRUE(d.problems->runaway.load());
  EXPECT_TRUE(subdivisionRanAway(scene));
  EXPECT_LT(guarded.numTriangles(), unguarded.numTriangles() / 4);  // stopped rounds early
  EXPECT_GT(unguarded.numTriangles(), 64u * 16u);

  // Subdivisions each under the limit but over 16 times the allowance add up to a stop, after a
  // few (their sum must pass 8 times the limit).
  const uint64_t perSubdivision = [&] {
    SubdivideCounters c;
    MicroMesh mm;
    Displacement free = makeDisplacement(runawayEntry, 0.0f, 0.0f, 0.5f, 8, 0.0f);
    subdivideTriangle(scene.meshes[0], 0, &free, mm, c);
    return c.shaderPoints;
  }() - 64 * 16;
  ASSERT_GT(perSubdivision, 16u * 64 * 16);
  d.problems->runaway = false;
  d.problems->excessPoints = 0;
  d.problems->pointLimit = perSubdivision + 1000;
  int subdivisions = 0;
  while (!d.problems->runaway.load() && subdivisions < 20) {
    MicroMesh mm;
    subdivideTriangle(scene.meshes[0], 0, &d, mm, counters);
    ++subdivisions;
  }
  EXPECT_TRUE(d.problems->runaway.load());
  EXPECT_GE(subdivisions, 8);
  EXPECT_LT(subdivisions, 20);

  // A bumpy surface at the same settings stays within its allowance, subdivided 50 times over.
  Scene bumpy;
  bumpy.meshes.push_back(makeQuad());
  bumpy.meshes[0].displacementIndex = 0;
  bumpy.displacements.push_back(makeDisplacement(testing::bumpyEntry, 0.1f, 2.0f, 0.01f, 10, 0.0f));
  EXPECT_EQ(setSubdivisionLimits(bumpy)[0], 2 * 65536.0);
  bumpy.displacements[0].problems->pointLimit = 1;
  for (int i = 0; i < 50; ++i) {
    MicroMesh mm;
    subdivideTriangle(bumpy.meshes[0], uint32_t(i % 2), &bumpy.displacements[0], mm, counters);
  }
  EXPECT_EQ(bumpy.displacements[0].problems->excessPoints.load(), 0u);
  EXPECT_FALSE(subdivisionRanAway(bumpy));
}

// Records the first point's dPdu and dPdv, and leaves P where it is.
glm::vec3 seenDPdu, seenDPdv;
void recordFrameEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  seenDPdu = {b->dPdu.x[0], b->dPdu.y[0], b->dPdu.z[0]};
  seenDPdv = {b->dPdv.x[0], b->dPdv.y[0], b->dPdv.z[0]};
  for (uint32_t i = 0; i < b->count; ++i) {
    b->Pout.x[i] = b->P.x[i], b->Pout.y[i] = b->P.y[i], b->Pout.z[i] = b->P.z[i];
    b->Nout.x[i] = b->N.x[i], b->Nout.y[i] = b->N.y[i], b->Nout.z[i] = b->N.z[i];
  }
}

// A polygon in the plane x = 0 has a degenerate (u, v) = object (x, y) (RI spec); its derivatives
// then follow st, so texture filter widths stay right on walls seen edge-on from z.
TEST(Subdivide, DegenerateSurfaceParametersTakeTheFrameFromSt) {
  Mesh wall;
  wall.P = {{0, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  wall.uv = {{0, 0}, {0, 1}, {0, 0}};
  wall.st = {{0, 0}, {2, 0}, {0, 4}};
  wall.indices = {0, 1, 2};
  const Displacement d = makeDisplacement(recordFrameEntry, 0.0f, 0.0f, 10.0f, 4, 0.0f);
  MicroMesh mm;
  SubdivideCounters counters;
  subdivideTriangle(wall, 0, &d, mm, counters);
  EXPECT_EQ(seenDPdu, glm::vec3(0, 0.5f, 0));   // dP/ds
  EXPECT_EQ(seenDPdv, glm::vec3(0, 0, 0.25f));  // dP/dt
  wall.uv = {{0, 0}, {1, 0}, {0, 1}};           // a regular (u, v) is used as it is
  subdivideTriangle(wall, 0, &d, mm, counters);
  EXPECT_EQ(seenDPdu, glm::vec3(0, 1, 0));
  EXPECT_EQ(seenDPdv, glm::vec3(0, 0, 1));
}

}  // namespace
}  // namespace relief
