// Tests of the RIB reader's geometry helpers: ear-clipping triangulation (convex, concave, holes,
// degenerate input) and the cubic bases of RiBasis.
#include "renderer/rib_geometry.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

namespace relief {
namespace {

using Loops = std::vector<std::vector<glm::vec3>>;

glm::vec3 corner(const Loops& loops, uint32_t index) {
  for (const auto& loop : loops) {
    if (index < loop.size()) return loop[index];
    index -= uint32_t(loop.size());
  }
  ADD_FAILURE() << "index out of range";
  return glm::vec3(0);
}

// Sum of the triangles' areas, each signed by its normal's z.
float signedAreaZ(const Loops& loops, const std::vector<uint32_t>& tris) {
  float area = 0.0f;
  for (size_t i = 0; i < tris.size(); i += 3) {
    const glm::vec3 a = corner(loops, tris[i]), b = corner(loops, tris[i + 1]),
                    c = corner(loops, tris[i + 2]);
    area += 0.5f * glm::cross(b - a, c - a).z;
  }
  return area;
}

TEST(Triangulate, ConvexPolygonIsAFanAroundTheFirstCorner) {
  const Loops square = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}};
  EXPECT_EQ(triangulatePolygon(square), (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
  const Loops triangle = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
  EXPECT_EQ(triangulatePolygon(triangle), (std::vector<uint32_t>{0, 1, 2}));
}

// A convex polygon of many points (a disk) is split in halves: n - 2 triangles, all wound as the
// loop, covering it, and small, not slivers from corner 0 across the whole disk.
TEST(Triangulate, LargeConvexPolygonsAreSplitInHalvesNotFanned) {
  const int n = 1000;
  std::vector<glm::vec3> disk;
  for (int i = 0; i < n; ++i) {
    const float a = 2.0f * float(M_PI) * float(i) / float(n);
    disk.emplace_back(std::cos(a), std::sin(a), 0.0f);
  }
  const Loops loops = {disk};
  const std::vector<uint32_t> tris = triangulatePolygon(loops);
  ASSERT_EQ(tris.size(), 3u * (n - 2));
  const float polygonArea = 0.5f * float(n) * std::sin(2.0f * float(M_PI) / float(n));
  EXPECT_NEAR(signedAreaZ(loops, tris), polygonArea, 1e-4f);
  int reachingAcross = 0;
  for (size_t i = 0; i < tris.size(); i += 3) {
    const glm::vec3 a = corner(loops, tris[i]), b = corner(loops, tris[i + 1]), c = corner(loops, tris[i + 2]);
    EXPECT_GT(glm::cross(b - a, c - a).z, 0.0f) << "triangle " << i / 3;
    if (std::max({glm::distance(a, b), glm::distance(b, c), glm::distance(c, a)}) > 1.0f) ++reachingAcross;
  }
  // A fan has about 2n/3 triangles with an edge longer than the radius; halves have a handful.
  EXPECT_LT(reachingAcross, 10);
  // Up to kBalancedConvexPoints it stays the fan.
  std::vector<glm::vec3> small;
  for (size_t i = 0; i < kBalancedConvexPoints; ++i) {
    const float a = 2.0f * float(M_PI) * float(i) / float(kBalancedConvexPoints);
    small.emplace_back(std::cos(a), std::sin(a), 0.0f);
  }
  const std::vector<uint32_t> fan = triangulatePolygon({small});
  for (size_t i = 0; i < fan.size(); i += 3) EXPECT_EQ(fan[i], 0u);
}

TEST(Triangulate, ConcavePolygonKeepsItsAreaAndWinding) {
  // An L shape (area 3) whose fan from corner 0 would cover the missing square.
  const Loops ell = {{{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {1, 2, 0}, {0, 2, 0}}};
  const std::vector<uint32_t> tris = triangulatePolygon(ell);
  ASSERT_EQ(tris.size(), 12u);
  EXPECT_NEAR(signedAreaZ(ell, tris), 3.0f, 1e-5f);
  for (size_t i = 0; i < tris.size(); i += 3) {  // every triangle counter-clockwise, none inverted
    const glm::vec3 a = corner(ell, tris[i]), b = corner(ell, tris[i + 1]),
                    c = corner(ell, tris[i + 2]);
    EXPECT_GT(glm::cross(b - a, c - a).z, 0.0f);
  }
  // Clockwise input stays clockwise.
  Loops reversed = ell;
  std::reverse(reversed[0].begin(), reversed[0].end());
  EXPECT_NEAR(signedAreaZ(reversed, triangulatePolygon(reversed)), -3.0f, 1e-5f);
}

TEST(Triangulate, HolesAreCutOut) {
  // A 4 x 4 square with two 1 x 1 holes, given in either winding.
  const Loops withHoles = {{{0, 0, 0}, {4, 0, 0}, {4, 4, 0}, {0, 4, 0}},
                           {{1, 1, 0}, {2, 1, 0}, {2, 2, 0}, {1, 2, 0}},
                           {{3, 3, 0}, {2.5f, 3, 0}, {2.5f, 2.5f, 0}, {3, 2.5f, 0}}};
  const std::vector<uint32_t> tris = triangulatePolygon(withHoles);
  EXPECT_EQ(tris.size(), 3u * (12 + 2 * 2 - 2));
  EXPECT_NEAR(signedAreaZ(withHoles, tris), 16.0f - 1.0f - 0.25f, 1e-4f);
  // No triangle covers a hole's centre.
  for (glm::vec3 centre : {glm::vec3(1.5f, 1.5f, 0), glm::vec3(2.75f, 2.75f, 0)}) {
    for (size_t i = 0; i < tris.size(); i += 3) {
      const glm::vec3 a = corner(withHoles, tris[i]), b = corner(withHoles, tris[i + 1]),
                      c = corner(withHoles, tris[i + 2]);
      const bool inside = glm::cross(b - a, centre - a).z > 0 &&
                          glm::cross(c - b, centre - b).z > 0 && glm::cross(a - c, centre - c).z > 0;
      EXPECT_FALSE(inside) << "triangle " << i / 3 << " covers a hole";
    }
  }
}

TEST(Triangulate, NonPlanarAxisAndDegenerateInputStillGiveTriangles) {
  // A polygon in the x = 1 plane (projection picks y, z) and one with repeated, collinear points.
  const Loops side = {{{1, 0, 0}, {1, 1, 0}, {1, 1, 1}, {1, 0.5f, 0.5f}, {1, 0, 1}}};
  EXPECT_EQ(triangulatePolygon(side).size(), 9u);
  const Loops degenerate = {{{0, 0, 0}, {1, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 0, 0}}};
  EXPECT_EQ(triangulatePolygon(degenerate).size(), 9u);
  EXPECT_TRUE(triangulatePolygon({{{0, 0, 0}, {1, 0, 0}}}).empty());
}

TEST(Triangulate, HugePolygonsFinishInBoundedTime) {
  // A concave comb far beyond the ear-clipping limit: bounded time, n - 2 triangles.
  std::vector<glm::vec3> comb;
  for (size_t i = 0; i < kMaxEarClippingPoints + 2; ++i)
    comb.emplace_back(float(i), i % 2 ? 1.0f : 2.0f, 0.0f);
  comb.emplace_back(float(comb.size()), 0.0f, 0.0f);
  comb.emplace_back(0.0f, 0.0f, 0.0f);
  EXPECT_EQ(triangulatePolygon({comb}).size(), 3 * (comb.size() - 2));
}

TEST(CubicBasis, NamedBasesInterpolateAndSumToOne) {
  for (const char* name : {"bezier", "b-spline", "catmull-rom"}) {
    CubicBasis basis;
    ASSERT_TRUE(namedCubicBasis(name, &basis)) << name;
    for (float u : {0.0f, 0.3f, 1.0f}) {
      float w[4];
      basis.weights(u, w);
      EXPECT_NEAR(w[0] + w[1] + w[2] + w[3], 1.0f, 1e-6f) << name;
    }
  }
  CubicBasis bezier;
  ASSERT_TRUE(namedCubicBasis("bezier", &bezier));
  EXPECT_EQ(bezier.step, 3);
  float w[4], dw[4];
  bezier.weights(0.0f, w);
  EXPECT_EQ(w[0], 1.0f);
  bezier.weights(1.0f, w);
  EXPECT_EQ(w[3], 1.0f);
  bezier.derivativeWeights(0.0f, dw);  // P'(0) = 3 (P1 - P0)
  EXPECT_FLOAT_EQ(dw[0], -3.0f);
  EXPECT_FLOAT_EQ(dw[1], 3.0f);
  CubicBasis catmull;
  ASSERT_TRUE(namedCubicBasis("catmull-rom", &catmull));
  catmull.weights(0.0f, w);  // passes through P1 at u = 0
  EXPECT_FLOAT_EQ(w[1], 1.0f);
  CubicBasis hermite, power;
  EXPECT_TRUE(namedCubicBasis("hermite", &hermite));
  EXPECT_EQ(hermite.step, 2);
  EXPECT_TRUE(namedCubicBasis("power", &power));
  EXPECT_EQ(power.step, 4);
  EXPECT_FALSE(namedCubicBasis("nurbs", &power));
}

// A cube's control mesh (faces wound outwards), optionally with every edge creased.
SubdivisionSurface controlCube(float creaseSharpness) {
  SubdivisionSurface s;
  s.P = {{-1, -1, 1}, {1, -1, 1}, {-1, 1, 1}, {1, 1, 1}, {-1, 1, -1}, {1, 1, -1}, {-1, -1, -1}, {1, -1, -1}};
  s.faces = {{0, 1, 3, 2}, {2, 3, 5, 4}, {4, 5, 7, 6}, {6, 7, 1, 0}, {1, 7, 5, 3}, {6, 0, 2, 4}};
  if (creaseSharpness > 0.0f)
    for (const auto& face : s.faces)
      for (size_t k = 0; k < 4; ++k) s.creases[SubdivisionSurface::edgeKey(face[k], face[(k + 1) % 4])] = creaseSharpness;
  return s;
}

float largestNorm(const SubdivisionSurface& s) {
  float r = 0.0f;
  for (const glm::vec3& p : s.P) r = std::max(r, glm::length(p));
  return r;
}

// The limit masks are right when a point's limit does not move as the mesh is subdivided further:
// the old points keep their indices, so limit(level k) and limit(level k + 1) must agree on them.
// Checked on a smooth cube (valence 3 and 4 points), on a cube with infinitely sharp creases, on
// one whose sharpness 2 has worn off by level 2, and on an open grid (boundary and corner rules).
TEST(CatmullClark, LimitPositionsDoNotMoveUnderFurtherSubdivision) {
  SubdivisionSurface grid;
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x) grid.P.emplace_back(float(x), float(y), 0.3f * float((x * 7 + y * 3) % 4));
  for (uint32_t y = 0; y < 3; ++y)
    for (uint32_t x = 0; x < 3; ++x) grid.faces.push_back({y * 4 + x, y * 4 + x + 1, (y + 1) * 4 + x + 1, (y + 1) * 4 + x});
  const std::pair<const char*, SubdivisionSurface> cases[] = {
      {"smooth cube", controlCube(0.0f)}, {"sharp cube", controlCube(kInfiniteSharpness)},
      {"worn cube", controlCube(2.0f)}, {"open grid", grid}};
  for (const auto& [name, control] : cases) {
    SubdivisionSurface level = subdivideCatmullClark(subdivideCatmullClark(control));
    SubdivisionSurface limit = level;
    projectToLimit(limit);
    SubdivisionSurface finer = subdivideCatmullClark(level);
    projectToLimit(finer);
    float moved = 0.0f, projected = 0.0f;
    for (size_t p = 0; p < level.P.size(); ++p) {
      moved = std::max(moved, glm::length(limit.P[p] - finer.P[p]));
      projected = std::max(projected, glm::length(limit.P[p] - level.P[p]));
    }
    EXPECT_LT(moved, 2e-5f) << name;
    if (std::string(name) != "sharp cube") {
      EXPECT_GT(projected, 1e-3f) << name;  // the projection did something
    }
  }
}

// Infinitely sharp creases on every edge keep the cube a cube (every point on its faces, the
// corners in place); semi-sharp ones round it less the sharper they are; a corner tag keeps its
// point; a hole's children stay holes; facevarying values interpolate linearly over each face.
TEST(CatmullClark, CreasesCornersHolesAndFacevaryingValues) {
  SubdivisionSurface sharp = controlCube(kInfiniteSharpness);
  for (int l = 0; l < 3; ++l) sharp = subdivideCatmullClark(sharp);
  projectToLimit(sharp);
  bool corner = false;
  for (const glm::vec3& p : sharp.P) {
    EXPECT_NEAR(std::max({std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)}), 1.0f, 1e-5f);
    corner = corner || p == glm::vec3(1, 1, 1);
  }
  EXPECT_TRUE(corner);

  float previous = 0.0f;
  for (float sharpness : {0.0f, 0.5f, 1.0f, 2.0f, kInfiniteSharpness}) {
    SubdivisionSurface s = controlCube(sharpness);
    for (int l = 0; l < 3; ++l) s = subdivideCatmullClark(s);
    projectToLimit(s);
    const float reach = largestNorm(s);
    EXPECT_GT(reach, previous + 0.01f) << sharpness;
    previous = reach;
  }
  EXPECT_NEAR(previous, std::sqrt(3.0f), 1e-5f);

  SubdivisionSurface cornered = controlCube(0.0f);
  cornered.corners.assign(cornered.P.size(), 0.0f);
  cornered.corners[3] = kInfiniteSharpness;
  cornered.holes.assign(cornered.faces.size(), 0);
  cornered.holes[2] = 1;
  SubdivisionSurface::Channel st;
  st.components = 2;
  for (size_t f = 0; f < 6; ++f) st.values.insert(st.values.end(), {0, 0, 1, 0, 1, 1, 0, 1});
  cornered.faceVarying.push_back(st);
  for (int l = 0; l < 2; ++l) cornered = subdivideCatmullClark(cornered);
  projectToLimit(cornered);
  EXPECT_EQ(cornered.P[3], glm::vec3(1, 1, 1));
  ASSERT_EQ(cornered.holes.size(), cornered.faces.size());
  ASSERT_EQ(cornered.parent.size(), cornered.faces.size());
  size_t corners = 0;
  for (size_t f = 0; f < cornered.faces.size(); ++f) {
    EXPECT_EQ(cornered.holes[f], cornered.parent[f] == 2) << f;
    corners += cornered.faces[f].size();
  }
  ASSERT_EQ(cornered.faceVarying[0].values.size(), 2 * corners);
  // Face 0's first child of its first child keeps the control corner's st and the quarter point.
  const float* v = cornered.faceVarying[0].values.data();
  EXPECT_EQ(glm::vec2(v[0], v[1]), glm::vec2(0, 0));
  EXPECT_EQ(glm::vec2(v[2], v[3]), glm::vec2(0.25f, 0));
  EXPECT_EQ(glm::vec2(v[4], v[5]), glm::vec2(0.25f, 0.25f));
  EXPECT_EQ(glm::vec2(v[6], v[7]), glm::vec2(0, 0.25f));
}

// The NURBS basis sums to one with derivatives summing to zero, matches a finite difference, is
// Bernstein's on clamped Bezier knots, and handles repeated interior knots and the range's ends.
TEST(NurbsBasis, PartitionOfUnityDerivativesAndBezierKnots) {
  const std::vector<float> bezier = {0, 0, 0, 0, 1, 1, 1, 1};
  float value[kMaxNurbsOrder], derivative[kMaxNurbsOrder];
  for (float t : {0.0f, 0.3f, 1.0f}) {
    ASSERT_EQ(nurbsBasis(bezier, 4, 4, t, value, derivative), 0);
    const float s = 1.0f - t;
    EXPECT_NEAR(value[0], s * s * s, 1e-6f);
    EXPECT_NEAR(value[1], 3 * t * s * s, 1e-6f);
    EXPECT_NEAR(value[2], 3 * t * t * s, 1e-6f);
    EXPECT_NEAR(value[3], t * t * t, 1e-6f);
    EXPECT_NEAR(derivative[0], -3 * s * s, 1e-5f);
  }
  const std::vector<float> knots = {0, 0, 0, 0.25f, 0.25f, 0.5f, 0.7f, 1, 1, 1};  // 7 points, order 3
  for (float t = 0.0f; t <= 1.0f; t += 0.0625f) {
    const int first = nurbsBasis(knots, 3, 7, t, value, derivative);
    ASSERT_GE(first, 0);
    ASSERT_LE(first + 3, 7);
    float sum = 0.0f, dsum = 0.0f;
    for (int k = 0; k < 3; ++k) {
      sum += value[k], dsum += derivative[k];
      EXPECT_GE(value[k], -1e-6f);
    }
    EXPECT_NEAR(sum, 1.0f, 1e-5f) << t;
    EXPECT_NEAR(dsum, 0.0f, 1e-3f) << t;
    // Finite difference of function first + 1 (away from the knots, where it is smooth).
    const float h = 1e-3f;
    if (t > h && t < 1 - h && std::fabs(t - 0.25f) > h && std::fabs(t - 0.5f) > h && std::fabs(t - 0.7f) > h) {
      float a[kMaxNurbsOrder], b[kMaxNurbsOrder], da[kMaxNurbsOrder], db[kMaxNurbsOrder];
      const int fa = nurbsBasis(knots, 3, 7, t - h, a, da), fb = nurbsBasis(knots, 3, 7, t + h, b, db);
      if (fa == first && fb == first) {
        for (int k = 0; k < 3; ++k) EXPECT_NEAR((b[k] - a[k]) / (2 * h), derivative[k], 2e-2f) << t << " " << k;
      }
    }
  }
  EXPECT_EQ(nurbsBasis({0, 0, 0, 0, 0, 0}, 3, 3, 0.5f, value, derivative), -1);  // empty range
}

}  // namespace
}  // namespace relief
