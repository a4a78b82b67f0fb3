// Tessellation of RenderMan quadrics into input triangle meshes (see tessellate.h).
#include "renderer/tessellate.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace relief {

Mesh tessellateSphere(float radius, float zmin, float zmax, float thetamaxDeg, int nu, int nv,
                      const glm::mat4& worldFromObject) {
  Mesh mesh;
  nu = std::max(nu, 1);
  nv = std::max(nv, 1);
  const float r = std::fabs(radius);
  if (r == 0.0f) return mesh;
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
        const float phi = u * thetamax;
        const glm::vec3 pObject(r * cosLat * std::cos(phi), r * cosLat * std::sin(phi), z);
        mesh.P.push_back(glm::vec3(worldFromObject * glm::vec4(pObject, 1.0f)));
        mesh.N.push_back(glm::normalize(normalFromObject * (pObject / (insideOut ? -r : r))));
      }
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

}  // namespace relief
