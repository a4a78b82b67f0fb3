// Grid traversal, voxel fills and hit reporting (see grid_accelerator.h).
#include "renderer/grid_accelerator.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <list>
#include <mutex>
#include <string_view>
#include <unordered_map>

#include "renderer/atomic_max.h"
#include "renderer/intersect.h"
#include "renderer/spin_mutex.h"
#include "renderer/ticks.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace relief {
namespace {

bool overlaps(const Bounds3& box, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 lo = glm::min(a, glm::min(b, c)), hi = glm::max(a, glm::max(b, c));
  return lo.x <= box.hi.x && box.lo.x <= hi.x && lo.y <= box.hi.y && box.lo.y <= hi.y &&
         lo.z <= box.hi.z && box.lo.z <= hi.z;
}

// Clips the ray to a box; false if it misses it within [t0, t1].
bool clipToBox(const glm::vec3& o, const glm::vec3& d, const glm::vec3& lo, const glm::vec3& hi,
               float& t0, float& t1) {
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0f) {
      if (o[a] < lo[a] || o[a] > hi[a]) return false;
      continue;
    }
    float tn = (lo[a] - o[a]) / d[a], tf = (hi[a] - o[a]) / d[a];
    if (tn > tf) std::swap(tn, tf);
    t0 = std::max(t0, tn), t1 = std::min(t1, tf);
  }
  return t0 <= t1;
}

// 3D DDA (Amanatides and Woo) over a grid of cubic cells, starting at ray parameter t0.
struct Dda {
  glm::ivec3 cell, step, res;
  glm::vec3 tNext, tDelta;
  Dda(const glm::vec3& o, const glm::vec3& d, const glm::vec3& lo, float size, glm::ivec3 resolution,
      float t0)
      : res(resolution) {
    const glm::vec3 entry = o + t0 * d;
    cell = glm::clamp(glm::ivec3(glm::floor((entry - lo) / size)), glm::ivec3(0), res - 1);
    for (int a = 0; a < 3; ++a) {
      if (d[a] == 0.0f) {
        step[a] = 0, tNext[a] = std::numeric_limits<float>::infinity(), tDelta[a] = 0;
        continue;
      }
      step[a] = d[a] > 0 ? 1 : -1;
      const float boundary = lo[a] + float(cell[a] + (d[a] > 0 ? 1 : 0)) * size;
      tNext[a] = (boundary - o[a]) / d[a];
      tDelta[a] = size / std::fabs(d[a]);
    }
  }
  int exitAxis() const {
    return tNext.x < tNext.y ? (tNext.x < tNext.z ? 0 : 2) : (tNext.y < tNext.z ? 1 : 2);
  }
  float tExit() const { return tNext[exitAxis()]; }
  // Moves to the next cell; false when leaving the grid.
  bool advance() {
    const int axis = exitAxis();
    cell[axis] += step[axis];
    if (cell[axis] < 0 || cell[axis] >= res[axis]) return false;
    tNext[axis] += tDelta[axis];
    return true;
  }
};

// Sub-voxel grid for dense voxels: cubic cells, one per kSubGridDensity triangles. The voxel holds
// a surface, so most cells are empty and occupied ones hold far more than this; finer grids test
// fewer triangles but pay 4 bytes per cell. Measured on the facade (720x480, 1 thread, one run,
// docs/cache.md): 3 -> 1.5 cut intersection time 27% for +1.3 bytes per triangle; 0.75 cut
// another 15% for +3.5 bytes more.
constexpr float kSubGridDensity = 1.5f;
constexpr int kMaxSubGridResolution = 32;

void buildSubGrid(VoxelGeometry& g, const Bounds3& box, float padding) {
  const uint32_t n = g.numTriangles();
  if (n < kSubGridThreshold) return;
  const int r = std::clamp(int(std::cbrt(float(n) / kSubGridDensity)), 2, kMaxSubGridResolution);
  const glm::vec3 extent = box.hi - box.lo;
  g.subCellSize = std::max({extent.x, extent.y, extent.z}) / float(r);
  g.subOrigin = box.lo;
  g.subResolution = glm::ivec3(r);
  const size_t numCells = size_t(r) * r * r;
  thread_local std::vector<uint32_t> offsets;
  offsets.assign(numCells + 1, 0);
  auto range = [&](uint32_t i, glm::ivec3& lo, glm::ivec3& hi) {
    const glm::uvec3 t = g.triangle(i);
    const glm::vec3 a = glm::min(g.P[t.x], glm::min(g.P[t.y], g.P[t.z])) - glm::vec3(padding);
    const glm::vec3 b = glm::max(g.P[t.x], glm::max(g.P[t.y], g.P[t.z])) + glm::vec3(padding);
    lo = glm::clamp(glm::ivec3(glm::floor((a - g.subOrigin) / g.subCellSize)), glm::ivec3(0), g.subResolution - 1);
    hi = glm::clamp(glm::ivec3(glm::floor((b - g.subOrigin) / g.subCellSize)), glm::ivec3(0), g.subResolution - 1);
  };
  std::vector<uint32_t> cursor;
  thread_local std::vector<uint32_t> refs;
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      for (size_t c = 0; c < numCells; ++c) offsets[c + 1] += offsets[c];
      refs.resize(offsets[numCells]);
      cursor.assign(offsets.begin(), offsets.end() - 1);
    }
    for (uint32_t i = 0; i < n; ++i) {
      glm::ivec3 lo, hi;
      range(i, lo, hi);
      for (int z = lo.z; z <= hi.z; ++z)
        for (int y = lo.y; y <= hi.y; ++y)
          for (int x = lo.x; x <= hi.x; ++x) {
            const size_t c = (size_t(z) * r + y) * r + x;
            if (pass == 0) ++offsets[c + 1];
            else refs[cursor[c]++] = i;
          }
    }
  }
  if (offsets[numCells] <= 65535) g.subOffsets16.assign(offsets.begin(), offsets.end());
  else g.subOffsets32.assign(offsets.begin(), offsets.end());
  if (n <= 65536) g.subTriangles16.assign(refs.begin(), refs.end());
  else g.subTriangles32.assign(refs.begin(), refs.end());
}

// Four floats at a time for the BVH build's bounds: SSE where there is SSE, plain loops elsewhere.
#if defined(__SSE2__)
using Lane4 = __m128;
inline Lane4 load4(const float* p) { return _mm_loadu_ps(p); }
inline void store4(float* p, Lane4 a) { _mm_storeu_ps(p, a); }
inline Lane4 splat4(float x) { return _mm_set1_ps(x); }
inline Lane4 min4(Lane4 a, Lane4 b) { return _mm_min_ps(a, b); }
inline Lane4 max4(Lane4 a, Lane4 b) { return _mm_max_ps(a, b); }
inline Lane4 sub4(Lane4 a, Lane4 b) { return _mm_sub_ps(a, b); }
#else
struct Lane4 {
  float v[4];
};
inline Lane4 load4(const float* p) {  // p may be a vec3 followed by other data, as for SSE
  Lane4 r;
  std::memcpy(r.v, p, sizeof r.v);
  return r;
}
inline void store4(float* p, Lane4 a) { std::memcpy(p, a.v, sizeof a.v); }
inline Lane4 splat4(float x) { return {{x, x, x, x}}; }
inline Lane4 min4(Lane4 a, Lane4 b) { return {{std::min(a.v[0], b.v[0]), std::min(a.v[1], b.v[1]), std::min(a.v[2], b.v[2]), std::min(a.v[3], b.v[3])}}; }
inline Lane4 max4(Lane4 a, Lane4 b) { return {{std::max(a.v[0], b.v[0]), std::max(a.v[1], b.v[1]), std::max(a.v[2], b.v[2]), std::max(a.v[3], b.v[3])}}; }
inline Lane4 sub4(Lane4 a, Lane4 b) { return {{a.v[0] - b.v[0], a.v[1] - b.v[1], a.v[2] - b.v[2], a.v[3] - b.v[3]}}; }
#endif

// SAH bins per split, and the depth below which splits turn to medians: a median split halves the
// count, so the binary tree's depth stays below kBvhSahDepth + 24 for fewer than 2^24 triangles.
// The 4-wide tree is no deeper, and a visit adds at most three entries to the traversal stack.
constexpr int kBvhBins = 16;
constexpr uint32_t kBvhSahDepth = 40;
constexpr int kBvhStack = 3 * (int(kBvhSahDepth) + 24) + 4;
// Leaves: nodes of at most kBvhMinLeaf triangles always are, nodes of up to kBvhLeafSize are where
// the heuristic, charging a node visit kBvhTraverseCost triangle tests, finds no cheaper split.
// The costs are deliberately high, since bytes are what the cache exists to save: leaves are tested
// four triangles at a time, so on the facade (docs/cache.md) leaves of up to 32 at cost 10 take
// 0.9 bytes per triangle off the 16/8 rule for 6% more intersection time and the same render time.
constexpr uint32_t kBvhMinLeaf = 4;
// The build's primitives are clusters of up to this many consecutive triangles of one contributor
// (subdivision emits siblings together, so a cluster is compact), which cuts the passes over
// primitives, most of the build's work, by about as much. Leaves still count triangles.
constexpr uint32_t kBvhCluster = 4;
static_assert(kBvhCluster <= kBvhMinLeaf, "a single cluster must always make a leaf");
constexpr float kBvhTraverseCost = 10.0f;

