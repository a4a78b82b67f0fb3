// Embree baseline: up-front displacement of every input triangle into one Embree BVH (see
// embree_accelerator.h). Without Embree (RELIEF_HAVE_EMBREE unset) only the factory exists and
// says so.
#include "renderer/embree_accelerator.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <thread>
#include <vector>

#include "renderer/atomic_max.h"
#include "renderer/geometry_cache.h"  // cacheThreadShard
#include "renderer/intersect.h"    // faceNormal
#include "renderer/subdivide.h"
#include "renderer/ticks.h"

#if RELIEF_HAVE_EMBREE
#include <embree3/rtcore.h>
#endif

namespace relief {

#if RELIEF_HAVE_EMBREE

namespace {

// The displaced geometry of a run of input triangles of one mesh: one Embree geometry. Chunks let
// threads tessellate independently without a final concatenation (which would double the peak).
struct Chunk {
  uint32_t mesh = 0;
  std::vector<float> P;            // xyz per vertex, plus one float so Embree may load 16 bytes
  std::vector<glm::vec2> bary;     // per vertex: weights of input corners 1 and 2
  std::vector<uint32_t> indices;   // 3 per micro-triangle
  std::vector<uint32_t> triangle;  // per micro-triangle: input triangle within the mesh
  std::vector<uint32_t> micro;     // per micro-triangle: its id (subdivide.h)
  uint64_t bytes() const {
    return P.capacity() * sizeof(float) + bary.capacity() * sizeof(glm::vec2) +
           (indices.capacity() + triangle.capacity() + micro.capacity()) * sizeof(uint32_t);
  }
};

constexpr uint32_t kChunkTriangles = 64;

class EmbreeAccelerator final : public Accelerator {
 public:
  EmbreeAccelerator(const Scene& scene, const AccelOptions& options, const EmbreeOptions& embree);
  ~EmbreeAccelerator() override;

  std::optional<Hit> intersect(const Ray& ray) override;
  bool occluded(const Ray& ray) override;
  AccelStats stats() const override;

 private:
  void tessellate(const AccelOptions& options, int threads);
  void build(const EmbreeOptions& embree, int threads);
  [[noreturn]] void fail(const std::string& what) const;

  static void onError(void* self, RTCError code, const char* message);
  static bool onMemory(void* self, ssize_t bytes, bool post);

