// Tests of the RIB reader's geometry helpers: ear-clipping triangulation (convex, concave, holes,
// degenerate input) and the cubic bases of RiBasis.
#include "renderer/rib_geometry.h"

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

TEST(Triangulate, HugePolygonsFinishAsFans) {
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

}  // namespace
}  // namespace relief