// Builds g's BVH (VoxelGeometry::BvhNode): binned surface-area-heuristic splits along the longest
// axis of the triangle boxes' centres (16 bins, O(n) per level), falling back to a median split
// where the centres do not spread over the bins or below kBvhSahDepth; leaves as said above. Boxes are the triangles'
// grown by `padding` (as the sub-grid's) and then rounded outward by one lattice step, so a
// decoded box always holds its triangles whatever the float rounding of the decode.
// Deterministic: the same triangles in the same order give the same tree. keyOf[i] is triangle i's
// key (input triangle, micro id); the build stores the keys in g, in leaf order (in their own
// order where there is no tree).
void buildBvh(VoxelGeometry& g, float padding, const std::vector<std::pair<uint32_t, uint32_t>>& keyOf) {
  const uint32_t n = uint32_t(keyOf.size());
  g.micro32.reserve(n);
  if (n == 0 || n >= (1u << 24)) {
    for (const auto& [triangleId, microId] : keyOf) g.appendKey(triangleId, microId);
    g.packKeys();
    return;
  }
  // The split works on (centre, index) records in place, so nth_element compares local data.
  struct Ref {
    glm::vec3 centre;
    uint32_t index;
  };
  // Triangle boxes padded to 4 floats a corner, for whole-vector min and max in the binning.
  struct alignas(16) Box {
    glm::vec3 lo;
    float padLo;
    glm::vec3 hi;
    float padHi;
  };
  // The tree is built over clusters (see kBvhCluster): cluster c holds triangles
  // [clusterFirst[c], clusterFirst[c + 1]) of one contributor, and Ref::index names a cluster.
  // A triangle joins the cluster before it only where their union stays about as compact as the
  // two apart (consecutive triangles are usually siblings, but not always neighbours).
  thread_local std::vector<uint32_t> clusterFirst;
  thread_local std::vector<Box> boxes;
  thread_local std::vector<Ref> refs;
  clusterFirst.clear(), boxes.clear(), refs.clear();
  glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
  auto halfArea = [](const glm::vec3& a, const glm::vec3& b) {
    const glm::vec3 d = b - a;
    return d.x * d.y + d.y * d.z + d.z * d.x;
  };
  for (uint32_t i = 0; i < n; ++i) {
    const glm::uvec3 t = g.triangle(i);
    const glm::vec3 tlo = glm::min(g.P[t.x], glm::min(g.P[t.y], g.P[t.z])) - glm::vec3(padding);
    const glm::vec3 thi = glm::max(g.P[t.x], glm::max(g.P[t.y], g.P[t.z])) + glm::vec3(padding);
    lo = glm::min(lo, tlo), hi = glm::max(hi, thi);
    if (!boxes.empty()) {
      Box& b = boxes.back();
      const glm::vec3 ulo = glm::min(b.lo, tlo), uhi = glm::max(b.hi, thi);
      if (i - clusterFirst.back() < kBvhCluster && keyOf[i].first == keyOf[clusterFirst.back()].first &&
          halfArea(ulo, uhi) <= 1.5f * (halfArea(b.lo, b.hi) + halfArea(tlo, thi))) {
        b.lo = ulo, b.hi = uhi;
        continue;
      }
    }
    clusterFirst.push_back(i);
    boxes.push_back(Box{tlo, 0.0f, thi, 0.0f});
  }
  const uint32_t clusters = uint32_t(clusterFirst.size());
  clusterFirst.push_back(n);
  refs.resize(clusters);
  for (uint32_t c = 0; c < clusters; ++c) refs[c] = {0.5f * (boxes[c].lo + boxes[c].hi), c};
  thread_local std::vector<uint8_t> refBin;  // per ref: its bin in the current split
  refBin.resize(clusters);
  auto trianglesOf = [&](uint32_t begin, uint32_t end) {
    uint32_t sum = 0;
    for (uint32_t k = begin; k < end; ++k) sum += clusterFirst[refs[k].index + 1] - clusterFirst[refs[k].index];
    return sum;
  };
  g.bvhOrigin = lo;
  g.bvhStep = glm::max((hi - lo) / 65535.0f, glm::vec3(std::numeric_limits<float>::min()));
  // The binary tree first (children side by side), collapsed into 4-wide nodes below.
  struct BinaryNode {
    uint16_t lo[3], hi[3];
    uint32_t data;  // leaf: kBvhLeafFlag | count << 24 | first triangle; else its first child
  };
  thread_local std::vector<BinaryNode> bin;
  auto quantize = [&](BinaryNode& node, glm::vec3 a, glm::vec3 b) {
    for (int k = 0; k < 3; ++k) {
      const float qa = std::floor((a[k] - g.bvhOrigin[k]) / g.bvhStep[k]) - 1.0f;
      const float qb = std::ceil((b[k] - g.bvhOrigin[k]) / g.bvhStep[k]) + 1.0f;
      node.lo[k] = uint16_t(std::clamp(qa, 0.0f, 65535.0f));
      node.hi[k] = uint16_t(std::clamp(qb, 0.0f, 65535.0f));
    }
  };
  bin.clear();
  bin.reserve(2 * ((n + kBvhLeafSize - 1) / kBvhLeafSize));
  bin.emplace_back();
  // A node's bounds (of its triangles' boxes and of their centres) come with its task when the
  // parent's SAH bins already hold them (min and max are exact, so they are the same bits as a
  // pass over the triangles would give); otherwise the node takes that pass itself.
  // A task's range [begin, end) is of refs (clusters); `count` is their triangles.
  struct Task {
    uint32_t node, begin, end, depth, count;
    bool bounded;
    glm::vec3 blo, bhi, clo, chi;
  };
  thread_local std::vector<Task> tasks;
  tasks.assign(1, Task{0, 0, clusters, 0, n, false, {}, {}, {}, {}});
  while (!tasks.empty()) {
    const Task task = tasks.back();
    tasks.pop_back();
    glm::vec3 blo = task.blo, bhi = task.bhi, clo = task.clo, chi = task.chi;
    if (!task.bounded) {
      blo = clo = glm::vec3(std::numeric_limits<float>::infinity());
      bhi = chi = glm::vec3(-std::numeric_limits<float>::infinity());
      for (uint32_t k = task.begin; k < task.end; ++k) {
        const Box& b = boxes[refs[k].index];
        blo = glm::min(blo, b.lo), bhi = glm::max(bhi, b.hi);
        clo = glm::min(clo, refs[k].centre), chi = glm::max(chi, refs[k].centre);
      }
    }
    quantize(bin[task.node], blo, bhi);
    const uint32_t count = task.count;
    // Its first ref for now; the first triangle once the clusters are in their final order.
    auto makeLeaf = [&] { bin[task.node].data = VoxelGeometry::kBvhLeafFlag | (count << 24) | task.begin; };
    if (count <= kBvhMinLeaf) {
      makeLeaf();
      continue;
    }
    const glm::vec3 extent = chi - clo;
    const int axis = extent.x >= extent.y ? (extent.x >= extent.z ? 0 : 2) : (extent.y >= extent.z ? 1 : 2);
    // Binned surface-area heuristic along the longest centre axis; a median split where the
    // centres do not spread over the bins, or deep down (keeps the depth within the stack).
    uint32_t mid = task.begin + (task.end - task.begin) / 2;
    bool binned = false;
    std::pair<Bounds3, Bounds3> childBounds[2];  // (boxes, centres) of a binned split's sides
    uint32_t childCount[2] = {0, 0};             // and their triangles
    if (extent[axis] > 0.0f && task.depth < kBvhSahDepth) {
      const float toBin = float(kBvhBins) / extent[axis];
      auto binOf = [&](const Ref& r) {
        return std::min(int((r.centre[axis] - clo[axis]) * toBin), kBvhBins - 1);
      };
      // Per bin, the bounds of its boxes and of its centres. Two sets of bins, for even and odd
      // triangles: neighbouring triangles mostly fall in one bin, and with one set each update
      // would wait for the previous one's store. Min and max are exact, so how the sets are
      // merged cannot change the tree. A centre is loaded with its Ref's index as the fourth
      // lane, which is never read back.
      // Each ref's bin is kept for the partition, so both see the same bins whatever the
      // compiler's float evaluation (the children's bounds and counts come from the bins).
      Lane4 lo[2][kBvhBins], hi[2][kBvhBins], cLo[2][kBvhBins], cHi[2][kBvhBins];
      uint32_t binCount[kBvhBins] = {};
      for (int i = 0; i < kBvhBins; ++i)
        for (int set = 0; set < 2; ++set)
          lo[set][i] = cLo[set][i] = splat4(std::numeric_limits<float>::infinity()),
          hi[set][i] = cHi[set][i] = splat4(-std::numeric_limits<float>::infinity());
      for (uint32_t k = task.begin; k < task.end; ++k) {
        const int i = binOf(refs[k]);
        refBin[k] = uint8_t(i);
        const Box& t = boxes[refs[k].index];
        const Lane4 c = load4(&refs[k].centre.x);
        lo[k & 1][i] = min4(lo[k & 1][i], load4(&t.lo.x));
        hi[k & 1][i] = max4(hi[k & 1][i], load4(&t.hi.x));
        cLo[k & 1][i] = min4(cLo[k & 1][i], c);
        cHi[k & 1][i] = max4(cHi[k & 1][i], c);
        binCount[i] += clusterFirst[refs[k].index + 1] - clusterFirst[refs[k].index];
      }
      // Empty bins hold (+inf, -inf) bounds, which change no minimum or maximum, and add no
      // triangles: merging or sweeping over them only repeats the neighbour's figures, and a
      // boundary next to one costs exactly what the boundary before it did (the first of equal
      // costs wins). So they are skipped, and the tree is the same; small nodes fill few bins.
      for (int i = 0; i < kBvhBins; ++i) {
        if (binCount[i] == 0) continue;
        lo[0][i] = min4(lo[0][i], lo[1][i]), hi[0][i] = max4(hi[0][i], hi[1][i]);
        cLo[0][i] = min4(cLo[0][i], cLo[1][i]), cHi[0][i] = max4(cHi[0][i], cHi[1][i]);
      }
      auto area = [](Lane4 a, Lane4 b) {
        alignas(16) float d[4];
        store4(d, sub4(b, a));
        return d[0] * d[1] + d[1] * d[2] + d[2] * d[0];
      };
      // Sweep from the right, then from the left, keeping the cheapest boundary.
      float rightArea[kBvhBins];
      uint32_t rightCount[kBvhBins];
      Lane4 accLo = lo[0][kBvhBins - 1], accHi = hi[0][kBvhBins - 1];
      uint32_t accCount = 0;
      for (int i = kBvhBins - 1; i > 0; --i) {
        if (binCount[i] == 0 && i < kBvhBins - 1) {
          rightArea[i] = rightArea[i + 1], rightCount[i] = rightCount[i + 1];
          continue;
        }
        accLo = min4(accLo, lo[0][i]), accHi = max4(accHi, hi[0][i]);
        accCount += binCount[i];
        rightArea[i] = accCount ? area(accLo, accHi) : 0.0f, rightCount[i] = accCount;
      }
      accLo = lo[0][0], accHi = hi[0][0];
      accCount = 0;
      float bestCost = std::numeric_limits<float>::infinity();
      int bestSplit = -1;
      for (int i = 1; i < kBvhBins; ++i) {
        if (binCount[i - 1] == 0) continue;
        accLo = min4(accLo, lo[0][i - 1]), accHi = max4(accHi, hi[0][i - 1]);
        accCount += binCount[i - 1];
        if (accCount == 0 || rightCount[i] == 0) continue;
        const float cost = area(accLo, accHi) * float(accCount) + rightArea[i] * float(rightCount[i]);
        if (cost < bestCost) bestCost = cost, bestSplit = i;
      }
      const float nodeArea = halfArea(blo, bhi);
      if (count <= kBvhLeafSize && (bestSplit < 0 || bestCost >= (float(count) - kBvhTraverseCost) * nodeArea)) {
        makeLeaf();
        continue;
      }
      if (bestSplit > 0) {
        // std::partition's own algorithm (so the same order) on the bins kept above.
        uint32_t first = task.begin, last = task.end;
        for (;;) {
          while (first != last && refBin[first] < bestSplit) ++first;
          if (first == last) break;
          --last;
          while (first != last && !(refBin[last] < bestSplit)) --last;
          if (first == last) break;
          std::swap(refs[first], refs[last]);
          std::swap(refBin[first], refBin[last]);
          ++first;
        }
        mid = first;
        binned = mid > task.begin && mid < task.end;
        for (int side = 0; side < 2; ++side) {
          const int from = side ? bestSplit : 0, to = side ? kBvhBins : bestSplit;
          Lane4 bl = lo[0][from], bh = hi[0][from], cl = cLo[0][from], ch = cHi[0][from];
          for (int i = from + 1; i < to; ++i)
            bl = min4(bl, lo[0][i]), bh = max4(bh, hi[0][i]), cl = min4(cl, cLo[0][i]), ch = max4(ch, cHi[0][i]);
          alignas(16) float f[4][4];
          store4(f[0], bl), store4(f[1], bh), store4(f[2], cl), store4(f[3], ch);
          childBounds[side] = {Bounds3{glm::vec3(f[0][0], f[0][1], f[0][2]), glm::vec3(f[1][0], f[1][1], f[1][2])},
                               Bounds3{glm::vec3(f[2][0], f[2][1], f[2][2]), glm::vec3(f[3][0], f[3][1], f[3][2])}};
          for (int i = from; i < to; ++i) childCount[side] += binCount[i];
        }
      }
    }
    if (!binned && count <= kBvhLeafSize) {
      makeLeaf();
      continue;
    }
    if (!binned) {
      mid = task.begin + (task.end - task.begin) / 2;
      std::nth_element(refs.begin() + task.begin, refs.begin() + mid, refs.begin() + task.end,
                       [axis](const Ref& a, const Ref& b) {
                         return a.centre[axis] < b.centre[axis] ||
                                (a.centre[axis] == b.centre[axis] && a.index < b.index);
                       });
      childCount[0] = trianglesOf(task.begin, mid);
      childCount[1] = count - childCount[0];
    }
    const uint32_t child = uint32_t(bin.size());
    bin.emplace_back(), bin.emplace_back();
    bin[task.node].data = child;
    for (int side = 1; side >= 0; --side) {
      const auto& [box, centres] = childBounds[side];
      tasks.push_back(Task{child + uint32_t(side), side ? mid : task.begin, side ? task.end : mid, task.depth + 1,
                           childCount[side], binned, box.lo, box.hi, centres.lo, centres.hi});
    }
  }
  // Collapse: each wide node takes its binary node's two children, then keeps opening the inner
  // child of largest surface area until it holds four (or only leaves). Leaves sit in their
  // parent's slots; the tree keeps the binary one's boxes, rounded further outwards to its nodes'
  // 8-bit codes, so it is at least as conservative.
  auto area = [](const BinaryNode& b) {
    const float dx = float(b.hi[0] - b.lo[0]), dy = float(b.hi[1] - b.lo[1]), dz = float(b.hi[2] - b.lo[2]);
    return dx * dy + dy * dz + dz * dx;
  };
  // Codes of a binary node's box in a wide node's frame, rounded outward (the box lies in the
  // frame, which is its parent's box rounded outward in turn).
  using Frame = VoxelGeometry::BvhFrame;
  auto encode = [](VoxelGeometry::BvhNode& node, int i, const Frame& f, const BinaryNode* b) {
    for (int k = 0; k < 3; ++k) {
      if (!b) {
        node.lo[k][i] = 255, node.hi[k][i] = 0;
        continue;
      }
      const uint32_t base = uint32_t(f.lo[k]), step = uint32_t(f.step[k]);
      const uint32_t lo = b->lo[k] > base ? (b->lo[k] - base) / step : 0u;
      const uint32_t hi = b->hi[k] > base ? (b->hi[k] - base + step - 1) / step : 0u;
      node.lo[k][i] = uint8_t(std::min(lo, 255u)), node.hi[k][i] = uint8_t(std::min(hi, 255u));
    }
  };
  {
    uint32_t rootLo[3], rootHi[3];
    for (int k = 0; k < 3; ++k) rootLo[k] = bin[0].lo[k], rootHi[k] = bin[0].hi[k];
    g.bvhRoot = Frame::of(rootLo, rootHi);
  }
  g.bvhNodes.assign(1, VoxelGeometry::BvhNode{});
  g.bvhNodes.reserve(bin.size() / 3 + 1);
  if (bin[0].data & VoxelGeometry::kBvhLeafFlag) {
    // A root that is a leaf (a sparse voxel) sits in the first slot of the wide root: its box
    // lets rays that miss the voxel's triangles pass without testing them, and lets the voxel's
    // proxy do so without the voxel.
    VoxelGeometry::BvhNode& root = g.bvhNodes[0];
    for (int i = 0; i < 4; ++i) {
      root.child[i] = i == 0 ? bin[0].data : VoxelGeometry::kBvhLeafFlag;
      encode(root, i, g.bvhRoot, i == 0 ? &bin[0] : nullptr);
    }
    bin.clear();
  }
  struct Job {
    uint32_t binary, wide;
    Frame frame;
  };
  thread_local std::vector<Job> jobs;
  jobs.clear();
  if (!bin.empty()) jobs.push_back({0, 0, g.bvhRoot});
  while (!jobs.empty()) {
    const Job job = jobs.back();
    jobs.pop_back();
    uint32_t kids[4] = {bin[job.binary].data, bin[job.binary].data + 1};
    int count = 2;
    while (count < 4) {
      int open = -1;
      float largest = -1.0f;
      for (int i = 0; i < count; ++i)
        if (!(bin[kids[i]].data & VoxelGeometry::kBvhLeafFlag) && area(bin[kids[i]]) > largest)
          open = i, largest = area(bin[kids[i]]);
      if (open < 0) break;
      const uint32_t first = bin[kids[open]].data;
      kids[open] = first, kids[count++] = first + 1;
    }
    for (int i = 0; i < 4; ++i) {
      encode(g.bvhNodes[job.wide], i, job.frame, i < count ? &bin[kids[i]] : nullptr);
      uint32_t ref = VoxelGeometry::kBvhLeafFlag;  // an empty leaf in an unused slot
      if (i < count) {
        const BinaryNode& b = bin[kids[i]];
        if (b.data & VoxelGeometry::kBvhLeafFlag) {
          ref = b.data;
        } else {
          ref = uint32_t(g.bvhNodes.size());
          const Frame frame = job.frame.child(g.bvhNodes[job.wide], i);
          g.bvhNodes.emplace_back();
          jobs.push_back({kids[i], ref, frame});
        }
      }
      g.bvhNodes[job.wide].child[i] = ref;
    }
  }
  g.bvhNodes.shrink_to_fit();
  // The triangles move into leaf order, so leaves address them directly: their indices and keys
  // are rewritten in that order (keys as runs again: neighbours in a leaf mostly share a
  // contributor). Vertices stay where they are.
  thread_local std::vector<uint32_t> order, firstOfRef;
  order.clear();
  firstOfRef.resize(clusters);
  for (uint32_t k = 0; k < clusters; ++k) {
    firstOfRef[k] = uint32_t(order.size());
    for (uint32_t i = clusterFirst[refs[k].index]; i < clusterFirst[refs[k].index + 1]; ++i) order.push_back(i);
  }
  // Leaves named their first ref: now their first triangle.
  for (VoxelGeometry::BvhNode& node : g.bvhNodes)
    for (uint32_t& ref : node.child)
      if ((ref & VoxelGeometry::kBvhLeafFlag) && (ref >> 24 & 127u))
        ref = (ref & ~0xffffffu) | firstOfRef[ref & 0xffffffu];
  if (!g.indices16.empty()) {
    std::vector<uint16_t> indices(3 * size_t(n));
    for (uint32_t k = 0; k < n; ++k)
      for (int c = 0; c < 3; ++c) indices[3 * size_t(k) + c] = g.indices16[3 * size_t(order[k]) + c];
    g.indices16.swap(indices);
  } else {
    std::vector<uint32_t> indices(3 * size_t(n));
    for (uint32_t k = 0; k < n; ++k)
      for (int c = 0; c < 3; ++c) indices[3 * size_t(k) + c] = g.indices32[3 * size_t(order[k]) + c];
    g.indices32.swap(indices);
  }
  for (uint32_t k = 0; k < n; ++k) g.appendKey(keyOf[order[k]].first, keyOf[order[k]].second);
  g.packKeys();
}

}  // namespace

