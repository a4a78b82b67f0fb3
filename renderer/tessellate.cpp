// Tessellation of RenderMan quadrics into input triangle meshes (see tessellate.h).
#include "renderer/tessellate.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <numbers>
#include <unordered_map>

namespace relief {

Mesh tessellateSphere(float radius, float zmin, float zmax, float thetamaxDeg, int nu, int nv,
                      const glm::mat4& worldFromObject) {
  Mesh mesh;
  nu = std::max(nu, 1);
  nv = std::max(nv, 1);
  const float r = std::fabs(radius);
  if (r == 0.0f) return mesh;
  // A negative radius (RI: x = r cos(phi) cos(theta), ...) is the sphere turned half a turn about
  // z, with the same z range and orientation: u starts at -x. (It was taken as |radius|.)
  const float phase = radius < 0.0f ? std::numbers::pi_v<float> : 0.0f;
  const float thetamax = std::clamp(thetamaxDeg, -360.0f, 360.0f) * std::numbers::pi_v<float> / 180.0f;
  const bool fullTurn = std::fabs(thetamaxDeg) >= 360.0f;
  // Latitudes of zmin/zmax; exactly +-pi/2 at the poles so the pole test below is exact.
  auto latitude = [r](float z) {
    if (z <= -r) return -std::numbers::pi_v<float> / 2;
    if (z >= r) return std::numbers::pi_v<float> / 2;
    return std::asin(z / r);
  };
  // v runs from zmin to zmax as given (RI: phi from asin(zmin/r) to asin(zmax/r)); swapped bounds
  // run it downward, which turns the sphere inside-out like the other quadrics.
  const float lat0 = latitude(zmin), lat1 = latitude(zmax);
  constexpr float kHalfPi = std::numbers::pi_v<float> / 2;
  const bool pole0 = std::fabs(lat0) == kHalfPi, pole1 = std::fabs(lat1) == kHalfPi;

  const glm::mat3 linear(worldFromObject);
  const glm::mat3 normalFromObject = glm::transpose(glm::inverse(linear));
  const bool flip = glm::determinant(linear) < 0.0f;

  // RI spec, Quadrics: "giving a negative thetamax ... will turn the quadric inside-out". The
  // normal is dP/du x dP/dv, which a clockwise sweep turns inward, as for the other quadrics.
  const bool insideOut = (thetamax < 0.0f) != (lat0 > lat1);

  const int rowLength = nu + 1;
  mesh.P.reserve(size_t(rowLength) * (nv + 1));
  for (int j = 0; j <= nv; ++j) {
    const float v = float(j) / float(nv);
    const float lat = j == 0 ? lat0 : j == nv ? lat1 : lat0 + v * (lat1 - lat0);
    const bool pole = (j == 0 && pole0) || (j == nv && pole1);
    const float cosLat = pole ? 0.0f : std::cos(lat);
    const float z = pole ? (lat > 0.0f ? r : -r) : r * std::sin(lat);
    for (int i = 0; i <= nu; ++i) {
      const float u = float(i) / float(nu);
      const size_t seamSource = size_t(j) * rowLength;  // i == 0 of this row
      if (i == nu && fullTurn) {
        // Same position and normal as u = 0, bit for bit, so the seam cannot crack.
        mesh.P.push_back(mesh.P[seamSource]);
        mesh.N.push_back(mesh.N[seamSource]);
      } else {
        const float phi = phase + u * thetamax;
        const glm::vec3 pObject(r * cosLat * std::cos(phi), r * cosLat * std::sin(phi), z);
        mesh.P.push_back(glm::vec3(worldFromObject * glm::vec4(pObject, 1.0f)));
        mesh.N.push_back(glm::normalize(normalFromObject * (pObject / (insideOut ? -r : r))));
      }
      // The surface's derivatives (RI: u = phi / thetamax, v along the latitude from zmin to
      // zmax); a seam's copies are averaged into one value by smoothSurfaceDerivatives.
      const float phi = phase + u * thetamax, sinLat = pole ? (lat > 0.0f ? 1.0f : -1.0f) : std::sin(lat);
      const glm::vec3 du(-thetamax * r * cosLat * std::sin(phi), thetamax * r * cosLat * std::cos(phi), 0.0f);
      const glm::vec3 dv = (lat1 - lat0) * r * glm::vec3(-sinLat * std::cos(phi), -sinLat * std::sin(phi), cosLat);
      mesh.dPdu.push_back(linear * du);
      mesh.dPdv.push_back(linear * dv);
      mesh.uv.emplace_back(u, v);
    }
  }
  mesh.st = mesh.uv;

  // Winding: dP/du x dP/dv, so (00, 10, 11) and (00, 11, 01) face out in object space (in for a
  // negative sweep); a mirroring worldFromObject reverses the winding, which the flip undoes.
  auto addTriangle = [&](uint32_t a, uint32_t b, uint32_t c) {
    mesh.indices.push_back(a);
    mesh.indices.push_back(flip ? c : b);
    mesh.indices.push_back(flip ? b : c);
  };
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const uint32_t v00 = uint32_t(j * rowLength + i), v10 = v00 + 1;
      const uint32_t v01 = v00 + uint32_t(rowLength), v11 = v01 + 1;
      addTriangle(v00, v10, v11);
      addTriangle(v00, v11, v01);
    }
  }
  return mesh;
}

