// Tests of the arbitrary output variables (depth, normal, cache misses per pixel) and of the pixel
// filters: analytic weights, normalisation, and images bit-identical across pixel orders and
// thread counts for every filter, sample count and light type.
#include <atomic>
#include <cmath>
#include <set>

#include <gtest/gtest.h>

#include "render_test_util.h"

namespace relief {
namespace {

using test::quad;

// A perspective camera at the origin looking down +z (fov 60) at a wall at z = 3.
Scene perspectiveWall() {
  Scene scene;
  scene.width = 24;
  scene.height = 16;
  scene.camera.fovDegrees = 60.0f;
  const uint32_t m = test::addMaterial(&scene, test::matte());
  scene.meshes.push_back(quad({-10, -10, 3}, {0, 20, 0}, {20, 0, 0}, m));  // outward normal -z
  scene.lights.push_back(test::distantLight({0, 0, 1}, glm::vec3(1.0f)));
  return scene;
}

TEST(RenderAov, DepthIsCameraDistanceToAPlane) {
  const Scene scene = perspectiveWall();
  Film depth(scene.width, scene.height), normal(scene.width, scene.height);
  AovFilms aovs;
  aovs.depth = &depth;
  aovs.normal = &normal;
  test::renderWith(scene, {}, aovs);
  for (int y = 0; y < scene.height; ++y)
    for (int x = 0; x < scene.width; ++x) {
      EXPECT_NEAR(depth.pixel(x, y).r, 3.0f, 1e-5f) << x << "," << y;
      EXPECT_EQ(depth.alpha(x, y), 1.0f);
      EXPECT_EQ(normal.pixel(x, y), glm::vec3(0, 0, -1)) << x << "," << y;
    }
}

TEST(RenderAov, DepthOfATiltedPlaneIsCameraSpaceZ) {
  Scene scene = perspectiveWall();
  // The plane z = 3 + y / 2 (tilted about x); its outward normal faces the camera.
  scene.meshes[0] = quad({-10, -10, -2}, {0, 20, 10}, {20, 0, 0}, 0);
  Film depth(scene.width, scene.height), normal(scene.width, scene.height);
  AovFilms aovs;
  aovs.depth = &depth;
  aovs.normal = &normal;
  test::renderWith(scene, {}, aovs);
  // Row y's centre ray has direction (., sy, 1) with sy = tan(30) (1 - (y + 0.5) / 8): it meets
  // the plane where z = 3 + z sy / 2.
  const float t = std::tan(30.0f * 3.14159265f / 180.0f);
  const glm::vec3 n = glm::normalize(glm::vec3(0, 1, -2));  // cross of the quad's edges
  for (int y : {0, 5, 15}) {
    const float sy = t * (1.0f - (float(y) + 0.5f) / 8.0f);
    EXPECT_NEAR(depth.pixel(7, y).r, 3.0f / (1.0f - 0.5f * sy), 1e-4f) << y;
    EXPECT_NEAR(glm::length(normal.pixel(7, y) - n), 0.0f, 1e-5f) << y;
  }
}

TEST(RenderAov, MissesHaveNoDepthOrNormal) {
  Scene scene = perspectiveWall();
  scene.meshes[0] = quad({0, -10, 3}, {0, 20, 0}, {20, 0, 0}, 0);  // right half only
  Film depth(scene.width, scene.height), normal(scene.width, scene.height);
  AovFilms aovs;
  aovs.depth = &depth;
  aovs.normal = &normal;
  test::renderWith(scene, {}, aovs);
  EXPECT_EQ(depth.pixel(2, 8).r, 0.0f);
  EXPECT_EQ(depth.alpha(2, 8), 0.0f);
  EXPECT_EQ(normal.pixel(2, 8), glm::vec3(0.0f));
  EXPECT_NEAR(depth.pixel(20, 8).r, 3.0f, 1e-5f);
}

// Counts a "cache miss" the first time each triangle is hit, as the grid accelerator does per voxel
// fill, so the AOV can be checked against the accelerator's own count.
class MissCountingAccelerator : public Accelerator {
 public:
  explicit MissCountingAccelerator(const Scene& scene) : inner_(scene) {}
  std::optional<Hit> intersect(const Ray& ray) override {
    std::optional<Hit> hit = inner_.intersect(ray);
    if (hit && built_.insert({hit->meshIndex, hit->triangleIndex}).second) {
      ++threadCacheMisses();
      ++misses_;
    }
    return hit;
  }
  bool occluded(const Ray& ray) override { return inner_.occluded(ray); }
  AccelStats stats() const override {
    AccelStats s;
    s.compulsoryMisses = misses_;
    return s;
  }

