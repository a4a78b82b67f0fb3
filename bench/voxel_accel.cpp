// Intersection inside a dense voxel: the geometry cache's sub-voxel grid (paper 3.3, as shipped in
// GridAccelerator) against a compact per-voxel BVH (binned SAH, 32-byte nodes, up to 4 triangles per
// leaf) over the very same displaced micro-triangles, traced with the same watertight triangle test.
// The issue asks to pick the structure by measurement; docs/cache.md records the result.
//
// Set-up: one bumpy displaced unit square, the whole contributor grid a single voxel (so the voxel
// holds every micro-triangle and its acceleration structure does all the work), triangle counts
// from about 2 thousand to half a million by the edge length. Rays: a perspective camera's pixel
// grid looking down at the square at 45 degrees. The cache is warmed first (every voxel filled),
// so the timed loop is pure intersection for both. Counters:
//   items/s       closest-hit queries per second (one thread)
//   accel_B/tri   BVH: bytes of its nodes per triangle (leaves own runs of reordered triangles,
//                 so there is no reference list), on top of vertices and indices
//   cache_B/tri   sub-grid: the cache's bytes per triangle, everything included (vertices,
//                 indices, keys, hit data, the sub-grid's cell offsets and references)
//   mismatches    rays whose nearest t differs between the two (must be 0)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <numeric>
#include <optional>
#include <vector>

#include "renderer/camera.h"
#include "renderer/grid_accelerator.h"
#include "renderer/intersect.h"
#include "renderer/subdivide.h"
#include "runtime/shader.h"

namespace relief::bench {
namespace {

// P += 0.04 * sin(20 x) * sin(20 y) * N: smooth bumps, so adaptive subdivision stays near uniform.
void bumpsEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  for (uint32_t i = 0; i < b->count; ++i) {
    const float h = 0.04f * std::sin(20.0f * b->P.x[i]) * std::sin(20.0f * b->P.y[i]);
    b->Pout.x[i] = b->P.x[i] + h * b->N.x[i];
    b->Pout.y[i] = b->P.y[i] + h * b->N.y[i];
    b->Pout.z[i] = b->P.z[i] + h * b->N.z[i];
    b->Nout.x[i] = b->N.x[i], b->Nout.y[i] = b->N.y[i], b->Nout.z[i] = b->N.z[i];
  }
}

Scene bumpySquare(float edgeLength) {
  Scene scene;
  scene.width = 256, scene.height = 256;
  scene.camera.perspective = true;
  scene.camera.fovDegrees = 40.0f;
  // Camera 1.6 units from the square's centre, 45 degrees above it; columns are the camera's
  // right, up and viewing (+z) axes in world space.
  const glm::vec3 eye(0.5f, -0.65f, -1.15f), centre(0.5f, 0.5f, 0.0f);
  const glm::vec3 forward = glm::normalize(centre - eye);
  const glm::vec3 right = glm::normalize(glm::cross(glm::vec3(0, 0, -1), forward));
  const glm::vec3 up = glm::cross(forward, right);
  scene.camera.worldFromCamera =
      glm::mat4(glm::vec4(right, 0), glm::vec4(up, 0), glm::vec4(forward, 0), glm::vec4(eye, 1));
  scene.materials.push_back(Material{});
  Mesh mesh;
  mesh.P = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  mesh.N = {{0, 0, -1}, {0, 0, -1}, {0, 0, -1}, {0, 0, -1}};
  mesh.uv = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  mesh.displacementIndex = 0;
  scene.meshes.push_back(mesh);
  static const auto shader = std::make_shared<const runtime::CompiledShader>(
      "bumps", bumpsEntry, std::vector<runtime::ParamInfo>{}, 0, nullptr);
  Displacement d;
  d.shader = std::make_shared<const runtime::ShaderInstance>(shader);
  d.boundWorld = 0.05f;
  d.edgeLength = edgeLength;
  d.maxDepth = 16;
  scene.displacements.push_back(d);
  return scene;
}

std::vector<Ray> cameraRays(const Scene& scene) {
  const CameraRays camera(scene.camera, scene.width, scene.height);
  std::vector<Ray> rays;
  for (int y = 0; y < scene.height; ++y)
    for (int x = 0; x < scene.width; ++x) rays.push_back(camera.generate(float(x) + 0.5f, float(y) + 0.5f));
  return rays;
}

// A compact binary BVH over an indexed triangle mesh: triangles are reordered so that each leaf
// owns a contiguous run, so leaves need no reference list.
class Bvh {
 public:
  struct Node {
    float lo[3], hi[3];
    uint32_t first;  // leaf: first triangle; inner: right child (left child is this + 1)
    uint16_t count;  // leaf: triangle count (> 0); inner: 0
    uint16_t axis;
  };
  static_assert(sizeof(Node) == 32);