// Per-ray set-up of the BVH's slab tests, shared by every voxel the ray visits. Direction
// components below 1e-20 of the longest are made that small instead, so no 0 * inf appears;
// within the grid such a ray moves less than float precision along that axis, so the test stays
// conservative, as the boxes are a lattice step larger than their triangles. A direction too short
// for this (never from the camera or the integrator, whose directions are unit vectors) is not
// `usable`: its voxels test every triangle.
struct GridAccelerator::SlabRay {
  explicit SlabRay(const Ray& ray) {
    const glm::vec3 absDir = glm::abs(ray.direction);
    const float longest = std::max({absDir.x, absDir.y, absDir.z});
    usable = longest >= 1e-15f;
    const float minDir = 1e-20f * longest;
    for (int k = 0; k < 3; ++k) {
      float dk = ray.direction[k];
      if (std::fabs(dk) < minDir) dk = std::signbit(dk) ? -minDir : minDir;
      inv[k] = usable ? 1.0f / dk : 0.0f;
      negative[k] = inv[k] < 0.0f;
    }
  }
  glm::vec3 inv;
  bool negative[3];
  bool usable;
};

namespace {

// A node frame's slab set-up for one ray: per axis, the distance of the frame's lo plane and of
// one step, so that a child plane of code q lies at t = base + q * scale. Two roundings more than
// the voxel lattice's own t = base + place * scale; boxes carry a lattice step of slack on top of
// the grid's padding, which is far beyond them.
struct FrameSlabs {
  float base[3], scale[3];
};
inline FrameSlabs frameSlabs(const VoxelGeometry::BvhFrame& f, const glm::vec3& base, const glm::vec3& scale) {
  FrameSlabs s;
  for (int k = 0; k < 3; ++k) s.base[k] = base[k] + f.lo[k] * scale[k], s.scale[k] = f.step[k] * scale[k];
  return s;
}

// The four children's slab tests of a BVH node at once: a bit per child the ray enters within
// [tLow, limit], and its entry distance. Per axis, the near and far planes' distances are
// t = base + q * scale (near is the low plane for a positive direction).
inline int enterChildren(const VoxelGeometry::BvhNode& node, const FrameSlabs& fs, const GridAccelerator::SlabRay& sr,
                         float tLow, float limit, float tNear[4]) {
#if defined(__SSE2__)
  __m128 vNear = _mm_set1_ps(tLow), vFar = _mm_set1_ps(limit);
  const __m128i zero = _mm_setzero_si128();
  for (int k = 0; k < 3; ++k) {
    const uint8_t* nearQ = sr.negative[k] ? node.hi[k] : node.lo[k];
    const uint8_t* farQ = sr.negative[k] ? node.lo[k] : node.hi[k];
    uint32_t nearBytes, farBytes;
    std::memcpy(&nearBytes, nearQ, 4), std::memcpy(&farBytes, farQ, 4);
    const __m128 qn = _mm_cvtepi32_ps(_mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(int(nearBytes)), zero), zero));
    const __m128 qf = _mm_cvtepi32_ps(_mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(int(farBytes)), zero), zero));
    const __m128 b = _mm_set1_ps(fs.base[k]), s = _mm_set1_ps(fs.scale[k]);
    // Operands in this order, a NaN plane is ignored (SSE max/min return the second operand
    // then), as std::max/min ignore it in the scalar code: the test stays conservative.
    vNear = _mm_max_ps(_mm_add_ps(b, _mm_mul_ps(qn, s)), vNear);
    vFar = _mm_min_ps(_mm_add_ps(b, _mm_mul_ps(qf, s)), vFar);
  }
  _mm_storeu_ps(tNear, vNear);
  return _mm_movemask_ps(_mm_cmple_ps(vNear, vFar));
