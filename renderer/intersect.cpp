// Watertight ray/triangle intersection (see intersect.h).
#include "renderer/intersect.h"

#include <cmath>
#include <utility>

namespace relief {

WatertightRay::WatertightRay(const Ray& ray) {
  const glm::vec3 d = ray.direction;
  const glm::vec3 ad = glm::abs(d);
  kz = ad.x > ad.y ? (ad.x > ad.z ? 0 : 2) : (ad.y > ad.z ? 1 : 2);
  kx = (kz + 1) % 3;
  ky = (kx + 1) % 3;
  // Keep the winding of the projected triangle: swapping x and y undoes the mirror of a negative z.
  if (d[kz] < 0.0f) std::swap(kx, ky);
  sx = d[kx] / d[kz];
  sy = d[ky] / d[kz];
  sz = 1.0f / d[kz];
  ox = ray.origin[kx], oy = ray.origin[ky], oz = ray.origin[kz];
}

bool intersectTriangleDouble(const Ray& ray, const WatertightRay& wr, const glm::vec3& a,
                             const glm::vec3& b, const glm::vec3& c, float tMin, float tMax,
                             TriangleHit& hit) {
  const double dz = ray.direction[wr.kz];
  const double sx = double(ray.direction[wr.kx]) / dz, sy = double(ray.direction[wr.ky]) / dz;
  const double ox = wr.ox, oy = wr.oy, oz = wr.oz;
  const double Az = double(a[wr.kz]) - oz, Bz = double(b[wr.kz]) - oz, Cz = double(c[wr.kz]) - oz;
  const double ax = (double(a[wr.kx]) - ox) - sx * Az, ay = (double(a[wr.ky]) - oy) - sy * Az;
  const double bx = (double(b[wr.kx]) - ox) - sx * Bz, by = (double(b[wr.ky]) - oy) - sy * Bz;
  const double cx = (double(c[wr.kx]) - ox) - sx * Cz, cy = (double(c[wr.ky]) - oy) - sy * Cz;
  const double u = cx * by - cy * bx;
  const double v = ax * cy - ay * cx;
  const double w = bx * ay - by * ax;
  if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) return false;
  const double det = u + v + w;
  if (det == 0.0 || !std::isfinite(det)) return false;
  const double T = (u * Az + v * Bz + w * Cz) / dz;
  const double t = T / det;
  if (!(t > double(tMin) && t < double(tMax))) return false;
  const float tf = float(t);
  // Rounding to float must not move the hit outside the interval asked for.
  if (!(tf > tMin && tf < tMax)) return false;
  hit.t = tf;
  hit.b0 = float(u / det);
  hit.b1 = float(v / det);
  hit.b2 = float(w / det);
  return true;
}

bool faceNormal(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, glm::vec3* n) {
  const glm::dvec3 e1 = glm::dvec3(b) - glm::dvec3(a), e2 = glm::dvec3(c) - glm::dvec3(a);
  const glm::dvec3 cr = glm::cross(e1, e2);
  const double len = glm::length(cr);
  if (!(len > 0.0) || !std::isfinite(len)) return false;
  *n = glm::vec3(cr / len);
  return true;
}

}  // namespace relief
