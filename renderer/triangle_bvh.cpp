// Building the plain triangle BVH (see triangle_bvh.h).
#include "renderer/triangle_bvh.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace relief {

constexpr uint32_t kLeafTriangles = 4;

TriangleBvh::TriangleBvh(std::vector<glm::vec3> corners, std::vector<uint32_t> ids) {
  const uint32_t n = uint32_t(ids.size());
  if (n == 0) return;
  std::vector<glm::vec3> centroids(n);
  for (uint32_t i = 0; i < n; ++i)
    centroids[i] = (corners[3 * size_t(i)] + corners[3 * size_t(i) + 1] + corners[3 * size_t(i) + 2]) / 3.0f;
  // build() reorders one permutation in place; corners and ids follow it once at the end.
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  nodes_.reserve(2 * size_t(n) / kLeafTriangles + 1);
  build(0, n, order, corners, centroids);
  corners_.resize(corners.size());
  ids_.resize(n);
  for (uint32_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) corners_[3 * size_t(i) + c] = corners[3 * size_t(order[i]) + c];
    ids_[i] = ids[order[i]];
  }
}

uint32_t TriangleBvh::build(uint32_t first, uint32_t end, std::vector<uint32_t>& order,
                            const std::vector<glm::vec3>& corners, const std::vector<glm::vec3>& centroids) {
  const uint32_t index = uint32_t(nodes_.size());
  nodes_.emplace_back();
  glm::vec3 lo(INFINITY), hi(-INFINITY), clo(INFINITY), chi(-INFINITY);
  for (uint32_t i = first; i < end; ++i) {
    for (int c = 0; c < 3; ++c) lo = glm::min(lo, corners[3 * size_t(order[i]) + c]), hi = glm::max(hi, corners[3 * size_t(order[i]) + c]);
    clo = glm::min(clo, centroids[order[i]]), chi = glm::max(chi, centroids[order[i]]);
  }
  // A little slack so a triangle lying in a box face is never excluded by the box's rounding.
  const glm::vec3 pad = 1e-5f * (glm::abs(lo) + glm::abs(hi) + (hi - lo)) + 1e-30f;
  nodes_[index].lo = lo - pad, nodes_[index].hi = hi + pad;
  const glm::vec3 span = chi - clo;
  const int axis = span.x >= span.y && span.x >= span.z ? 0 : span.y >= span.z ? 1 : 2;
  if (end - first <= kLeafTriangles || !(span[axis] > 0.0f)) {
    nodes_[index].first = first, nodes_[index].count = end - first;
    return index;
  }
  // Median split on the widest centroid axis: balanced, so the depth stays under the stack of
  // forEach. Ties are broken by triangle index, which keeps the build deterministic.
  const uint32_t mid = first + (end - first) / 2;
  std::nth_element(order.begin() + first, order.begin() + mid, order.begin() + end, [&](uint32_t a, uint32_t b) {
    return centroids[a][axis] < centroids[b][axis] || (centroids[a][axis] == centroids[b][axis] && a < b);
  });
  build(first, mid, order, corners, centroids);
  const uint32_t right = build(mid, end, order, corners, centroids);
  nodes_[index].right = right;
  return index;
}

}  // namespace relief