#else
  int mask = 0;
  for (int i = 0; i < 4; ++i) {
    float tFar = limit;
    tNear[i] = tLow;
    for (int k = 0; k < 3; ++k) {
      const float a = fs.base[k] + float(sr.negative[k] ? node.hi[k][i] : node.lo[k][i]) * fs.scale[k];
      const float b = fs.base[k] + float(sr.negative[k] ? node.lo[k][i] : node.hi[k][i]) * fs.scale[k];
      tNear[i] = std::max(tNear[i], a), tFar = std::min(tFar, b);
    }
    mask |= int(tNear[i] <= tFar) << i;
  }
  return mask;
#endif
}

// The slab set-up of a voxel's BVH lattice for one ray (the same arithmetic for a resident voxel
// and for its proxy, so both take the same decision).
void lattice(const glm::vec3& origin, const glm::vec3& step, const Ray& ray, const GridAccelerator::SlabRay& sr,
             glm::vec3& base, glm::vec3& scale) {
  for (int k = 0; k < 3; ++k) {
    base[k] = (origin[k] - ray.origin[k]) * sr.inv[k];
    scale[k] = step[k] * sr.inv[k];
  }
}

}  // namespace

// The nearest hit so far, with what is needed to report it after the voxel is released.
struct GridAccelerator::Best {
  bool found = false;
  float t = 0;
  uint32_t triangleId = 0, microId = 0;
  TriangleHit hit{};
  glm::vec3 p[3];
  glm::vec2 bary[3];
  bool better(float t2, uint32_t tri, uint32_t micro) const {
    if (!found || t2 < t) return true;
    if (t2 > t) return false;
    return tri < triangleId || (tri == triangleId && micro < microId);
  }
};

GridAccelerator::GridAccelerator(const Scene& scene, const AccelOptions& options)
    : scene_(scene),
      options_(options),
      grid_(scene, options),
      voxelCounted_(grid_.numVoxels()),
      knownEmpty_(grid_.numVoxels()),
      side_(std::make_unique<SideCache>()),
      subtreeMemos_(options.learnSubtrees && grid_.anyDisplaced() ? grid_.numTriangles() : 0),
      proxies_(options.voxelProxies && !options.subVoxelGrid ? grid_.numVoxels() : 0) {
  // Undisplaced scenes go through the cache too: a fill then stores the input triangles whole,
  // and dense voxels get sub-voxel grids. Testing every contributor of a voxel instead made
  // sphere_box's undisplaced baseline (131K triangles in a few voxels of a room-sized grid) 8x
  // slower than the displaced render.
  cache_ = std::make_unique<GeometryCache>(grid_.numVoxels(), options.cacheBudgetTriangles);
  positionStep_ = choosePositionStep();
  if (!grid_.outside().empty()) {
    std::vector<glm::vec3> corners;
    corners.reserve(3 * grid_.outside().size());
    for (uint32_t id : grid_.outside()) {
      const auto [m, t] = grid_.split(id);
      // Snapped like the triangles in voxels, so every form of a triangle is the same bits.
      for (int c = 0; c < 3; ++c)
        corners.push_back(snapToLattice(scene.meshes[m].P[scene.meshes[m].indices[3 * size_t(t) + c]], positionStep_));
    }
    outside_ = TriangleBvh(std::move(corners), std::vector<uint32_t>(grid_.outside().begin(), grid_.outside().end()));
  }
  const char* env = std::getenv("RELIEF_CHECK_BUDGET");
  cache_->setCheckBudget(options.checkBudget || (env && std::string_view(env) == "1"));
  if (grid_.anyDisplaced() && (options.sideCacheTriangles || options.learnSubtrees)) {
    // A contributor listed in one voxel only is subdivided by that voxel's fills alone: keeping
    // its whole subdivision, or a memo, would only cost memory (sphere_box: 131K such small
    // triangles, about 60 MB of side cache or 200 MB of memos for no time saved; culling never
    // drops any of its parts, so only refills of its voxel could use the memo's decisions).
    std::vector<uint8_t> seen(grid_.numTriangles(), 0);
    sharedContributor_.assign(grid_.numTriangles(), 0);
    for (uint32_t v = 0; v < grid_.numVoxels(); ++v)
      for (uint32_t id : grid_.allContributors(v)) {
        if (seen[id]) sharedContributor_[id] = kShared;
        seen[id] = 1;
      }
    // A memo pays where a subdivision is dear: a triangle asking for fewer than 4^kMemoMinLevels
    // micro-triangles is cheaper to cull again than to remember. The sphere's 65K input triangles
    // of about 11 micro-triangles each held 68 MB of memos at a 10% budget (of 1 MB of
    // triangles), and rendered faster without them.
    constexpr int kMemoMinLevels = 3;
    for (uint32_t id = 0; id < grid_.numTriangles(); ++id) {
      if (!sharedContributor_[id]) continue;
      const auto [m, t] = grid_.split(id);
      const Displacement* d = grid_.displacement(m);
      if (!d) continue;
      glm::vec3 p[3];
      for (int c = 0; c < 3; ++c) p[c] = scene.meshes[m].P[scene.meshes[m].indices[3 * size_t(t) + c]];
      const int levels = undisplacedLevels(p, d->edgeLength, d->maxDepth);
      if (levels >= kMemoMinLevels) sharedContributor_[id] |= kMemoWorthy;
      // A contributor whose whole subdivision would not fit the side cache many times over is
      // subdivided per voxel, culled: a 100 x 100 displaced floor of two triangles made 8.4M
      // micro-triangles of side cache (2.7 GB, 226 s) where culled fills took 151 MB and 12.5 s,
      // for the same image.
      if (levels <= 30 && (uint64_t(1) << (2 * levels)) * 8 <= options.sideCacheTriangles)
        sharedContributor_[id] |= kSideWorthy;
    }
  }
}

