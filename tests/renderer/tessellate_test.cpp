// Tests of tessellateSphere: outward normals and winding, parameter ranges, closedness.
#include "renderer/tessellate.h"

#include <cmath>
#include <map>
#include <tuple>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

namespace relief {
namespace {

TEST(TessellateSphere, NormalsAndWindingFaceOutward) {
  const glm::mat4 worldFromObject = glm::translate(glm::mat4(1.0f), glm::vec3(1, 2, 3));
  Mesh mesh = tessellateSphere(2.0f, -2.0f, 2.0f, 360.0f, 16, 8, worldFromObject);
  ASSERT_EQ(mesh.numTriangles(), 16u * 8u * 2u);
  const glm::vec3 centre(1, 2, 3);
  for (size_t i = 0; i < mesh.P.size(); ++i) {
    EXPECT_NEAR(glm::length(mesh.P[i] - centre), 2.0f, 1e-5f);
    EXPECT_GT(glm::dot(mesh.N[i], mesh.P[i] - centre), 1.9f);
  }
  int numDegenerate = 0;
  for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
    glm::vec3 a = mesh.P[mesh.indices[3 * t]], b = mesh.P[mesh.indices[3 * t + 1]],
              c = mesh.P[mesh.indices[3 * t + 2]];
    glm::vec3 ng = glm::cross(b - a, c - a);
    if (glm::length(ng) == 0.0f) {
      ++numDegenerate;
      continue;
    }
    EXPECT_GT(glm::dot(ng, (a + b + c) / 3.0f - centre), 0.0f) << "triangle " << t;
  }
  EXPECT_EQ(numDegenerate, 2 * 16);  // one per pole quad, exactly zero area
}

TEST(TessellateSphere, MirroringTransformKeepsOutwardWinding) {
  const glm::mat4 mirror = glm::scale(glm::mat4(1.0f), glm::vec3(-1, 1, 1));
  Mesh mesh = tessellateSphere(1.0f, -1.0f, 1.0f, 360.0f, 8, 6, mirror);
  for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
    glm::vec3 a = mesh.P[mesh.indices[3 * t]], b = mesh.P[mesh.indices[3 * t + 1]],
              c = mesh.P[mesh.indices[3 * t + 2]];
    glm::vec3 ng = glm::cross(b - a, c - a);
    if (glm::length(ng) > 0.0f) {
      EXPECT_GT(glm::dot(ng, a + b + c), 0.0f);
    }
  }
}

// RI spec, Quadrics: a negative thetamax turns the quadric inside-out, as dP/du x dP/dv says
// (and as Cylinder, Cone, Disk and the rest do): normals and winding face the centre.
// Swapped z bounds run v downward (RI: from asin(zmin/r) to asin(zmax/r)) and turn it inside-out
// too; both together cancel.
TEST(TessellateSphere, NegativeSweepTurnsItInsideOut) {
  Mesh swapped = tessellateSphere(1.0f, 0.8f, -0.5f, 360.0f, 12, 6, glm::mat4(1.0f));
  EXPECT_NEAR(swapped.P.front().z, 0.8f, 1e-6f);  // v = 0 at zmin as given
  EXPECT_NEAR(swapped.P.back().z, -0.5f, 1e-6f);
  for (size_t i = 0; i < swapped.P.size(); ++i) EXPECT_LT(glm::dot(swapped.N[i], swapped.P[i]), -0.99f);
  Mesh both = tessellateSphere(1.0f, 1.0f, -1.0f, -360.0f, 12, 6, glm::mat4(1.0f));
  for (size_t i = 0; i < both.P.size(); ++i) EXPECT_GT(glm::dot(both.N[i], both.P[i]), 0.99f);
  Mesh mesh = tessellateSphere(1.0f, -1.0f, 1.0f, -360.0f, 12, 6, glm::mat4(1.0f));
  for (size_t i = 0; i < mesh.P.size(); ++i) EXPECT_LT(glm::dot(mesh.N[i], mesh.P[i]), -0.99f);
  int inward = 0;
  for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
    glm::vec3 a = mesh.P[mesh.indices[3 * t]], b = mesh.P[mesh.indices[3 * t + 1]],
              c = mesh.P[mesh.indices[3 * t + 2]];
    glm::vec3 ng = glm::cross(b - a, c - a);
    if (glm::length(ng) > 0.0f) {
      EXPECT_LT(glm::dot(ng, a + b + c), 0.0f) << "triangle " << t;
      ++inward;
    }
  }
  EXPECT_GT(inward, 100);
}