  const Scene& scene_;
  std::vector<Chunk> chunks_;  // geometry id = chunk index
  RTCDevice device_ = nullptr;
  RTCScene rtcScene_ = nullptr;
  AccelStats stats_;
  std::atomic<int64_t> embreeBytes_{0}, embreePeak_{0};
  // Ray time per thread shard, as the grid's (two clock reads per ray, summed over threads).
  static constexpr int kTimeShards = 16;
  struct alignas(64) TimeShard {
    std::atomic<uint64_t> ticks{0};
  };
  TimeShard rayTicks_[kTimeShards];
  void addRayTime(uint64_t startTicks);
  std::mutex errorMutex_;
  RTCError firstError_ = RTC_ERROR_NONE;
  std::string errorMessage_;
};

void EmbreeAccelerator::onError(void* self, RTCError code, const char* message) {
  auto* a = static_cast<EmbreeAccelerator*>(self);
  std::lock_guard<std::mutex> lock(a->errorMutex_);
  if (a->firstError_ != RTC_ERROR_NONE) return;
  a->firstError_ = code;
  a->errorMessage_ = message ? message : "";
}

bool EmbreeAccelerator::onMemory(void* self, ssize_t bytes, bool) {
  auto* a = static_cast<EmbreeAccelerator*>(self);
  const int64_t now = a->embreeBytes_.fetch_add(bytes, std::memory_order_relaxed) + bytes;
  atomicMax(a->embreePeak_, now);
  return true;  // never refuse: the limit under test is the process's, not ours
}

void EmbreeAccelerator::fail(const std::string& what) const {
  const std::string detail = errorMessage_.empty() ? "" : " (" + errorMessage_ + ")";
  if (firstError_ == RTC_ERROR_OUT_OF_MEMORY)
    throw EmbreeOutOfMemory("embree: out of memory while " + what + detail);
  throw std::runtime_error("embree: error while " + what + detail);
}

EmbreeAccelerator::EmbreeAccelerator(const Scene& scene, const AccelOptions& options,
                                     const EmbreeOptions& embree)
    : scene_(scene) {
  const int threads = std::clamp(
      embree.threads > 0 ? embree.threads : int(std::thread::hardware_concurrency()), 1, 256);
  try {
    tessellate(options, threads);
  } catch (const std::bad_alloc&) {
    chunks_.clear();
    chunks_.shrink_to_fit();
    throw EmbreeOutOfMemory("embree: out of memory while displacing the scene up front (" +
                            std::to_string(stats_.displacedTrianglesCreated) +
                            " displaced triangles so far)");
  }
  try {
    try {
      build(embree, threads);
    } catch (const std::bad_alloc&) {
      firstError_ = RTC_ERROR_OUT_OF_MEMORY;
      fail("building the BVH");
    }
  } catch (...) {
    // The destructor does not run for a half-built object: release Embree's state here.
    if (rtcScene_) rtcReleaseScene(rtcScene_);
    if (device_) rtcReleaseDevice(device_);
    rtcScene_ = nullptr, device_ = nullptr;
    throw;
  }
}

EmbreeAccelerator::~EmbreeAccelerator() {
  if (rtcScene_) rtcReleaseScene(rtcScene_);
  if (device_) rtcReleaseDevice(device_);
}

void EmbreeAccelerator::tessellate(const AccelOptions& options, int threads) {
  const auto start = std::chrono::steady_clock::now();
  struct Job {
    uint32_t mesh, begin, end;
  };
  std::vector<Job> jobs;
  for (uint32_t m = 0; m < scene_.meshes.size(); ++m)
    for (uint32_t t = 0; t < scene_.meshes[m].numTriangles(); t += kChunkTriangles)
      jobs.push_back({m, t, std::min(t + kChunkTriangles, scene_.meshes[m].numTriangles())});
  chunks_.resize(jobs.size());

  std::atomic<size_t> next{0};
  std::atomic<bool> outOfMemory{false};
  std::vector<SubdivideCounters> counters(static_cast<size_t>(threads));
  auto worker = [&](int id) {
    MicroMesh mm;
    std::vector<uint32_t> remap;
    try {
      for (size_t j; !outOfMemory.load(std::memory_order_relaxed) && (j = next.fetch_add(1)) < jobs.size();) {
        const Job& job = jobs[j];
        const Mesh& mesh = scene_.meshes[job.mesh];
        const Displacement* disp = nullptr;
        if (options.displace && mesh.displacementIndex < scene_.displacements.size() &&
            scene_.displacements[mesh.displacementIndex].shader)
          disp = &scene_.displacements[mesh.displacementIndex];
        Chunk& c = chunks_[j];
        c.mesh = job.mesh;
        for (uint32_t t = job.begin; t < job.end; ++t) {
          bool finite = true;
          for (int k = 0; k < 3; ++k) {
            const uint32_t i = mesh.indices[3 * size_t(t) + k];
            finite = finite && i < mesh.P.size() && std::isfinite(mesh.P[i].x) &&
                     std::isfinite(mesh.P[i].y) && std::isfinite(mesh.P[i].z);
          }
          if (!finite) continue;  // as the contributor grid: the reader reports such triangles
          subdivideTriangle(mesh, t, disp, mm, counters[size_t(id)]);
          const uint32_t base = uint32_t(c.bary.size());
          for (size_t v = 0; v < mm.P.size(); ++v) {
            c.P.insert(c.P.end(), {mm.P[v].x, mm.P[v].y, mm.P[v].z});
            c.bary.push_back(mm.bary[v]);
          }
          for (uint32_t i : mm.indices) c.indices.push_back(base + i);
          c.triangle.insert(c.triangle.end(), mm.numTriangles(), t);
          c.micro.insert(c.micro.end(), mm.ids.begin(), mm.ids.end());
        }
        c.P.push_back(0.0f);
        c.P.shrink_to_fit(), c.bary.shrink_to_fit(), c.indices.shrink_to_fit();
        c.triangle.shrink_to_fit(), c.micro.shrink_to_fit();
      }
    } catch (const std::bad_alloc&) {
      outOfMemory.store(true);
    }
  };
  if (threads == 1) {
    worker(0);
  } else {
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(worker, t);
    for (std::thread& t : pool) t.join();
  }
  for (const Chunk& c : chunks_) stats_.displacedTrianglesCreated += c.triangle.size();
  if (outOfMemory) throw std::bad_alloc();
  uint64_t displaceTicks = 0;
  for (const SubdivideCounters& c : counters) {
    stats_.shaderPoints += c.shaderPoints;
    displaceTicks += c.displaceTicks;
    stats_.trianglesBeforeSimplification += c.trianglesBeforeSimplification;
    stats_.trianglesAfterSimplification += c.trianglesAfterSimplification;
  }
  stats_.uniqueDisplacedTriangles = stats_.displacedTrianglesCreated;
  stats_.peakResidentTriangles = stats_.residentTriangles = stats_.displacedTrianglesCreated;
  // Thread-summed, as the grid's fill times: the threads' wall time less their time in shaders.
  stats_.displaceSeconds = double(displaceTicks) * nanosPerTick() * 1e-9;
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stats_.subdivideSeconds = std::max(0.0, wall * double(threads) - stats_.displaceSeconds);
  stats_.upFront = true;
}

void EmbreeAccelerator::build(const EmbreeOptions& embree, int threads) {
  const std::string config = "threads=" + std::to_string(threads);
  device_ = rtcNewDevice(config.c_str());
  if (!device_) {
    firstError_ = rtcGetDeviceError(nullptr);
    fail("creating the device");
  }
  rtcSetDeviceErrorFunction(device_, &EmbreeAccelerator::onError, this);
  rtcSetDeviceMemoryMonitorFunction(device_, &EmbreeAccelerator::onMemory, this);
  rtcScene_ = rtcNewScene(device_);
  if (!rtcScene_) fail("creating the scene");
  // Robust: Embree's watertight mode, as the crack-free micro-meshes need (intersect.h).
  rtcSetSceneFlags(rtcScene_, RTCSceneFlags(RTC_SCENE_FLAG_ROBUST |
                                            (embree.compact ? RTC_SCENE_FLAG_COMPACT : 0)));
  for (uint32_t id = 0; id < chunks_.size(); ++id) {
    const Chunk& c = chunks_[id];
    if (c.triangle.empty()) continue;
    RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!g) fail("creating a geometry");
    // Shared buffers: Embree reads our arrays in place instead of copying them.
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, c.P.data(), 0,
                               3 * sizeof(float), c.bary.size());
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, c.indices.data(), 0,
                               3 * sizeof(uint32_t), c.triangle.size());
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(rtcScene_, g, id);
    rtcReleaseGeometry(g);
    if (firstError_ != RTC_ERROR_NONE) fail("adding geometry");
  }
  rtcCommitScene(rtcScene_);
  if (firstError_ != RTC_ERROR_NONE) fail("building the BVH");
  uint64_t ours = chunks_.capacity() * sizeof(Chunk);
  for (const Chunk& c : chunks_) ours += c.bytes();
  stats_.peakResidentBytes = ours + uint64_t(std::max<int64_t>(0, embreePeak_.load()));
  stats_.residentBytes = ours + uint64_t(std::max<int64_t>(0, embreeBytes_.load()));
  // Everything is created once and kept: what was made is what is resident (Embree's BVH included).
  stats_.createdBytes = stats_.residentBytes;
}

