// RenderMan's standard lights and surfaces in a Whitted ray tracer (see shading.h). Formulas follow
// the RenderMan Interface 3.2 standard shaders: diffuse() sums Cl * N.L, specular() sums
// Cl * pow(max(0, N.H), 1 / roughness) over lights within 90 degrees of N.
#include "renderer/shading.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "renderer/subdivide.h"

namespace relief {

namespace {

constexpr float kPi = 3.14159265358979f;
// Hits skipped in a row (culled back faces, transparent layers of a shadow ray) before giving up:
// bounds the work on pathological stacks of coincident surfaces.
constexpr int kMaxSkips = 64;

float smoothstep(float lo, float hi, float x) {
  if (lo >= hi) return x >= hi ? 1.0f : 0.0f;
  const float t = std::clamp((x - lo) / (hi - lo), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

bool isBlack(const glm::vec3& c) { return !(c.r > 0.0f || c.g > 0.0f || c.b > 0.0f); }

// Two unit vectors completing `n` to an orthonormal basis (branchless, Duff et al. 2017).
void basis(const glm::vec3& n, glm::vec3* a, glm::vec3* b) {
  const float sign = std::copysign(1.0f, n.z);
  const float s = -1.0f / (sign + n.z);
  const float t = n.x * n.y * s;
  *a = glm::vec3(1.0f + sign * n.x * n.x * s, sign * t, -sign * n.x);
  *b = glm::vec3(t, sign + n.y * n.y * s, -n.y);
}

}  // namespace

glm::vec2 stratifiedSample(int index, int count, glm::vec2 jitter) {
  if (count <= 1) return jitter;
  // The multiplier: the integer nearest count / phi that is coprime to count (1 always is).
  int k = std::max(1, int(std::lround(double(count) * 0.6180339887)));
  while (k > 1 && std::gcd(k, count) != 1) --k;
  const int sx = index % count;
  const int sy = int((int64_t(index) * k) % count);
  const float inv = 1.0f / float(count);
  return {std::min((float(sx) + jitter.x) * inv, 0.99999994f),
          std::min((float(sy) + jitter.y) * inv, 0.99999994f)};
}

struct Integrator::Surface {
  const Mesh* mesh = nullptr;
  const Material* material = nullptr;
  const Hit* hit = nullptr;
  glm::vec3 P{0};
  glm::vec3 N{0};    // outward shading normal (face normal where displaced)
  glm::vec3 Ng{0};   // outward geometric normal
  glm::vec3 Nf{0};   // shading normal turned toward the viewer
  glm::vec3 Ngf{0};  // geometric normal turned toward the viewer
  glm::vec3 V{0};    // unit, toward the viewer
  float epsilon = 0;  // offset clearing the float error in P (Integrator::epsilonAt)
  bool front = true;  // the ray arrived on the outward side
  glm::vec3 Cs{1.0f}, Os{1.0f};
};

namespace {
const Material kDefaultMaterial;
}

Integrator::Integrator(const Scene& scene, Accelerator& accel, const ShadingOptions& options)
    : scene_(scene), accel_(accel), options_(options) {
  options_.maxDepth = std::max(0, options_.maxDepth);
  if (!scene.lights.empty()) {
    lights_ = scene.lights;
  } else {
    // Readers that fill only the older fields.
    for (const DistantLight& d : scene.distantLights) {
      Light l;
      l.type = LightType::Distant;
      l.direction = -d.directionToLight;
      l.color = d.color;
      lights_.push_back(l);
    }
    if (scene.ambientColor != glm::vec3(0.0f)) {
      Light l;
      l.type = LightType::Ambient;
      l.color = scene.ambientColor;
      lights_.push_back(l);
    }
  }
  for (Light& l : lights_) {
    if (glm::length(l.direction) > 0.0f) l.direction = glm::normalize(l.direction);
    l.samples = std::max(1, l.samples);
  }
  allLights_.resize(lights_.size());
  std::iota(allLights_.begin(), allLights_.end(), 0u);

  for (const Material& m : scene.materials) {
    anyOneSided_ = anyOneSided_ || (!m.twoSided && m.type != SurfaceType::Glass);
    throughShadows_ = throughShadows_ || m.type == SurfaceType::Glass || !m.twoSided ||
                      m.opacity != glm::vec3(1.0f) || !m.castsShadows;
  }

  glm::vec3 lo(1e30f), hi(-1e30f);
  float bound = 0.0f;
  for (const Mesh& mesh : scene.meshes) {
    for (const glm::vec3& p : mesh.P) lo = glm::min(lo, p), hi = glm::max(hi, p);
    if (mesh.displacementIndex < scene.displacements.size())
      bound = std::max(bound, scene.displacements[mesh.displacementIndex].boundWorld);
  }
  const float extent = hi.x >= lo.x ? glm::length(hi - lo) + 2.0f * bound : 1.0f;
  sceneEpsilon_ = std::max(extent, 1e-3f) * 2e-5f;
  if (!std::isfinite(sceneEpsilon_)) sceneEpsilon_ = std::numeric_limits<float>::max();
}

float Integrator::epsilonAt(const glm::vec3& P, const glm::vec3& origin) const {
  const glm::vec3 a = glm::max(glm::abs(P), glm::abs(origin));
  const float local = std::max({a.x, a.y, a.z});
  if (!std::isfinite(local)) return sceneEpsilon_;
  return std::max(local * 0x1p-19f, std::min(sceneEpsilon_, local * 0x1p-13f));
}

glm::vec3 Integrator::surfaceColor(const Mesh& mesh, const Material& material, const Hit& hit) {
  if (mesh.Cs.empty() || hit.triangleIndex >= mesh.numTriangles()) return material.color;
  // Hit::bary holds for displaced hits too (the point the micro-geometry was displaced from, to 2^-16).
  const uint32_t* idx = &mesh.indices[3 * size_t(hit.triangleIndex)];
  const float b1 = std::clamp(hit.bary.x, 0.0f, 1.0f);
  const float b2 = std::clamp(hit.bary.y, 0.0f, 1.0f - b1);
  return (1.0f - b1 - b2) * mesh.Cs[idx[0]] + b1 * mesh.Cs[idx[1]] + b2 * mesh.Cs[idx[2]];
}

float Integrator::fresnel(float cosI, float etaRatio) {
  cosI = std::clamp(cosI, 0.0f, 1.0f);
  const float sin2T = etaRatio * etaRatio * (1.0f - cosI * cosI);
  if (sin2T >= 1.0f) return 1.0f;
  const float cosT = std::sqrt(1.0f - sin2T);
  const float rs = (etaRatio * cosI - cosT) / (etaRatio * cosI + cosT);
  const float rp = (cosI - etaRatio * cosT) / (cosI + etaRatio * cosT);
  return 0.5f * (rs * rs + rp * rp);
}

bool Integrator::refract(const glm::vec3& incident, const glm::vec3& n, float etaRatio,
                         glm::vec3* transmitted) {
  const float cosI = -glm::dot(incident, n);
  const float sin2T = etaRatio * etaRatio * (1.0f - cosI * cosI);
  if (sin2T >= 1.0f) return false;
  const float cosT = std::sqrt(1.0f - sin2T);
  *transmitted = glm::normalize(etaRatio * incident + (etaRatio * cosI - cosT) * n);
  return true;
}

bool Integrator::resolve(const Ray& ray, const Hit& hit, Surface* s) const {
  const Mesh& mesh = scene_.meshes[hit.meshIndex];
  const Material& material =
      mesh.materialIndex < scene_.materials.size() ? scene_.materials[mesh.materialIndex]
                                                   : kDefaultMaterial;
  s->mesh = &mesh;
  s->material = &material;
  s->hit = &hit;
  s->P = hit.P;
  s->epsilon = epsilonAt(hit.P, ray.origin);
  s->Ng = hit.Ng;
  s->N = hit.Ng;
  // Displaced surfaces shade with the micro-triangle's face normal (as in the paper): it carries
  // the displaced detail, which interpolated input normals would not. A shader that sets N other
  // than as the displaced surface's own normal (a bump) has that N as the shading normal
  // (language.md §5), evaluated at the hit: it is not stored with the cached geometry.
  const bool displaced = options_.displaced && mesh.displacementIndex < scene_.displacements.size() &&
                         scene_.displacements[mesh.displacementIndex].shader != nullptr;
  bool oriented = false;  // N and Ng already face the side the surface's orientation gives
  if (displaced) {
    const Displacement& disp = scene_.displacements[mesh.displacementIndex];
    glm::vec3 n;
    if (disp.shader->shader().ownNormal() &&
        displacedShadingNormal(mesh, hit.triangleIndex, disp, hit.bary, &n)) {
      // A shader given normals on the orientation's side (cornerData) puts its N there too.
      s->N = n;
      oriented = shaderNormalsReversed(mesh, disp);
      // The shader's N faces as the input normal does; where given normals oppose the winding,
      // they define the outside, as for undisplaced surfaces below.
      if (glm::dot(s->N, s->Ng) < 0.0f) s->Ng = -s->Ng;
    }
  }
  if (!displaced && !mesh.N.empty() && hit.triangleIndex < mesh.numTriangles()) {
    const uint32_t* idx = &mesh.indices[3 * size_t(hit.triangleIndex)];
    const float b1 = hit.bary.x, b2 = hit.bary.y;
    const glm::vec3 n = (1.0f - b1 - b2) * mesh.N[idx[0]] + b1 * mesh.N[idx[1]] + b2 * mesh.N[idx[2]];
    const float len = glm::length(n);
    if (len > 0.0f && std::isfinite(len)) {
      s->N = n / len;
      // Given normals define the outside: keep the geometric normal on their side.
      if (glm::dot(s->N, s->Ng) < 0.0f) s->Ng = -s->Ng;
    }
  }
  if (material.reverseOrientation && !oriented) s->N = -s->N, s->Ng = -s->Ng;
  const glm::vec3 d = glm::normalize(ray.direction);
  s->V = -d;
  s->front = glm::dot(d, s->Ng) < 0.0f;
  // One-sided surfaces are invisible from behind, behind being the side the winding and
  // orientation give (RI spec, Sides), whatever normals the primitive supplies for shading; glass
  // needs its inside, so it never culls.
  if (!material.twoSided && material.type != SurfaceType::Glass) {
    const glm::vec3 outward = material.reverseOrientation ? -hit.Ng : hit.Ng;
    if (!(glm::dot(d, outward) < 0.0f)) return false;
  }
  s->Ngf = s->front ? s->Ng : -s->Ng;
  s->Nf = s->front ? s->N : -s->N;
  s->Cs = surfaceColor(mesh, material, hit);
  s->Os = glm::clamp(material.opacity, glm::vec3(0.0f), glm::vec3(1.0f));
  return true;
}

std::optional<Hit> Integrator::findHit(Ray ray) const {
  if (!anyOneSided_) return accel_.intersect(ray);
  for (int i = 0; i < kMaxSkips; ++i) {
    std::optional<Hit> hit = accel_.intersect(ray);
    if (!hit) return hit;
    Surface s;
    if (resolve(ray, *hit, &s)) return hit;
    // Past the culled face exactly: hits are found for t in (tMin, tMax), and the same ray meets
    // the same triangle at the same t, so it is not found again. Skipping an epsilon more (2e-5
    // of the scene) lost front faces just behind a back face: a band where two sheets cross.
    ray.tMin = hit->t;
  }
  return std::nullopt;
}

glm::vec3 Integrator::transmittance(const Ray& ray, RenderStats* stats) const {
  ++stats->shadowRays;
  if (!throughShadows_) return accel_.occluded(ray) ? glm::vec3(0.0f) : glm::vec3(1.0f);
  glm::vec3 through(1.0f);
  Ray r = ray;
  for (int i = 0; i < kMaxSkips; ++i) {
    const std::optional<Hit> hit = accel_.intersect(r);
    if (!hit) return through;
    Surface s;
    if (resolve(r, *hit, &s)) {
      const Material& m = *s.material;
      if (!m.castsShadows) {
        // invisible to shadow rays: Attribute "visibility" "int transmission" [0]
      } else if (m.opaqueShadows) {
        return glm::vec3(0.0f);  // "string transmission" ["opaque"]: whatever its opacity
      } else if (m.type == SurfaceType::Glass) {
        // Light crossing the interface: what Fresnel lets through, tinted once per object (on the
        // way in), as a camera ray refracted through it would be. The bending is ignored, as in
        // every Whitted renderer: shadows of glass are coloured, not focused. Since the unbent
        // ray meets the far side at the outside angle, every interface is taken from outside
        // (reflectance is the same both ways along a refracted path), so no false total internal
        // reflection blackens the shadow.
        const float cosI = std::abs(glm::dot(s.V, s.Ng));
        through *= m.Kt * (1.0f - fresnel(cosI, 1.0f / std::max(m.eta, 1e-4f))) *
                   (s.front ? glm::clamp(m.transmitColor, glm::vec3(0.0f), glm::vec3(1.0f))
                            : glm::vec3(1.0f));
      } else {
        through *= glm::vec3(1.0f) - s.Os;
      }
      if (isBlack(through)) return glm::vec3(0.0f);
    }
    // Past this surface exactly, as findHit skips a culled face: an epsilon more lost a second
    // surface just behind it (where two transparent sheets cross, one shadowed for the other).
    r.tMin = hit->t;
    if (!(r.tMin < r.tMax)) return through;
  }
  return glm::vec3(0.0f);
}

glm::vec3 Integrator::ambient(const Surface& s) const {
  const std::vector<uint32_t>& ids = lightsOf(*s.mesh);
  glm::vec3 sum(0.0f);
  for (uint32_t id : ids)
    if (id < lights_.size() && lights_[id].type == LightType::Ambient) sum += lights_[id].color;
  return sum;
}

void Integrator::illuminate(const Surface& s, uint64_t seed, RenderStats* stats,
                            std::vector<LightSample>* out) const {
  out->clear();
  const std::vector<uint32_t>& ids = lightsOf(*s.mesh);
  // Shadow rays start off the side of the surface the light is on (the geometric side: a smooth
  // shading normal may lean over the horizon of the true surface).
  auto shadow = [&](const glm::vec3& L, float distance, const glm::vec3& Cl, bool traced) {
    if (isBlack(Cl)) return;
    if (!traced) {
      out->push_back({L, Cl});
      return;
    }
    const float side = glm::dot(s.Ng, L) >= 0.0f ? 1.0f : -1.0f;
    Ray r;
    r.origin = s.P + side * s.epsilon * s.Ng;
    r.direction = L;
    r.tMin = 0.0f;
    r.tMax = distance - s.epsilon;
    if (!(r.tMax > 0.0f)) return;
    const glm::vec3 through = transmittance(r, stats);
    if (!isBlack(through)) out->push_back({L, Cl * through});
  };
  for (uint32_t id : ids) {
    if (id >= lights_.size()) continue;
    const Light& light = lights_[id];
    switch (light.type) {
      case LightType::Ambient:
        break;
      case LightType::Distant: {
        const glm::vec3 L = -light.direction;
        if (glm::dot(s.Nf, L) > 0.0f) shadow(L, 1e30f, light.color, light.shadows);
        break;
      }
      case LightType::Point:
      case LightType::Spot: {
        const glm::vec3 toLight = light.position - s.P;
        const float d2 = glm::dot(toLight, toLight);
        if (!(d2 > 0.0f)) break;
        const float d = std::sqrt(d2);
        const glm::vec3 L = toLight / d;
        if (!(glm::dot(s.Nf, L) > 0.0f)) break;
        float atten = 1.0f / d2;
        if (light.type == LightType::Spot) {
          // RenderMan's spotlight: cosine-power beam, smoothstep edge over conedeltaangle.
          const float cosAngle = glm::dot(-L, light.direction);
          if (!(cosAngle > 0.0f)) break;
          atten *= std::pow(cosAngle, light.beamDistribution) *
                   smoothstep(std::cos(light.coneAngle),
                              std::cos(light.coneAngle - light.coneDeltaAngle), cosAngle);
        }
        shadow(L, d, light.color * atten, light.shadows);
        break;
      }
      case LightType::Area: {
        glm::vec3 normal;
        float area;
        glm::vec3 diskA(0.0f), diskB(0.0f);
        if (light.shape == AreaShape::Rectangle) {
          const glm::vec3 c = glm::cross(light.edgeU, light.edgeV);
          area = glm::length(c);
          normal = area > 0.0f ? c / area : glm::vec3(0, 0, 1);
        } else {
          normal = light.direction;
          area = kPi * light.radius * light.radius;
          basis(normal, &diskA, &diskB);
        }
        if (!(area > 0.0f)) break;
        const int n = light.samples;
        const uint64_t lightSeed = mix64(seed ^ (uint64_t(id) * 0x9e3779b97f4a7c15ull));
        for (int i = 0; i < n; ++i) {
          const uint64_t r = mix64(lightSeed + uint64_t(i));
          const glm::vec2 u = stratifiedSample(i, n, {unitFloat(r), unitFloat(mix64(r))});
          glm::vec3 q;
          if (light.shape == AreaShape::Rectangle) {
            q = light.corner + u.x * light.edgeU + u.y * light.edgeV;
          } else {
            const float radius = light.radius * std::sqrt(u.x), phi = 2.0f * kPi * u.y;
            q = light.position + radius * (std::cos(phi) * diskA + std::sin(phi) * diskB);
          }
          const glm::vec3 toLight = q - s.P;
          const float d2 = glm::dot(toLight, toLight);
          if (!(d2 > 0.0f)) continue;
          const float d = std::sqrt(d2);
          const glm::vec3 L = toLight / d;
          if (!(glm::dot(s.Nf, L) > 0.0f)) continue;
          // Each sample is a point light of 1/n of the intensity, emitting from the front face
          // (edgeU x edgeV, or the disk's normal) with Lambert's cosine: seen head-on from afar,
          // the light acts as a point light of its intensity.
          const float cosLight = -glm::dot(normal, L);
          if (!(cosLight > 0.0f)) continue;
          shadow(L, d, light.color * (cosLight / (float(n) * d2)), light.shadows);
        }
        break;
      }
    }
  }
}

// Below this weight a secondary ray could change the pixel by at most a quarter of an 8-bit step
// (for radiance up to 1), so it is not traced: without the cut, glass in front of a mirror spawns
// two rays per hit and --max-depth 100 took minutes for a thumbnail (the tree is exponential in
// depth, its total weight is not).
constexpr float kMinRayWeight = 1.0f / 1024.0f;
// Partly transparent surfaces one ray composites at most (each continues the ray by recursion, so
// this bounds the stack, also under ASan); beyond, what lies behind is left out. Layers of Os 0.05
// reach the weight cut above at about 135, of Os 0.5 at 10.
constexpr int kMaxTransparentLayers = 256;

glm::vec3 Integrator::shade(const Ray& ray, const Surface& s, int depth, uint64_t seed,
                            RenderStats* stats, float weight, glm::vec3* opacity, int layers) const {
  const Material& m = *s.material;
  if (opacity) *opacity = m.type == SurfaceType::Glass ? glm::vec3(1.0f) : s.Os;

  std::vector<LightSample> lights;
  const bool needsLights = m.type != SurfaceType::Constant && (m.Kd != 0.0f || m.Ks != 0.0f);
  if (needsLights) illuminate(s, seed ^ (uint64_t(depth) << 56), stats, &lights);
  auto diffuse = [&] {
    glm::vec3 c(0.0f);
    for (const LightSample& l : lights) c += l.Cl * std::max(0.0f, glm::dot(s.Nf, l.L));
    return c;
  };
  auto specular = [&] {
    glm::vec3 c(0.0f);
    const float exponent = 1.0f / std::max(m.roughness, 1e-4f);
    for (const LightSample& l : lights) {
      const glm::vec3 H = glm::normalize(l.L + s.V);
      c += l.Cl * std::pow(std::max(0.0f, glm::dot(s.Nf, H)), exponent);
    }
    return c;
  };
  const bool canRecurse = depth < options_.maxDepth;
  // A secondary ray whose contribution is scaled by `factor` (its largest component).
  auto worth = [&](float factor) { return canRecurse && weight * factor >= kMinRayWeight; };
  auto trace = [&](const glm::vec3& origin, const glm::vec3& direction, uint64_t* counter, float factor) {
    ++*counter;
    Ray r;
    r.origin = origin;
    r.direction = direction;
    r.tMin = 0.0f;
    r.tMax = 1e30f;
    return radianceAt(r, depth + 1, mix64(seed + uint64_t(depth) + 1), stats, nullptr, weight * factor);
  };
  auto largest = [](const glm::vec3& v) { return std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)}); };
  const glm::vec3 I = -s.V;
  const glm::vec3 R = glm::normalize(I - 2.0f * glm::dot(I, s.Nf) * s.Nf);
  // Reflection rays leave from the viewer's side of the true surface.
  const glm::vec3 above = s.P + s.epsilon * s.Ngf;

