// Shared helpers of the geometry tests (subdivide, watertight, cache, accel): a hand-written bumpy
// displacement shader behind the real runtime::ShaderInstance interface (no JIT), a displaced sphere
// scene, seeded ray sets, a brute-force reference intersector, and hit keys for the tests that
// compare accelerators hit for hit (cache budgets, side cache, memos, threads).
#pragma once

#include <cmath>
#include <cstring>
#include <memory>
#include <numbers>
#include <optional>
#include <random>
#include <thread>
#include <tuple>
#include <vector>

#include "renderer/accel.h"
#include "renderer/contributor_grid.h"
#include "renderer/geometry_cache.h"
#include "renderer/intersect.h"
#include "renderer/subdivide.h"
#include "renderer/tessellate.h"
#include "runtime/shader.h"

namespace relief::testing {

// The paper's test displacement: h = Km * sin(freq*2*pi*u) * sin(freq*pi*v), P += h * N.
inline void bumpyEntry(const RlfShadingBatch* b, const void* params, RlfStatus*) {
  float km, freq;
  std::memcpy(&km, params, 4);
  std::memcpy(&freq, static_cast<const char*>(params) + 4, 4);
  const float pi = std::numbers::pi_v<float>;
  for (uint32_t i = 0; i < b->count; ++i) {
    const float h = km * std::sin(freq * 2 * pi * b->u[i]) * std::sin(freq * pi * b->v[i]);
    b->Pout.x[i] = b->P.x[i] + h * b->N.x[i];
    b->Pout.y[i] = b->P.y[i] + h * b->N.y[i];
    b->Pout.z[i] = b->P.z[i] + h * b->N.z[i];
    b->Nout.x[i] = b->N.x[i], b->Nout.y[i] = b->N.y[i], b->Nout.z[i] = b->N.z[i];
  }
}

// Returns NaN for every point with u > 0.5 (exercises the non-finite fallback).
inline void nanEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  for (uint32_t i = 0; i < b->count; ++i) {
    const float x = b->u[i] > 0.5f ? std::nanf("") : b->P.x[i];
    b->Pout.x[i] = x, b->Pout.y[i] = b->P.y[i], b->Pout.z[i] = b->P.z[i];
    b->Nout.x[i] = b->N.x[i], b->Nout.y[i] = b->N.y[i], b->Nout.z[i] = b->N.z[i];
  }
}

inline std::shared_ptr<const runtime::ShaderInstance> makeShader(RlfShaderEntry entry, float km,
                                                                 float freq) {
  std::vector<runtime::ParamInfo> params(2);
  params[0].name = "Km", params[0].offset = 0, params[0].defaultNumbers = {km};
  params[1].name = "freq", params[1].offset = 4, params[1].defaultNumbers = {freq};
  auto compiled = std::make_shared<runtime::CompiledShader>("bumpy", entry, params, 8, nullptr);
  return std::make_shared<runtime::ShaderInstance>(compiled);
}

struct SphereOptions {
  float radius = 1.0f;
  int nu = 16, nv = 8;
  float km = 0.1f, freq = 4.0f;
  float edgeLength = 0.05f;
  int maxDepth = 8;
  float flatness = 0.0f;
  bool displaced = true;
  RlfShaderEntry entry = bumpyEntry;
};

inline Scene makeSphereScene(const SphereOptions& o) {
  Scene scene;
  scene.meshes.push_back(tessellateSphere(o.radius, -o.radius, o.radius, 360.0f, o.nu, o.nv, glm::mat4(1.0f)));
  if (o.displaced) {
    Displacement d;
    d.shader = makeShader(o.entry, o.km, o.freq);
    d.boundWorld = o.km;
    d.edgeLength = o.edgeLength;
    d.maxDepth = o.maxDepth;
    d.flatness = o.flatness;
    scene.displacements.push_back(d);
    scene.meshes[0].displacementIndex = 0;
  }
  return scene;
}

