// Tests of the light sources: point and spot inverse-square falloff, the spot cone and its
// smoothstep edge, shadows of a blocker for point, spot and distant lights, an area light's
// penumbra, coloured shadows through glass, Illuminate lists and the fallback to the older
// Scene::distantLights. Scenes are built in code: an orthographic camera over a matte wall at z = 0
// (the Illuminate render reads its scene from RIB, since the reader decides each mesh's lights).
#include <algorithm>
#include <cmath>
#include <sstream>

#include <gtest/gtest.h>

#include "render_test_util.h"
#include "renderer/rib_reader.h"

namespace relief {
namespace {

using test::quad;

// 40 x 40 pixels over [-4, 4]^2: pixel i's centre is at -4 + 0.2 (i + 0.5).
constexpr int kSize = 40;
float worldX(int i) { return -4.0f + 0.2f * (float(i) + 0.5f); }
float worldY(int j) { return 4.0f - 0.2f * (float(j) + 0.5f); }
int pixelAt(float x) { return int(std::floor((x + 4.0f) / 0.2f)); }

Scene wallScene() {
  Scene scene = test::orthoScene(kSize, 4.0f);
  const uint32_t m = test::addMaterial(&scene, test::matte());
  scene.meshes.push_back(quad({-6, -6, 0}, {0, 12, 0}, {12, 0, 0}, m));  // normal -z
  return scene;
}

// A blocker at z = -1 over x in [-0.5, 0.5], the full height of the view.
void addBlocker(Scene* scene) {
  const uint32_t m = test::addMaterial(scene, test::matte());
  scene->meshes.push_back(quad({-0.5f, -6, -1}, {0, 12, 0}, {1, 0, 0}, m));
}

TEST(RenderLight, PointLightFallsOffWithTheSquareOfDistance) {
  Scene scene = wallScene();
  scene.lights.push_back(test::pointLight({0, 0, -2}, glm::vec3(8.0f)));
  const Film film = test::renderWith(scene);
  for (int i : {20, 24, 30, 39}) {
    const float x = worldX(i), y = worldY(19);
    const float d = std::sqrt(x * x + y * y + 4.0f);
    EXPECT_NEAR(film.pixel(i, 19).r, 8.0f * (2.0f / d) / (d * d), 1e-5f) << i;
  }
}

TEST(RenderLight, PointLightShadow) {
  Scene scene = wallScene();
  scene.lights.push_back(test::pointLight({0, 0, -2}, glm::vec3(8.0f)));
  addBlocker(&scene);
  // The blocker's shadow on the wall spans |x| <= 1 (twice its width); the camera sees the wall
  // for |x| > 0.5.
  const Film film = test::renderWith(scene);
  EXPECT_EQ(film.pixel(pixelAt(0.7f), 19).r, 0.0f);
  EXPECT_EQ(film.pixel(pixelAt(-0.9f), 19).r, 0.0f);
  EXPECT_GT(film.pixel(pixelAt(1.3f), 19).r, 0.1f);
}

// Attribute "visibility" "int transmission" [0]: the blocker stays visible to the camera but no
// longer shadows the wall; restoring it brings the shadow back.
TEST(RenderLight, SurfaceThatCastsNoShadowsLetsShadowRaysThrough) {
  Scene scene = wallScene();
  scene.lights.push_back(test::pointLight({0, 0, -2}, glm::vec3(8.0f)));
  addBlocker(&scene);
  scene.materials[scene.meshes.back().materialIndex].castsShadows = false;
  const Film lit = test::renderWith(scene);
  EXPECT_GT(lit.pixel(pixelAt(0.7f), 19).r, 0.1f);
  EXPECT_GT(lit.pixel(pixelAt(-0.9f), 19).r, 0.1f);
  EXPECT_GT(lit.pixel(pixelAt(0.0f), 19).r, 0.0f);  // the blocker itself, lit from the front
  scene.materials[scene.meshes.back().materialIndex].castsShadows = true;
  const Film shadowed = test::renderWith(scene);
  EXPECT_EQ(shadowed.pixel(pixelAt(0.7f), 19).r, 0.0f);
  // Half transparent, it lets half the light through; with "string transmission" ["opaque"]
  // (older PRMan) it shadows fully whatever its opacity.
  Material& blocker = scene.materials[scene.meshes.back().materialIndex];
  blocker.opacity = glm::vec3(0.5f);
  const float half = test::renderWith(scene).pixel(pixelAt(0.7f), 19).r;
  EXPECT_NEAR(half, 0.5f * lit.pixel(pixelAt(0.7f), 19).r, 1e-5f);
  // A second one just behind it (closer than the scene's epsilon, as where two sheets cross)
  // lets half of that through: the shadow ray resumes exactly past the first, not an epsilon on.
  Scene two = scene;
  two.meshes.push_back(quad({-0.5f, -6, -1.0f + 1e-5f}, {0, 12, 0}, {1, 0, 0}, two.meshes.back().materialIndex));
  EXPECT_NEAR(test::renderWith(two).pixel(pixelAt(0.7f), 19).r, 0.25f * lit.pixel(pixelAt(0.7f), 19).r, 1e-5f);
  blocker.opaqueShadows = true;
  EXPECT_EQ(test::renderWith(scene).pixel(pixelAt(0.7f), 19).r, 0.0f);
}

float smoothstep(float lo, float hi, float x) {
  const float t = std::clamp((x - lo) / (hi - lo), 0.0f, 1.0f);
  return t * t * (3 - 2 * t);
}

TEST(RenderLight, SpotConeAndFalloff) {
  Scene scene = wallScene();
  Light spot;
  spot.type = LightType::Spot;
  spot.position = {0, 0, -2};
  spot.direction = {0, 0, 1};
  spot.color = glm::vec3(4.0f);
  spot.coneAngle = 0.5f;
  spot.coneDeltaAngle = 0.1f;
  spot.beamDistribution = 2.0f;
  scene.lights.push_back(spot);
  const Film film = test::renderWith(scene);
  bool sawEdge = false;
  for (int i = 0; i < kSize; ++i) {
    const float x = worldX(i), y = worldY(19);
    const float d = std::sqrt(x * x + y * y + 4.0f);
    const float cosAngle = 2.0f / d;  // to the axis, and also the incidence on the wall
    const float full = 4.0f * std::pow(cosAngle, 2.0f) / (d * d) * cosAngle;
    const float expected = full * smoothstep(std::cos(0.5f), std::cos(0.4f), cosAngle);
    EXPECT_NEAR(film.pixel(i, 19).r, expected, 1e-5f) << i;
    if (expected > 0.05f * full && expected < 0.95f * full) sawEdge = true;
    if (std::acos(cosAngle) > 0.5f) {
      EXPECT_EQ(film.pixel(i, 19).r, 0.0f) << i;
    }
  }
  EXPECT_TRUE(sawEdge);  // some pixel fell in the smoothstep band
}

TEST(RenderLight, SpotLightShadow) {
  Scene scene = wallScene();
  Light spot;
  spot.type = LightType::Spot;
  spot.position = {0, 0, -2};
  spot.direction = {0, 0, 1};
  spot.color = glm::vec3(4.0f);
  spot.coneAngle = 1.0f;
  scene.lights.push_back(spot);
  EXPECT_GT(test::renderWith(scene).pixel(pixelAt(0.7f), 19).r, 0.1f);
  addBlocker(&scene);
  EXPECT_EQ(test::renderWith(scene).pixel(pixelAt(0.7f), 19).r, 0.0f);
}

TEST(RenderLight, DistantLightShadow) {
  Scene scene = wallScene();
  scene.lights.push_back(test::distantLight({1, 0, 1}, glm::vec3(1.0f)));  // travels +x, +z
  addBlocker(&scene);
  // The shadow falls one unit along +x from the blocker: x in [0.5, 1.5].
  const Film film = test::renderWith(scene);
  EXPECT_EQ(film.pixel(pixelAt(0.7f), 19).r, 0.0f);
  EXPECT_EQ(film.pixel(pixelAt(1.3f), 19).r, 0.0f);
  EXPECT_NEAR(film.pixel(pixelAt(1.9f), 19).r, std::sqrt(0.5f), 1e-5f);
  EXPECT_NEAR(film.pixel(pixelAt(-0.9f), 19).r, std::sqrt(0.5f), 1e-5f);
}

// A 1 x 1 area light at z = -2 over a blocker of width 1 at z = -1: umbra |x| <= 0.5 (hidden by
// the blocker), penumbra 0.5 < |x| < 1.5, full light beyond.
TEST(RenderLight, AreaLightGivesAPenumbra) {
  Scene scene = wallScene();
  Light area;
  area.type = LightType::Area;
  area.shape = AreaShape::Rectangle;
  area.corner = {-0.5f, -0.5f, -2};
  area.edgeU = {1, 0, 0};
  area.edgeV = {0, 1, 0};
  area.color = glm::vec3(4.0f);
  area.samples = 64;
  scene.lights.push_back(area);
  const Film open = test::renderWith(scene);
  addBlocker(&scene);
  const Film shadowed = test::renderWith(scene);
  const int inner = pixelAt(0.7f), outer = pixelAt(1.3f), lit = pixelAt(1.9f);
  const float innerFraction = shadowed.pixel(inner, 19).r / open.pixel(inner, 19).r;
  const float outerFraction = shadowed.pixel(outer, 19).r / open.pixel(outer, 19).r;
  EXPECT_GT(innerFraction, 0.02f);
  EXPECT_LT(outerFraction, 0.98f);
  EXPECT_LT(innerFraction, outerFraction);  // brightening toward the lit side
  EXPECT_NEAR(innerFraction, 0.2f, 0.1f);   // the visible fraction of the light: (x - 0.5)
  EXPECT_NEAR(outerFraction, 0.8f, 0.1f);
  EXPECT_EQ(shadowed.pixel(lit, 19), open.pixel(lit, 19));
  // Unshadowed: the light's intensity spread over its area, each point emitting with the cosine
  // law; integrated here on a fine grid.
  const glm::vec3 P(worldX(20), worldY(19), 0.0f);
  double irradiance = 0.0;
  constexpr int kGrid = 200;
  for (int a = 0; a < kGrid; ++a)
    for (int b = 0; b < kGrid; ++b) {
      const glm::vec3 q(-0.5f + (float(a) + 0.5f) / kGrid, -0.5f + (float(b) + 0.5f) / kGrid, -2.0f);
      const glm::vec3 d = q - P;
      const float d2 = glm::dot(d, d), cosine = 2.0f / std::sqrt(d2);
      irradiance += 4.0 / (kGrid * kGrid) * double(cosine * cosine / d2);
    }
  EXPECT_NEAR(open.pixel(20, 19).r, irradiance, 0.02 * irradiance);
}

TEST(RenderLight, DiskAreaLightIlluminates) {
  Scene scene = wallScene();
  Light disk;
  disk.type = LightType::Area;
  disk.shape = AreaShape::Disk;
  disk.position = {0, 0, -20};
  disk.direction = {0, 0, 1};
  disk.radius = 0.5f;
  disk.color = glm::vec3(400.0f);
  disk.samples = 16;
  scene.lights.push_back(disk);
  EXPECT_NEAR(test::renderWith(scene).pixel(20, 19).r, 1.0f, 0.01f);  // ~ 400 / 20^2
}

// Through a glass bar the shadow is tinted by the transmit colour (and dimmed by Fresnel at both
// interfaces); an opaque bar casts a black shadow.
TEST(RenderLight, GlassCastsAColouredShadow) {
  Scene scene = wallScene();
  scene.lights.push_back(test::distantLight({1, 0, 1}, glm::vec3(1.0f)));
  Material glass;
  glass.type = SurfaceType::Glass;
  glass.eta = 1.5f;
  glass.Kt = 1.0f;
  glass.transmitColor = {1.0f, 0.5f, 0.25f};
  const uint32_t g = test::addMaterial(&scene, glass);
  scene.meshes.push_back(test::box({-0.5f, -6, -1.5f}, {0.5f, 6, -1}, g));
  const Film film = test::renderWith(scene);
  const glm::vec3 lit = film.pixel(pixelAt(-1.5f), 19);
  const glm::vec3 shade = film.pixel(pixelAt(1.3f), 19);  // shadow spans x in [0.5, 2]
  EXPECT_NEAR(lit.r, std::sqrt(0.5f), 1e-5f);
  EXPECT_GT(shade.r, 0.5f * lit.r);
  EXPECT_LT(shade.r, lit.r);
  EXPECT_NEAR(shade.g / shade.r, 0.5f, 1e-5f);
  EXPECT_NEAR(shade.b / shade.r, 0.25f, 1e-5f);

  scene.materials[g] = test::matte();
  EXPECT_EQ(test::renderWith(scene).pixel(pixelAt(1.3f), 19), glm::vec3(0.0f));
}

TEST(RenderLight, IlluminateListsRestrictLights) {
  Scene scene = wallScene();
  scene.lights.push_back(test::distantLight({0, 0, 1}, {1, 0, 0}));
  scene.lights.push_back(test::distantLight({0, 0, 1}, {0, 1, 0}));
  EXPECT_EQ(test::renderWith(scene).pixel(20, 20), glm::vec3(1, 1, 0));
  scene.meshes[0].lights = {1};
  EXPECT_EQ(test::renderWith(scene).pixel(20, 20), glm::vec3(0, 1, 0));
}

// RenderMan's rule: a light reaches only geometry declared after it while it is on. A sphere with
// every light but the ambient one switched off shows only ambient light; one declared before any
// light is black; both would have taken every light if an empty list meant "all".
TEST(RenderLight, IlluminateCanLeaveASurfaceUnlit) {
  auto centre = [](const std::string& world) {
    SceneError error;
    std::optional<Scene> scene = readRibString(
        "Format 9 9 1\nPixelSamples 1 1\nWorldBegin\n" + world + "WorldEnd\n", "light.rib", RibReadOptions{}, &error);
    EXPECT_TRUE(scene) << error.format();
    return scene ? test::renderWith(*scene).pixel(4, 4) : glm::vec3(-1.0f);
  };
  const std::string sphere = "AttributeBegin\nTranslate 0 0 5\nSphere 0.8 -0.8 0.8 360\nAttributeEnd\n";
  const std::string lights =
      "LightSource \"ambientlight\" \"fill\" \"intensity\" [0.25]\n"
      "LightSource \"distantlight\" \"key\" \"from\" [0 0 0] \"to\" [0 0 1]\n";
  EXPECT_NEAR(centre(lights + sphere).r, 1.25f, 1e-3f);
  EXPECT_NEAR(centre(lights + "Illuminate \"key\" 0\n" + sphere).r, 0.25f, 1e-3f);
  EXPECT_EQ(centre(lights + "Illuminate \"key\" 0\nIlluminate \"fill\" 0\n" + sphere), glm::vec3(0.0f));
  EXPECT_EQ(centre(sphere + lights), glm::vec3(0.0f));
}

// A light declared inside an attribute block is off after its AttributeEnd, so it lights nothing
// unless Illuminate turns it on again: the reader says so, at the light's line (features.rib had
// lost two area lights without a word). A light that reaches something, or a scene whose meshes
// take every light, is not mentioned.
TEST(RenderLight, ALightSwitchedOffBeforeAnyGeometryIsReported) {
  auto warningsOf = [](const std::string& world) {
    SceneError error;
    RibReadOptions options;
    std::ostringstream log;
    options.warnings = &log;
    std::optional<Scene> scene =
        readRibString("Format 9 9 1\nPixelSamples 1 1\nWorldBegin\n" + world + "WorldEnd\n", "lost.rib", options, &error);
    EXPECT_TRUE(scene) << error.format();
    return log.str();
  };
  const std::string blockLight =
      "LightSource \"distantlight\" \"key\" \"from\" [0 0 0] \"to\" [0 0 1]\n"
      "AttributeBegin\nLightSource \"pointlight\" \"lamp\" \"from\" [0 2 0]\nAttributeEnd\n";
  const std::string sphere = "AttributeBegin\nTranslate 0 0 5\nSphere 0.8 -0.8 0.8 360\nAttributeEnd\n";
  const std::string lost = warningsOf(blockLight + sphere);
  EXPECT_NE(lost.find("lost.rib:6: warning: light 'lamp' lights no geometry"), std::string::npos) << lost;
  EXPECT_NE(lost.find("'Illuminate \"lamp\" 1' turns it on"), std::string::npos) << lost;
  EXPECT_EQ(lost.find("'key'"), std::string::npos) << lost;
  EXPECT_EQ(warningsOf(blockLight + "Illuminate \"lamp\" 1\n" + sphere), "");
}

// BMRT's Attribute "light" "shadows": "off" makes the lights declared after it trace no shadow
// rays (RenderMan's standard lights have no shadow() call), "on" restores them. A backdrop sphere
// around everything then no longer darkens the scene.
TEST(RenderLight, LightShadowsAttributeSwitchesShadowRays) {
  auto centre = [](const std::string& world, std::string* warnings = nullptr) {
    SceneError error;
    RibReadOptions options;
    std::ostringstream log;
    options.warnings = &log;
    std::optional<Scene> scene = readRibString("Format 9 9 1\nPixelSamples 1 1\nWorldBegin\n" + world + "WorldEnd\n", "light.rib", options, &error);
    EXPECT_TRUE(scene) << error.format();
    if (warnings) *warnings = log.str();
    return scene ? test::renderWith(*scene).pixel(4, 4) : glm::vec3(-1.0f);
  };
  const std::string backdrop =
      "AttributeBegin\nSurface \"constant\"\nColor [0.5 0.5 0.5]\nSphere 50 -50 50 360\nAttributeEnd\n";
  const std::string sphere = "AttributeBegin\nTranslate 0 0 5\nSphere 0.8 -0.8 0.8 360\nAttributeEnd\n";
  const std::string key = "LightSource \"distantlight\" 1 \"from\" [0 0 0] \"to\" [0 0 1]\n";
  EXPECT_EQ(centre(key + backdrop + sphere), glm::vec3(0.0f));  // shadowed by the backdrop
  EXPECT_NEAR(centre("Attribute \"light\" \"shadows\" [\"off\"]\n" + key + backdrop + sphere).r, 1.0f, 1e-3f);
  EXPECT_EQ(centre("Attribute \"light\" \"shadows\" [\"off\"]\nAttribute \"light\" \"string shadows\" [\"on\"]\n" +
                   key + backdrop + sphere),
            glm::vec3(0.0f));
  // A light whose from and to coincide has no direction: it lights nothing, with a warning.
  std::string warnings;
  EXPECT_EQ(centre("LightSource \"distantlight\" 1 \"to\" [0 0 0]\n" + sphere, &warnings), glm::vec3(0.0f));
  EXPECT_NE(warnings.find("light.rib:4: warning: 'distantlight': 'from' and 'to' coincide"), std::string::npos)
      << warnings;
  SceneError error;
  EXPECT_FALSE(readRibString("WorldBegin\nAttribute \"light\" \"shadows\" [\"maybe\"]\nWorldEnd\n", "bad.rib",
                             RibReadOptions{}, &error));
  EXPECT_NE(error.format().find("bad.rib:2"), std::string::npos) << error.format();
}

TEST(RenderLight, AmbientLightsAddUnshadowed) {
  Scene scene = wallScene();
  scene.materials[0].Ka = 0.5f;
  Light ambient;
  ambient.type = LightType::Ambient;
  ambient.color = {0.4f, 0.2f, 0.0f};
  scene.lights.push_back(ambient);
  addBlocker(&scene);
  EXPECT_EQ(test::renderWith(scene).pixel(pixelAt(1.3f), 19), glm::vec3(0.2f, 0.1f, 0.0f));
}

TEST(RenderLight, OlderDistantLightsStillWork) {
  Scene scene = wallScene();
  DistantLight d;
  d.directionToLight = {0, 0, -1};
  d.color = glm::vec3(0.5f);
  scene.distantLights.push_back(d);
  scene.ambientColor = glm::vec3(0.25f);
  scene.materials[0].Ka = 1.0f;
  EXPECT_NEAR(test::renderWith(scene).pixel(20, 20).r, 0.75f, 1e-6f);
}

}  // namespace
}  // namespace relief