  glm::vec3 Ci(0.0f);
  switch (m.type) {
    case SurfaceType::Matte:
      Ci = s.Cs * (m.Ka * ambient(s) + m.Kd * diffuse());
      break;
    case SurfaceType::Plastic:
      Ci = s.Cs * (m.Ka * ambient(s) + m.Kd * diffuse()) + m.specularColor * m.Ks * specular();
      break;
    case SurfaceType::Metal:
      Ci = s.Cs * (m.Ka * ambient(s) + m.Ks * specular());
      break;
    case SurfaceType::Mirror: {  // shinymetal, with a traced reflection for its environment map
      glm::vec3 reflected(0.0f);
      const float factor = std::fabs(m.Kr) * largest(s.Cs * s.Os);
      if (m.Kr != 0.0f && worth(factor)) reflected = trace(above, R, &stats->reflectionRays, factor);
      Ci = s.Cs * (m.Ka * ambient(s) + m.Ks * specular() + m.Kr * reflected);
      break;
    }
    case SurfaceType::Glass: {
      const float etaRatio = s.front ? 1.0f / std::max(m.eta, 1e-4f) : m.eta;
      const float cosI = std::clamp(glm::dot(s.V, s.Nf), 0.0f, 1.0f);
      const float kr = fresnel(cosI, etaRatio);
      glm::vec3 reflected(0.0f), transmitted(0.0f);
      if (m.Kr * kr > 0.0f && worth(m.Kr * kr)) reflected = trace(above, R, &stats->reflectionRays, m.Kr * kr);
      const glm::vec3 filter =
          s.front ? glm::clamp(m.transmitColor, glm::vec3(0.0f), glm::vec3(1.0f)) : glm::vec3(1.0f);
      glm::vec3 T;
      const float through = m.Kt * (1.0f - kr) * largest(filter);
      if (m.Kt * (1.0f - kr) > 0.0f && worth(through) && refract(I, s.Nf, etaRatio, &T))
        transmitted = trace(s.P - s.epsilon * s.Ngf, T, &stats->refractionRays, through);
      // As the classic glass shader: a faint ambient/diffuse body (Kd defaults to 0), highlights,
      // and Fresnel-weighted traced reflection and refraction.
      Ci = s.Cs * (m.Ka * ambient(s) + m.Kd * diffuse()) + m.Ks * m.specularColor * specular() +
           m.Kr * kr * reflected +
           m.Kt * (1.0f - kr) * filter * transmitted;
      return Ci;  // glass's opacity is its transmission
    }
    case SurfaceType::Constant:
      Ci = s.Cs;
      break;
  }
  Ci *= s.Os;
  if (s.Os != glm::vec3(1.0f) && weight * largest(glm::vec3(1.0f) - s.Os) >= kMinRayWeight &&
      layers < kMaxTransparentLayers) {
    // Partly transparent: composite what lies behind, continuing the same ray at the same depth
    // (RI: opacity is the hider's compositing; --max-depth counts reflections and refractions, and
    // at --max-depth 0 a layer of Os 0.5 had hidden everything behind it).
    // The same ray resumes exactly past this hit (hits are found in the open interval (tMin, tMax),
    // so it is not found again); skipping an epsilon more lost a surface just behind it.
    Ray behind = ray;
    behind.tMin = s.hit->t;
    glm::vec3 behindOpacity(0.0f);
    Ci += (glm::vec3(1.0f) - s.Os) * radianceAt(behind, depth, mix64(seed + 0x51ull), stats, nullptr,
                                                weight * largest(glm::vec3(1.0f) - s.Os),
                                                opacity ? &behindOpacity : nullptr, layers + 1);
    if (opacity) *opacity += (glm::vec3(1.0f) - s.Os) * behindOpacity;
  }
  return Ci;
}