inline glm::vec3 randomDirection(std::mt19937& rng) {
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  const float z = 2.0f * uni(rng) - 1.0f, phi = 2.0f * std::numbers::pi_v<float> * uni(rng);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Rays from a sphere of radius `distance` around the origin, aimed near the centre.
inline std::vector<Ray> randomRays(int count, uint32_t seed, float distance, float jitter) {
  std::mt19937 rng(seed);
  std::vector<Ray> rays;
  for (int i = 0; i < count; ++i) {
    const glm::vec3 from = distance * randomDirection(rng);
    const glm::vec3 to = jitter * randomDirection(rng);
    rays.push_back(Ray{from, to - from, 0.0f, 1e30f});
  }
  return rays;
}

// Every displaced micro-triangle of the scene, intersected one by one; with a position step, on
// the lattice the grid accelerator snaps its vertices to (GridAccelerator::positionStep).
class BruteForce {
 public:
  explicit BruteForce(const Scene& scene, float positionStep = 0.0f) {
    for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
      const Mesh& mesh = scene.meshes[m];
      const Displacement* d = mesh.displacementIndex < scene.displacements.size()
                                  ? &scene.displacements[mesh.displacementIndex]
                                  : nullptr;
      for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
        MicroMesh mm;
        SubdivideCounters counters;
        subdivideTriangle(mesh, t, d, mm, counters);
        for (glm::vec3& p : mm.P) p = snapToLattice(p, positionStep);
        meshes_.push_back({m, t, std::move(mm)});
      }
    }
  }
  // The accelerator intersects the triangles outside its grid (huge ones) in double precision;
  // so does this reference for the triangles marked here.
  void intersectInDouble(uint32_t mesh, uint32_t triangle) {
    for (Entry& e : meshes_)
      if (e.mesh == mesh && e.triangle == triangle) e.inDouble = true;
  }
  struct Result {
    float t;
    uint32_t mesh, triangle, micro;
    glm::vec2 bary;  // on the input triangle, combined as GridAccelerator::intersect does
  };
  std::optional<Result> intersect(const Ray& ray) const {
    const WatertightRay wr(ray);
    std::optional<Result> best;
    for (const Entry& e : meshes_) {
      for (uint32_t i = 0; i < e.micro.numTriangles(); ++i) {
        const uint32_t* tri = &e.micro.indices[3 * size_t(i)];
        TriangleHit h;
        const bool hit = e.inDouble ? intersectTriangleDouble(ray, wr, e.micro.P[tri[0]], e.micro.P[tri[1]],
                                                              e.micro.P[tri[2]], ray.tMin, ray.tMax, h)
                                    : intersectTriangle(wr, e.micro.P[tri[0]], e.micro.P[tri[1]],
                                                        e.micro.P[tri[2]], ray.tMin, ray.tMax, h);
        if (!hit) continue;
        if (!best || h.t < best->t ||
            (h.t == best->t && std::tie(e.mesh, e.triangle, e.micro.ids[i]) <
                                   std::tie(best->mesh, best->triangle, best->micro)))
          best = Result{h.t, e.mesh, e.triangle, e.micro.ids[i],
                        h.b0 * e.micro.bary[tri[0]] + h.b1 * e.micro.bary[tri[1]] + h.b2 * e.micro.bary[tri[2]]};
      }
    }
    return best;
  }
  uint64_t numTriangles() const {
    uint64_t n = 0;
    for (const Entry& e : meshes_) n += e.micro.numTriangles();
    return n;
  }

 private:
  struct Entry {
    uint32_t mesh, triangle;
    MicroMesh micro;
    bool inDouble = false;
  };
  std::vector<Entry> meshes_;
};

// A hit reduced to what determinism tests compare: found, t, mesh, triangle, micro id and the
// barycentrics on the input triangle.
using HitKey = std::tuple<bool, float, uint32_t, uint32_t, uint32_t, float, float>;

inline HitKey hitKey(const std::optional<Hit>& hit) {
  if (!hit) return {false, 0.0f, 0, 0, 0, 0.0f, 0.0f};
  return {true, hit->t, hit->meshIndex, hit->triangleIndex, hit->microIndex, hit->bary.x, hit->bary.y};
}

inline std::vector<HitKey> hitKeys(Accelerator& accel, const std::vector<Ray>& rays) {
  std::vector<HitKey> keys;
  for (const Ray& r : rays) keys.push_back(hitKey(accel.intersect(r)));
  return keys;
}

// The same on two threads sharing `accel`, each taking every other ray.
inline std::vector<HitKey> hitKeysOnTwoThreads(Accelerator& accel, const std::vector<Ray>& rays) {
  std::vector<HitKey> keys(rays.size());
  auto worker = [&](size_t first) {
    for (size_t i = first; i < rays.size(); i += 2) keys[i] = hitKey(accel.intersect(rays[i]));
  };
  std::thread a(worker, 0), b(worker, 1);
  a.join(), b.join();
  return keys;
}

}  // namespace relief::testing