  Bvh(std::vector<glm::vec3> P, const std::vector<uint32_t>& indices) : P_(std::move(P)) {
    const size_t n = indices.size() / 3;
    tris_.resize(n);
    for (size_t i = 0; i < n; ++i) tris_[i] = {indices[3 * i], indices[3 * i + 1], indices[3 * i + 2]};
    centroids_.resize(n);
    for (size_t i = 0; i < n; ++i) centroids_[i] = (P_[tris_[i][0]] + P_[tris_[i][1]] + P_[tris_[i][2]]) / 3.0f;
    order_.resize(n);
    std::iota(order_.begin(), order_.end(), 0u);
    nodes_.reserve(2 * n / 2 + 1);
    build(0, uint32_t(n));
    std::vector<std::array<uint32_t, 3>> sorted(n);
    for (size_t i = 0; i < n; ++i) sorted[i] = tris_[order_[i]];
    tris_ = std::move(sorted);
    centroids_.clear(), centroids_.shrink_to_fit(), order_.clear(), order_.shrink_to_fit();
  }

  size_t nodeBytes() const { return nodes_.size() * sizeof(Node); }

  std::optional<float> intersect(const Ray& ray) const {
    const WatertightRay wr(ray);
    const glm::vec3 inv = 1.0f / ray.direction;
    float tMax = ray.tMax;
    bool found = false;
    uint32_t stack[64];
    int top = 0;
    stack[top++] = 0;
    TriangleHit h;
    while (top) {
      const Node& node = nodes_[stack[--top]];
      if (!slab(node, ray.origin, inv, ray.tMin, tMax)) continue;
      if (node.count) {
        for (uint32_t i = node.first; i < node.first + node.count; ++i) {
          const auto& t = tris_[i];
          if (intersectTriangle(wr, P_[t[0]], P_[t[1]], P_[t[2]], ray.tMin, tMax, h)) {
            tMax = h.t;
            found = true;
          }
        }
        continue;
      }
      const uint32_t self = uint32_t(&node - nodes_.data());
      // Near child last on the stack, so it is visited first.
      if (ray.direction[node.axis] < 0) {
        stack[top++] = self + 1, stack[top++] = node.first;
      } else {
        stack[top++] = node.first, stack[top++] = self + 1;
      }
    }
    return found ? std::optional<float>(tMax) : std::nullopt;
  }

 private:
  static bool slab(const Node& n, glm::vec3 o, glm::vec3 inv, float t0, float t1) {
    for (int a = 0; a < 3; ++a) {
      float tn = (n.lo[a] - o[a]) * inv[a], tf = (n.hi[a] - o[a]) * inv[a];
      if (tn > tf) std::swap(tn, tf);
      t0 = std::max(t0, tn);
      t1 = std::min(t1, tf * 1.0000004f);  // robust far plane (Ize 2013)
      if (t0 > t1) return false;
    }
    return true;
  }

  void bounds(uint32_t begin, uint32_t end, glm::vec3& lo, glm::vec3& hi) const {
    lo = glm::vec3(1e30f), hi = glm::vec3(-1e30f);
    for (uint32_t i = begin; i < end; ++i)
      for (uint32_t v : tris_[order_[i]]) lo = glm::min(lo, P_[v]), hi = glm::max(hi, P_[v]);
  }

  static float area(glm::vec3 lo, glm::vec3 hi) {
    const glm::vec3 e = glm::max(hi - lo, glm::vec3(0));
    return e.x * e.y + e.y * e.z + e.z * e.x;
  }

  uint32_t build(uint32_t begin, uint32_t end) {
    const uint32_t index = uint32_t(nodes_.size());
    nodes_.push_back(Node{});
    glm::vec3 lo, hi;
    bounds(begin, end, lo, hi);
    for (int a = 0; a < 3; ++a) nodes_[index].lo[a] = lo[a], nodes_[index].hi[a] = hi[a];
    const uint32_t n = end - begin;
    auto leaf = [&] {
      nodes_[index].first = begin, nodes_[index].count = uint16_t(n);
      return index;
    };
    if (n <= 4) return leaf();
    glm::vec3 clo(1e30f), chi(-1e30f);
    for (uint32_t i = begin; i < end; ++i) clo = glm::min(clo, centroids_[order_[i]]), chi = glm::max(chi, centroids_[order_[i]]);
    // Binned SAH over 16 bins per axis.
    constexpr int kBins = 16;
    float bestCost = float(n);  // cost of a leaf relative to one triangle test per node area
    int bestAxis = -1, bestSplit = 0;
    for (int a = 0; a < 3; ++a) {
      const float extent = chi[a] - clo[a];
      if (!(extent > 0)) continue;
      std::array<glm::vec3, kBins> blo, bhi;
      std::array<uint32_t, kBins> count{};
      blo.fill(glm::vec3(1e30f)), bhi.fill(glm::vec3(-1e30f));
      for (uint32_t i = begin; i < end; ++i) {
        const uint32_t t = order_[i];
        const int b = std::min(kBins - 1, int(kBins * (centroids_[t][a] - clo[a]) / extent));
        ++count[b];
        for (uint32_t v : tris_[t]) blo[b] = glm::min(blo[b], P_[v]), bhi[b] = glm::max(bhi[b], P_[v]);
      }
      std::array<float, kBins> leftCost{};
      glm::vec3 l0(1e30f), l1(-1e30f);
      uint32_t left = 0;
      for (int b = 0; b < kBins - 1; ++b) {
        l0 = glm::min(l0, blo[b]), l1 = glm::max(l1, bhi[b]), left += count[b];
        leftCost[b] = float(left) * area(l0, l1);
      }
      glm::vec3 r0(1e30f), r1(-1e30f);
      uint32_t right = 0;
      for (int b = kBins - 1; b > 0; --b) {
        r0 = glm::min(r0, blo[b]), r1 = glm::max(r1, bhi[b]), right += count[b];
        const float cost = 1.0f + (leftCost[b - 1] + float(right) * area(r0, r1)) / area(lo, hi);
        if (cost < bestCost) bestCost = cost, bestAxis = a, bestSplit = b;
      }
    }
    uint32_t mid;
    if (bestAxis < 0) {
      if (n <= 16) return leaf();
      mid = begin + n / 2;  // all centroids coincide: split by count
    } else {
      const float extent = chi[bestAxis] - clo[bestAxis];
      mid = uint32_t(std::partition(order_.begin() + begin, order_.begin() + end, [&](uint32_t t) {
                       return std::min(kBins - 1, int(kBins * (centroids_[t][bestAxis] - clo[bestAxis]) / extent)) < bestSplit;
                     }) - order_.begin());
      if (mid == begin || mid == end) mid = begin + n / 2;
    }
    build(begin, mid);
    const uint32_t right = build(mid, end);
    nodes_[index].first = right, nodes_[index].count = 0, nodes_[index].axis = uint16_t(bestAxis < 0 ? 0 : bestAxis);
    return index;
  }

