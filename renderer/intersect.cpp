// Watertight ray/triangle intersection (see intersect.h).
#include "renderer/intersect.h"

#include <cmath>
#include <utility>

namespace relief {

WatertightRay::WatertightRay(const Ray& ray) : origin(ray.origin) {
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
}

bool intersectTriangle(const WatertightRay& ray, const glm::vec3& a, const glm::vec3& b,
                       const glm::vec3& c, float tMin, float tMax, TriangleHit& hit) {
  const glm::vec3 A = a - ray.origin, B = b - ray.origin, C = c - ray.origin;
  const float ax = A[ray.kx] - ray.sx * A[ray.kz], ay = A[ray.ky] - ray.sy * A[ray.kz];
  const float bx = B[ray.kx] - ray.sx * B[ray.kz], by = B[ray.ky] - ray.sy * B[ray.kz];
  const float cx = C[ray.kx] - ray.sx * C[ray.kz], cy = C[ray.ky] - ray.sy * C[ray.kz];
  float u = cx * by - cy * bx;
  float v = ax * cy - ay * cx;
  float w = bx * ay - by * ax;
  // An exact zero may be a rounding artefact deciding which of two neighbours owns the ray; redo
  // the 2x2 determinants in double, where the products of floats are exact.
  if (u == 0.0f || v == 0.0f || w == 0.0f) {
    u = float(double(cx) * double(by) - double(cy) * double(bx));
    v = float(double(ax) * double(cy) - double(ay) * double(cx));
    w = float(double(bx) * double(ay) - double(by) * double(ax));
  }
  if ((u < 0.0f || v < 0.0f || w < 0.0f) && (u > 0.0f || v > 0.0f || w > 0.0f)) return false;
  const float det = u + v + w;
  if (det == 0.0f || !std::isfinite(det)) return false;
  const float az = ray.sz * A[ray.kz], bz = ray.sz * B[ray.kz], cz = ray.sz * C[ray.kz];
  const float T = u * az + v * bz + w * cz;
  const float invDet = 1.0f / det;
  const float t = T * invDet;
  if (!(t > tMin && t < tMax)) return false;
  hit.t = t;
  hit.b0 = u * invDet;
  hit.b1 = v * invDet;
  hit.b2 = w * invDet;
  return true;
}

}  // namespace relief
