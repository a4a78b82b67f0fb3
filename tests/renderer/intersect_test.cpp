// The four-lane triangle test (intersectTriangles4) against the scalar watertight test it stands in
// for: every lane's verdict and hit must be bit-identical, or images would depend on how a leaf's
// triangles fall into groups of four.
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "renderer/intersect.h"

#if defined(__SSE2__)
namespace relief {
namespace {

uint32_t bits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  return b;
}

struct Tri {
  glm::vec3 a, b, c;
};

// Compares the lanes of one group of four with the scalar test; counts hits and undecided lanes.
void expectLanesMatchScalar(const Ray& ray, const Tri (&tris)[4], float tMin, float tMax, int& hitsSeen,
                            int& undecidedSeen) {
  const WatertightRay wr(ray);
  glm::vec3 corners[4][3];
  for (int k = 0; k < 4; ++k) corners[k][0] = tris[k].a, corners[k][1] = tris[k].b, corners[k][2] = tris[k].c;
  TriangleHits4 hits;
  unsigned undecided = 0;
  const unsigned mask = intersectTriangles4(wr, cornersOf(corners), tMin, tMax, hits, undecided);
  for (int k = 0; k < 4; ++k) {
    TriangleHit h{};
    const bool scalar = intersectTriangle(wr, tris[k].a, tris[k].b, tris[k].c, tMin, tMax, h);
    if (undecided >> k & 1) {
      ++undecidedSeen;
      continue;  // the caller hands these to the scalar test
    }
    ASSERT_EQ(bool(mask >> k & 1), scalar) << "lane " << k;
    if (!scalar) continue;
    ++hitsSeen;
    EXPECT_EQ(bits(hits.t[k]), bits(h.t)) << "lane " << k;
    EXPECT_EQ(bits(hits.b0[k]), bits(h.b0));
    EXPECT_EQ(bits(hits.b1[k]), bits(h.b1));
    EXPECT_EQ(bits(hits.b2[k]), bits(h.b2));
  }
}

TEST(Intersect4, RandomTrianglesMatchTheScalarTestBitForBit) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> pos(-1.0f, 1.0f), dir(-1.0f, 1.0f), small(-1e-3f, 1e-3f);
  int hits = 0, undecided = 0;
  for (int round = 0; round < 20000; ++round) {
    Ray ray;
    ray.origin = glm::vec3(pos(rng), pos(rng), pos(rng)) * 3.0f;
    do ray.direction = glm::vec3(dir(rng), dir(rng), dir(rng));
    while (glm::length(ray.direction) < 0.1f);
    // Triangles around a point on the ray, some tiny, so that hits, misses and grazes all occur.
    const float along = std::abs(pos(rng)) * 4.0f;
    const glm::vec3 centre = ray.origin + along * ray.direction;
    Tri tris[4];
    for (Tri& t : tris) {
      const float scale = round % 3 == 0 ? 0.01f : 0.5f;
      t.a = centre + glm::vec3(pos(rng), pos(rng), pos(rng)) * scale;
      t.b = centre + glm::vec3(pos(rng), pos(rng), pos(rng)) * scale;
      t.c = centre + glm::vec3(pos(rng), pos(rng), pos(rng)) * scale;
    }
    if (round % 7 == 0) tris[1].c = tris[1].b + glm::vec3(small(rng), 0, 0);  // nearly degenerate
    if (round % 11 == 0) tris[2].c = tris[2].b;                               // degenerate
    const float tMax = round % 5 == 0 ? along : std::numeric_limits<float>::infinity();
    expectLanesMatchScalar(ray, tris, round % 4 == 0 ? along * 0.999f : 0.0f, tMax, hits, undecided);
    if (HasFatalFailure()) return;
  }
  // The comparison covered both verdicts in quantity.
  EXPECT_GT(hits, 10000);
}

TEST(Intersect4, RaysThroughSharedEdgesAndVerticesAreLeftToTheScalarTest) {
  // A fan of four triangles around the origin in the z = 1 plane; rays along +z through a vertex
  // or along an edge give exact zeros in the edge functions, which only the scalar test resolves.
  const glm::vec3 o(0, 0, 1), e[4] = {{1, 0, 1}, {0, 1, 1}, {-1, 0, 1}, {0, -1, 1}};
  Tri fan[4];
  for (int k = 0; k < 4; ++k) fan[k] = {o, e[k], e[(k + 1) % 4]};
  int hits = 0, undecided = 0;
  for (const glm::vec3 origin : {glm::vec3(0, 0, 0), glm::vec3(0.5f, 0, 0), glm::vec3(0, -0.25f, 0),
                                 glm::vec3(0.3f, 0.2f, 0), glm::vec3(-0.1f, -0.6f, 0)}) {
    Ray ray;
    ray.origin = origin, ray.direction = glm::vec3(0, 0, 1);
    expectLanesMatchScalar(ray, fan, 0.0f, 10.0f, hits, undecided);
  }
  EXPECT_GT(undecided, 0);  // the vertex and the edges
  EXPECT_EQ(hits, 2);       // the two interior points, one triangle each
}