void EmbreeAccelerator::addRayTime(uint64_t startTicks) {
  const uint64_t end = readTicks();
  if (end <= startTicks) return;  // a thread moved between cores whose counters disagree
  rayTicks_[cacheThreadShard() % kTimeShards].ticks.fetch_add(end - startTicks, std::memory_order_relaxed);
}

AccelStats EmbreeAccelerator::stats() const {
  AccelStats s = stats_;
  uint64_t ticks = 0;
  for (const TimeShard& shard : rayTicks_) ticks += shard.ticks.load(std::memory_order_relaxed);
  s.intersectSeconds = double(ticks) * nanosPerTick() * 1e-9;
  return s;
}

bool usable(const Ray& ray) {
  const glm::vec3 o = ray.origin, d = ray.direction;
  return std::isfinite(o.x + o.y + o.z + d.x + d.y + d.z) && d != glm::vec3(0.0f) &&
         !(ray.tMax <= ray.tMin) && !std::isnan(ray.tMin) && !std::isnan(ray.tMax);
}

void setRay(const Ray& ray, RTCRay& r) {
  r.org_x = ray.origin.x, r.org_y = ray.origin.y, r.org_z = ray.origin.z;
  r.dir_x = ray.direction.x, r.dir_y = ray.direction.y, r.dir_z = ray.direction.z;
  // Embree accepts t in [tnear, tfar]; ours is the open interval, so step inside it.
  r.tnear = std::max(0.0f, std::nextafter(ray.tMin, std::numeric_limits<float>::infinity()));
  r.tfar = std::nextafter(std::min(ray.tMax, std::numeric_limits<float>::max()), 0.0f);
  r.time = 0.0f;
  r.mask = 0xffffffffu;
  r.id = 0;
  r.flags = 0;
}

