// Tests of the Embree baseline (embree_accelerator.*): it holds exactly the micro-triangles the
// cache would create, reports the same hit fields as the grid accelerator, and renders the same
// image within a stated tolerance.
//
// Why a tolerance and not bit-identity: Embree's triangle test is not intersect.h's, so t and the
// barycentrics differ in the last bits, and among hits at equal t either may win. Shading uses the
// micro-triangle's own normal, so a pixel changes only where a ray or a shadow ray grazes an edge
// and lands on a different micro-triangle or slips past one: silhouettes and shadow terminators.
// Such a flip can change a pixel by the whole direct light, so the bound is on how many pixels
// differ noticeably (> 8/255: 0.5% of them), plus a mean absolute difference below 1/255 so that
// no systematic shift (a wrong normal, st or bary) can hide under the count.
#include "renderer/embree_accelerator.h"

#include <cmath>

#include <gtest/gtest.h>

#include "geometry_test_util.h"
#include "renderer/film.h"
#include "renderer/render.h"

namespace relief {
namespace {

using testing::BruteForce;
using testing::makeSphereScene;
using testing::randomRays;
using testing::SphereOptions;

#if RELIEF_HAVE_EMBREE

std::unique_ptr<Accelerator> makeEmbree(const Scene& scene, bool displace = true) {
  AccelOptions options;
  options.displace = displace;
  EmbreeOptions embree;
  embree.threads = 2;
  return makeEmbreeAccelerator(scene, options, embree);
}

TEST(EmbreeAccelerator, HoldsEveryDisplacedMicroTriangle) {
  SphereOptions o;
  o.edgeLength = 0.08f;
  const Scene scene = makeSphereScene(o);
  auto accel = makeEmbree(scene);
  const AccelStats s = accel->stats();
  EXPECT_EQ(s.displacedTrianglesCreated, BruteForce(scene).numTriangles());
  EXPECT_EQ(s.peakResidentTriangles, s.displacedTrianglesCreated);
  EXPECT_GT(s.shaderPoints, 0u);
  // At least the vertex and index arrays: 12 bytes of indices per triangle.
  EXPECT_GT(s.peakResidentBytes, 12 * s.displacedTrianglesCreated);
}

TEST(EmbreeAccelerator, AgreesWithBruteForceOnDisplacedSphere) {
  SphereOptions o;
  o.edgeLength = 0.08f;
  const Scene scene = makeSphereScene(o);
  auto accel = makeEmbree(scene);
  BruteForce reference(scene);
  const int numRays = 400;
  int hits = 0, sameTriangle = 0, disagree = 0;
  for (const Ray& ray : randomRays(numRays, 11, 3.0f, 1.5f)) {
    const auto hit = accel->intersect(ray);
    const auto expected = reference.intersect(ray);
    EXPECT_EQ(accel->occluded(ray), hit.has_value());
    if (hit.has_value() != expected.has_value()) {
      ++disagree;
      continue;
    }
    if (!hit) continue;
    ++hits;
    EXPECT_NEAR(hit->t, expected->t, 1e-4f * expected->t);
    sameTriangle += hit->meshIndex == expected->mesh && hit->triangleIndex == expected->triangle &&
                    hit->microIndex == expected->micro;
    EXPECT_NEAR(glm::length(hit->Ng), 1.0f, 1e-4f);
    EXPECT_LT(glm::length(ray.origin + hit->t * ray.direction - hit->P), 1e-5f);
    // bary and st locate the hit on the input triangle within the displacement bound.
    const Mesh& mesh = scene.meshes[hit->meshIndex];
    const uint32_t* idx = &mesh.indices[3 * size_t(hit->triangleIndex)];
    const glm::vec3 onInput = (1.0f - hit->bary.x - hit->bary.y) * mesh.P[idx[0]] +
                              hit->bary.x * mesh.P[idx[1]] + hit->bary.y * mesh.P[idx[2]];
    EXPECT_LT(glm::length(onInput - hit->P), o.km * 1.01f + 1e-4f);
    const glm::vec2 st = (1.0f - hit->bary.x - hit->bary.y) * mesh.uv[idx[0]] +
                         hit->bary.x * mesh.uv[idx[1]] + hit->bary.y * mesh.uv[idx[2]];
    EXPECT_LT(glm::length(st - hit->st), 1e-4f);
  }
  EXPECT_GT(hits, numRays / 4);
  // Grazing rays may slip differently past a silhouette edge; no more than 1% of them.
  EXPECT_LE(disagree, numRays / 100);
  EXPECT_GE(sameTriangle, hits - hits / 100);
}

TEST(EmbreeAccelerator, UndisplacedHitsTheInputTriangles) {
  const Scene scene = makeSphereScene(SphereOptions{});
  auto accel = makeEmbree(scene, /*displace=*/false);
  Scene flat = scene;
  flat.meshes[0].displacementIndex = UINT32_MAX;
  BruteForce reference(flat);
  EXPECT_EQ(accel->stats().shaderPoints, 0u);
  EXPECT_EQ(accel->stats().displacedTrianglesCreated, scene.meshes[0].numTriangles());
  int agree = 0, total = 0;
  for (const Ray& ray : randomRays(300, 5, 3.0f, 0.5f)) {
    const auto hit = accel->intersect(ray);
    const auto expected = reference.intersect(ray);
    ++total;
    if (hit.has_value() != expected.has_value()) continue;
    if (hit && (hit->triangleIndex != expected->triangle || hit->microIndex != kWholeTriangleId))
      continue;
    ++agree;
  }
  EXPECT_GE(agree, total - total / 100);
}

TEST(EmbreeAccelerator, RespectsRayIntervalAndRejectsMalformedRays) {
  SphereOptions o;
  o.displaced = false;
  const Scene scene = makeSphereScene(o);
  auto accel = makeEmbree(scene);
  Ray ray{{0, 0, -5}, {0, 0, 1}, 0.0f, 1e30f};
  auto hit = accel->intersect(ray);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->t, 4.0f, 1e-3f);  // the front of the unit sphere's tessellation
  ray.tMin = hit->t + 1e-3f;
  auto back = accel->intersect(ray);
  ASSERT_TRUE(back);
  EXPECT_GT(back->t, 5.5f);  // the far side
  ray.tMax = 3.0f;
  ray.tMin = 0.0f;
  EXPECT_FALSE(accel->intersect(ray));
  EXPECT_FALSE(accel->occluded(ray));
  const float nan = std::nanf("");
  EXPECT_FALSE(accel->intersect(Ray{{nan, 0, -5}, {0, 0, 1}, 0.0f, 1e30f}));
  EXPECT_FALSE(accel->occluded(Ray{{0, 0, -5}, {0, 0, 0}, 0.0f, 1e30f}));
  EXPECT_FALSE(accel->intersect(Ray{{0, 0, -5}, {0, 0, 1}, 2.0f, 1.0f}));
}

TEST(EmbreeAccelerator, EmptySceneNeverHits) {
  const Scene scene;
  auto accel = makeEmbree(scene);
  EXPECT_FALSE(accel->intersect(Ray{{0, 0, -5}, {0, 0, 1}, 0.0f, 1e30f}));
  EXPECT_FALSE(accel->occluded(Ray{{0, 0, -5}, {0, 0, 1}, 0.0f, 1e30f}));
}

// A displaced sphere over an undisplaced floor, lit by a low light so it casts a shadow.
Scene makeLitScene() {
  SphereOptions o;
  o.edgeLength = 0.04f;
  o.km = 0.08f;
  o.freq = 5.0f;
  Scene scene = makeSphereScene(o);
  Mesh floor;
  floor.P = {{-4, -1.1f, -4}, {4, -1.1f, -4}, {4, -1.1f, 4}, {-4, -1.1f, 4}};
  floor.indices = {0, 1, 2, 0, 2, 3};
  scene.meshes.push_back(floor);
  scene.width = 96, scene.height = 64;
  scene.camera.worldFromCamera =
      glm::mat4(1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0.6f, -4.5f, 1);  // looks down +z
  scene.camera.fovDegrees = 45.0f;
  const glm::vec3 toLight = glm::normalize(glm::vec3(1.0f, 1.2f, -0.8f));
  DistantLight d;
  d.directionToLight = toLight;
  scene.distantLights.push_back(d);
  Light l;
  l.type = LightType::Distant;
  l.direction = -toLight;
  scene.lights.push_back(l);
  Light ambient;
  ambient.type = LightType::Ambient;
  ambient.color = glm::vec3(0.1f);
  scene.lights.push_back(ambient);
  scene.ambient = 0.1f, scene.ambientColor = glm::vec3(0.1f);
  for (uint32_t i = 0; i < scene.lights.size(); ++i)
    for (Mesh& m : scene.meshes) m.lights.push_back(i);
  scene.materials.push_back(Material{});
  return scene;
}

TEST(EmbreeAccelerator, RendersTheGridAcceleratorsImageWithinTolerance) {
  const Scene scene = makeLitScene();
  RenderOptions options;
  options.threads = 2;
  Film grid(scene.width, scene.height), embree(scene.width, scene.height);
  auto gridAccel = makeGridAccelerator(scene, AccelOptions{});
  render(scene, *gridAccel, options, &grid);
  auto embreeAccel = makeEmbree(scene);
  render(scene, *embreeAccel, options, &embree);
  double sum = 0;
  int differing = 0, lit = 0;
  for (int y = 0; y < scene.height; ++y)
    for (int x = 0; x < scene.width; ++x) {
      float worst = 0;
      for (int c = 0; c < 3; ++c) {
        const float a = linearToSrgb(grid.pixel(x, y)[c]), b = linearToSrgb(embree.pixel(x, y)[c]);
        sum += std::fabs(a - b);
        worst = std::max(worst, std::fabs(a - b));
      }
      differing += worst > 8.0f / 255.0f;
      lit += grid.pixel(x, y).r > 0.2f;
    }
  const int pixels = scene.width * scene.height;
  EXPECT_GT(lit, pixels / 10);  // the comparison is about a real image, not a black one
  EXPECT_LT(sum / (3.0 * pixels), 1.0 / 255.0);
  EXPECT_LE(differing, pixels / 200);
}

#else

TEST(EmbreeAccelerator, FactoryExplainsMissingEmbree) {
  const Scene scene;
  EXPECT_FALSE(haveEmbree());
  EXPECT_THROW(makeEmbreeAccelerator(scene, AccelOptions{}, EmbreeOptions{}), std::runtime_error);
}

#endif

}  // namespace
}  // namespace relief
