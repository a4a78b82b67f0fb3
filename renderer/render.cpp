// The render loop and pixel orders (see render.h); shading lives in shading.cpp.
#include "renderer/render.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <thread>

#include "renderer/atomic_max.h"
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

// One traced sample: what the filter needs of it.
struct Sample {
  glm::vec3 color;
  float alpha;
};

// The traced samples, held per tile of kTile x kTile pixels only while an output pixel still
// needs them. A tile is allocated when its first pixel is traced; once it and every tile within
// the filter's reach are traced, its output pixels are filtered (by the thread that traced the
// last of them), and once every tile within reach of it is filtered, it is freed. Holding every
// sample of the image instead cost 16 bytes a sample: 354 MB at 720x480 and 64 samples a pixel,
// 2.1 GB at 1920x1080. Only the traced region's frontier is held now, and the filter reads the
// same samples in the same order, so images are bit for bit the same.
// Thread safety: a tile's samples are written before the release of its traced count; the
// acquire-release counters carry that to the thread that filters it, and the filtering to the
// thread that frees it.
class TileSamples {
 public:
  static constexpr int kTile = 8;

  TileSamples(int width, int height, int spp, int reach)
      : width_(width), height_(height), spp_(spp),
        tilesX_((width + kTile - 1) / kTile), tilesY_((height + kTile - 1) / kTile),
        radius_((std::max(reach, 0) + kTile - 1) / kTile),
        tiles_(size_t(tilesX_) * size_t(tilesY_)) {
    for (int ty = 0; ty < tilesY_; ++ty)
      for (int tx = 0; tx < tilesX_; ++tx) {
        Tile& t = tiles_[index(tx, ty)];
        int around = 0;
        forNeighbours(tx, ty, [&](int, int) { ++around; });
        t.pixels = uint32_t((std::min(width_, (tx + 1) * kTile) - tx * kTile) *
                            (std::min(height_, (ty + 1) * kTile) - ty * kTile));
        t.untraced.store(around, std::memory_order_relaxed);
        t.unfiltered.store(around, std::memory_order_relaxed);
      }
  }
  ~TileSamples() {
    for (Tile& t : tiles_) delete[] t.samples.load(std::memory_order_relaxed);
  }

  // The spp samples of pixel (x, y), to be written by the thread tracing it.
  Sample* samplesFor(int x, int y) {
    Tile& t = tiles_[index(x / kTile, y / kTile)];
    Sample* p = t.samples.load(std::memory_order_acquire);
    if (!p) {
      Sample* fresh = new Sample[size_t(kTile) * kTile * size_t(spp_)]();
      if (t.samples.compare_exchange_strong(p, fresh, std::memory_order_acq_rel)) {
        p = fresh;
        atomicMax(peak_, bytesPerTile() + live_.fetch_add(bytesPerTile(), std::memory_order_relaxed));
      } else {
        delete[] fresh;  // another thread's allocation won
      }
    }
    return p + offset(x, y);
  }
  // The samples of pixel (x, y) for filtering: its tile is live (traced, or given zeros by
  // filterRest) until every tile within reach of it is filtered.
  const Sample* samplesOf(int x, int y) const {
    return tiles_[index(x / kTile, y / kTile)].samples.load(std::memory_order_relaxed) + offset(x, y);
  }

  // Pixel (x, y) is traced; calls filter(x0, y0, x1, y1) for each output tile this makes ready.
  template <class Filter>
  void traced(int x, int y, Filter&& filter) {
    const int tx = x / kTile, ty = y / kTile;
    Tile& t = tiles_[index(tx, ty)];
    if (t.traced.fetch_add(1, std::memory_order_acq_rel) + 1 != t.pixels) return;
    forNeighbours(tx, ty, [&](int nx, int ny) {
      if (tiles_[index(nx, ny)].untraced.fetch_sub(1, std::memory_order_acq_rel) == 1) filterTile(nx, ny, filter);
    });
  }
  // Filters the tiles never made ready (a stopped render), with zeros for what was not traced:
  // their untraced neighbours get zeroed storage first (none of those has been freed, since a
  // tile is freed only once every tile within its reach is filtered).
  template <class Filter>
  void filterRest(Filter&& filter) {
    for (int ty = 0; ty < tilesY_; ++ty)
      for (int tx = 0; tx < tilesX_; ++tx)
        if (!tiles_[index(tx, ty)].filtered) {
          forNeighbours(tx, ty, [&](int nx, int ny) { samplesFor(nx * kTile, ny * kTile); });
          filterTile(tx, ty, filter);
        }
  }
  uint64_t peakBytes() const { return peak_.load(std::memory_order_relaxed); }

