// Tests of the built-in surfaces against their RenderMan formulas and optics: matte and metal
// energy, the plastic highlight's position, mirror reflection, glass Fresnel, Snell refraction,
// total internal reflection and coloured transmission, constant, opacity, Sides 1 and smooth
// normals. Scenes are built in code and intersected by brute force.
#include <cmath>

#include <gtest/gtest.h>

#include "render_test_util.h"
#include "renderer/shading.h"

namespace relief {
namespace {

using test::quad;

constexpr float kDeg = 3.14159265358979f / 180.0f;

// A wall at z = 0 facing the camera (outward normal -z), spanning [-4, 4]^2.
Mesh wall(uint32_t material, float z = 0.0f) {
  return quad({-4, -4, z}, {0, 8, 0}, {8, 0, 0}, material);
}

// Traces one ray through an Integrator with brute-force intersection.
SampleResult traceOne(const Scene& scene, const Ray& ray, int maxDepth = kDefaultMaxDepth) {
  test::BruteForceAccelerator accel(scene);
  ShadingOptions options;
  options.maxDepth = maxDepth;
  Integrator integrator(scene, accel, options);
  RenderStats stats;
  return integrator.trace(ray, 1, &stats);
}

Ray rayFrom(glm::vec3 origin, glm::vec3 direction) {
  Ray r;
  r.origin = origin;
  r.direction = glm::normalize(direction);
  return r;
}

TEST(RenderMaterial, FresnelAtNormalIncidence) {
  for (float eta : {1.33f, 1.5f, 2.4f}) {
    const float expected = ((eta - 1.0f) / (eta + 1.0f)) * ((eta - 1.0f) / (eta + 1.0f));
    EXPECT_NEAR(Integrator::fresnel(1.0f, 1.0f / eta), expected, 1e-6f) << eta;  // entering
    EXPECT_NEAR(Integrator::fresnel(1.0f, eta), expected, 1e-6f) << eta;         // leaving
  }
  // Grazing incidence reflects everything; reflectance grows with the angle.
  EXPECT_NEAR(Integrator::fresnel(1e-4f, 1.0f / 1.5f), 1.0f, 1e-3f);
  EXPECT_LT(Integrator::fresnel(std::cos(30 * kDeg), 1.0f / 1.5f),
            Integrator::fresnel(std::cos(70 * kDeg), 1.0f / 1.5f));
}

TEST(RenderMaterial, TotalInternalReflectionBeyondTheCriticalAngle) {
  const float critical = std::asin(1.0f / 1.5f);  // leaving glass of index 1.5
  const glm::vec3 n(0, 0, -1);                     // facing the incoming ray (travelling +z)
  glm::vec3 t;
  const float below = critical - 2 * kDeg, above = critical + 2 * kDeg;
  EXPECT_TRUE(Integrator::refract(glm::vec3(std::sin(below), 0, std::cos(below)), n, 1.5f, &t));
  EXPECT_LT(Integrator::fresnel(std::cos(below), 1.5f), 1.0f);
  EXPECT_FALSE(Integrator::refract(glm::vec3(std::sin(above), 0, std::cos(above)), n, 1.5f, &t));
  EXPECT_EQ(Integrator::fresnel(std::cos(above), 1.5f), 1.0f);
}

TEST(RenderMaterial, RefractionFollowsSnell) {
  for (float angle : {10.0f, 30.0f, 45.0f, 70.0f}) {
    const float a = angle * kDeg;
    glm::vec3 t;
    ASSERT_TRUE(Integrator::refract(glm::vec3(std::sin(a), 0, std::cos(a)), {0, 0, -1}, 1.0f / 1.5f, &t));
    EXPECT_NEAR(glm::length(t), 1.0f, 1e-6f);
    EXPECT_NEAR(t.x, std::sin(a) / 1.5f, 1e-6f) << angle;  // sin(t) = sin(i) / eta
    EXPECT_GT(t.z, 0.0f);
    EXPECT_EQ(t.y, 0.0f);
  }
}

// A ray enters a glass block through its face z = 0 at 45 degrees; inside, a constant-coloured
// strip at depth 1 is only where Snell's law sends the refracted ray (x = tan(asin(sin 45 / 1.5))),
// with red before it and blue after (where an unbent ray would arrive, x = 1).
TEST(RenderMaterial, GlassRefractionDirectionMatchesSnell) {
  Scene scene;
  Material glass;
  glass.type = SurfaceType::Glass;
  glass.eta = 1.5f;
  glass.Kr = 0.0f;  // isolate the transmitted part
  glass.Kt = 1.0f;
  glass.Ks = 0.0f;
  const uint32_t g = test::addMaterial(&scene, glass);
  const uint32_t red = test::addMaterial(&scene, test::constant({1, 0, 0}));
  const uint32_t green = test::addMaterial(&scene, test::constant({0, 1, 0}));
  const uint32_t blue = test::addMaterial(&scene, test::constant({0, 0, 1}));
  const float x = std::tan(std::asin(std::sin(45 * kDeg) / 1.5f));  // 0.5345
  scene.meshes.push_back(wall(g));
  scene.meshes.push_back(quad({-5, -5, 1}, {0, 10, 0}, {x - 0.02f + 5, 0, 0}, red));
  scene.meshes.push_back(quad({x - 0.02f, -5, 1}, {0, 10, 0}, {0.04f, 0, 0}, green));
  scene.meshes.push_back(quad({x + 0.02f, -5, 1}, {0, 10, 0}, {5, 0, 0}, blue));
  const SampleResult r = traceOne(scene, rayFrom({-1, 0, -1}, {1, 0, 1}));
  const float expected = 1.0f - Integrator::fresnel(std::cos(45 * kDeg), 1.0f / 1.5f);
  EXPECT_NEAR(r.color.g, expected, 1e-5f);
  EXPECT_EQ(r.color.r, 0.0f);
  EXPECT_EQ(r.color.b, 0.0f);
}

// Straight through a slab at normal incidence: two interfaces each pass 1 - F, the transmit colour
// tints once (entering), and light bounced twice inside adds F^2 (1 - F)^2 more.
TEST(RenderMaterial, GlassSlabTransmitsWithFresnelAndColour) {
  Scene scene = test::orthoScene(8, 1.0f);
  Material glass;
  glass.type = SurfaceType::Glass;
  glass.eta = 1.5f;
  glass.Kr = 1.0f;
  glass.Kt = 1.0f;
  glass.Ks = 0.0f;
  glass.transmitColor = {1.0f, 0.5f, 0.25f};
  const uint32_t g = test::addMaterial(&scene, glass);
  const uint32_t white = test::addMaterial(&scene, test::constant({1, 1, 1}));
  scene.meshes.push_back(test::box({-3, -3, -1}, {3, 3, -0.5f}, g));
  scene.meshes.push_back(wall(white, 1.0f));
  const Film film = test::renderWith(scene);
  const float f = 0.04f, through = (1 - f) * (1 - f);
  const float expected = through * (1 + f * f);  // deeper bounces are below 1e-5
  const glm::vec3 c = film.pixel(4, 4);
  EXPECT_NEAR(c.r, expected, 1e-4f);
  EXPECT_NEAR(c.g, 0.5f * expected, 1e-4f);
  EXPECT_NEAR(c.b, 0.25f * expected, 1e-4f);
}

TEST(RenderMaterial, GlassReflectsFresnelFractionAtNormalIncidence) {
  // Only the reflection: Kt 0, and a white constant wall behind the camera seen in the glass.
  Scene scene = test::orthoScene(8, 1.0f);
  Material glass;
  glass.type = SurfaceType::Glass;
  glass.eta = 1.5f;
  glass.Kt = 0.0f;
  glass.Ks = 0.0f;
  const uint32_t g = test::addMaterial(&scene, glass);
  const uint32_t white = test::addMaterial(&scene, test::constant({1, 1, 1}));
  scene.meshes.push_back(wall(g));
  // Behind the camera (z = -10), facing +z toward the glass; the ortho camera starts at z = -5.
  scene.meshes.push_back(quad({-4, -4, -10}, {8, 0, 0}, {0, 8, 0}, white));
  const Film film = test::renderWith(scene);
  EXPECT_NEAR(film.pixel(3, 3).r, 0.04f, 1e-6f);
}

// A mirror tilted 45 degrees sends the camera's +z rays to -x, onto a constant wall.
// Glass between two mirrors spawns two rays at every glass hit, so the ray tree grows as 2^depth:
// --max-depth 100 took minutes for a thumbnail. Rays whose weight falls below 1/1024 are not
// traced, which bounds the tree whatever the depth (and changes the colour by less than that).
TEST(RenderMaterial, DeepRayTreesAreCutByWeight) {
  Scene scene;
  Material glass;
  glass.type = SurfaceType::Glass;
  glass.eta = 1.5f;
  glass.Ks = 0.0f;
  Material mirror;
  mirror.type = SurfaceType::Mirror;
  mirror.Ka = mirror.Ks = 0.0f;
  const uint32_t g = test::addMaterial(&scene, glass);
  const uint32_t m = test::addMaterial(&scene, mirror);
  scene.meshes.push_back(test::box({-3, -3, 0}, {3, 3, 0.5f}, g));
  scene.meshes.push_back(quad({-4, -4, -2}, {8, 0, 0}, {0, 8, 0}, m));  // behind the ray, facing +z
  scene.meshes.push_back(wall(m, 2.0f));                                  // ahead, facing -z
  test::BruteForceAccelerator accel(scene);
  ShadingOptions options;
  options.maxDepth = 24;  // uncut: about 2^24 rays
  Integrator integrator(scene, accel, options);
  RenderStats stats;
  const SampleResult r = integrator.trace(rayFrom({0.1f, 0.2f, -1}, {0.05f, 0.02f, 1}), 1, &stats);
  EXPECT_LT(stats.reflectionRays + stats.refractionRays, 20000u);
  EXPECT_TRUE(std::isfinite(r.color.r));
}

TEST(RenderMaterial, MirrorReflection) {
  Scene scene;
  Material mirror;
  mirror.type = SurfaceType::Mirror;
  mirror.color = {1.0f, 0.5f, 1.0f};
  mirror.Ka = mirror.Ks = 0.0f;
  mirror.Kr = 0.8f;
  const uint32_t m = test::addMaterial(&scene, mirror);
  const uint32_t wallColour = test::addMaterial(&scene, test::constant({0.2f, 0.4f, 0.6f}));
  // Outward normal (-1, 0, -1) / sqrt 2, facing the camera.
  scene.meshes.push_back(quad({1, -1, -1}, {-2, 0, 2}, {0, 2, 0}, m));
  scene.meshes.push_back(quad({-3, -5, -5}, {0, 0, 10}, {0, 10, 0}, wallColour));  // x = -3
  const Ray ray = rayFrom({0.1f, 0.2f, -5}, {0, 0, 1});
  const SampleResult r = traceOne(scene, ray);
  EXPECT_NEAR(r.color.r, 0.8f * 1.0f * 0.2f, 1e-6f);
  EXPECT_NEAR(r.color.g, 0.8f * 0.5f * 0.4f, 1e-6f);
  EXPECT_NEAR(r.color.b, 0.8f * 1.0f * 0.6f, 1e-6f);
  // With no secondary rays allowed the mirror shows nothing.
  EXPECT_EQ(traceOne(scene, ray, 0).color, glm::vec3(0.0f));
}

TEST(RenderMaterial, MatteIsKaAmbientPlusKdLambert) {
  Scene scene = test::orthoScene(8, 1.0f);
  const uint32_t m = test::addMaterial(&scene, test::matte({1.0f, 0.5f, 0.25f}, 0.5f, 0.8f));
  scene.meshes.push_back(wall(m));
  Light ambient;
  ambient.type = LightType::Ambient;
  ambient.color = glm::vec3(0.2f);
  scene.lights.push_back(ambient);
  scene.lights.push_back(test::distantLight({0, -1, 1}, glm::vec3(1.0f)));  // 45 degrees
  const glm::vec3 c = test::renderWith(scene).pixel(2, 5);
  const float light = 0.5f * 0.2f + 0.8f * std::sqrt(0.5f);
  EXPECT_NEAR(c.r, light, 1e-5f);
  EXPECT_NEAR(c.g, 0.5f * light, 1e-5f);
  EXPECT_NEAR(c.b, 0.25f * light, 1e-5f);
}

// Plastic's highlight under an orthographic camera peaks where the half vector is the normal:
// straight under the point light. Its diffuse part is Kd * I / d^2 there.
TEST(RenderMaterial, PlasticHighlightSitsUnderThePointLight) {
  Scene scene = test::orthoScene(40, 2.0f);
  Material plastic;
  plastic.type = SurfaceType::Plastic;
  plastic.Ka = 0.0f;
  plastic.Kd = 0.0f;
  plastic.Ks = 1.0f;
  plastic.roughness = 0.05f;
  plastic.specularColor = {1.0f, 1.0f, 0.5f};
  const uint32_t p = test::addMaterial(&scene, plastic);
  scene.meshes.push_back(wall(p));
  // Raster (25, 25) centre is world (0.55, -0.55).
  scene.lights.push_back(test::pointLight({0.55f, -0.55f, -2.0f}, glm::vec3(4.0f)));
  const Film film = test::renderWith(scene);
  int bestX = -1, bestY = -1;
  float best = -1.0f;
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 40; ++x)
      if (film.pixel(x, y).r > best) best = film.pixel(x, y).r, bestX = x, bestY = y;
  EXPECT_EQ(bestX, 25);
  EXPECT_EQ(bestY, 25);
  EXPECT_NEAR(best, 4.0f / 4.0f, 1e-4f);  // N.H = 1: Ks * Cl = I / d^2
  EXPECT_NEAR(film.pixel(25, 25).b, 0.5f * best, 1e-5f);  // specularcolor, not Cs
  // Elsewhere: Cl * pow(N.H, 1 / roughness), with H between the light and the viewer (-z).
  for (int x : {0, 5, 20, 30}) {
    const glm::vec3 P(-2.0f + 0.1f * (float(x) + 0.5f), -0.55f, 0.0f);
    const glm::vec3 toLight = glm::vec3(0.55f, -0.55f, -2.0f) - P;
    const glm::vec3 H = glm::normalize(glm::normalize(toLight) + glm::vec3(0, 0, -1));
    const float expected = 4.0f / glm::dot(toLight, toLight) * std::pow(-H.z, 20.0f);
    EXPECT_NEAR(film.pixel(x, 25).r, expected, 1e-5f) << x;
    EXPECT_LT(film.pixel(x, 25).r, best);
  }

