// Test doubles for the scene and render tests: a brute-force Accelerator over the undisplaced
// input triangles (the reference the real grid accelerator must agree with), a ShaderProvider
// serving hand-written C++ displacement shaders through the runtime ABI, and helpers that build
// scenes in code (quads, boxes, cameras, materials, lights) for the shading tests.
#pragma once

#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "renderer/accel.h"
#include "renderer/film.h"
#include "renderer/render.h"
#include "renderer/scene.h"
#include "runtime/shader.h"

namespace relief::test {

// Nearest hit by testing every triangle; ties go to the lowest (mesh, triangle) as accel.h asks.
class BruteForceAccelerator : public Accelerator {
 public:
  explicit BruteForceAccelerator(const Scene& scene) : scene_(scene) {}

  std::optional<Hit> intersect(const Ray& ray) override {
    std::optional<Hit> best;
    float tMax = ray.tMax;
    for (uint32_t m = 0; m < scene_.meshes.size(); ++m) {
      const Mesh& mesh = scene_.meshes[m];
      for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
        float tHit, b1, b2;
        if (!hitTriangle(mesh, t, ray, tMax, &tHit, &b1, &b2)) continue;
        if (best && tHit == best->t) continue;  // keep the lower index on ties
        Hit h;
        h.t = tHit;
        h.P = ray.origin + tHit * ray.direction;
        const glm::vec3 p0 = mesh.P[mesh.indices[3 * t]], p1 = mesh.P[mesh.indices[3 * t + 1]],
                        p2 = mesh.P[mesh.indices[3 * t + 2]];
        h.Ng = glm::normalize(glm::cross(p1 - p0, p2 - p0));
        h.bary = glm::vec2(b1, b2);
        h.meshIndex = m;
        h.triangleIndex = t;
        best = h;
        tMax = tHit;
      }
    }
    return best;
  }

  bool occluded(const Ray& ray) override {
    for (const Mesh& mesh : scene_.meshes)
      for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
        float tHit, b1, b2;
        if (hitTriangle(mesh, t, ray, ray.tMax, &tHit, &b1, &b2)) return true;
      }
    return false;
  }

  AccelStats stats() const override { return {}; }

 private:
  // Möller–Trumbore with t in (tMin, tMax) exclusive.
  static bool hitTriangle(const Mesh& mesh, uint32_t tri, const Ray& ray, float tMax, float* t,
                          float* b1, float* b2) {
    const glm::vec3 p0 = mesh.P[mesh.indices[3 * tri]], p1 = mesh.P[mesh.indices[3 * tri + 1]],
                    p2 = mesh.P[mesh.indices[3 * tri + 2]];
    const glm::vec3 e1 = p1 - p0, e2 = p2 - p0;
    const glm::vec3 pv = glm::cross(ray.direction, e2);
    const float det = glm::dot(e1, pv);
    if (std::fabs(det) < 1e-20f) return false;
    const float inv = 1.0f / det;
    const glm::vec3 tv = ray.origin - p0;
    *b1 = glm::dot(tv, pv) * inv;
    if (*b1 < 0.0f || *b1 > 1.0f) return false;
    const glm::vec3 qv = glm::cross(tv, e1);
    *b2 = glm::dot(ray.direction, qv) * inv;
    if (*b2 < 0.0f || *b1 + *b2 > 1.0f) return false;
    *t = glm::dot(e2, qv) * inv;
    return *t > ray.tMin && *t < tMax;
  }

  const Scene& scene_;
};

// "push": P += Km * N. Parameter block: float Km at offset 0.
inline void pushEntry(const RlfShadingBatch* batch, const void* params, RlfStatus*) {
  const float km = *static_cast<const float*>(params);
  for (uint32_t i = 0; i < batch->count; ++i) {
    batch->Pout.x[i] = batch->P.x[i] + km * batch->N.x[i];
    batch->Pout.y[i] = batch->P.y[i] + km * batch->N.y[i];
    batch->Pout.z[i] = batch->P.z[i] + km * batch->N.z[i];
    batch->Nout.x[i] = batch->N.x[i];
    batch->Nout.y[i] = batch->N.y[i];
    batch->Nout.z[i] = batch->N.z[i];
  }
}

inline std::shared_ptr<const runtime::CompiledShader> makePushShader() {
  std::vector<runtime::ParamInfo> params(3);
  params[0].name = "Km";
  params[0].type = runtime::ParamType::Float;
  params[0].offset = 0;
  params[0].defaultNumbers = {0.1f};
  params[1].name = "tint";
  params[1].type = runtime::ParamType::Color;
  params[1].offset = 4;
  params[1].defaultNumbers = {1, 1, 1};
  params[2].name = "map";
  params[2].type = runtime::ParamType::String;
  params[2].offset = 16;
  params[2].defaultStrings = {""};
  // Triples of each spatial kind, for the spaces their values are bound in.
  const char* spatial[3] = {"centre", "direction", "facing"};
  const runtime::ParamType kinds[3] = {runtime::ParamType::Point, runtime::ParamType::Vector,
                                       runtime::ParamType::Normal};
  for (int k = 0; k < 3; ++k) {
    runtime::ParamInfo& info = params.emplace_back();
    info.name = spatial[k];
    info.type = kinds[k];
    info.offset = uint32_t(24 + 12 * k);
    info.defaultNumbers = {0, 0, 1};
  }
  return std::make_shared<runtime::CompiledShader>("push", &pushEntry, std::move(params), 60,
                                                   nullptr);
}