float GridAccelerator::choosePositionStep() const {
  // Vertices are snapped to a lattice fine against the micro-triangles (1/1024 of the smallest
  // target edge length) and no coarser than half the grid's padding (about 2^-18 of the scene's
  // reach): a snapped triangle then reaches at most a quarter of the padding beyond the unsnapped
  // one, so every voxel it enters holds it (the voxel boxes and the contributor lists are grown
  // by the padding). The step must not depend on the voxel size: the image would then change
  // with --grid-resolution (it did, from 17 voxels across on the sphere). A voxel of a grid up
  // to 2^19 / 2^18 = 2 voxels across spans fewer than 2^19 steps and packs (VoxelGeometry::P).
  // Where the lattice is finer than the floats (far from the origin), snapping leaves a
  // coordinate as it is (snapToLattice).
  // Undisplaced scenes keep their input positions: their sparse voxels are tested straight from
  // the input meshes, and every form of a triangle must be the same bits.
  if (!grid_.anyDisplaced()) return 0.0f;
  float wanted = 0.5f * grid_.padding();
  for (uint32_t m = 0; m < scene_.meshes.size(); ++m)
    if (const Displacement* d = grid_.displacement(m); d && d->shader && d->edgeLength > 0.0f)
      wanted = std::min(wanted, d->edgeLength / 1024.0f);
  if (!std::isfinite(wanted) || !(wanted > 0.0f)) return 0.0f;
  int e = 0;
  std::frexp(wanted, &e);                // wanted in [2^(e-1), 2^e)
  const float step = std::ldexp(1.0f, e - 1);  // the power of two at or below it
  return step >= std::numeric_limits<float>::min() ? step : 0.0f;
}

void GridAccelerator::addCounters(const SubdivideCounters& counters) {
  shaderPoints_.fetch_add(counters.shaderPoints, std::memory_order_relaxed);
  displaceTicks_.fetch_add(counters.displaceTicks, std::memory_order_relaxed);
  simplifyBefore_.fetch_add(counters.trianglesBeforeSimplification, std::memory_order_relaxed);
  simplifyAfter_.fetch_add(counters.trianglesAfterSimplification, std::memory_order_relaxed);
  if (counters.status.nonFinite) nonFinite_.fetch_add(counters.status.nonFinite);
  if (counters.status.loopLimit) loopLimit_.fetch_add(counters.status.loopLimit);
  if (counters.status.indexClamped) indexClamped_.fetch_add(counters.status.indexClamped);
  if (counters.status.unknownSpace) unknownSpace_.fetch_add(counters.status.unknownSpace);
  if (counters.status.textureErrors) textureErrors_.fetch_add(counters.status.textureErrors);
}

// The side cache of whole (unculled) contributor subdivisions, shared by the threads: entries sit
// in a list in recency order (front: most recent) with a hash index, so a lookup, a touch and an
// eviction cost O(1) even with the 100K+ contributors of a finely tessellated scene. Entries are
// immutable once in, and held by shared_ptr, so a fill may go on reading one that is evicted
// meanwhile. Per-thread caches (the first version) subdivided a contributor once per thread.
struct GridAccelerator::SideCache {
  struct Entry {
    uint32_t id = 0;
    std::shared_ptr<const MicroMesh> mesh;
  };
  SpinMutex mutex;
  uint64_t triangles = 0;
  std::list<Entry> entries;
  std::unordered_map<uint32_t, std::list<Entry>::iterator> index;
};

GridAccelerator::~GridAccelerator() {
  for (std::atomic<const VoxelProxy*>& p : proxies_) delete p.load(std::memory_order_relaxed);
  for (std::atomic<SubtreeMemo*>& b : subtreeMemos_) delete b.load(std::memory_order_relaxed);
}

SubtreeMemo* GridAccelerator::subtreeMemo(uint32_t id, int rounds) {
  SubtreeMemo* boxes = subtreeMemos_[id].load(std::memory_order_acquire);
  if (boxes) return boxes;
  // Memos are kept for the whole render; past their cap, contributors go without (fills then
  // cull on the bound margin, as without memos). Checked before making one, so two threads may
  // each add one past the cap.
  if (subtreeBytes_.load(std::memory_order_relaxed) >= options_.memoBytesLimit) return nullptr;
  // The lattice spans the reach the contributor grid assumes: the input triangle grown by its
  // displacement bound (a subtree reaching beyond it, against its shader's bound, is not learnt).
  const auto [m, triangle] = grid_.split(id);
  const Mesh& mesh = scene_.meshes[m];
  const Displacement* d = grid_.displacement(m);
  const Bounds3 reach = triangleReach(mesh, triangle, d ? std::max(0.0f, d->boundWorld) : 0.0f);
  const CullBox reference{reach.lo, reach.hi};
  // Rounds: what the first learning fill reached, or what the undisplaced triangle's longest edge
  // suggests (one round per halving down to the edge length, and one more for the displacement),
  // whichever is deeper; a first fill in a flat corner may stop rounds before the rest.
  if (d && d->edgeLength > 0.0f) {
    glm::vec3 p[3];
    for (int c = 0; c < 3; ++c) p[c] = mesh.P[mesh.indices[3 * size_t(triangle) + c]];
    rounds = std::max(rounds, 1 + undisplacedLevels(p, d->edgeLength, kCullRounds));
  }
  auto made = std::make_unique<SubtreeMemo>(reference, std::min(rounds, kCullRounds));
  if (subtreeMemos_[id].compare_exchange_strong(boxes, made.get(), std::memory_order_acq_rel)) {
    subtreeBytes_.fetch_add(made->bytes(), std::memory_order_relaxed);
    return made.release();
  }
  return boxes;  // another thread's, made meanwhile
}

std::shared_ptr<const MicroMesh> GridAccelerator::sideCached(uint32_t id, SubdivideCounters& counters) {
  SideCache& side = *side_;
  {
    std::lock_guard<SpinMutex> lock(side.mutex);
    if (const auto found = side.index.find(id); found != side.index.end()) {
      side.entries.splice(side.entries.begin(), side.entries, found->second);
      sideHits_.fetch_add(1, std::memory_order_relaxed);
      return found->second->mesh;
    }
  }
  // Subdivided outside the lock: two threads missing the same contributor at once both do the
  // work (rare: Hilbert order keeps threads apart), and the first to finish is kept.
  sideMisses_.fetch_add(1, std::memory_order_relaxed);
  auto mesh = std::make_shared<MicroMesh>();
  const auto [m, triangle] = grid_.split(id);
  subdivideTriangle(scene_.meshes[m], triangle, grid_.displacement(m), *mesh, counters);
  const uint64_t n = mesh->numTriangles();
  std::list<SideCache::Entry> victims;  // freed after the mutex is released (declared first)
  std::lock_guard<SpinMutex> lock(side.mutex);
  if (const auto found = side.index.find(id); found != side.index.end()) {
    side.entries.splice(side.entries.begin(), side.entries, found->second);
    return found->second->mesh;
  }
  // Evict least recently used entries until the new one fits (it is kept even if it alone is
  // larger than the capacity: it is needed now, and goes at the next miss).
  while (!side.entries.empty() && side.triangles + n > options_.sideCacheTriangles) {
    side.triangles -= side.entries.back().mesh->numTriangles();
    side.index.erase(side.entries.back().id);
    victims.splice(victims.begin(), side.entries, std::prev(side.entries.end()));
  }
  side.triangles += n;
  if (side.triangles > sidePeak_.load(std::memory_order_relaxed))
    sidePeak_.store(side.triangles, std::memory_order_relaxed);  // written under the mutex only
  side.entries.push_front({id, std::move(mesh)});
  side.index[id] = side.entries.begin();
  return side.entries.front().mesh;
}