 private:
  test::BruteForceAccelerator inner_;
  std::set<std::pair<uint32_t, uint32_t>> built_;
  uint64_t misses_ = 0;
};

TEST(RenderAov, CacheMissesAreCountedWhereGeometryWasBuilt) {
  Scene scene = perspectiveWall();
  scene.meshes[0] = quad({0, -10, 3}, {0, 20, 0}, {20, 0, 0}, 0);  // right half only
  MissCountingAccelerator accel(scene);
  Film film(scene.width, scene.height), misses(scene.width, scene.height);
  AovFilms aovs;
  aovs.cacheMiss = &misses;
  RenderOptions options;
  options.threads = 1;
  options.order = PixelOrder::Scanline;
  render(scene, accel, options, &film, aovs);
  double total = 0;
  int nonZero = 0;
  for (int y = 0; y < scene.height; ++y)
    for (int x = 0; x < scene.width; ++x) {
      const float m = misses.pixel(x, y).r;
      total += m;
      nonZero += m > 0.0f;
      if (film.alpha(x, y) == 0.0f) {
        EXPECT_EQ(m, 0.0f) << x << "," << y;  // nothing built there
      }
    }
  EXPECT_EQ(total, double(accel.stats().compulsoryMisses));
  EXPECT_GE(accel.stats().compulsoryMisses, 1u);
  EXPECT_GE(nonZero, 1);
  EXPECT_LE(nonZero, 2);
}

TEST(RenderFilter, Weights) {
  const PixelFilter gaussian = PixelFilter::make(FilterType::Gaussian);
  EXPECT_EQ(gaussian.width, 2.0f);
  EXPECT_EQ(gaussian.weight(0, 0), 1.0f);
  EXPECT_NEAR(gaussian.weight(0.5f, 0), std::exp(-0.5f), 1e-6f);  // RenderMan: exp(-2 (2x/w)^2)
  EXPECT_EQ(gaussian.weight(1.0f, 0), 0.0f);  // the support is open
  const PixelFilter bh = PixelFilter::make(FilterType::BlackmanHarris);
  EXPECT_EQ(bh.width, 3.0f);
  EXPECT_NEAR(bh.weight(0, 0), 1.0f, 1e-4f);
  EXPECT_GT(bh.weight(1.0f, 0), 0.0f);
  EXPECT_LT(bh.weight(1.0f, 0), bh.weight(0.5f, 0));
  EXPECT_EQ(bh.weight(1.5f, 0), 0.0f);
  const PixelFilter box = PixelFilter::make(FilterType::Box);
  EXPECT_EQ(box.weight(0.49f, -0.49f), 1.0f);
  EXPECT_EQ(box.weight(0.5f, 0), 0.0f);
  FilterType parsed;
  EXPECT_TRUE(parseFilter("blackman-harris", &parsed));
  EXPECT_EQ(parsed, FilterType::BlackmanHarris);
  EXPECT_FALSE(parseFilter("mitchell", &parsed));
}

// A sharp vertical edge: the box filter keeps it within one pixel, wider filters spread it over
// their support, and every filter keeps flat regions flat (weights are normalised).
TEST(RenderFilter, WiderFiltersBlurAnEdge) {
  Scene scene = test::orthoScene(12, 3.0f);  // pixels 0.5 wide
  const uint32_t white = test::addMaterial(&scene, test::constant({1, 1, 1}));
  scene.meshes.push_back(quad({0, -5, 0}, {0, 10, 0}, {10, 0, 0}, white));  // x >= 0: columns 6..
  for (FilterType f : {FilterType::Box, FilterType::Gaussian, FilterType::BlackmanHarris}) {
    RenderOptions options;
    options.filter = f;
    options.samplesPerPixel = 16;
    const Film film = test::renderWith(scene, options);
    EXPECT_EQ(film.pixel(0, 5).r, 0.0f) << filterName(f);
    EXPECT_NEAR(film.pixel(11, 5).r, 1.0f, 1e-6f) << filterName(f);
    EXPECT_NEAR(film.alpha(11, 5), 1.0f, 1e-6f) << filterName(f);
    if (f == FilterType::Box) {
      EXPECT_EQ(film.pixel(5, 5).r, 0.0f);
      EXPECT_EQ(film.pixel(6, 5).r, 1.0f);
    } else {
      EXPECT_GT(film.pixel(5, 5).r, 0.05f) << filterName(f);
      EXPECT_LT(film.pixel(6, 5).r, 0.95f) << filterName(f);
    }
  }
}

// An orthographic view of a matte floor behind a glass box: camera, shadow, reflection and
// refraction rays all reach something. Returns the matte material's index.
uint32_t glassBoxScene(Scene* scene, int width, int height) {
  *scene = test::orthoScene(width, 2.0f);
  scene->height = height;
  const uint32_t m = test::addMaterial(scene, test::matte({0.9f, 0.6f, 0.3f}, 0.1f, 1.0f));
  Material glass;
  glass.type = SurfaceType::Glass;
  glass.transmitColor = {0.6f, 0.9f, 1.0f};
  const uint32_t g = test::addMaterial(scene, glass);
  scene->meshes.push_back(quad({-6, -6, 0}, {0, 12, 0}, {12, 0, 0}, m));
  scene->meshes.push_back(test::box({-0.7f, -0.5f, -1.2f}, {0.4f, 0.6f, -0.6f}, g));
  return m;
}

TEST(RenderFilter, ImageIsBitIdenticalAcrossOrdersAndThreads) {
  Scene scene;
  const uint32_t m = glassBoxScene(&scene, 23, 17);
  scene.meshes.push_back(quad({0.8f, 0.2f, -0.8f}, {0, 0.7f, 0}, {0.6f, 0, 0}, m));
  Light area;
  area.type = LightType::Area;
  area.corner = {-1, 1, -3};
  area.edgeU = {1, 0, 0};
  area.edgeV = {0, 1, 0};
  area.color = glm::vec3(6.0f);
  area.samples = 5;
  scene.lights.push_back(area);
  scene.lights.push_back(test::pointLight({2, -1, -2}, glm::vec3(2.0f)));
  for (FilterType f : {FilterType::Gaussian, FilterType::BlackmanHarris, FilterType::Box}) {
    for (int spp : {1, 3, 4}) {
      RenderOptions base;
      base.filter = f;
      base.samplesPerPixel = spp;
      base.threads = 1;
      base.order = PixelOrder::Hilbert;
      const Film reference = test::renderWith(scene, base);
      double sum = 0;
      for (float v : reference.data()) sum += v;
      EXPECT_GT(sum, 10.0);
      for (auto [order, threads] : {std::pair{PixelOrder::Scanline, 3}, std::pair{PixelOrder::Bucket, 2},
                                    std::pair{PixelOrder::Hilbert, 4}}) {
        RenderOptions o = base;
        o.order = order;
        o.threads = threads;
        const Film film = test::renderWith(scene, o);
        EXPECT_TRUE(film.data() == reference.data())
            << filterName(f) << " " << spp << " spp, " << pixelOrderName(order) << ", " << threads
            << " threads";
      }
    }
  }
}

// Traced samples wait for filtering only until every pixel within the filter's reach is traced:
// in scanline order, a few rows' worth, not the image's. The image is the same whatever the order
// (ImageIsBitIdenticalAcrossOrdersAndThreads), so the bound is on memory alone.
TEST(RenderFilter, SamplesAreHeldOnlyWhileNeeded) {
  Scene scene;
  glassBoxScene(&scene, 96, 80);
  const uint64_t everySample = uint64_t(96) * 80 * 16 * 16;  // 16 spp, 16 bytes each
  for (FilterType f : {FilterType::Box, FilterType::BlackmanHarris}) {
    RenderOptions o;
    o.filter = f;
    o.samplesPerPixel = 16;
    o.threads = 1;
    o.order = PixelOrder::Scanline;
    test::BruteForceAccelerator accel(scene);
    Film film(scene.width, scene.height);
    const RenderStats stats = render(scene, accel, o, &film);
    // Both reach into the next 8x8 tile only: three rows of tiles are held at most (24 of 80 rows).
    EXPECT_GT(stats.peakSampleBytes, 0u) << filterName(f);
    EXPECT_LE(stats.peakSampleBytes, everySample * 24 / 80) << filterName(f);
    EXPECT_TRUE(film.data() == test::renderWith(scene, [&] {
                  RenderOptions h = o;
                  h.order = PixelOrder::Hilbert;
                  h.threads = 3;
                  return h;
                }()).data())
        << filterName(f);
  }
}

TEST(RenderFilter, SampleOffsetsAreStratified) {
  for (int count : {2, 3, 4, 5, 9, 16}) {
    const int side = int(std::lround(std::sqrt(double(count))));
    std::set<int> cells, columns, rows;
    for (int i = 0; i < count; ++i) {
      const glm::vec2 o = pixelSampleOffset(77, i, count);
      ASSERT_GE(o.x, 0.0f);
      ASSERT_LT(o.x, 1.0f);
      ASSERT_GE(o.y, 0.0f);
      ASSERT_LT(o.y, 1.0f);
      cells.insert(int(o.x * float(side)) + side * int(o.y * float(side)));
      columns.insert(int(o.x * float(count)));
      rows.insert(int(o.y * float(count)));
    }
    if (side * side == count) {
      EXPECT_EQ(int(cells.size()), count) << count;  // one sample per cell of the grid
    } else {
      EXPECT_EQ(int(columns.size()), count) << count;  // n-rooks: one per column and row
      EXPECT_EQ(int(rows.size()), count) << count;
    }
  }
  EXPECT_EQ(pixelSampleOffset(5, 0, 1), glm::vec2(0.5f));
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// Plays a geometry cache whose voxels are often being filled by another thread: while the calling
// thread defers (threadDefersBusyVoxels), one ray in 97 throws VoxelBusy, and voxels read as
// filling for three queries in four. The geometry itself is the brute-force reference.
class BusyAccelerator : public Accelerator {
 public:
  explicit BusyAccelerator(const Scene& scene) : inner_(scene) {}
  std::optional<Hit> intersect(const Ray& ray) override {
    maybeBusy();
    return inner_.intersect(ray);
  }
  bool occluded(const Ray& ray) override {
    maybeBusy();
    return inner_.occluded(ray);
  }
  bool filling(uint32_t) const override { return queries_.fetch_add(1) % 4 != 3; }
  AccelStats stats() const override { return {}; }
  uint64_t thrown() const { return thrown_.load(); }

 private:
  void maybeBusy() {
    if (threadDefersBusyVoxels() && rays_.fetch_add(1) % 97 == 50) {
      thrown_.fetch_add(1);
      throw VoxelBusy{uint32_t(thrown_.load() % 7)};
    }
  }
  test::BruteForceAccelerator inner_;
  std::atomic<uint64_t> rays_{0}, thrown_{0};
  mutable std::atomic<uint64_t> queries_{0};
};

// A shared walk puts aside pixels whose rays meet a busy voxel, camera, shadow, reflection and
// refraction rays alike, and traces them again later: the image, the AOVs and the ray counts must
// be those of a render that never waited.
TEST(RenderLoop, PutAsidePixelsAreTracedAgain) {
  Scene scene;
  glassBoxScene(&scene, 64, 40);  // 40 chunks of 64 pixels
  scene.lights.push_back(test::pointLight({2, -1, -2}, glm::vec3(2.0f)));
  RenderOptions options;
  options.samplesPerPixel = 3;
  options.threads = 1;
  test::BruteForceAccelerator plain(scene);
  Film reference(scene.width, scene.height), referenceDepth(scene.width, scene.height);
  AovFilms referenceAovs;
  referenceAovs.depth = &referenceDepth;
  const RenderStats expected = render(scene, plain, options, &reference, referenceAovs);
  ASSERT_GT(expected.shadowRays, 0u);
  ASSERT_GT(expected.refractionRays, 0u);
  for (int threads : {2, 3}) {
    SCOPED_TRACE(std::to_string(threads) + " threads");
    BusyAccelerator busy(scene);
    Film film(scene.width, scene.height), depth(scene.width, scene.height);
    AovFilms aovs;
    aovs.depth = &depth;
    options.threads = threads;
    options.sharedWalk = true;
    const RenderStats got = render(scene, busy, options, &film, aovs);
    EXPECT_TRUE(got.sharedWalk);
    EXPECT_GT(busy.thrown(), 20u);
    EXPECT_GE(got.deferredPixels, busy.thrown());  // a chunk's untried rest is put aside too
    EXPECT_TRUE(film.data() == reference.data());
    EXPECT_TRUE(depth.data() == referenceDepth.data());
    EXPECT_EQ(got.cameraRays, expected.cameraRays);
    EXPECT_EQ(got.cameraHits, expected.cameraHits);
    EXPECT_EQ(got.shadowRays, expected.shadowRays);
    EXPECT_EQ(got.reflectionRays, expected.reflectionRays);
    EXPECT_EQ(got.refractionRays, expected.refractionRays);
  }
  // Without a shared walk no thread defers: nothing is thrown.
  BusyAccelerator busy(scene);
  Film film(scene.width, scene.height);
  options.threads = 2;
  options.sharedWalk = false;
  EXPECT_EQ(render(scene, busy, options, &film).deferredPixels, 0u);
  EXPECT_EQ(busy.thrown(), 0u);
}

}  // namespace
}  // namespace relief