TEST(TessellateSphere, ParametersSpanUnitSquare) {
  Mesh mesh = tessellateSphere(1.0f, -0.5f, 0.8f, 270.0f, 12, 5, glm::mat4(1.0f));
  float uMin = 1, uMax = 0, vMin = 1, vMax = 0;
  for (size_t i = 0; i < mesh.uv.size(); ++i) {
    uMin = std::min(uMin, mesh.uv[i].x), uMax = std::max(uMax, mesh.uv[i].x);
    vMin = std::min(vMin, mesh.uv[i].y), vMax = std::max(vMax, mesh.uv[i].y);
    EXPECT_EQ(mesh.st[i], mesh.uv[i]);
    // v = 0 at zmin, 1 at zmax; u follows the azimuth over thetamax.
    float phi = std::atan2(mesh.P[i].y, mesh.P[i].x);
    if (phi < -1e-4f) phi += 2.0f * float(M_PI);
    EXPECT_NEAR(phi / (1.5f * float(M_PI)), mesh.uv[i].x, 1e-4f);
  }
  EXPECT_EQ(uMin, 0.0f);
  EXPECT_EQ(uMax, 1.0f);
  EXPECT_EQ(vMin, 0.0f);
  EXPECT_EQ(vMax, 1.0f);
  for (size_t i = 0; i < mesh.P.size(); ++i) {
    if (mesh.uv[i].y == 0.0f) {
      EXPECT_NEAR(mesh.P[i].z, -0.5f, 1e-5f);
    }
    if (mesh.uv[i].y == 1.0f) {
      EXPECT_NEAR(mesh.P[i].z, 0.8f, 1e-5f);
    }
  }
}

// Closed: every edge, keyed by its end positions (seam and pole copies have distinct indices but
// identical positions), is used exactly twice, once in each direction. Zero-area pole triangles are
// skipped: they add each of their edges once in each direction (a fin), which the count would see.
TEST(TessellateSphere, FullSphereIsClosed) {
  const glm::mat4 worldFromObject =
      glm::rotate(glm::mat4(1.0f), 0.7f, glm::vec3(1, 1, 0)) * glm::scale(glm::mat4(1.0f), glm::vec3(3));
  Mesh mesh = tessellateSphere(1.0f, -1.0f, 1.0f, 360.0f, 20, 10, worldFromObject);
  using Key = std::tuple<float, float, float>;
  auto key = [](glm::vec3 p) { return Key(p.x, p.y, p.z); };
  std::map<std::pair<Key, Key>, int> directed;
  for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
    glm::vec3 p0 = mesh.P[mesh.indices[3 * t]], p1 = mesh.P[mesh.indices[3 * t + 1]],
              p2 = mesh.P[mesh.indices[3 * t + 2]];
    if (p0 == p1 || p1 == p2 || p2 == p0) continue;
    for (int e = 0; e < 3; ++e) {
      Key a = key(mesh.P[mesh.indices[3 * t + e]]), b = key(mesh.P[mesh.indices[3 * t + (e + 1) % 3]]);
      ++directed[{a, b}];
    }
  }
  for (const auto& [edge, count] : directed) {
    EXPECT_EQ(count, 1);
    auto reverse = directed.find({edge.second, edge.first});
    ASSERT_NE(reverse, directed.end());
    EXPECT_EQ(reverse->second, 1);
  }
}

// Per-vertex derivatives of a tessellated sphere: close to the analytic dP/du = 2 pi r cos(lat)
// (-sin phi, cos phi, 0) and dP/dv = pi r (-sin(lat) cos phi, -sin(lat) sin phi, cos lat) away from
// the poles, and the same at both copies of a seam vertex (one group by position and normal).
TEST(TessellateSphere, SmoothDerivativesAreSharedAndCloseToAnalytic) {
  Mesh mesh = tessellateSphere(2.0f, -2.0f, 2.0f, 360.0f, 32, 16, glm::mat4(1.0f));
  smoothSurfaceDerivatives(mesh);
  ASSERT_EQ(mesh.dPdu.size(), mesh.P.size());
  const float pi = std::numbers::pi_v<float>;
  for (size_t i = 0; i < mesh.P.size(); ++i) {
    const float u = mesh.uv[i].x, v = mesh.uv[i].y;
    if (v < 0.1f || v > 0.9f) continue;
    const float lat = -pi / 2 + v * pi, phi = u * 2 * pi;
    const glm::vec3 du = 2 * pi * 2.0f * std::cos(lat) * glm::vec3(-std::sin(phi), std::cos(phi), 0);
    const glm::vec3 dv = pi * 2.0f * glm::vec3(-std::sin(lat) * std::cos(phi), -std::sin(lat) * std::sin(phi), std::cos(lat));
    EXPECT_LT(glm::length(mesh.dPdu[i] - du), 0.02f * glm::length(du)) << i;
    EXPECT_LT(glm::length(mesh.dPdv[i] - dv), 0.02f * glm::length(dv)) << i;
  }
  // The seam: vertex (row j, u = 1) copies (row j, u = 0) and gets its derivatives.
  for (int j = 0; j <= 16; ++j) {
    const size_t first = size_t(j) * 33, last = first + 32;
    ASSERT_EQ(mesh.P[first], mesh.P[last]);
    EXPECT_EQ(mesh.dPdu[first], mesh.dPdu[last]) << j;
    EXPECT_EQ(mesh.dPdv[first], mesh.dPdv[last]) << j;
  }
}

}  // namespace
}  // namespace relief