std::unique_ptr<VoxelGeometry> GridAccelerator::buildVoxel(uint32_t voxel) {
  const auto start = std::chrono::steady_clock::now();
  ++threadCacheMisses();  // for the "cachemiss" AOV: this thread's ray caused a fill
  auto g = std::make_unique<VoxelGeometry>();
  const Bounds3 box = grid_.voxelBounds(voxel);
  const CullBox cull{box.lo, box.hi};
  // A micro-triangle is stored in every voxel it overlaps but counted as unique only in the voxel
  // holding its centroid, and only on the voxel's first fill.
  const bool countUnique = voxelCounted_[voxel].exchange(1, std::memory_order_relaxed) == 0;
  const Bounds3& gridBounds = grid_.bounds();
  uint64_t unique = 0;
  // The centroid's cell is clamp(floor((c - lo) / size), 0, res - 1); it is this voxel exactly
  // when, per axis, (c - lo) / size lies in [cell, cell + 1), open-ended at the grid's faces
  // (floor(q) >= k iff q >= k for whole k): no floor, conversion or clamp per triangle.
  glm::vec3 cellLo, cellHi;
  {
    const glm::ivec3 res = grid_.resolution();
    const glm::ivec3 cell(int(voxel % uint32_t(res.x)), int(voxel / uint32_t(res.x) % uint32_t(res.y)),
                          int(voxel / uint32_t(res.x) / uint32_t(res.y)));
    assert(grid_.voxelIndex(cell) == voxel);
    for (int k = 0; k < 3; ++k) {
      cellLo[k] = cell[k] == 0 ? -std::numeric_limits<float>::infinity() : float(cell[k]);
      cellHi[k] = cell[k] == res[k] - 1 ? std::numeric_limits<float>::infinity() : float(cell[k] + 1);
    }
  }
  thread_local MicroMesh culled;
  thread_local std::vector<uint32_t> remap;
  thread_local std::vector<uint8_t> reached;  // per contributor: some micro-triangle kept here
  thread_local std::vector<glm::vec2> bary;
  thread_local std::vector<LearntSubtree> learnt;
  // The voxel is gathered in per-thread arrays and copied into its own once, at its final size.
  thread_local std::vector<glm::vec3> points;
  thread_local std::vector<uint32_t> indices;
  thread_local std::vector<std::pair<uint32_t, uint32_t>> keys;  // (input triangle, micro id)
  // The vertices of whole input triangles, by their snapped position's bits (see below).
  struct PositionHash {
    size_t operator()(const std::array<uint32_t, 3>& p) const {
      return size_t((uint64_t(p[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(p[1]) * 0xC2B2AE3D27D4EB4Full) ^
                    (uint64_t(p[2]) * 0x165667B19E3779F9ull));
    }
  };
  thread_local std::unordered_map<std::array<uint32_t, 3>, uint32_t, PositionHash> wholeVertices;
  // Cleared before use; after a huge voxel its buckets are let go rather than kept (and zeroed
  // by every later clear) on the thread.
  if (wholeVertices.bucket_count() > (size_t(1) << 16)) decltype(wholeVertices)().swap(wholeVertices);
  if (!wholeVertices.empty()) wholeVertices.clear();
  bary.clear(), points.clear(), indices.clear(), keys.clear();
  SubdivideCounters counters;
  const std::span<const uint32_t> contributors = grid_.contributors(voxel);
  reached.assign(contributors.size(), 0);
  for (size_t k = 0; k < contributors.size(); ++k) {
    const uint32_t id = contributors[k];
    const auto [mesh, triangle] = grid_.split(id);
    std::shared_ptr<const MicroMesh> whole;
    const uint8_t sharing = sharedContributor_.empty() ? 0 : sharedContributor_[id];
    if ((sharing & kSideWorthy) && options_.sideCacheTriangles)
      whole = sideCached(id, counters);
    else if (subtreeMemos_.empty() || !(sharing & kMemoWorthy))
      subdivideTriangle(scene_.meshes[mesh], triangle, grid_.displacement(mesh), culled, counters, &cull);
    else {
      const SubtreeMemo* known = subtreeMemos_[id].load(std::memory_order_acquire);
      // Past the memos' cap, a contributor without one will not get one: nothing to learn.
      const bool learn = known || subtreeBytes_.load(std::memory_order_relaxed) < options_.memoBytesLimit;
      subdivideTriangle(scene_.meshes[mesh], triangle, grid_.displacement(mesh), culled, counters, &cull,
                        known, learn ? &learnt : nullptr);
      if (learn && !learnt.empty()) {
        // Sized by the deepest subtree this fill learnt (a subdivision reaching round r anywhere
        // keeps some subtree of round r whole, unless culling cut them all).
        uint32_t deepest = 0;
        for (const LearntSubtree& l : learnt) deepest = std::max(deepest, l.code);
        if (SubtreeMemo* memo = subtreeMemo(id, (31 - __builtin_clz(deepest)) / 2))
          for (const LearntSubtree& l : learnt) memo->learn(l.code, l.hasBox ? &l.box : nullptr, l.decisions);
      }
    }
    const MicroMesh& mm = whole ? *whole : culled;
    remap.assign(mm.P.size(), UINT32_MAX);
    // An input triangle kept whole (undisplaced, or never split) has its corners' barycentrics
    // by position (subdivideTriangle: corners 0, 1, 2 at (0, 0), (1, 0), (0, 1)), and a hit on
    // it takes them so (intersectVoxel). So its vertices need none of their own and are shared
    // with every whole triangle of the voxel that has them: undisplaced meshes then store their
    // vertices once, not once per triangle.
    const bool wholeCorners = mm.numTriangles() == 1 && mm.ids[0] == kWholeTriangleId;
    assert(!wholeCorners || (mm.indices[0] == 0 && mm.indices[1] == 1 && mm.indices[2] == 2 &&
                             mm.bary[0] == glm::vec2(0, 0) && mm.bary[1] == glm::vec2(1, 0) && mm.bary[2] == glm::vec2(0, 1)));
    for (uint32_t i = 0; i < mm.numTriangles(); ++i) {
      const uint32_t* tri = &mm.indices[3 * size_t(i)];
      if (!overlaps(box, mm.P[tri[0]], mm.P[tri[1]], mm.P[tri[2]])) continue;
      reached[k] = 1;
      for (int c = 0; c < 3; ++c) {
        uint32_t& slot = remap[tri[c]];
        if (slot == UINT32_MAX) {
          const glm::vec3 p = snapToLattice(mm.P[tri[c]], positionStep_);
          if (wholeCorners) {
            const auto [it, added] = wholeVertices.try_emplace(
                std::array<uint32_t, 3>{std::bit_cast<uint32_t>(p.x), std::bit_cast<uint32_t>(p.y), std::bit_cast<uint32_t>(p.z)},
                uint32_t(points.size()));
            slot = it->second;
            if (!added) {
              indices.push_back(slot);
              continue;
            }
          } else {
            slot = uint32_t(points.size());
          }
          points.push_back(p);
          bary.push_back(mm.bary[tri[c]]);
        }
        indices.push_back(slot);
      }
      keys.emplace_back(id, mm.ids[i]);
      if (countUnique) {
        const glm::vec3 centroid = (mm.P[tri[0]] + mm.P[tri[1]] + mm.P[tri[2]]) / 3.0f;
        const glm::vec3 q = (centroid - gridBounds.lo) / grid_.voxelSize();
        unique += glm::all(glm::greaterThanEqual(q, cellLo)) && glm::all(glm::lessThan(q, cellHi));
      }
    }
  }
  addCounters(counters);
  // Refinement: a contributor none of whose micro-triangles reached the voxel never will (rule 1),
  // so refills of this voxel skip it.
  if (options_.refineContributors) {
    if (const uint32_t dropped = grid_.refine(voxel, reached))
      droppedContributors_.fetch_add(dropped, std::memory_order_relaxed);
  }
  if (unique) uniqueTriangles_.fetch_add(unique, std::memory_order_relaxed);
  g->P.assign(points.begin(), points.end());
  if (points.size() <= 65536) g->indices16.assign(indices.begin(), indices.end());
  else g->indices32.assign(indices.begin(), indices.end());
  // Resident memory is what the budget and the byte statistics describe: no growth slack.
  g->setBary(bary);
  if (options_.subVoxelGrid) {
    g->micro32.reserve(keys.size());
    for (const auto& [triangleId, microId] : keys) g->appendKey(triangleId, microId);
    g->packKeys();
    buildSubGrid(*g, box, grid_.padding());
  } else {
    buildBvh(*g, grid_.padding(), keys);  // stores the keys in leaf order
  }
  g->packPositions(positionStep_, 0.5f * (box.lo + box.hi));
  g->packIndices();
  g->packBary();
  if (!proxies_.empty() && !g->bvhNodes.empty() && !proxies_[voxel].load(std::memory_order_acquire)) {
    // Every fill of a voxel builds the same BVH (rule 1), so whichever fill publishes it, the
    // proxy is the root a resident voxel would have.
    auto proxy = std::make_unique<VoxelProxy>();
    proxy->origin = g->bvhOrigin, proxy->step = g->bvhStep, proxy->root = g->bvhRoot;
    proxy->nodes[0] = g->bvhNodes[0];
    uint32_t next = 1;
    for (uint32_t& ref : proxy->nodes[0].child)
      if (!(ref & VoxelGeometry::kBvhLeafFlag)) {
        proxy->nodes[next] = g->bvhNodes[ref];
        ref = next++;
      }
    const VoxelProxy* expected = nullptr;
    if (proxies_[voxel].compare_exchange_strong(expected, proxy.get(), std::memory_order_acq_rel)) {
      proxy.release();
      proxyBytes_.fetch_add(sizeof(VoxelProxy), std::memory_order_relaxed);
    }
  }
  const uint64_t n = g->numTriangles();
  // Contributors whose displaced geometry misses the voxel: later rays skip it without a lookup.
  // Safe to skip at any time, since a refill would be empty again (rule 1).
  if (n == 0) knownEmpty_[voxel].store(1, std::memory_order_relaxed);
  atomicMax(maxVoxelTriangles_, n);
  fillNanos_.fetch_add(uint64_t(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                    std::chrono::steady_clock::now() - start)
                                    .count()),
                       std::memory_order_relaxed);
  return g;
}

bool GridAccelerator::passes(const VoxelProxy& p, const Ray& ray, const SlabRay& sr, const glm::vec3& base,
                             const glm::vec3& scale, float limit) {
  // The decisions the BVH traversal takes first, with the same arithmetic: the root's children
  // the ray enters, then, for those that are nodes, their children. The traversal tests
  // triangles only in a leaf, and `limit` can only shrink through a hit, so a ray entering no
  // leaf here enters none there (and a root child that is a leaf is a leaf entered).
  float tNear[4];
  const int mask = enterChildren(p.nodes[0], frameSlabs(p.root, base, scale), sr, ray.tMin, limit, tNear);
  for (int i = 0; i < 4; ++i) {
    if (!(mask >> i & 1)) continue;
    const uint32_t ref = p.nodes[0].child[i];
    if (ref & VoxelGeometry::kBvhLeafFlag) return false;
    if (enterChildren(p.nodes[ref], frameSlabs(p.root.child(p.nodes[0], i), base, scale), sr, ray.tMin, limit, tNear))
      return false;
  }
  return true;
}

void GridAccelerator::intersectVoxel(uint32_t voxel, const WatertightRay& wr, const SlabRay& sr, const Ray& ray,
                                     uint64_t stamp, bool anyHit, Best& best) {
  TriangleHit h;
  // Hits up to and including best.t still count (ties go to the smaller key). The limit changes
  // only with `best`, so it is kept here rather than recomputed per triangle.
  constexpr float kInfinity = std::numeric_limits<float>::infinity();
  float limit = best.found ? std::nextafter(best.t, kInfinity) : ray.tMax;
  // Makes `h` on the triangle with this key the best hit if it beats it.
  auto improves = [&](uint32_t triangleId, uint32_t microId) {
    if (!best.better(h.t, triangleId, microId)) return false;
    best.found = true, best.t = h.t, best.triangleId = triangleId;
    best.microId = microId, best.hit = h;
    limit = std::nextafter(best.t, kInfinity);
    return true;
  };
  // Undisplaced voxels too sparse for a sub-voxel grid are tested straight from the input mesh:
  // building their voxel would cost more than it saves (the facade's baseline: 0.39 s vs 0.26 s).
  if (!grid_.anyDisplaced() && grid_.contributors(voxel).size() < kSubGridThreshold) {
    for (uint32_t id : grid_.contributors(voxel)) {
      const auto [m, t] = grid_.split(id);
      const Mesh& mesh = scene_.meshes[m];
      glm::vec3 p[3];
      for (int c = 0; c < 3; ++c) p[c] = mesh.P[mesh.indices[3 * size_t(t) + c]];
      if (!intersectTriangle(wr, p[0], p[1], p[2], ray.tMin, limit, h)) continue;
      if (!improves(id, kWholeTriangleId)) continue;
      const glm::vec2 corner[3] = {{0, 0}, {1, 0}, {0, 1}};
      for (int c = 0; c < 3; ++c) best.p[c] = p[c], best.bary[c] = corner[c];
      if (anyHit) return;
    }
    return;
  }
  // The top of a voxel's BVH outlives the voxel (VoxelProxy): a ray that passes it would test no
  // triangle, so it need not touch the cache, nor bring the voxel back.
  // The proxy's lattice is the voxel's own, so its slab set-up serves the traversal below too.
  glm::vec3 base, scale;
  bool latticeReady = false;
  if (sr.usable && !proxies_.empty()) {
    if (const VoxelProxy* p = proxies_[voxel].load(std::memory_order_acquire)) {
      lattice(p->origin, p->step, ray, sr, base, scale);
      latticeReady = true;
      if (passes(*p, ray, sr, base, scale, limit)) {
        traverseNanos_[cacheThreadShard() % kTimeShards].proxySkips.fetch_add(1, std::memory_order_relaxed);
        return;
      }
    }
  }
  const VoxelGeometry* g = cache_->acquire(voxel, stamp, [this](uint32_t v) { return buildVoxel(v); });
  // Takes `h`, a hit on triangle i, if it beats the best.
  auto accept = [&](uint32_t i, const glm::uvec3& tri) {
    const auto [triangleId, microId] = g->key(i);
    if (!improves(triangleId, microId)) return;
    // A whole input triangle's corners share vertices with other whole triangles of the voxel,
    // whose barycentrics are their own: its corners are its corners (buildVoxel).
    static constexpr glm::vec2 kCorner[3] = {{0, 0}, {1, 0}, {0, 1}};
    for (int c = 0; c < 3; ++c)
      best.p[c] = g->vertex(tri[c]), best.bary[c] = microId == kWholeTriangleId ? kCorner[c] : g->bary(tri[c]);
  };
  auto test = [&](uint32_t i) {
    const glm::uvec3 tri = g->triangle(i);
    if (intersectTriangle(wr, g->vertex(tri.x), g->vertex(tri.y), g->vertex(tri.z), ray.tMin, limit, h))
      accept(i, tri);
  };
#if defined(__SSE2__)
  // Packed positions decode in the lanes with the arithmetic of VoxelGeometry::vertex.
  const __m128 pStep = _mm_set1_ps(g->pStep);
  const __m128 pBaseAxis[3] = {_mm_set1_ps(g->pBase.x), _mm_set1_ps(g->pBase.y), _mm_set1_ps(g->pBase.z)};
  const __m128i fieldShift[3] = {_mm_cvtsi32_si128(0), _mm_cvtsi32_si128(g->pBits[0]),
                                 _mm_cvtsi32_si128(g->pBits[0] + g->pBits[1])};
  __m128i fieldMask[3];
  for (int axis = 0; axis < 3; ++axis) fieldMask[axis] = _mm_set1_epi64x(int64_t((uint64_t(1) << g->pBits[axis]) - 1));
  const size_t recordBytes = g->pBytes;
  const uint32_t packed = g->numPacked();
#endif
  // Triangles [first, end) in groups of four lanes, then in order, as `test` one by one would: a
  // lane's hit is bit-identical to the scalar test's, and re-checked against the limit the lanes
  // before it may have lowered.
  auto testRange = [&](uint32_t first, uint32_t end) {
#if !defined(__SSE2__)
    for (uint32_t k = first; k < end && !(anyHit && best.found); ++k) test(k);
#else
    for (uint32_t k = first; k < end; k += 4) {
      const uint32_t n = std::min(4u, end - k);
      glm::uvec3 tri[4];
      for (uint32_t j = 0; j < 4; ++j) tri[j] = g->triangle(k + std::min(j, n - 1));  // short groups repeat their last
      Corners4 corners;
      bool allPacked = true;
      for (uint32_t j = 0; j < 4; ++j) allPacked &= tri[j].x < packed && tri[j].y < packed && tri[j].z < packed;
      if (allPacked) {
        // The four lanes' records of a corner load as two pairs of 64-bit words; each axis's
        // field is cut out of all four with the voxel's shift and mask, gathered into one
        // vector and decoded there, with the arithmetic of VoxelGeometry::vertex.
        const uint8_t* records = g->packedP.data();
        auto load2 = [&](uint32_t v0, uint32_t v1) {
          return _mm_unpacklo_epi64(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(records + recordBytes * v0)),
                                    _mm_loadl_epi64(reinterpret_cast<const __m128i*>(records + recordBytes * v1)));
        };
        auto lanes = [](__m128i w01, __m128i w23, __m128i shift, __m128i mask) {
          const __m128 a = _mm_castsi128_ps(_mm_and_si128(_mm_srl_epi64(w01, shift), mask));
          const __m128 b = _mm_castsi128_ps(_mm_and_si128(_mm_srl_epi64(w23, shift), mask));
          return _mm_cvtepi32_ps(_mm_castps_si128(_mm_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0))));
        };
        __m128* out[3] = {corners.a, corners.b, corners.c};
        for (int corner = 0; corner < 3; ++corner) {
          const __m128i w01 = load2(tri[0][corner], tri[1][corner]), w23 = load2(tri[2][corner], tri[3][corner]);
          for (int axis = 0; axis < 3; ++axis)
            out[corner][axis] = _mm_add_ps(pBaseAxis[axis], _mm_mul_ps(lanes(w01, w23, fieldShift[axis], fieldMask[axis]), pStep));
        }
      } else {
        glm::vec3 v[4][3];
        for (uint32_t j = 0; j < 4; ++j)
          for (int corner = 0; corner < 3; ++corner) v[j][corner] = g->vertex(tri[j][corner]);
        corners = cornersOf(v);
      }
      TriangleHits4 hits;
      unsigned undecided = 0;
      const unsigned lanes = (1u << n) - 1;
      const unsigned mask = intersectTriangles4(wr, corners, ray.tMin, limit, hits, undecided) & lanes;
      undecided &= lanes;
      if (!(mask | undecided)) continue;
      for (uint32_t j = 0; j < n; ++j) {
        if (undecided >> j & 1) {
          test(k + j);
        } else if ((mask >> j & 1) && hits.t[j] < limit) {
          h.t = hits.t[j], h.b0 = hits.b0[j], h.b1 = hits.b1[j], h.b2 = hits.b2[j];
          accept(k + j, tri[j]);
        }
        if (anyHit && best.found) return;
      }
    }
