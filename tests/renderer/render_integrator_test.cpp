// Tests of the integrator and render loop on small scenes read from RIB and intersected by the
// brute-force stand-in: Lambert shading, back lighting, shadow rays, and images that are
// bit-identical across pixel orders, thread counts and runs.
#include <cmath>
#include <sstream>

#include <gtest/gtest.h>

#include "render_test_util.h"
#include "renderer/render.h"
#include "renderer/rib_reader.h"

namespace relief {
namespace {

Scene load(const std::string& text) {
  RibReadOptions options;
  SceneError error;
  std::optional<Scene> scene = readRibString(text, "test.rib", options, &error);
  EXPECT_TRUE(scene) << error.format();
  return scene ? std::move(*scene) : Scene{};
}

// An orthographic camera looking down +z at a unit-grey wall at z = 0 spanning [-4, 4]^2, plus
// whatever `extra` adds to the world.
std::string wallScene(const std::string& lights, const std::string& extra = "") {
  return "Format 40 40 1\nProjection \"orthographic\"\nScreenWindow -2 2 -2 2\n"
         "Translate 0 0 5\nWorldBegin\n" +
         lights +
         "\nSurface \"matte\" \"Ka\" [1] \"Kd\" [1]\n"
         "Polygon \"P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0]\n" +
         extra + "\nWorldEnd\n";
}

Film renderScene(const Scene& scene, PixelOrder order = PixelOrder::Hilbert, int threads = 1,
                 int spp = 0, FilterType filter = FilterType::Gaussian) {
  test::BruteForceAccelerator accel(scene);
  Film film(scene.width, scene.height);
  RenderOptions options;
  options.order = order;
  options.threads = threads;
  options.samplesPerPixel = spp;
  options.filter = filter;
  render(scene, accel, options, &film);
  return film;
}

TEST(RenderIntegrator, LambertFacingLight) {
  const Scene scene =
      load(wallScene("LightSource \"distantlight\" 1 \"intensity\" [0.8] \"from\" [0 0 -1] \"to\" [0 0 0]"));
  const Film film = renderScene(scene);
  const glm::vec3 c = film.pixel(20, 20);
  EXPECT_FLOAT_EQ(c.r, 0.8f);
  EXPECT_FLOAT_EQ(c.g, 0.8f);
}

TEST(RenderIntegrator, CosineFalloff) {
  const Scene scene =
      load(wallScene("LightSource \"distantlight\" 1 \"from\" [0 -1 -1] \"to\" [0 0 0]"));
  const Film film = renderScene(scene);
  EXPECT_NEAR(film.pixel(5, 33).r, std::sqrt(0.5f), 1e-5f);
}

TEST(RenderIntegrator, LightBehindTheSurfaceGivesBlack) {
  const Scene scene =
      load(wallScene("LightSource \"distantlight\" 1 \"from\" [0 0 1] \"to\" [0 0 0]"));
  const Film film = renderScene(scene);
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x) ASSERT_EQ(film.pixel(x, y), glm::vec3(0)) << x << "," << y;
}

TEST(RenderIntegrator, AmbientAndMaterialColour) {
  const Scene scene = load(wallScene("LightSource \"ambientlight\" 1 \"intensity\" [0.5]",
                                     "Color [1 0.5 0.25] Surface \"matte\" \"Ka\" [0.5]\n"
                                     "Polygon \"P\" [-1 -1 -1  1 -1 -1  1 1 -1  -1 1 -1]"));
  const Film film = renderScene(scene);
  EXPECT_EQ(film.pixel(0, 0), glm::vec3(0.5f));  // the wall: Ka 1
  EXPECT_EQ(film.pixel(20, 20), glm::vec3(0.25f, 0.125f, 0.0625f));
}

TEST(RenderIntegrator, ColouredAmbientLight) {
  const Scene scene =
      load(wallScene("LightSource \"ambientlight\" 1 \"intensity\" [0.5] \"lightcolor\" [1 0.5 0]"));
  EXPECT_EQ(renderScene(scene).pixel(3, 3), glm::vec3(0.5f, 0.25f, 0.0f));
}

TEST(RenderIntegrator, VertexColoursAreInterpolated) {
  const Scene scene = load(
      "Format 40 40 1\nPixelSamples 1 1\nProjection \"orthographic\"\nScreenWindow 0 1 0 1\nTranslate 0 0 5\n"
      "WorldBegin\nLightSource \"ambientlight\" 1\n"
      "Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"Cs\" [1 0 0  0 1 0  0 0 1]\nWorldEnd\n");
  const Film film = renderScene(scene);
  const glm::vec3 nearOrigin = film.pixel(0, 39), nearX = film.pixel(38, 39), nearY = film.pixel(0, 1);
  EXPECT_GT(nearOrigin.r, 0.9f);
  EXPECT_GT(nearX.g, 0.9f);
  EXPECT_GT(nearY.b, 0.9f);
  const glm::vec3 mid = film.pixel(10, 29);  // about (0.26, 0.26): a mixture of all three
  EXPECT_NEAR(mid.r + mid.g + mid.b, 1.0f, 1e-5f);
  EXPECT_GT(mid.r, 0.3f);
  EXPECT_GT(mid.g, 0.2f);
  EXPECT_GT(mid.b, 0.2f);
}

TEST(RenderIntegrator, MissesAreBlack) {
  const Scene scene =
      load("Format 8 8 1\nTranslate 0 0 5\nWorldBegin\nLightSource \"ambientlight\" 1\n"
           "Polygon \"P\" [10 10 0  11 10 0  11 11 0]\nWorldEnd\n");
  const Film film = renderScene(scene);
  EXPECT_EQ(film.pixel(4, 4), glm::vec3(0));
}

TEST(RenderIntegrator, OccluderCastsAShadow) {
  // Light arrives along (-1, 0, 1): the occluder at z = -1 over [-0.25, 0.25]^2 shadows the wall
  // around x = -1 (raster column 10) but not x = +1 (column 30).
  const Scene scene = load(wallScene(
      "LightSource \"ambientlight\" 1 \"intensity\" [0.1]\n"
      "LightSource \"distantlight\" 2 \"from\" [1 0 -1] \"to\" [0 0 0]",
      "Polygon \"P\" [-0.25 -0.25 -1  0.25 -0.25 -1  0.25 0.25 -1  -0.25 0.25 -1]"));
  const Film film = renderScene(scene);
  EXPECT_NEAR(film.pixel(10, 20).r, 0.1f, 1e-6f);
  EXPECT_NEAR(film.pixel(30, 20).r, 0.1f + std::sqrt(0.5f), 1e-5f);
  EXPECT_NEAR(film.pixel(20, 20).r, 0.1f + std::sqrt(0.5f), 1e-5f);  // the lit occluder
}

TEST(RenderIntegrator, ImageIsIdenticalAcrossOrdersThreadsAndRuns) {
  const Scene scene = load(
      "Format 37 29 1\nPixelSamples 2 2\nProjection \"perspective\" \"fov\" [40]\n"
      "Translate 0 0 5\nRotate -20 1 0 0\nWorldBegin\n"
      "LightSource \"distantlight\" 1 \"from\" [-2 3 -1.5] \"to\" [0 0 0]\n"
      "LightSource \"ambientlight\" 2 \"intensity\" [0.1]\n"
      "Color [0.9 0.5 0.3]\nRotate -60 0 0 1\nSphere 1 -0.5 1 200\n"
      "Polygon \"P\" [-4 -1 -4  -4 -1 4  4 -1 4  4 -1 -4]\nWorldEnd\n");
  const Film reference = renderScene(scene, PixelOrder::Hilbert, 1);
  double sum = 0;
  for (float v : reference.data()) sum += v;
  EXPECT_GT(sum, 10.0);  // something was rendered
  struct Variant {
    PixelOrder order;
    int threads;
  };
  for (Variant v : {Variant{PixelOrder::Scanline, 2}, Variant{PixelOrder::Bucket, 3},
                    Variant{PixelOrder::Hilbert, 4}, Variant{PixelOrder::Hilbert, 1}}) {
    const Film film = renderScene(scene, v.order, v.threads);
    EXPECT_TRUE(film.data() == reference.data())
        << pixelOrderName(v.order) << " with " << v.threads << " threads";
  }
}

TEST(RenderIntegrator, ProgressRisesToOneHundred) {
  const Scene scene =
      load(wallScene("LightSource \"distantlight\" 1 \"from\" [0 0 -1] \"to\" [0 0 0]"));
  test::BruteForceAccelerator accel(scene);
  Film film(scene.width, scene.height);
  RenderOptions options;
  options.threads = 3;
  std::vector<int> reports;
  options.progress = [&](int percent) { reports.push_back(percent); };
  render(scene, accel, options, &film);
  ASSERT_FALSE(reports.empty());
  EXPECT_EQ(reports.back(), 100);
  for (size_t i = 1; i < reports.size(); ++i) EXPECT_GT(reports[i], reports[i - 1]);
  EXPECT_TRUE(film.data() == renderScene(scene).data());
}

// RI CropWindow: the crop's pixels are bit for bit the whole render's, its border pixels too
// (their filter reaches pixels outside the crop), on any thread count and order, and the AOVs
// follow the crop.
TEST(RenderIntegrator, CropWindowRendersExactlyThoseOfTheWholeImage) {
  const Scene scene =
      load("Format 40 30 1\nPixelSamples 2 2\nCropWindow 0.3 0.62 0.25 0.5\n"
           "Projection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\nWorldBegin\n"
           "LightSource \"distantlight\" 1 \"from\" [-1 1 -1] \"to\" [0 0 0]\n"
           "Surface \"plastic\"\nSphere 1.2 -1.2 1.2 360\n"
           "Polygon \"P\" [-4 -1.2 -4  4 -1.2 -4  4 -1.2 4  -4 -1.2 4]\nWorldEnd\n");
  const PixelRect crop = cropPixels(scene.cropWindow, scene.width, scene.height);
  EXPECT_EQ(crop.x, 12);  // ceil(40 * 0.3), not 13 for 0.3f * 40 = 12.0000005
  EXPECT_EQ(crop.w, 13);  // ceil(40 * 0.62) - 12
  EXPECT_EQ(crop.y, 8);
  EXPECT_EQ(crop.h, 7);
  const Film whole = renderScene(scene);
  for (int threads : {1, 2})
    for (PixelOrder order : {PixelOrder::Scanline, PixelOrder::Hilbert}) {
      test::BruteForceAccelerator accel(scene);
      Film film(crop.w, crop.h), depth(crop.w, crop.h);
      RenderOptions options;
      options.threads = threads;
      options.order = order;
      options.fullWidth = scene.width, options.fullHeight = scene.height;
      options.cropX = crop.x, options.cropY = crop.y;
      AovFilms aovs;
      aovs.depth = &depth;
      const RenderStats stats = render(scene, accel, options, &film, aovs);
      EXPECT_LT(stats.cameraRays, uint64_t(scene.width * scene.height * 4) / 4);  // the crop and a margin only
      int different = 0, hits = 0;
      for (int y = 0; y < crop.h; ++y)
        for (int x = 0; x < crop.w; ++x) {
          different += film.pixel(x, y) != whole.pixel(crop.x + x, crop.y + y) ||
                       film.alpha(x, y) != whole.alpha(crop.x + x, crop.y + y);
          hits += depth.alpha(x, y) > 0.0f;
        }
      EXPECT_EQ(different, 0) << threads << " threads";
      EXPECT_GT(hits, 0);
    }
}

TEST(RenderIntegrator, SamplesJitterInsideThePixel) {
  // A vertical edge through the middle of pixel column 2: one centred sample sees all or nothing,
  // 16 jittered samples see about half (box filter: no sample of a neighbour counts).
  const std::string rib =
      "Format 4 1 1\nProjection \"orthographic\"\nScreenWindow 0 4 -0.5 0.5\nTranslate 0 0 5\n"
      "WorldBegin\nLightSource \"ambientlight\" 1\n"
      "Polygon \"P\" [2.5 -1 0  9 -1 0  9 1 0  2.5 1 0]\nWorldEnd\n";
  const Scene scene = load(rib);
  const Film one = renderScene(scene, PixelOrder::Scanline, 1, 1);
  const Film many = renderScene(scene, PixelOrder::Scanline, 1, 16, FilterType::Box);
  EXPECT_EQ(one.pixel(1, 0).r, 0.0f);
  EXPECT_EQ(one.alpha(1, 0), 0.0f);
  EXPECT_EQ(one.alpha(3, 0), 1.0f);
  EXPECT_EQ(many.alpha(2, 0), many.pixel(2, 0).r);  // coverage = premultiplied white
  EXPECT_EQ(many.pixel(1, 0).r, 0.0f);
  EXPECT_EQ(many.pixel(3, 0).r, 1.0f);
  EXPECT_GT(many.pixel(2, 0).r, 0.2f);
  EXPECT_LT(many.pixel(2, 0).r, 0.8f);
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// The same promise through the real accelerator, with displacement and a small cache budget:
// the image may not depend on order, threads or what the cache happened to hold.
TEST(RenderIntegrator, GridAcceleratorImageIsIdenticalAcrossOrdersThreadsAndBudgets) {
  test::TestShaderProvider shaders;
  RibReadOptions options;
  options.shaders = &shaders;
  SceneError error;
  std::optional<Scene> scene = readRibString(
      "Format 33 25 1\nProjection \"perspective\" \"fov\" [40]\n"
      "Translate 0 0 5\nRotate -20 1 0 0\nWorldBegin\n"
      "LightSource \"distantlight\" 1 \"from\" [-2 3 -1.5] \"to\" [0 0 0]\n"
      "LightSource \"ambientlight\" 2 \"intensity\" [0.1]\n"
      "AttributeBegin\nAttribute \"displacementbound\" \"float sphere\" [0.2]\n"
      "Attribute \"relief\" \"float edgelength\" [0.05]\n"
      "Displacement \"push\" \"Km\" [0.15]\nSphere 1 -1 1 360\nAttributeEnd\n"
      "Polygon \"P\" [-4 -1.3 -4  -4 -1.3 4  4 -1.3 4  4 -1.3 -4]\nWorldEnd\n",
      "grid.rib", options, &error);
  ASSERT_TRUE(scene) << error.format();

  AccelStats lastStats;
  auto renderWith = [&](PixelOrder order, int threads, uint64_t budget) {
    AccelOptions accelOptions;
    accelOptions.cacheBudgetTriangles = budget;
    std::unique_ptr<Accelerator> accel = makeGridAccelerator(*scene, accelOptions);
    Film film(scene->width, scene->height);
    RenderOptions renderOptions;
    renderOptions.order = order;
    renderOptions.threads = threads;
    render(*scene, *accel, renderOptions, &film);
    lastStats = accel->stats();
    return film;
  };
  const Film reference = renderWith(PixelOrder::Hilbert, 1, UINT64_MAX);
  // The push shader grows the sphere to radius 1.15: the centre pixel must see it lit.
  EXPECT_GT(reference.pixel(16, 12).r, 0.1f);
  const Film scanline = renderWith(PixelOrder::Scanline, 2, UINT64_MAX);
  EXPECT_TRUE(scanline.data() == reference.data());
  const Film small = renderWith(PixelOrder::Bucket, 2, 2000);
  EXPECT_GT(lastStats.capacityMisses, 0u);  // the budget really forced evictions
  EXPECT_TRUE(small.data() == reference.data());
}

// Reads `rib` (with the "push" test shader) and renders it with the grid accelerator on one thread;
// a blank film of the given size when the scene does not load.
Film renderGridScene(const std::string& rib, int width, int height) {
  test::TestShaderProvider shaders;
  RibReadOptions options;
  options.shaders = &shaders;
  SceneError error;
  std::optional<Scene> scene = readRibString(rib, "scene.rib", options, &error);
  EXPECT_TRUE(scene) << error.format();
  Film film(width, height);
  if (!scene) return film;
  std::unique_ptr<Accelerator> accel = makeGridAccelerator(*scene, AccelOptions{});
  RenderOptions renderOptions;
  renderOptions.threads = 1;
  render(*scene, *accel, renderOptions, &film);
  return film;
}

// A displaced sphere on a ground plane of half-size 4 and on one of 1e6 and 1e8 (left out of the
// grid as outside triangles): wherever the small plane or the sphere shows, the pictures agree.
// The huge planes used to lose the sphere's shadow (shadow rays started 2e-5 of the scene's
// extent off the surface, 56 units for the 1e6 plane) and to tear and vanish (float edge
// functions of a triangle reaching 1e8 units).
// With or without displacement anywhere in the scene (without it, the grid's neighbourhood is
// that of the triangles of ordinary size).
class HugeGroundPlane : public ::testing::TestWithParam<bool> {};
INSTANTIATE_TEST_SUITE_P(RenderIntegrator, HugeGroundPlane, ::testing::Bool());

TEST_P(HugeGroundPlane, KeepsTheShadowAndStaysWhole) {
  const std::string displace = GetParam() ? "Displacement \"push\" \"Km\" [0.15]\n" : "";
  auto renderFloor = [&](const std::string& half) {
    return renderGridScene(
        "Format 48 36 1\nPixelSamples 1 1\nProjection \"perspective\" \"fov\" [40]\n"
        "Translate 0 0 5\nRotate -20 1 0 0\nWorldBegin\n"
        "LightSource \"distantlight\" 1 \"from\" [-2 3 -1.5] \"to\" [0 0 0]\n"
        "LightSource \"ambientlight\" 2 \"intensity\" [0.1]\n"
        "AttributeBegin\nAttribute \"displacementbound\" \"float sphere\" [0.2]\n"
        "Attribute \"relief\" \"float edgelength\" [0.05]\n" +
        displace + "Sphere 1 -1 1 360\nAttributeEnd\n"
        "Polygon \"P\" [-" + half + " -1.3 -" + half + "  -" + half + " -1.3 " + half + "  " + half +
            " -1.3 " + half + "  " + half + " -1.3 -" + half + "]\nWorldEnd\n",
        48, 36);
  };
  const Film small = renderFloor("4");
  int shown = 0, shadowed = 0;
  for (int y = 0; y < 36; ++y)
    for (int x = 0; x < 48; ++x) {
      shown += small.pixel(x, y).r > 0.0f;
      shadowed += small.pixel(x, y).r > 0.0f && small.pixel(x, y).r < 0.12f;
    }
  ASSERT_GT(shown, 800);
  ASSERT_GT(shadowed, 20);  // the sphere's shadow on the floor
  for (const char* half : {"1e5", "1e6", "1e8"}) {
    SCOPED_TRACE(half);
    const Film huge = renderFloor(half);
    int differ = 0;
    for (int y = 0; y < 36; ++y)
      for (int x = 0; x < 48; ++x)
        if (small.pixel(x, y).r > 0.0f && std::fabs(huge.pixel(x, y).r - small.pixel(x, y).r) > 0.02f) ++differ;
    EXPECT_LE(differ, 5);
  }
}

// The same scene built at 1e-6 and 1e6 of its size (camera included) renders the same picture:
// no absolute tolerance hides in the camera's near plane (1e-4 by default until it became the RI
// default RI_EPSILON; the 1e-6 scene was black), the ray offsets or the grid.
TEST(RenderIntegrator, SceneScaleChangesNothing) {
  auto renderAt = [&](const std::string& k) {
    return renderGridScene(
        "Format 40 30 1\nProjection \"perspective\" \"fov\" [40]\n"
        "Translate 0 0 5" + k + "\nRotate -20 1 0 0\nWorldBegin\nScale 1" + k + " 1" + k + " 1" + k + "\n"
        "LightSource \"distantlight\" 1 \"from\" [-2 3 -1.5] \"to\" [0 0 0]\n"
        "LightSource \"ambientlight\" 2 \"intensity\" [0.1]\n"
        "AttributeBegin\nAttribute \"displacementbound\" \"float sphere\" [0.2] \"string coordinatesystem\" [\"object\"]\n"
        "Attribute \"relief\" \"float edgelength\" [0.05" + k + "]\n"
        "Displacement \"push\" \"Km\" [0]\nSphere 1 -1 1 360\nAttributeEnd\n"
        "Polygon \"P\" [-4 -1.3 -4  -4 -1.3 4  4 -1.3 4  4 -1.3 -4]\nWorldEnd\n",
        40, 30);
  };
  const Film unit = renderAt("");
  int lit = 0;
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 40; ++x) lit += unit.pixel(x, y).r > 0.2f;
  ASSERT_GT(lit, 300);
  for (const char* k : {"e-6", "e6"}) {
    SCOPED_TRACE(k);
    const Film scaled = renderAt(k);
    int differ = 0;
    for (int y = 0; y < 30; ++y)
      for (int x = 0; x < 40; ++x) differ += std::fabs(scaled.pixel(x, y).r - unit.pixel(x, y).r) > 0.02f;
    EXPECT_LE(differ, 6);
  }
}

// The undisplaced sphere through the grid accelerator agrees with brute force nearly everywhere
// (edge pixels may differ where the two triangle tests round differently).
TEST(RenderIntegrator, GridAcceleratorAgreesWithBruteForce) {
  const Scene scene = load(
      "Format 40 30 1\nProjection \"perspective\" \"fov\" [40]\n"
      "Translate 0 0 5\nWorldBegin\n"
      "LightSource \"distantlight\" 1 \"from\" [-2 3 -1.5] \"to\" [0 0 0]\n"
      "Sphere 1 -1 1 360\n"
      "Polygon \"P\" [-4 -1 -4  -4 -1 4  4 -1 4  4 -1 -4]"
      " \"Cs\" [1 0 0  0 1 0  0 0 1  1 1 1]\nWorldEnd\n");
  const Film brute = renderScene(scene);
  std::unique_ptr<Accelerator> accel = makeGridAccelerator(scene, AccelOptions{});
  Film film(scene.width, scene.height);
  render(scene, *accel, RenderOptions{}, &film);
  int differing = 0;
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x)
      if (glm::length(film.pixel(x, y) - brute.pixel(x, y)) > 1e-3f) ++differing;
  EXPECT_LE(differing, 6);
}

}  // namespace
}  // namespace relief