 private:
  struct Tile {
    std::atomic<Sample*> samples{nullptr};
    std::atomic<uint32_t> traced{0};   // its pixels traced
    std::atomic<int> untraced{0};      // tiles within reach (itself included) not all traced
    std::atomic<int> unfiltered{0};    // tiles within reach (itself included) not filtered
    uint32_t pixels = 0;
    bool filtered = false;  // written by the one thread that filters it
  };
  size_t index(int tx, int ty) const { return size_t(ty) * size_t(tilesX_) + size_t(tx); }
  size_t offset(int x, int y) const {
    return (size_t(y % kTile) * kTile + size_t(x % kTile)) * size_t(spp_);
  }
  uint64_t bytesPerTile() const { return uint64_t(kTile) * kTile * uint64_t(spp_) * sizeof(Sample); }
  template <class F>
  void forNeighbours(int tx, int ty, F&& f) const {
    for (int ny = std::max(0, ty - radius_); ny <= std::min(tilesY_ - 1, ty + radius_); ++ny)
      for (int nx = std::max(0, tx - radius_); nx <= std::min(tilesX_ - 1, tx + radius_); ++nx) f(nx, ny);
  }
  template <class Filter>
  void filterTile(int tx, int ty, Filter& filter) {
    tiles_[index(tx, ty)].filtered = true;
    filter(tx * kTile, ty * kTile, std::min(width_, (tx + 1) * kTile), std::min(height_, (ty + 1) * kTile));
    forNeighbours(tx, ty, [&](int nx, int ny) {
      Tile& n = tiles_[index(nx, ny)];
      if (n.unfiltered.fetch_sub(1, std::memory_order_acq_rel) == 1) {
        Sample* p = n.samples.exchange(nullptr, std::memory_order_acq_rel);
        if (p) live_.fetch_sub(bytesPerTile(), std::memory_order_relaxed);
        delete[] p;
      }
    });
  }

  int width_, height_, spp_, tilesX_, tilesY_, radius_;
  std::vector<Tile> tiles_;
  std::atomic<uint64_t> live_{0}, peak_{0};
};

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

glm::vec2 pixelSampleOffset(uint64_t pixel, int index, int count) {
  if (count <= 1) return {0.5f, 0.5f};
  const uint64_t r = mix64(mix64(pixel) ^ uint64_t(index));
  const glm::vec2 jitter(unitFloat(r), unitFloat(mix64(r)));
  const int side = int(std::lround(std::sqrt(double(count))));
  if (side * side == count)
    return {(float(index % side) + jitter.x) / float(side),
            (float(index / side) + jitter.y) / float(side)};
  return stratifiedSample(index, count, jitter);
}

