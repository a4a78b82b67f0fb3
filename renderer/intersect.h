// Watertight ray/triangle intersection (Woop, Benthin and Wald 2013, "Watertight Ray/Triangle
// Intersection"). Used by the grid accelerator and by geometry tests as the brute-force reference.
//
// Why watertight: the crack-free subdivision (subdivide.h) makes neighbouring micro-triangles share
// their edge vertices bit for bit; this test evaluates a shared edge's edge function from the same
// two sheared vertices on both sides (negated exactly), so a ray can never slip between them.
#pragma once

#include <glm/glm.hpp>

#include "renderer/accel.h"

namespace relief {

// Per-ray set-up: the axis permutation and shear that map the ray onto +z through the origin.
struct WatertightRay {
  explicit WatertightRay(const Ray& ray);
  glm::vec3 origin;
  int kx, ky, kz;
  float sx, sy, sz;
};

struct TriangleHit {
  float t;
  float b0, b1, b2;  // barycentric weights of a, b, c
};

// Intersects triangle (a, b, c) from either side. Returns true with `hit` filled when the ray hits
// it at tMin < t < tMax. Zero-area (or edge-on) triangles never hit. Never produces NaN for finite
// input.
bool intersectTriangle(const WatertightRay& ray, const glm::vec3& a, const glm::vec3& b,
                       const glm::vec3& c, float tMin, float tMax, TriangleHit& hit);

}  // namespace relief
