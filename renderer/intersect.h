// Watertight ray/triangle intersection (Woop, Benthin and Wald 2013, "Watertight Ray/Triangle
// Intersection"). Used by the grid accelerator and by geometry tests as the brute-force reference.
//
// Why watertight: the crack-free subdivision (subdivide.h) makes neighbouring micro-triangles share
// their edge vertices bit for bit; this test evaluates a shared edge's edge function from the same
// two sheared vertices on both sides (negated exactly), so a ray can never slip between them.
#pragma once

#include <cmath>

#include <glm/glm.hpp>

#include "renderer/accel.h"

namespace relief {

// Per-ray set-up: the axis permutation and shear that map the ray onto +z through the origin.
struct WatertightRay {
  explicit WatertightRay(const Ray& ray);
  int kx, ky, kz;
  float sx, sy, sz;
  float ox, oy, oz;  // origin[kx], origin[ky], origin[kz]
};

struct TriangleHit {
  float t;
  float b0, b1, b2;  // barycentric weights of a, b, c
};

// Intersects triangle (a, b, c) from either side. Returns true with `hit` filled when the ray hits
// it at tMin < t < tMax. Zero-area (or edge-on) triangles never hit. Never produces NaN for finite
// input.
// Inline: it is the innermost call of every traversal (a quarter of a render's time), and the
// per-ray permutation and shear then stay in registers across a voxel's triangles.
inline bool intersectTriangle(const WatertightRay& ray, const glm::vec3& a, const glm::vec3& b,
                              const glm::vec3& c, float tMin, float tMax, TriangleHit& hit) {
  // The permuted components straight from the vertices: the same subtractions as translating the
  // whole vertices first, without building vectors that runtime indices would force into memory.
  const float Az = a[ray.kz] - ray.oz, Bz = b[ray.kz] - ray.oz, Cz = c[ray.kz] - ray.oz;
  const float ax = (a[ray.kx] - ray.ox) - ray.sx * Az, ay = (a[ray.ky] - ray.oy) - ray.sy * Az;
  const float bx = (b[ray.kx] - ray.ox) - ray.sx * Bz, by = (b[ray.ky] - ray.oy) - ray.sy * Bz;
  const float cx = (c[ray.kx] - ray.ox) - ray.sx * Cz, cy = (c[ray.ky] - ray.oy) - ray.sy * Cz;
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
  const float az = ray.sz * Az, bz = ray.sz * Bz, cz = ray.sz * Cz;
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
