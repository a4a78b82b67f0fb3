// The render loop, pixel orders and the Lambert integrator (see render.h).
#include "renderer/render.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <cmath>
#include <cstdlib>
#include <thread>

#include "renderer/camera.h"

namespace relief {

bool parsePixelOrder(std::string_view text, PixelOrder* order) {
  if (text == "scanline") *order = PixelOrder::Scanline;
  else if (text == "bucket") *order = PixelOrder::Bucket;
  else if (text == "hilbert") *order = PixelOrder::Hilbert;
  else return false;
  return true;
}

std::string_view pixelOrderName(PixelOrder order) {
  switch (order) {
    case PixelOrder::Scanline: return "scanline";
    case PixelOrder::Bucket: return "bucket";
    case PixelOrder::Hilbert: return "hilbert";
  }
  return "?";
}

namespace {

int sign(int v) { return (v > 0) - (v < 0); }
int floorHalf(int v) { return v >= 0 ? v / 2 : -((1 - v) / 2); }

// Generalised Hilbert curve over the rectangle spanned from (x, y) by the major axis (ax, ay)
// and the minor axis (bx, by) (each axis-aligned). A rectangle is split in two along its major
// axis when it is long, otherwise into three parts (the classic U of the Hilbert curve), with
// split points rounded so every part keeps an even length where possible; odd-by-odd leftovers
// cost at most a diagonal step.
void hilbertRect(int x, int y, int ax, int ay, int bx, int by, int width,
                 std::vector<uint32_t>* out) {
  const int w = std::abs(ax + ay), h = std::abs(bx + by);
  const int dax = sign(ax), day = sign(ay), dbx = sign(bx), dby = sign(by);
  if (h == 1) {
    for (int i = 0; i < w; ++i, x += dax, y += day) out->push_back(uint32_t(y * width + x));
    return;
  }
  if (w == 1) {
    for (int i = 0; i < h; ++i, x += dbx, y += dby) out->push_back(uint32_t(y * width + x));
    return;
  }
  int ax2 = floorHalf(ax), ay2 = floorHalf(ay), bx2 = floorHalf(bx), by2 = floorHalf(by);
  const int w2 = std::abs(ax2 + ay2), h2 = std::abs(bx2 + by2);
  if (2 * w > 3 * h) {
    if ((w2 % 2) && w > 2) ax2 += dax, ay2 += day;
    hilbertRect(x, y, ax2, ay2, bx, by, width, out);
    hilbertRect(x + ax2, y + ay2, ax - ax2, ay - ay2, bx, by, width, out);
  } else {
    if ((h2 % 2) && h > 2) bx2 += dbx, by2 += dby;
    hilbertRect(x, y, bx2, by2, ax2, ay2, width, out);
    hilbertRect(x + bx2, y + by2, ax, ay, bx - bx2, by - by2, width, out);
    hilbertRect(x + (ax - dax) + (bx2 - dbx), y + (ay - day) + (by2 - dby), -bx2, -by2,
                -(ax - ax2), -(ay - ay2), width, out);
  }
}

// SplitMix64 finaliser: decorrelates consecutive pixel and sample indices.
uint64_t mix64(uint64_t z) {
  z += 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

float toUnitFloat(uint64_t bits) { return float(bits >> 40) * (1.0f / 16777216.0f); }

// Where sample `index` of `count` falls inside pixel `pixel`: the centre for one sample, jittered
// strata for a square count, uniform jitter otherwise. Seeded by (pixel, index) only.
glm::vec2 sampleOffset(uint64_t pixel, int index, int count) {
  if (count == 1) return {0.5f, 0.5f};
  const uint64_t r = mix64(mix64(pixel) ^ uint64_t(index));
  const float jx = toUnitFloat(r), jy = toUnitFloat(mix64(r));
  const int side = int(std::lround(std::sqrt(double(count))));
  if (side * side == count) return {(float(index % side) + jx) / float(side), (float(index / side) + jy) / float(side)};
  return {jx, jy};
}

}  // namespace

std::vector<uint32_t> pixelOrder(PixelOrder order, int width, int height) {
  std::vector<uint32_t> out;
  if (width <= 0 || height <= 0) return out;
  out.reserve(size_t(width) * size_t(height));
  switch (order) {
    case PixelOrder::Scanline:
      for (uint32_t i = 0; i < uint32_t(width) * uint32_t(height); ++i) out.push_back(i);
      break;
    case PixelOrder::Bucket:
      for (int ty = 0; ty < height; ty += kBucketSize)
        for (int tx = 0; tx < width; tx += kBucketSize)
          for (int y = ty; y < std::min(ty + kBucketSize, height); ++y)
            for (int x = tx; x < std::min(tx + kBucketSize, width); ++x)
              out.push_back(uint32_t(y * width + x));
      break;
    case PixelOrder::Hilbert:
      if (width >= height)
        hilbertRect(0, 0, width, 0, 0, height, width, &out);
      else
        hilbertRect(0, 0, 0, height, width, 0, width, &out);
      break;
  }
  return out;
}

Integrator::Integrator(const Scene& scene, Accelerator& accel) : scene_(scene), accel_(accel) {
  glm::vec3 lo(1e30f), hi(-1e30f);
  float bound = 0.0f;
  for (const Mesh& mesh : scene.meshes) {
    for (const glm::vec3& p : mesh.P) lo = glm::min(lo, p), hi = glm::max(hi, p);
    if (mesh.displacementIndex < scene.displacements.size())
      bound = std::max(bound, scene.displacements[mesh.displacementIndex].boundWorld);
  }
  const float extent = hi.x >= lo.x ? glm::length(hi - lo) + 2.0f * bound : 1.0f;
  // Large enough to clear float error in the hit point of a scene this size, small against any
  // feature a displacement shader can make.
  epsilon_ = std::max(extent, 1e-3f) * 2e-5f;
}

glm::vec3 Integrator::radiance(const Ray& ray, RenderStats* stats, bool* hitSomething) const {
  const std::optional<Hit> hit = accel_.intersect(ray);
  if (hitSomething) *hitSomething = hit.has_value();
  if (!hit) return glm::vec3(0.0f);
  ++stats->cameraHits;
  const Material defaultMaterial;
  const Mesh& mesh = scene_.meshes[hit->meshIndex];
  const Material& material = mesh.materialIndex < scene_.materials.size()
                                 ? scene_.materials[mesh.materialIndex]
                                 : defaultMaterial;
  glm::vec3 N = hit->Ng;
  if (glm::dot(N, ray.direction) > 0.0f) N = -N;  // two-sided: face the viewer
  glm::vec3 light(material.Ka * scene_.ambientColor);
  for (const DistantLight& l : scene_.distantLights) {
    const float cosine = glm::dot(N, l.directionToLight);
    if (!(cosine > 0.0f)) continue;
    Ray shadow;
    shadow.origin = hit->P + N * epsilon_;
    shadow.direction = l.directionToLight;
    shadow.tMin = 0.0f;
    shadow.tMax = 1e30f;
    ++stats->shadowRays;
    if (accel_.occluded(shadow)) continue;
    light += material.Kd * cosine * l.color;
  }
  return light * surfaceColor(mesh, material, *hit);
}

glm::vec3 Integrator::surfaceColor(const Mesh& mesh, const Material& material, const Hit& hit) {
  if (mesh.Cs.empty() || hit.triangleIndex >= mesh.numTriangles()) return material.color;
  // Hit::bary is exact for displaced hits too (the point the micro-geometry was displaced from).
  const uint32_t* idx = &mesh.indices[3 * size_t(hit.triangleIndex)];
  const float b1 = std::clamp(hit.bary.x, 0.0f, 1.0f);
  const float b2 = std::clamp(hit.bary.y, 0.0f, 1.0f - b1);
  return (1.0f - b1 - b2) * mesh.Cs[idx[0]] + b1 * mesh.Cs[idx[1]] + b2 * mesh.Cs[idx[2]];
}

RenderStats render(const Scene& scene, Accelerator& accel, const RenderOptions& options, Film* film) {
  const auto start = std::chrono::steady_clock::now();
  const int width = film->width(), height = film->height();
  const std::vector<uint32_t> order = pixelOrder(options.order, width, height);
  const CameraRays camera(scene.camera, width, height);
  const Integrator integrator(scene, accel);
  const int spp = std::max(1, options.samplesPerPixel > 0 ? options.samplesPerPixel : scene.pixelSamples);
  int numThreads = options.threads > 0 ? options.threads : int(std::thread::hardware_concurrency());
  numThreads = std::clamp(numThreads, 1, 256);

  // Threads pull chunks of the order so that each thread still walks a coherent stretch of it.
  constexpr size_t kChunk = 64;
  std::atomic<size_t> next{0};
  std::atomic<size_t> donePixels{0};
  std::mutex progressMutex;
  int lastPercent = -1;  // guarded by progressMutex
  std::vector<RenderStats> perThread(static_cast<size_t>(numThreads));
  auto worker = [&](int id) {
    RenderStats stats;  // local: neighbouring entries of perThread would share cache lines
    while (true) {
      const size_t begin = next.fetch_add(kChunk);
      if (begin >= order.size()) break;
      const size_t end = std::min(begin + kChunk, order.size());
      for (size_t i = begin; i < end; ++i) {
        const uint32_t pixel = order[i];
        const int x = int(pixel % uint32_t(width)), y = int(pixel / uint32_t(width));
        glm::vec3 sum(0.0f);
        int covered = 0;
        for (int s = 0; s < spp; ++s) {
          const glm::vec2 offset = sampleOffset(pixel, s, spp);
          const Ray ray = camera.generate(float(x) + offset.x, float(y) + offset.y);
          ++stats.cameraRays;
          bool hit = false;
          sum += integrator.radiance(ray, &stats, &hit);
          covered += hit ? 1 : 0;
        }
        film->setPixel(x, y, sum / float(spp), float(covered) / float(spp));
      }
      if (options.progress) {
        const size_t done = donePixels.fetch_add(end - begin) + (end - begin);
        const int percent = int(done * 100 / order.size());
        std::lock_guard<std::mutex> lock(progressMutex);
        if (percent > lastPercent) {
          lastPercent = percent;
          options.progress(percent);
        }
      }
    }
    perThread[size_t(id)] = stats;
  };
  if (numThreads == 1) {
    worker(0);
  } else {
    std::vector<std::thread> threads;
    for (int t = 0; t < numThreads; ++t) threads.emplace_back(worker, t);
    for (std::thread& t : threads) t.join();
  }

  RenderStats total;
  for (const RenderStats& s : perThread) {
    total.cameraRays += s.cameraRays;
    total.shadowRays += s.shadowRays;
    total.cameraHits += s.cameraHits;
  }
  total.threads = numThreads;
  total.samplesPerPixel = spp;
  total.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return total;
}

}  // namespace relief