TEST(Intersect4, NonFiniteCornersAndLimitsNeverHit) {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  Ray ray;
  ray.origin = glm::vec3(0.2f, 0.2f, 0), ray.direction = glm::vec3(0, 0, 1);
  const Tri good = {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
  Tri tris[4] = {good, good, good, good};
  tris[0].a.z = nan;
  tris[1].b = glm::vec3(inf, 0, 1);
  tris[2].c = glm::vec3(0, inf, inf);
  int hits = 0, undecided = 0;
  expectLanesMatchScalar(ray, tris, 0.0f, 10.0f, hits, undecided);
  EXPECT_EQ(hits, 1);  // only the finite triangle
  hits = 0;
  expectLanesMatchScalar(ray, tris, 0.0f, 1.0f, hits, undecided);  // t == tMax: outside
  EXPECT_EQ(hits, 0);
  expectLanesMatchScalar(ray, tris, 1.0f, 10.0f, hits, undecided);  // t == tMin: outside
  EXPECT_EQ(hits, 0);
}

}  // namespace
}  // namespace relief
#endif  // __SSE2__ (without it the grid accelerator tests one triangle at a time)

// The double-precision test for huge triangles and the face normal, on every machine.
namespace relief {
namespace {

// A ground plane at y = -1.06 reaching 1e8 units, split along its diagonal: rays from near the
// origin find it at the analytic distance (float edge functions lose the origin's position, whose
// ulp is 8 units there) and exactly one of the two halves owns each ray, the diagonal included.
TEST(IntersectDouble, HugeTriangleIsHitWhereItIs) {
  const float h = 1e8f;
  const glm::vec3 p0(-h, -1.06f, -h), p1(-h, -1.06f, h), p2(h, -1.06f, h), p3(h, -1.06f, -h);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> dir(-1.0f, 1.0f);
  int hits = 0;
  for (int i = 0; i < 2000; ++i) {
    Ray ray{{0.3f, 2.7f, 5.9f}, glm::normalize(glm::vec3(dir(rng), -0.2f - 0.8f * std::fabs(dir(rng)), dir(rng))), 0.0f, 1e30f};
    if (i % 100 == 0) ray.direction = glm::normalize(glm::vec3(-0.3f, -3.76f, -5.9f) + glm::vec3(0.1f * float(i / 100), 0, 0.1f * float(i / 100)));
    const WatertightRay wr(ray);
    TriangleHit a{}, b{};
    const bool hitA = intersectTriangleDouble(ray, wr, p0, p1, p2, 0.0f, 1e30f, a);
    const bool hitB = intersectTriangleDouble(ray, wr, p0, p2, p3, 0.0f, 1e30f, b);
    ASSERT_TRUE(hitA || hitB) << i;
    const double expected = (-1.06 - 2.7) / double(ray.direction.y);
    const TriangleHit& hit = hitA ? a : b;
    EXPECT_NEAR(hit.t, expected, 1e-5 * expected) << i;
    EXPECT_NEAR(hit.b0 + hit.b1 + hit.b2, 1.0f, 1e-6f);
    hits += hitA + hitB;
  }
  EXPECT_EQ(hits, 2000);  // never both: no double hits along the shared diagonal
  // The limits hold after rounding t to float.
  const Ray down{{0.0f, 0.0f, 0.0f}, {0.0f, -1.0f, 0.0f}, 0.0f, 1e30f};
  const WatertightRay wr(down);
  TriangleHit hit{};
  EXPECT_TRUE(intersectTriangleDouble(down, wr, p0, p1, p2, 0.0f, 1.07f, hit));
  EXPECT_EQ(hit.t, 1.06f);
  EXPECT_FALSE(intersectTriangleDouble(down, wr, p0, p1, p2, 0.0f, 1.06f, hit));
  EXPECT_FALSE(intersectTriangleDouble(down, wr, p0, p1, p2, 1.06f, 2.0f, hit));
}

TEST(IntersectDouble, FaceNormalOfAnySize) {
  glm::vec3 n;
  for (float s : {1e-30f, 1.0f, 1e20f, 1e37f}) {
    ASSERT_TRUE(faceNormal(glm::vec3(0.0f), glm::vec3(s, 0.0f, 0.0f), glm::vec3(0.0f, s, 0.0f), &n)) << s;
    EXPECT_EQ(n, glm::vec3(0.0f, 0.0f, 1.0f)) << s;
  }
  EXPECT_FALSE(faceNormal(glm::vec3(0.0f), glm::vec3(1.0f), glm::vec3(2.0f), &n));
  EXPECT_FALSE(faceNormal(glm::vec3(0.0f), glm::vec3(INFINITY, 0.0f, 0.0f), glm::vec3(0.0f, 1.0f, 0.0f), &n));
}

}  // namespace
}  // namespace relief