// Serves "push"; records the search path of every request.
class TestShaderProvider : public runtime::ShaderProvider {
 public:
  std::shared_ptr<const runtime::CompiledShader> find(std::string_view name,
                                                      std::span<const std::string> searchPath,
                                                      std::string* error) override {
    lastSearchPath.assign(searchPath.begin(), searchPath.end());
    if (name == "push") return makePushShader();
    *error = "no shader named '" + std::string(name) + "'";
    return nullptr;
  }
  std::vector<std::string> lastSearchPath;
};

// A parallelogram (two triangles) whose outward normal is normalize(cross(edgeU, edgeV)).
inline Mesh quad(const glm::vec3& corner, const glm::vec3& edgeU, const glm::vec3& edgeV,
                 uint32_t material) {
  Mesh m;
  m.P = {corner, corner + edgeU, corner + edgeU + edgeV, corner + edgeV};
  m.indices = {0, 1, 2, 0, 2, 3};
  m.materialIndex = material;
  return m;
}

// An axis-aligned closed box with outward-facing triangles.
inline Mesh box(const glm::vec3& lo, const glm::vec3& hi, uint32_t material) {
  Mesh m;
  m.materialIndex = material;
  auto face = [&](glm::vec3 c, glm::vec3 u, glm::vec3 v) {
    const uint32_t base = uint32_t(m.P.size());
    m.P.insert(m.P.end(), {c, c + u, c + u + v, c + v});
    m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  };
  const glm::vec3 d = hi - lo;
  const glm::vec3 X(d.x, 0, 0), Y(0, d.y, 0), Z(0, 0, d.z);
  face(lo, Y, X);           // z = lo: normal -z
  face(lo + Z, X, Y);       // z = hi: normal +z
  face(lo, X, Z);           // y = lo: normal -y
  face(lo + Y, Z, X);       // y = hi: normal +y
  face(lo, Z, Y);           // x = lo: normal -x
  face(lo + X, Y, Z);       // x = hi: normal +x
  return m;
}

// A `size` x `size` image seen by an orthographic camera at z = -5 looking down +z, whose screen
// window spans [-half, half]^2 of the world's x and y: raster (i, j) is world
// x = -half + (i + 0.5) * 2 half / size, y = half - (j + 0.5) * 2 half / size.
inline Scene orthoScene(int size, float half) {
  Scene s;
  s.width = s.height = size;
  s.camera.perspective = false;
  s.camera.worldFromCamera = glm::translate(glm::mat4(1.0f), glm::vec3(0, 0, -5));
  s.camera.screenWindowSet = true;
  s.camera.screenWindow[0] = -half, s.camera.screenWindow[1] = half;
  s.camera.screenWindow[2] = -half, s.camera.screenWindow[3] = half;
  return s;
}

inline uint32_t addMaterial(Scene* s, const Material& m) {
  s->materials.push_back(m);
  return uint32_t(s->materials.size() - 1);
}

inline Material matte(glm::vec3 color = glm::vec3(1.0f), float Ka = 0.0f, float Kd = 1.0f) {
  Material m;
  m.type = SurfaceType::Matte;
  m.color = color;
  m.Ka = Ka;
  m.Kd = Kd;
  return m;
}

inline Material constant(glm::vec3 color) {
  Material m;
  m.type = SurfaceType::Constant;
  m.color = color;
  return m;
}

inline Light pointLight(glm::vec3 position, glm::vec3 color) {
  Light l;
  l.type = LightType::Point;
  l.position = position;
  l.color = color;
  return l;
}

inline Light distantLight(glm::vec3 direction, glm::vec3 color) {
  Light l;
  l.type = LightType::Distant;
  l.direction = glm::normalize(direction);
  l.color = color;
  return l;
}

inline Film renderWith(const Scene& scene, RenderOptions options = {}, const AovFilms& aovs = {}) {
  BruteForceAccelerator accel(scene);
  Film film(scene.width, scene.height);
  if (options.threads == 0) options.threads = 1;
  render(scene, accel, options, &film, aovs);
  return film;
}

// Fuzzes a parser with `iterations` seeded mutations of `base` (1-4 deletions, insertions of
// `alphabet` characters, or replacements each) and calls `accepts(text)` on each, which returns
// whether the text was accepted (and checks the error otherwise). Returns {accepted, rejected}.
template <typename Accepts>
std::pair<int, int> mutationFuzz(const std::string& base, const std::string& alphabet, uint64_t seed,
                                 int iterations, Accepts accepts) {
  uint64_t state = seed;
  auto next = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return uint32_t(state >> 33);
  };
  int accepted = 0, rejected = 0;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    std::string text = base;
    const int edits = 1 + int(next() % 4);
    for (int e = 0; e < edits; ++e) {
      const size_t at = next() % text.size();
      switch (next() % 3) {
        case 0: text.erase(at, 1 + next() % 8); break;
        case 1: text.insert(at, 1, alphabet[next() % alphabet.size()]); break;
        default: text[at] = alphabet[next() % alphabet.size()]; break;
      }
      if (text.empty()) text.push_back('x');
    }
    (accepts(text) ? accepted : rejected)++;
  }
  return {accepted, rejected};
}

}  // namespace relief::test