#endif
  };
  if (!g->bvhNodes.empty() && sr.usable) {
    // Slab tests against the decoded boxes, as t = base + q * scale per axis.
    if (!latticeReady) lattice(g->bvhOrigin, g->bvhStep, ray, sr, base, scale);
    const float tLow = ray.tMin;
    // Node and entry distance in separate arrays: a pop that reloads both halves of one 8-byte
    // entry written as two 4-byte stores stalls on store forwarding. Entries are node indices or
    // leaves (kBvhLeafFlag), so leaves too are visited nearest first.
    uint32_t stackNode[kBvhStack];
    float stackT[kBvhStack];
    VoxelGeometry::BvhFrame stackFrame[kBvhStack];  // of nodes (leaves need none)
    int top = 0;
    stackNode[top] = 0, stackT[top] = tLow, stackFrame[top] = g->bvhRoot, ++top;
    while (top > 0 && !(anyHit && best.found)) {
      --top;
      if (stackT[top] > limit) continue;  // a nearer hit was found since it was pushed
      const uint32_t ref = stackNode[top];
      if (ref & VoxelGeometry::kBvhLeafFlag) {
        const uint32_t first = ref & 0xffffffu, count = (ref >> 24) & 0x7fu;
        testRange(first, first + count);
        continue;
      }
      const VoxelGeometry::BvhNode& node = g->bvhNodes[ref];
      const VoxelGeometry::BvhFrame frame = stackFrame[top];
      float tNear[4];
      const int mask = enterChildren(node, frameSlabs(frame, base, scale), sr, tLow, limit, tNear);
      if (!mask) continue;
      // Push the entered children farthest first, so the nearest is popped next.
      int hitSlot[4];
      float hitT[4];
      int hits = 0;
      for (int i = 0; i < 4; ++i) {
        if (!(mask >> i & 1)) continue;
        int j = hits++;
        for (; j > 0 && hitT[j - 1] < tNear[i]; --j) hitSlot[j] = hitSlot[j - 1], hitT[j] = hitT[j - 1];
        hitSlot[j] = i, hitT[j] = tNear[i];
      }
      for (int j = 0; j < hits; ++j) {
        const uint32_t child = node.child[hitSlot[j]];
        stackNode[top] = child, stackT[top] = hitT[j];
        if (!(child & VoxelGeometry::kBvhLeafFlag)) stackFrame[top] = frame.child(node, hitSlot[j]);
        ++top;
      }
    }
  } else if (g->subResolution.x == 0) {  // a direction the BVH cannot take, or a sparse sub-grid voxel
    testRange(0, g->numTriangles());
  } else {
    // Walk the sub-cells along the ray's whole passage through the (padded) voxel box, so every
    // stored triangle the ray meets inside the voxel is tested, whatever the outer DDA's rounding.
    const glm::vec3 hi = g->subOrigin + glm::vec3(g->subResolution) * g->subCellSize;
    float t0 = std::max(ray.tMin, 0.0f), t1 = ray.tMax;
    if (clipToBox(ray.origin, ray.direction, g->subOrigin, hi, t0, t1)) {
      Dda dda(ray.origin, ray.direction, g->subOrigin, g->subCellSize, g->subResolution, t0);
      const int r = g->subResolution.x;
      for (;;) {
        const size_t c = (size_t(dda.cell.z) * r + dda.cell.y) * r + dda.cell.x;
        const uint32_t end = g->subOffset(c + 1);
        for (uint32_t k = g->subOffset(c); k < end; ++k) {
          test(g->subTriangle(k));
          if (anyHit && best.found) break;
        }
        if (anyHit && best.found) break;
        const float tExit = dda.tExit();
        if (best.found && best.t < tExit) break;
        if (tExit > t1 || !dda.advance()) break;
      }
    }
  }
  cache_->release(voxel);
}