std::optional<Hit> EmbreeAccelerator::intersect(const Ray& ray) {
  if (!usable(ray)) return std::nullopt;
  const uint64_t start = readTicks();
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  setRay(ray, rh.ray);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(rtcScene_, &context, &rh);
  addRayTime(start);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  const Chunk& c = chunks_[rh.hit.geomID];
  const uint32_t prim = rh.hit.primID;
  const uint32_t* tri = &c.indices[3 * size_t(prim)];
  glm::vec3 p[3];
  glm::vec2 b[3];
  for (int k = 0; k < 3; ++k) {
    const float* v = &c.P[3 * size_t(tri[k])];
    p[k] = glm::vec3(v[0], v[1], v[2]);
    b[k] = c.bary[tri[k]];
  }
  Hit hit;
  hit.t = rh.ray.tfar;
  hit.P = ray.origin + hit.t * ray.direction;
  if (!faceNormal(p[0], p[1], p[2], &hit.Ng)) hit.Ng = -glm::normalize(ray.direction);
  // Embree's (u, v) weigh corners 1 and 2 of the micro-triangle, like intersect.h's b1, b2.
  const float u = rh.hit.u, v = rh.hit.v;
  hit.bary = (1.0f - u - v) * b[0] + u * b[1] + v * b[2];
  const Mesh& mesh = scene_.meshes[c.mesh];
  const uint32_t t = c.triangle[prim];
  glm::vec2 st[3];
  const glm::vec2 corner[3] = {{0, 0}, {1, 0}, {0, 1}};
  for (int k = 0; k < 3; ++k) {
    const uint32_t i = mesh.indices[3 * size_t(t) + k];
    st[k] = mesh.st.size() == mesh.P.size()   ? mesh.st[i]
            : mesh.uv.size() == mesh.P.size() ? mesh.uv[i]
                                              : corner[k];
  }
  hit.st = (1.0f - hit.bary.x - hit.bary.y) * st[0] + hit.bary.x * st[1] + hit.bary.y * st[2];
  hit.meshIndex = c.mesh;
  hit.triangleIndex = t;
  hit.microIndex = c.micro[prim];
  return hit;
}

bool EmbreeAccelerator::occluded(const Ray& ray) {
  if (!usable(ray)) return false;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay r;
  setRay(ray, r);
  const uint64_t start = readTicks();
  rtcOccluded1(rtcScene_, &context, &r);
  addRayTime(start);
  return r.tfar == -std::numeric_limits<float>::infinity();
}

}  // namespace

bool haveEmbree() { return true; }

std::unique_ptr<Accelerator> makeEmbreeAccelerator(const Scene& scene, const AccelOptions& options,
                                                   const EmbreeOptions& embree) {
  return std::make_unique<EmbreeAccelerator>(scene, options, embree);
}

#else  // !RELIEF_HAVE_EMBREE

bool haveEmbree() { return false; }

std::unique_ptr<Accelerator> makeEmbreeAccelerator(const Scene&, const AccelOptions&,
                                                   const EmbreeOptions&) {
  throw std::runtime_error("this build of Relief has no Embree (install libembree-dev and rebuild)");
}

#endif

}  // namespace relief