  scene.materials[p].Ks = 0.0f;
  scene.materials[p].Kd = 1.0f;
  scene.materials[p].color = {1.0f, 0.5f, 0.5f};
  const Film diffuse = test::renderWith(scene);
  EXPECT_NEAR(diffuse.pixel(25, 25).r, 1.0f, 1e-4f);  // Kd * Cs * I / d^2 * cos 0
  EXPECT_NEAR(diffuse.pixel(25, 25).g, 0.5f, 1e-4f);
}

TEST(RenderMaterial, MetalIsCsTimesSpecular) {
  Scene scene = test::orthoScene(8, 1.0f);
  Material metal;
  metal.type = SurfaceType::Metal;
  metal.color = {1.0f, 0.8f, 0.4f};
  metal.Ka = 0.0f;
  metal.Ks = 0.7f;
  metal.Kd = 1.0f;  // metal has no diffuse term: must be ignored
  metal.roughness = 0.2f;
  const uint32_t m = test::addMaterial(&scene, metal);
  scene.meshes.push_back(wall(m));
  scene.lights.push_back(test::distantLight({0, 0, 1}, glm::vec3(1.0f)));  // along the view
  const glm::vec3 c = test::renderWith(scene).pixel(4, 4);
  EXPECT_NEAR(c.r, 0.7f, 1e-5f);
  EXPECT_NEAR(c.g, 0.56f, 1e-5f);
  EXPECT_NEAR(c.b, 0.28f, 1e-5f);
  // A light 60 degrees off: H is 30 degrees off the normal, pow(cos 30, 1 / roughness).
  scene.lights[0] = test::distantLight({0, -std::sin(60 * kDeg), std::cos(60 * kDeg)}, glm::vec3(1.0f));
  EXPECT_NEAR(test::renderWith(scene).pixel(4, 4).r, 0.7f * std::pow(std::cos(30 * kDeg), 5.0f), 1e-5f);
}

TEST(RenderMaterial, ConstantIgnoresLights) {
  Scene scene = test::orthoScene(8, 1.0f);
  const uint32_t c = test::addMaterial(&scene, test::constant({0.3f, 0.6f, 0.9f}));
  scene.meshes.push_back(wall(c));
  const glm::vec3 dark = test::renderWith(scene).pixel(4, 4);
  scene.lights.push_back(test::distantLight({0, 0, 1}, glm::vec3(5.0f)));
  EXPECT_EQ(test::renderWith(scene).pixel(4, 4), dark);
  EXPECT_EQ(dark, glm::vec3(0.3f, 0.6f, 0.9f));
}

// The opacity scenes: a constant red material of opacity `opacity` (f) and an opaque blue one (b),
// no meshes yet.
struct RedOverBlue {
  Scene scene = test::orthoScene(8, 1.0f);
  uint32_t f = 0, b = 0;
  explicit RedOverBlue(float opacity) {
    Material front = test::constant({1, 0, 0});
    front.opacity = glm::vec3(opacity);
    f = test::addMaterial(&scene, front);
    b = test::addMaterial(&scene, test::constant({0, 0, 1}));
  }
};

TEST(RenderMaterial, OpacityCompositesWhatIsBehind) {
  RedOverBlue materials(0.25f);
  Scene& scene = materials.scene;
  const uint32_t f = materials.f, b = materials.b;
  scene.meshes.push_back(wall(f, -1.0f));
  scene.meshes.push_back(wall(b, 0.0f));
  const Film both = test::renderWith(scene);
  const glm::vec3 c = both.pixel(4, 4);
  EXPECT_NEAR(c.r, 0.25f, 1e-6f);
  EXPECT_NEAR(c.b, 0.75f, 1e-6f);
  EXPECT_NEAR(both.alpha(4, 4), 1.0f, 1e-6f);
  // A wall just behind (closer than the scene's epsilon, as where two sheets cross) is still
  // composited: the ray resumes exactly past the transparent hit.
  scene.meshes.back() = wall(b, -1.0f + 1e-5f);
  const glm::vec3 close = test::renderWith(scene).pixel(4, 4);
  EXPECT_NEAR(close.r, 0.25f, 1e-6f);
  EXPECT_NEAR(close.b, 0.75f, 1e-6f);
}

// Compositing through partly transparent surfaces is the hider's (RI), not ray recursion: ten
// layers of Os 0.1 over an opaque wall composite fully even at --max-depth 0 (each layer used to
// take one level: at the default 5 the wall behind was lost, and at 0 everything behind the first).
TEST(RenderMaterial, TransparentLayersDoNotUseTheRayDepth) {
  RedOverBlue materials(0.1f);
  Scene& scene = materials.scene;
  const uint32_t f = materials.f, b = materials.b;
  for (int k = 0; k < 10; ++k) scene.meshes.push_back(wall(f, -1.0f - 0.1f * float(k)));
  scene.meshes.push_back(wall(b, 0.0f));
  const float behind = std::pow(0.9f, 10.0f);
  for (int maxDepth : {0, kDefaultMaxDepth}) {
    SCOPED_TRACE(maxDepth);
    const SampleResult r = traceOne(scene, rayFrom({0.5f, 0.5f, -20}, {0, 0, 1}), maxDepth);
    EXPECT_NEAR(r.color.r, 1.0f - behind, 1e-5f);
    EXPECT_NEAR(r.color.b, behind, 1e-5f);
    EXPECT_NEAR(r.alpha, 1.0f, 1e-5f);
  }
}

TEST(RenderMaterial, AlphaIsTheOpacityAccumulatedAlongTheRay) {
  // As RenderMan's Oi: one wall of opacity 0.25 over nothing gives alpha 0.25 (colour
  // premultiplied by it), two give 1 - 0.75^2, a fully transparent one gives 0. Coloured opacity
  // counts by its mean.
  Scene scene = test::orthoScene(8, 1.0f);
  Material front = test::constant({1, 1, 1});
  front.opacity = glm::vec3(0.25f);
  const uint32_t f = test::addMaterial(&scene, front);
  scene.meshes.push_back(wall(f, -1.0f));
  Film film = test::renderWith(scene);
  EXPECT_NEAR(film.alpha(4, 4), 0.25f, 1e-6f);
  EXPECT_NEAR(film.pixel(4, 4).r, 0.25f, 1e-6f);
  scene.meshes.push_back(wall(f, 0.0f));
  film = test::renderWith(scene);
  EXPECT_NEAR(film.alpha(4, 4), 1.0f - 0.75f * 0.75f, 1e-6f);
  scene.meshes.pop_back();
  scene.materials[f].opacity = glm::vec3(0.0f);
  EXPECT_EQ(test::renderWith(scene).alpha(4, 4), 0.0f);
  scene.materials[f].opacity = glm::vec3(1.0f, 0.5f, 0.0f);
  EXPECT_NEAR(test::renderWith(scene).alpha(4, 4), 0.5f, 1e-6f);
}

TEST(RenderMaterial, OneSidedSurfacesAreInvisibleFromBehind) {
  Scene scene = test::orthoScene(8, 1.0f);
  Material oneSided = test::constant({1, 0, 0});
  oneSided.twoSided = false;
  const uint32_t f = test::addMaterial(&scene, oneSided);
  const uint32_t b = test::addMaterial(&scene, test::constant({0, 0, 1}));
  // Facing away from the camera (outward normal +z): culled; the blue wall behind shows.
  scene.meshes.push_back(quad({-4, -4, -1}, {8, 0, 0}, {0, 8, 0}, f));
  scene.meshes.push_back(wall(b, 0.0f));
  EXPECT_EQ(test::renderWith(scene).pixel(4, 4), glm::vec3(0, 0, 1));
  // A front face just behind the culled one (closer than the scene's epsilon, as where two sheets
  // of one surface cross) is still found: the ray resumes exactly past the culled face.
  Scene close = scene;
  close.meshes.back() = wall(b, -1.0f + 1e-5f);
  EXPECT_EQ(test::renderWith(close).pixel(4, 4), glm::vec3(0, 0, 1));
  // Reversed orientation turns it toward the camera.
  scene.materials[f].reverseOrientation = true;
  EXPECT_EQ(test::renderWith(scene).pixel(4, 4), glm::vec3(1, 0, 0));
  // Two-sided (the default) is seen from both sides.
  scene.materials[f].reverseOrientation = false;
  scene.materials[f].twoSided = true;
  EXPECT_EQ(test::renderWith(scene).pixel(4, 4), glm::vec3(1, 0, 0));
  // The side is the winding's, whatever normals the mesh supplies for shading: normals toward
  // the camera do not make the back visible, normals away do not hide the front.
  scene.materials[f].twoSided = false;
  scene.meshes[0].N.assign(scene.meshes[0].P.size(), glm::vec3(0, 0, -1));
  EXPECT_EQ(test::renderWith(scene).pixel(4, 4), glm::vec3(0, 0, 1));
  scene.materials[f].reverseOrientation = true;
  scene.meshes[0].N.assign(scene.meshes[0].P.size(), glm::vec3(0, 0, 1));
  EXPECT_EQ(test::renderWith(scene).pixel(4, 4), glm::vec3(1, 0, 0));
}

// An undisplaced mesh with normals is shaded with them (interpolated), not with its face normal.
TEST(RenderMaterial, SmoothNormalsForUndisplacedMeshes) {
  Scene scene = test::orthoScene(8, 1.0f);
  const uint32_t m = test::addMaterial(&scene, test::matte());
  Mesh w = wall(m);
  const glm::vec3 tilted = glm::normalize(glm::vec3(0, -1, -1));  // 45 degrees toward -y
  w.N.assign(4, tilted);
  scene.meshes.push_back(w);
  scene.lights.push_back(test::distantLight({0, 0, 1}, glm::vec3(1.0f)));
  EXPECT_NEAR(test::renderWith(scene).pixel(4, 4).r, std::sqrt(0.5f), 1e-5f);
  scene.meshes[0].N.clear();
  EXPECT_NEAR(test::renderWith(scene).pixel(4, 4).r, 1.0f, 1e-6f);
}

}  // namespace
}  // namespace relief