  std::vector<glm::vec3> P_;
  std::vector<std::array<uint32_t, 3>> tris_;
  std::vector<glm::vec3> centroids_;
  std::vector<uint32_t> order_;
  std::vector<Node> nodes_;
};

// mode 0: one voxel with its sub-grid; 1: the BVH; 2: the production grid at its automatic
// resolution (many small voxels), for scale.
void denseVoxel(benchmark::State& state, float edgeLength, int mode) {
  const bool useBvh = mode == 1;
  const Scene scene = bumpySquare(edgeLength);
  const std::vector<Ray> rays = cameraRays(scene);
  AccelOptions options;
  options.gridResolution = mode == 2 ? 0 : 1;
  GridAccelerator grid(scene, options);
  for (const Ray& r : rays) grid.intersect(r);  // warm: the one voxel is filled
  // The same micro-triangles for the BVH: the square's two input triangles, whole.
  std::vector<glm::vec3> P;
  std::vector<uint32_t> indices;
  SubdivideCounters counters;
  MicroMesh mm;
  for (uint32_t t = 0; t < 2; ++t) {
    subdivideTriangle(scene.meshes[0], t, &scene.displacements[0], mm, counters);
    const uint32_t base = uint32_t(P.size());
    P.insert(P.end(), mm.P.begin(), mm.P.end());
    for (uint32_t i : mm.indices) indices.push_back(base + i);
  }
  const size_t triangles = indices.size() / 3;
  const Bvh bvh(P, indices);
  uint64_t mismatches = 0;
  for (const Ray& r : rays) {
    const std::optional<Hit> a = grid.intersect(r);
    const std::optional<float> b = bvh.intersect(r);
    if (a.has_value() != b.has_value() || (a && a->t != *b)) ++mismatches;
  }
  size_t i = 0;
  for (auto _ : state) {
    for (int k = 0; k < 1024; ++k, i = (i + 1) % rays.size()) {
      if (useBvh) benchmark::DoNotOptimize(bvh.intersect(rays[i]));
      else benchmark::DoNotOptimize(grid.intersect(rays[i]));
    }
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * 1024);
  state.counters["triangles"] = double(triangles);
  state.counters["mismatches"] = double(mismatches);
  const AccelStats s = grid.stats();
  state.counters["voxels"] = double(grid.grid().numVoxels());
  if (useBvh) {
    state.counters["accel_B/tri"] = double(bvh.nodeBytes()) / double(triangles);
  } else {
    state.counters["cache_B/tri"] = double(s.createdBytes) / double(std::max<uint64_t>(1, s.displacedTrianglesCreated));
  }
}

void registerAll() {
  for (float edge : {0.04f, 0.02f, 0.01f, 0.005f, 0.0025f}) {
    for (int mode : {0, 1, 2}) {
      const char* name[] = {"subgrid", "bvh", "auto-grid"};
      benchmark::RegisterBenchmark(
          (std::string("DenseVoxel/") + name[mode] + "/edge:" + std::to_string(edge)).c_str(),
          [edge, mode](benchmark::State& s) { denseVoxel(s, edge, mode); })
          ->Unit(benchmark::kMillisecond)
          ->MinTime(0.5);
    }
  }
}

}  // namespace
}  // namespace relief::bench

int main(int argc, char** argv) {
  relief::bench::registerAll();
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
