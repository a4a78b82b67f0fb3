// Watertight ray/triangle intersection (Woop, Benthin and Wald 2013, "Watertight Ray/Triangle
// Intersection"). Used by the grid accelerator and by geometry tests as the brute-force reference.
//
// Why watertight: the crack-free subdivision (subdivide.h) makes neighbouring micro-triangles share
// their edge vertices bit for bit; this test evaluates a shared edge's edge function from the same
// two sheared vertices on both sides (negated exactly), so a ray can never slip between them.
#pragma once

#include <cmath>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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

// intersectTriangle in double precision, for huge triangles: a ground plane reaching 1e8 units
// leaves float edge functions and depths nothing of the ray origin's position (its ulp is 8 units),
// so the plane tore and vanished around a unit sphere. Differences of floats are exact in double
// and the products keep 53 bits, so such a triangle is hit to float precision at the hit point.
// Watertight as the float test: a shared edge's function comes from the same sheared vertices.
bool intersectTriangleDouble(const Ray& ray, const WatertightRay& wr, const glm::vec3& a,
                             const glm::vec3& b, const glm::vec3& c, float tMin, float tMax,
                             TriangleHit& hit);

// The unit normal of triangle (a, b, c) along (b - a) x (c - a), computed in double so that
// triangles of any size (edges of 1e20, whose cross product overflows a float) and any thinness
// get one; false for a degenerate or non-finite triangle.
bool faceNormal(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, glm::vec3* n);

// Four triangles' hits, lane k for the k-th triangle (valid where intersectTriangles4's mask says).
struct TriangleHits4 {
  float t[4], b0[4], b1[4], b2[4];
};

#if defined(__SSE2__)
// Four triangles' corners in SSE lanes, lane k for the k-th triangle: a[axis], b[axis], c[axis]
// hold the world x, y and z of corners a, b and c.
struct Corners4 {
  __m128 a[3], b[3], c[3];
};

// The lanes of four triangles given as corners v[lane][0..2].
inline Corners4 cornersOf(const glm::vec3 (&v)[4][3]) {
  Corners4 k;
  __m128* corner[3] = {k.a, k.b, k.c};
  for (int c = 0; c < 3; ++c)
    for (int axis = 0; axis < 3; ++axis)
      corner[c][axis] = _mm_setr_ps(v[0][c][axis], v[1][c][axis], v[2][c][axis], v[3][c][axis]);
  return k;
}

// intersectTriangle on four triangles at once. Each lane takes the same IEEE operations in the
// same order as the scalar test, so its verdict and hit are bit-identical to it: a BVH leaf or a
// sparse voxel tests a group of four in the time of about two. Returns the mask of lanes that hit;
// `undecided` gets the lanes whose edge functions have an exact zero, which the caller must test
// with intersectTriangle (it redoes them in double).
inline unsigned intersectTriangles4(const WatertightRay& ray, const Corners4& k, float tMin, float tMax,
                                    TriangleHits4& hits, unsigned& undecided) {
  const __m128 ox = _mm_set1_ps(ray.ox), oy = _mm_set1_ps(ray.oy), oz = _mm_set1_ps(ray.oz);
  const __m128 sx = _mm_set1_ps(ray.sx), sy = _mm_set1_ps(ray.sy), sz = _mm_set1_ps(ray.sz);
  const __m128 Az = _mm_sub_ps(k.a[ray.kz], oz);
  const __m128 Bz = _mm_sub_ps(k.b[ray.kz], oz);
  const __m128 Cz = _mm_sub_ps(k.c[ray.kz], oz);
  const __m128 ax = _mm_sub_ps(_mm_sub_ps(k.a[ray.kx], ox), _mm_mul_ps(sx, Az));
  const __m128 ay = _mm_sub_ps(_mm_sub_ps(k.a[ray.ky], oy), _mm_mul_ps(sy, Az));
  const __m128 bx = _mm_sub_ps(_mm_sub_ps(k.b[ray.kx], ox), _mm_mul_ps(sx, Bz));
  const __m128 by = _mm_sub_ps(_mm_sub_ps(k.b[ray.ky], oy), _mm_mul_ps(sy, Bz));
  const __m128 cx = _mm_sub_ps(_mm_sub_ps(k.c[ray.kx], ox), _mm_mul_ps(sx, Cz));
  const __m128 cy = _mm_sub_ps(_mm_sub_ps(k.c[ray.ky], oy), _mm_mul_ps(sy, Cz));
  const __m128 u = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
  const __m128 v = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
  const __m128 w = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
  const __m128 zero = _mm_setzero_ps();
  undecided = unsigned(_mm_movemask_ps(
      _mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(u, zero), _mm_cmpeq_ps(v, zero)), _mm_cmpeq_ps(w, zero))));
  // Ordered comparisons, false for NaN, as the scalar test's are.
  const __m128 negative = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(u, zero), _mm_cmplt_ps(v, zero)), _mm_cmplt_ps(w, zero));
  const __m128 positive = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(u, zero), _mm_cmpgt_ps(v, zero)), _mm_cmpgt_ps(w, zero));
  const __m128 det = _mm_add_ps(_mm_add_ps(u, v), w);
  // det != 0 and finite: |det| <= FLT_MAX is false for infinities and NaN.
  const __m128 absDet = _mm_andnot_ps(_mm_set1_ps(-0.0f), det);
  const __m128 detUsable = _mm_and_ps(_mm_cmpneq_ps(det, zero), _mm_cmple_ps(absDet, _mm_set1_ps(3.40282347e38f)));
  const __m128 T = _mm_add_ps(_mm_add_ps(_mm_mul_ps(u, _mm_mul_ps(sz, Az)), _mm_mul_ps(v, _mm_mul_ps(sz, Bz))),
                              _mm_mul_ps(w, _mm_mul_ps(sz, Cz)));
  const __m128 invDet = _mm_div_ps(_mm_set1_ps(1.0f), det);
  const __m128 t = _mm_mul_ps(T, invDet);
  const __m128 inRange = _mm_and_ps(_mm_cmpgt_ps(t, _mm_set1_ps(tMin)), _mm_cmplt_ps(t, _mm_set1_ps(tMax)));
  const __m128 hit = _mm_andnot_ps(_mm_and_ps(negative, positive), _mm_and_ps(detUsable, inRange));
  const unsigned mask = unsigned(_mm_movemask_ps(hit)) & ~undecided;
  if (mask) {
    _mm_storeu_ps(hits.t, t);
    _mm_storeu_ps(hits.b0, _mm_mul_ps(u, invDet));
    _mm_storeu_ps(hits.b1, _mm_mul_ps(v, invDet));
    _mm_storeu_ps(hits.b2, _mm_mul_ps(w, invDet));
  }
  return mask;
}
#endif

}  // namespace relief