uint64_t GridAccelerator::nextStamp() {
  // Stamps are taken from the shared clock in blocks, so the one shared write on the ray path
  // happens once per kStampBlock rays: threads' stamps then agree to within a block, which LRU
  // order can afford, and one thread takes exactly the sequence a per-ray count would give.
  struct Block {
    uint64_t accel = 0, next = 0, end = 0;
  };
  thread_local Block block;
  if (block.accel != id_ || block.next == block.end) {
    block.accel = id_;
    block.next = clock_.fetch_add(kStampBlock, std::memory_order_relaxed);
    block.end = block.next + kStampBlock;
  }
  return block.next++;
}

void GridAccelerator::addTraverseTime(uint64_t startTicks) {
  const uint64_t end = readTicks();
  // A thread moved between cores whose counters disagree must not add a wrapped-around span.
  if (end <= startTicks) return;
  traverseNanos_[cacheThreadShard() % kTimeShards].ticks.fetch_add(end - startTicks, std::memory_order_relaxed);
}

template <bool kAnyHit>
void GridAccelerator::traverse(const Ray& ray, Best& best) {
  const Bounds3& bounds = grid_.bounds();
  const glm::vec3 o = ray.origin, d = ray.direction;
  // A ray with NaN/Inf parts, or no direction, hits nothing (callers get no hit, never a hang).
  if (!std::isfinite(o.x + o.y + o.z + d.x + d.y + d.z) || d == glm::vec3(0.0f)) return;
  const WatertightRay wr(ray);
  if (!outside_.empty()) {
    // The undisplaced triangles outside the grid first: a hit there shortens the walk below.
    // Hits up to and including best.t count, ties going to the smaller key, as in the voxels.
    constexpr float kInfinity = std::numeric_limits<float>::infinity();
    auto limit = [&] { return best.found ? std::nextafter(best.t, kInfinity) : ray.tMax; };
    const glm::vec2 corner[3] = {{0, 0}, {1, 0}, {0, 1}};
    outside_.forEach(ray, std::max(ray.tMin, 0.0f), limit,
                     [&](uint32_t id, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
                       TriangleHit h;
                       if (!intersectTriangleDouble(ray, wr, a, b, c, ray.tMin, limit(), h) ||
                           !best.better(h.t, id, kWholeTriangleId))
                         return false;
                       best.found = true, best.t = h.t, best.triangleId = id;
                       best.microId = kWholeTriangleId, best.hit = h;
                       best.p[0] = a, best.p[1] = b, best.p[2] = c;
                       for (int k = 0; k < 3; ++k) best.bary[k] = corner[k];
                       return kAnyHit;
                     });
    if (kAnyHit && best.found) return;
  }
  float t0 = std::max(ray.tMin, 0.0f);
  float t1 = best.found ? std::min(ray.tMax, std::nextafter(best.t, std::numeric_limits<float>::infinity())) : ray.tMax;
  if (!clipToBox(ray.origin, ray.direction, bounds.lo, bounds.hi, t0, t1)) return;
  Dda dda(ray.origin, ray.direction, bounds.lo, grid_.voxelSize(), grid_.resolution(), t0);
  const SlabRay sr(ray);
  const uint64_t stamp = nextStamp();
  for (;;) {
    const float tExit = dda.tExit();
    const uint32_t voxel = grid_.voxelIndex(dda.cell);
    if (grid_.hasContributors(voxel) && !knownEmpty_[voxel].load(std::memory_order_relaxed)) {
      intersectVoxel(voxel, wr, sr, ray, stamp, kAnyHit, best);
      if (kAnyHit && best.found) return;
      if (best.found && best.t < tExit) return;
    }
    if (tExit > t1 || !dda.advance()) return;
  }
}

std::optional<Hit> GridAccelerator::intersect(const Ray& ray) {
  Best best;
  const uint64_t start = readTicks();
  traverse<false>(ray, best);
  addTraverseTime(start);
  if (!best.found) return std::nullopt;
  Hit hit;
  hit.t = best.t;
  hit.P = ray.origin + best.t * ray.direction;
  if (!faceNormal(best.p[0], best.p[1], best.p[2], &hit.Ng)) hit.Ng = -glm::normalize(ray.direction);
  const auto [m, t] = grid_.split(best.triangleId);
  const Mesh& mesh = scene_.meshes[m];
  const glm::vec2 b = best.hit.b0 * best.bary[0] + best.hit.b1 * best.bary[1] + best.hit.b2 * best.bary[2];
  glm::vec2 st[3];
  const glm::vec2 corner[3] = {{0, 0}, {1, 0}, {0, 1}};
  for (int c = 0; c < 3; ++c) {
    const uint32_t i = mesh.indices[3 * size_t(t) + c];
    st[c] = mesh.st.size() == mesh.P.size()   ? mesh.st[i]
            : mesh.uv.size() == mesh.P.size() ? mesh.uv[i]
                                              : corner[c];
  }
  hit.st = (1.0f - b.x - b.y) * st[0] + b.x * st[1] + b.y * st[2];
  hit.bary = b;
  hit.meshIndex = m;
  hit.triangleIndex = t;
  hit.microIndex = best.microId;
  return hit;
}

bool GridAccelerator::occluded(const Ray& ray) {
  Best best;
  const uint64_t start = readTicks();
  traverse<true>(ray, best);
  addTraverseTime(start);
  return best.found;
}

AccelStats GridAccelerator::stats() const {
  AccelStats s;
  s.budgetTriangles = options_.cacheBudgetTriangles;
  s.contributorEntries = grid_.numEntries();
  s.outsideTriangles = grid_.outside().size();
  s.gridResolution = grid_.resolution();
  uint64_t traverse = 0;
  for (const TimeShard& shard : traverseNanos_) traverse += shard.ticks.load(std::memory_order_relaxed);
  traverse = uint64_t(double(traverse) * nanosPerTick());
  // Without displacement the cache holds input triangles only: none of its counts are about
  // displaced geometry, which is what the statistics report (docs/statistics.md), and building a
  // voxel of input triangles counts as intersecting it.
  if (!grid_.anyDisplaced()) {
    s.intersectSeconds = double(traverse) * 1e-9;
    return s;
  }
  const CacheStats c = cache_->stats();
  s.accesses = c.accesses, s.hits = c.hits;
  s.compulsoryMisses = c.compulsoryMisses, s.capacityMisses = c.capacityMisses;
  s.displacedTrianglesCreated = c.createdTriangles;
  s.peakResidentTriangles = c.peakResidentTriangles, s.residentTriangles = c.residentTriangles;
  s.peakResidentBytes = c.peakResidentBytes, s.residentBytes = c.residentBytes;
  s.createdBytes = c.createdBytes, s.evictions = c.evictions;
  s.budgetViolations = c.budgetViolations;
  s.droppedContributors = droppedContributors_.load(std::memory_order_relaxed);
  s.maxVoxelTriangles = maxVoxelTriangles();
  s.sideCacheHits = sideHits_.load(std::memory_order_relaxed);
  s.sideCacheMisses = sideMisses_.load(std::memory_order_relaxed);
  s.sideCachePeakTriangles = sidePeak_.load(std::memory_order_relaxed);
  for (const TimeShard& shard : traverseNanos_) s.proxySkips += shard.proxySkips.load(std::memory_order_relaxed);
  s.memoBytes = subtreeBytes_.load(std::memory_order_relaxed) + proxyBytes_.load(std::memory_order_relaxed) +
                subtreeMemos_.size() * sizeof(subtreeMemos_[0]) + proxies_.size() * sizeof(proxies_[0]);
  s.uniqueDisplacedTriangles = uniqueTriangles_.load(std::memory_order_relaxed);
  s.shaderPoints = shaderPoints_.load(std::memory_order_relaxed);
  s.trianglesBeforeSimplification = simplifyBefore_.load(std::memory_order_relaxed);
  s.trianglesAfterSimplification = simplifyAfter_.load(std::memory_order_relaxed);
  const double displace = double(displaceTicks_.load(std::memory_order_relaxed)) * nanosPerTick() * 1e-9;
  s.displaceSeconds = displace;
  const double fill = double(fillNanos_.load(std::memory_order_relaxed)) * 1e-9;
  s.subdivideSeconds = std::max(0.0, fill - displace);
  s.intersectSeconds = std::max(0.0, double(traverse) * 1e-9 - fill);
  return s;
}

RlfStatus GridAccelerator::shaderStatus() const {
  RlfStatus s{};
  s.nonFinite = nonFinite_.load(), s.loopLimit = loopLimit_.load();
  s.indexClamped = indexClamped_.load(), s.unknownSpace = unknownSpace_.load();
  s.textureErrors = textureErrors_.load();
  return s;
}

std::unique_ptr<Accelerator> makeGridAccelerator(const Scene& scene, const AccelOptions& options) {
  return std::make_unique<GridAccelerator>(scene, options);
}

}  // namespace relief
