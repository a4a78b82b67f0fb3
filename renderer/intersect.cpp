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

}  // namespace relief
