// A plain binary BVH over whole input triangles, for the undisplaced triangles the contributor
// grid leaves out (contributor_grid.h, "outside"): big floors, walls and sky domes around a small
// displaced object. Keeping them out of the grid lets its voxels fit the displaced geometry, which
// is what the cache's laziness and budget work on. Built once, read-only afterwards (any thread).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "renderer/intersect.h"

namespace relief {

class TriangleBvh {
 public:
  // `corners` holds 3 world-space corners per triangle; `ids[i]` names triangle i in hits.
  TriangleBvh(std::vector<glm::vec3> corners, std::vector<uint32_t> ids);
  TriangleBvh() = default;

  bool empty() const { return ids_.empty(); }
  size_t size() const { return ids_.size(); }

  // Calls visit(id, a, b, c) for every triangle whose leaf box the ray segment [tMin, tMax()]
  // enters, nearest boxes first; tMax() is read again before each box, so a visitor that records
  // a hit narrows the search. visit returns true to stop (an any-hit query that found one).
  template <class TMax, class Visit>
  void forEach(const Ray& ray, float tMin, TMax tMax, Visit visit) const;

 private:
  struct Node {
    glm::vec3 lo, hi;
    uint32_t first = 0, count = 0;  // leaf: triangles [first, first + count); inner: count == 0
    uint32_t right = 0;             // inner: the second child (the first follows the node)
  };
  // Builds the node over triangles order[first, end) (and its subtree), reordering that range.
  uint32_t build(uint32_t first, uint32_t end, std::vector<uint32_t>& order,
                 const std::vector<glm::vec3>& corners, const std::vector<glm::vec3>& centroids);
  std::vector<Node> nodes_;
  std::vector<glm::vec3> corners_;  // 3 per triangle, in leaf order
  std::vector<uint32_t> ids_;       // in leaf order
};

template <class TMax, class Visit>
void TriangleBvh::forEach(const Ray& ray, float tMin, TMax tMax, Visit visit) const {
  if (nodes_.empty()) return;
  // + 0.0f turns -0 into +0, so a zero component gives +inf on both slabs alike (an origin on a
  // face then gives NaN, which the comparisons below ignore).
  const glm::vec3 inv = 1.0f / (ray.direction + 0.0f);
  auto enter = [&](const Node& n, float& tNear) {
    float t0 = tMin, t1 = tMax();
    for (int a = 0; a < 3; ++a) {
      float ta = (n.lo[a] - ray.origin[a]) * inv[a], tb = (n.hi[a] - ray.origin[a]) * inv[a];
      if (ta > tb) std::swap(ta, tb);
      // NaN (0 * inf on a face) must not exclude the box: the comparisons keep the other bound.
      t0 = ta > t0 ? ta : t0;
      t1 = tb < t1 ? tb : t1;
    }
    tNear = t0;
    return t0 <= t1 * (1.0f + 2e-6f);
  };
  uint32_t stack[64];
  int top = 0;
  float tNear = 0.0f;
  if (!enter(nodes_[0], tNear)) return;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    if (n.count > 0) {
      for (uint32_t i = n.first; i < n.first + n.count; ++i)
        if (visit(ids_[i], corners_[3 * size_t(i)], corners_[3 * size_t(i) + 1], corners_[3 * size_t(i) + 2]))
          return;
      continue;
    }
    const uint32_t a = uint32_t(&n - nodes_.data()) + 1, b = n.right;
    float ta = 0.0f, tb = 0.0f;
    const bool hitA = enter(nodes_[a], ta), hitB = enter(nodes_[b], tb);
    if (hitA && hitB) {
      // The farther child first on the stack, so the nearer is visited first.
      stack[top++] = ta <= tb ? b : a;
      stack[top++] = ta <= tb ? a : b;
    } else if (hitA) {
      stack[top++] = a;
    } else if (hitB) {
      stack[top++] = b;
    }
  }
}

}  // namespace relief