glm::vec3 Integrator::radianceAt(const Ray& ray, int depth, uint64_t seed, RenderStats* stats,
                                 SampleResult* first, float weight, glm::vec3* opacity, int layers) const {
  if (opacity) *opacity = glm::vec3(0.0f);
  const std::optional<Hit> hit = findHit(ray);
  if (!hit) return glm::vec3(0.0f);
  Surface s;
  resolve(ray, *hit, &s);
  glm::vec3 own(1.0f);
  if (first) {
    first->depth = hit->t;
    first->normal = s.N;
    opacity = opacity ? opacity : &own;
  }
  const glm::vec3 c = shade(ray, s, depth, seed, stats, weight, opacity, layers);
  if (first) {
    first->hit = true;
    first->alpha = std::clamp((opacity->r + opacity->g + opacity->b) / 3.0f, 0.0f, 1.0f);
  }
  // A NaN from a degenerate input would otherwise spread through the filter to whole neighbourhoods.
  return std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b) ? c : glm::vec3(0.0f);
}

SampleResult Integrator::trace(const Ray& ray, uint64_t seed, RenderStats* stats) const {
  SampleResult result;
  result.color = radianceAt(ray, 0, seed, stats, &result);
  if (result.hit) ++stats->cameraHits;
  return result;
}

glm::vec3 Integrator::radiance(const Ray& ray, RenderStats* stats, bool* hit) const {
  const SampleResult r = trace(ray, 0, stats);
  if (hit) *hit = r.hit;
  return r.color;
}

}  // namespace relief