RenderStats render(const Scene& scene, Accelerator& accel, const RenderOptions& options, Film* film,
                   const AovFilms& aovs) {
  const auto start = std::chrono::steady_clock::now();
  // The whole image, the crop the film holds, and the window traced: the crop grown by the
  // filter's reach, so its border pixels gather the same neighbours as in the whole image. Pixel
  // coordinates below are the window's (x, y), the whole image's (x + winX, y + winY).
  const bool cropped = options.fullWidth > 0 && options.fullHeight > 0;
  const int fullWidth = cropped ? options.fullWidth : film->width();
  const int fullHeight = cropped ? options.fullHeight : film->height();
  const int cropX = cropped ? options.cropX : 0, cropY = cropped ? options.cropY : 0;
  const PixelFilter filter = PixelFilter::make(options.filter);
  const int reach = int(std::ceil(filter.radius()));
  const int winX = std::max(0, cropX - reach), winY = std::max(0, cropY - reach);
  const int width = std::min(fullWidth, cropX + film->width() + reach) - winX;
  const int height = std::min(fullHeight, cropY + film->height() + reach) - winY;
  auto inCrop = [&](int x, int y) {
    const int cx = x + winX - cropX, cy = y + winY - cropY;
    return cx >= 0 && cy >= 0 && cx < film->width() && cy < film->height();
  };
  // Seeds and sample positions follow the pixel's place in the whole image.
  auto imagePixel = [&](int x, int y) { return uint32_t((y + winY) * fullWidth + (x + winX)); };
  const std::vector<uint32_t> order = pixelOrder(options.order, width, height);
  const CameraRays camera(scene.camera, fullWidth, fullHeight);
  ShadingOptions shading;
  shading.maxDepth = options.maxDepth >= 0 ? options.maxDepth
                     : scene.maxDepth >= 0 ? scene.maxDepth
                                          : kDefaultMaxDepth;
  shading.displaced = options.displaced;
  const Integrator integrator(scene, accel, shading);
  const int spp = std::max(1, options.samplesPerPixel > 0 ? options.samplesPerPixel : scene.pixelSamples);
  int numThreads = options.threads > 0 ? options.threads : int(std::thread::hardware_concurrency());
  numThreads = std::clamp(numThreads, 1, 256);

  // Every sample is traced into its own slot, and an output pixel is filtered once every pixel
  // within the filter's reach is traced (TileSamples): summing samples as they arrived would make
  // a pixel's sum depend on which neighbour's samples came first.
  TileSamples samples(width, height, spp, reach);
  // Filters output pixels [x0, x1) x [y0, y1): each gathers the samples within the filter's
  // support in a fixed order (neighbour pixels in scanline order, samples by index), so the sum
  // is bit-identical whichever thread filters it and whenever.
  auto filterPixels = [&](int x0, int y0, int x1, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        if (!inCrop(x, y)) continue;  // a margin pixel, traced for its neighbours only
        glm::vec3 sum(0.0f);
        float alphaSum = 0.0f, weightSum = 0.0f;
        for (int py = std::max(0, y - reach); py <= std::min(height - 1, y + reach); ++py)
          for (int px = std::max(0, x - reach); px <= std::min(width - 1, x + reach); ++px) {
            const uint32_t pixel = imagePixel(px, py);
            const Sample* pixelSamples = samples.samplesOf(px, py);
            for (int s = 0; s < spp; ++s) {
              const glm::vec2 offset = pixelSampleOffset(pixel, s, spp);
              const float w = filter.weight(float(px - x) + offset.x - 0.5f,
                                            float(py - y) + offset.y - 0.5f);
              if (w == 0.0f) continue;
              const Sample& sample = pixelSamples[s];
              sum += w * sample.color;
              alphaSum += w * sample.alpha;
              weightSum += w;
            }
          }
        const int fx = x + winX - cropX, fy = y + winY - cropY;
        if (weightSum > 0.0f) {
          film->setPixel(fx, fy, sum / weightSum, alphaSum / weightSum);
        } else {
          // A support so narrow that it misses every sample: fall back to the pixel's own mean.
          const Sample* own = samples.samplesOf(x, y);
          for (int s = 0; s < spp; ++s) {
            sum += own[s].color;
            alphaSum += own[s].alpha;
          }
          film->setPixel(fx, fy, sum / float(spp), alphaSum / float(spp));
        }
      }
  };

  // How threads share the pixel order. With one stretch per thread, each thread owns a contiguous
  // part of the order and walks it from the front, so threads work in different parts of the image
  // and rarely wait on each other's voxel fills (interleaved chunks that wait had both threads
  // fill the same voxels at once: 1.26x on 2 threads). Under a cache budget, though, each thread
  // then keeps its own working set (docs/performance.md: about twice one thread's capacity misses).
  // There the threads share one walk instead, and a thread that needs a voxel its neighbour is
  // filling does not wait for it: the pixel is put aside (VoxelBusy) and traced again once the
  // fill is done, while the thread goes on with the next pixels.
  // A thread that finishes its stretch steals chunks from the back of the stretch with most work
  // left, far from where its owner is. A stretch is one 64-bit word, front in the high half and
  // back in the low, so a claim from either end is one compare-and-swap.
  const bool sharedWalk = numThreads > 1 && options.sharedWalk;
  const int numStretches = sharedWalk ? 1 : numThreads;
  constexpr uint64_t kChunk = 64;
  // Pixels a thread may put aside before it waits for a fill like a thread that does not defer:
  // running far ahead of the fill would push the put-aside pixels' other voxels out of the budget.
  constexpr size_t kMaxDeferred = 4096;
  struct alignas(64) Stretch {
    std::atomic<uint64_t> range{0};
  };
  std::vector<Stretch> stretches(static_cast<size_t>(numStretches));
  for (int t = 0; t < numStretches; ++t) {
    const uint64_t front = order.size() * uint64_t(t) / uint64_t(numStretches);
    const uint64_t back = order.size() * uint64_t(t + 1) / uint64_t(numStretches);
    stretches[size_t(t)].range.store(front << 32 | back, std::memory_order_relaxed);
  }
  // Claims up to kChunk pixels of stretch `s`, from its front or its back; false once it is empty.
  auto claim = [&](size_t s, bool fromFront, size_t& begin, size_t& end) {
    uint64_t range = stretches[s].range.load(std::memory_order_relaxed);
    while (true) {
      const uint64_t front = range >> 32, back = range & 0xffffffffull;
      if (front >= back) return false;
      const uint64_t take = std::min(kChunk, back - front);
      const uint64_t next = fromFront ? (front + take) << 32 | back : front << 32 | (back - take);
      if (stretches[s].range.compare_exchange_weak(range, next, std::memory_order_relaxed)) {
        begin = size_t(fromFront ? front : back - take);
        end = size_t(fromFront ? front + take : back);
        return true;
      }
    }
  };
  auto claimAny = [&](int id, size_t& begin, size_t& end) {
    if (claim(size_t(id % numStretches), true, begin, end)) return true;
    while (true) {
      size_t victim = stretches.size();
      uint64_t most = 0;
      for (size_t s = 0; s < stretches.size(); ++s) {
        const uint64_t range = stretches[s].range.load(std::memory_order_relaxed);
        const uint64_t front = range >> 32, back = range & 0xffffffffull;
        if (back > front && back - front > most) most = back - front, victim = s;
      }
      if (victim == stretches.size()) return false;
      if (claim(victim, false, begin, end)) return true;
    }
  };
  std::atomic<size_t> donePixels{0};
  std::mutex progressMutex;
  int lastPercent = -1;  // guarded by progressMutex
  auto reportDone = [&](size_t count) {
    if (!options.progress || count == 0) return;
    const size_t done = donePixels.fetch_add(count) + count;
    const int percent = int(done * 100 / order.size());
    std::lock_guard<std::mutex> lock(progressMutex);
    if (percent > lastPercent) {
      lastPercent = percent;
      options.progress(percent);
    }
  };
  std::vector<RenderStats> perThread(static_cast<size_t>(numThreads));
  std::atomic<bool> failed{false};
  std::mutex failureMutex;
  std::exception_ptr failure;
  auto tracer = [&](int id) {
    RenderStats stats;  // local: neighbouring entries of perThread would share cache lines
    struct Deferred {
      size_t index;     // in `order`
      uint32_t voxel;   // the voxel being filled when the pixel was put aside
      uint64_t misses;  // the pixel's cache misses so far, for the "cachemiss" AOV
    };
    std::vector<Deferred> deferred;  // in order of deferral
    size_t deferredFront = 0;
    // Traces pixel order[i]; false if it met a voxel being filled (only while deferring), in which
    // case its partial work is dropped, counters included, and `*busy` names the voxel.
    auto tracePixel = [&](size_t i, uint64_t missesSoFar, uint32_t* busy, uint64_t* misses) {
      const int x = int(order[i] % uint32_t(width)), y = int(order[i] / uint32_t(width));
      const uint32_t pixel = imagePixel(x, y);
      const uint64_t missesBefore = threadCacheMisses();
      const RenderStats statsBefore = stats;
      float nearest = 0.0f;
      glm::vec3 normal(0.0f);
      Sample* pixelSamples = samples.samplesFor(x, y);
      try {
        for (int s = 0; s < spp; ++s) {
          const glm::vec2 offset = pixelSampleOffset(pixel, s, spp);
          const Ray ray = camera.generate(float(x + winX) + offset.x, float(y + winY) + offset.y);
          ++stats.cameraRays;
          const SampleResult r =
              integrator.trace(ray, mix64(uint64_t(pixel) * 0x10001ull + uint64_t(s)), &stats);
          pixelSamples[s] = {r.color, r.alpha};
          if (r.hit && (nearest == 0.0f || r.depth < nearest)) {
            nearest = r.depth;
            normal = r.normal;
          }
        }
      } catch (const VoxelBusy& b) {
        stats = statsBefore;
        *busy = b.voxel;
        *misses = missesSoFar + (threadCacheMisses() - missesBefore);
        return false;
      }
      const int fx = x + winX - cropX, fy = y + winY - cropY;
      if (inCrop(x, y)) {
        if (aovs.depth) aovs.depth->setPixel(fx, fy, glm::vec3(nearest), nearest > 0.0f ? 1.0f : 0.0f);
        if (aovs.normal) aovs.normal->setPixel(fx, fy, normal, nearest > 0.0f ? 1.0f : 0.0f);
        if (aovs.cacheMiss)
          aovs.cacheMiss->setPixel(fx, fy, glm::vec3(float(missesSoFar + threadCacheMisses() - missesBefore)));
      }
      samples.traced(x, y, filterPixels);
      return true;
    };
    // Traces put-aside pixels whose fill is done, oldest first; with `all`, every one, waiting
    // for the fills. Returns the number traced.
    auto retryDeferred = [&](bool all) {
      size_t traced = 0;
      while (deferredFront < deferred.size()) {
        Deferred& d = deferred[deferredFront];
        if (!all && accel.filling(d.voxel)) break;
        uint32_t busy = 0;
        uint64_t misses = 0;
        if (tracePixel(d.index, d.misses, &busy, &misses)) {
          ++deferredFront, ++traced;
        } else {
          // Another fill in its way: back of the queue.
          deferred.push_back({d.index, busy, misses});
          ++stats.deferredPixels;
          ++deferredFront;
        }
      }
      if (deferredFront == deferred.size()) deferred.clear(), deferredFront = 0;
      return traced;
    };
    threadDefersBusyVoxels() = sharedWalk;
    size_t begin = 0, end = 0;
    while (!subdivisionRanAway(scene) && !failed.load(std::memory_order_relaxed) && claimAny(id, begin, end)) {
      size_t traced = 0;
      for (size_t i = begin; i < end; ++i) {
        uint32_t busy = 0;
        uint64_t misses = 0;
        if (tracePixel(i, 0, &busy, &misses)) {
          ++traced;
        } else {
          // The rest of the chunk lies next to this pixel and most likely needs the same voxel:
          // put it aside untried (retrying costs a partial trace and an exception each time).
          deferred.push_back({i, busy, misses});
          for (size_t j = i + 1; j < end; ++j) deferred.push_back({j, busy, 0});
          stats.deferredPixels += end - i;
          break;
        }
        if (deferredFront < deferred.size()) traced += retryDeferred(false);
      }
      if (deferred.size() - deferredFront > kMaxDeferred) {
        threadDefersBusyVoxels() = false;
        traced += retryDeferred(true);
        threadDefersBusyVoxels() = sharedWalk;
      }
      reportDone(traced);
    }
    threadDefersBusyVoxels() = false;
    if (!subdivisionRanAway(scene) && !failed.load(std::memory_order_relaxed)) reportDone(retryDeferred(true));
    perThread[size_t(id)] = stats;
  };

  if (numThreads == 1) {
    tracer(0);
  } else {
    // An exception on a tracing thread (bad_alloc in a fill: its voxel is abandoned, see
    // GeometryCache) stops the others at their next chunk and is rethrown here, where a
    // one-thread render would have thrown it, instead of terminating the process.
    auto guarded = [&](int id) {
      try {
        tracer(id);
      } catch (...) {
        std::lock_guard lock(failureMutex);
        if (!failure) failure = std::current_exception();
        failed.store(true, std::memory_order_relaxed);
      }
    };
    std::vector<std::thread> threads;
    for (int t = 0; t < numThreads; ++t) threads.emplace_back(guarded, t);
    for (std::thread& t : threads) t.join();
    if (failure) std::rethrow_exception(failure);
  }
  // Only a stopped render leaves tiles unfiltered; its film is not written, but is kept whole.
  samples.filterRest(filterPixels);

  RenderStats total;
  for (const RenderStats& s : perThread) {
    total.cameraRays += s.cameraRays;
    total.shadowRays += s.shadowRays;
    total.cameraHits += s.cameraHits;
    total.reflectionRays += s.reflectionRays;
    total.refractionRays += s.refractionRays;
    total.deferredPixels += s.deferredPixels;
  }
  total.stopped = subdivisionRanAway(scene);
  total.threads = numThreads;
  total.sharedWalk = sharedWalk;
  total.samplesPerPixel = spp;
  total.peakSampleBytes = samples.peakBytes();
  total.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return total;
}

}  // namespace relief