void smoothSurfaceDerivatives(Mesh& mesh) {
  const size_t n = mesh.P.size();
  // The surface's own derivatives, where the tessellator gave them; else the facets'.
  const bool exact = mesh.dPdu.size() == n && mesh.dPdv.size() == n;
  std::vector<glm::vec3> givenU, givenV;
  if (exact) givenU = std::move(mesh.dPdu), givenV = std::move(mesh.dPdv);
  mesh.dPdu.assign(n, glm::vec3(0.0f));
  mesh.dPdv.assign(n, glm::vec3(0.0f));
  if (!exact && mesh.uv.size() != n) return;
  // Vertices by position and normal bits: a seam's copies and a pole's are one group.
  struct Key {
    std::array<uint32_t, 6> bits;
    bool operator==(const Key& o) const { return bits == o.bits; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      uint64_t h = 0x9E3779B97F4A7C15ull;
      for (uint32_t b : k.bits) h = (h ^ b) * 0x100000001B3ull;
      return size_t(h);
    }
  };
  std::unordered_map<Key, uint32_t, KeyHash> groupOf;
  std::vector<uint32_t> group(n);
  for (size_t i = 0; i < n; ++i) {
    const glm::vec3 nrm = mesh.N.size() == n ? mesh.N[i] : glm::vec3(0.0f);
    const Key key{{std::bit_cast<uint32_t>(mesh.P[i].x), std::bit_cast<uint32_t>(mesh.P[i].y), std::bit_cast<uint32_t>(mesh.P[i].z),
                   std::bit_cast<uint32_t>(nrm.x), std::bit_cast<uint32_t>(nrm.y), std::bit_cast<uint32_t>(nrm.z)}};
    group[i] = groupOf.try_emplace(key, uint32_t(groupOf.size())).first->second;
  }
  std::vector<glm::dvec3> sumU(groupOf.size(), glm::dvec3(0.0)), sumV(groupOf.size(), glm::dvec3(0.0));
  std::vector<uint32_t> count(groupOf.size(), 0);
  if (exact) {
    // Copies of one point (a seam's, a pole's) take their mean: at a pole each copy's dPdv points
    // along its own meridian, and displaced along them the pole would open.
    for (size_t i = 0; i < n; ++i) {
      const glm::vec3 du = givenU[i], dv = givenV[i];
      if (!std::isfinite(du.x + du.y + du.z + dv.x + dv.y + dv.z)) continue;
      sumU[group[i]] += glm::dvec3(du), sumV[group[i]] += glm::dvec3(dv), ++count[group[i]];
    }
  }
  for (uint32_t t = 0; !exact && t < mesh.numTriangles(); ++t) {
    const uint32_t* idx = &mesh.indices[3 * size_t(t)];
    const glm::vec3 e1 = mesh.P[idx[1]] - mesh.P[idx[0]], e2 = mesh.P[idx[2]] - mesh.P[idx[0]];
    const glm::vec2 d1 = mesh.uv[idx[1]] - mesh.uv[idx[0]], d2 = mesh.uv[idx[2]] - mesh.uv[idx[0]];
    const float det = d1.x * d2.y - d1.y * d2.x;
    // Degenerate relative to the map's own scale (poles; NURBS knots may span 1e-5).
    if (!(std::fabs(det) > 1e-6f * glm::length(d1) * glm::length(d2)) || glm::length(glm::cross(e1, e2)) == 0.0f)
      continue;
    const glm::vec3 du = (e1 * d2.y - e2 * d1.y) / det, dv = (e2 * d1.x - e1 * d2.x) / det;
    if (!std::isfinite(du.x + du.y + du.z + dv.x + dv.y + dv.z)) continue;
    for (int c = 0; c < 3; ++c) {
      const uint32_t g = group[idx[c]];
      sumU[g] += glm::dvec3(du), sumV[g] += glm::dvec3(dv), ++count[g];
    }
  }
  for (size_t i = 0; i < n; ++i) {
    const uint32_t g = group[i];
    if (!count[g]) continue;
    mesh.dPdu[i] = glm::vec3(sumU[g] / double(count[g]));
    mesh.dPdv[i] = glm::vec3(sumV[g] / double(count[g]));
  }
}

}  // namespace relief
