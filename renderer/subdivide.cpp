// Adaptive crack-free subdivision with batched displacement (see subdivide.h for the scheme).
#include "renderer/subdivide.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <tuple>

#include "renderer/atomic_max.h"
#include "renderer/ticks.h"

namespace relief {
namespace {

struct Float3Soa {
  std::vector<float> x, y, z;
  void resize(size_t n) { x.resize(n), y.resize(n), z.resize(n); }
  void set(size_t i, glm::vec3 v) { x[i] = v.x, y[i] = v.y, z[i] = v.z; }
  glm::vec3 get(size_t i) const { return {x[i], y[i], z[i]}; }
  RlfFloat3Array view(size_t first = 0) { return {x.data() + first, y.data() + first, z.data() + first}; }
};

// Undisplaced attributes of the vertices of one subdivision, structure of arrays. The arrays only
// grow (their length is the capacity, `count` the vertices in use): a new vertex costs one
// capacity check instead of one per array, and every field of it is written by whoever appends it.
// P, N, u, v, s and t are kept as the shader batch takes them (RlfShadingBatch), so a batch points
// into them instead of copying them.
struct Vertices {
  Float3Soa P, N;
  // Per-vertex dP/du and dP/dv (Mesh::dPdu), interpolated like N; only when `derivatives`.
  Float3Soa dPdu, dPdv;
  bool derivatives = false;
  std::vector<float> u, v, s, t;
  std::vector<glm::vec2> bary;
  std::vector<uint8_t> level;
  std::vector<uint8_t> decided;  // midpoints: kUndecided, kQueued or kFlatEdge (its edge's decision)
  std::vector<glm::vec3> displaced;
  uint32_t count = 0;
  void clear() { count = 0; }
  void truncate(uint32_t n) { count = n; }
  uint32_t size() const { return count; }
  glm::vec2 uv(uint32_t k) const { return {u[k], v[k]}; }
  glm::vec2 st(uint32_t k) const { return {s[k], t[k]}; }
  void setUv(uint32_t k, glm::vec2 p) { u[k] = p.x, v[k] = p.y; }
  void setSt(uint32_t k, glm::vec2 p) { s[k] = p.x, t[k] = p.y; }
  // The index of a new vertex, its fields to be written by the caller.
  uint32_t append() {
    if (count == u.size()) grow();
    return count++;
  }
  void grow() {
    const size_t n = std::max<size_t>(256, 2 * u.size());
    P.resize(n), N.resize(n), u.resize(n), v.resize(n), s.resize(n), t.resize(n);
    dPdu.resize(n), dPdv.resize(n);
    bary.resize(n), level.resize(n);
    decided.resize(n), displaced.resize(n);
  }
};

// Vertices::decided of a midpoint.
constexpr uint8_t kUndecided = 0, kQueued = 1, kFlatEdge = 2;

// The SoA buffers of one shader batch, reused across calls on one thread.
struct Batch {
  Float3Soa Ng, dPdu, dPdv, dNdu, dNdv, Pout, Nout;  // P, N, u, v, s, t: views into the Vertices
  std::vector<float> du, dv, dsdu, dsdv, dtdu, dtdv;
  // Elements [0, constCount) of the fields uniform over an input triangle (Ng, dPdu, dPdv, dNdu,
  // dNdv, the s/t seeds) already hold the current triangle's values: each call fills them once.
  uint32_t constCount = 0;
  void grow(size_t n) {
    if (Pout.x.size() < n) resize(std::max(n, 2 * Pout.x.size()));
  }
  void resize(size_t n) {
    for (Float3Soa* a : {&Ng, &dPdu, &dPdv, &dNdu, &dNdv, &Pout, &Nout}) a->resize(n);
    for (std::vector<float>* a : {&du, &dv, &dsdu, &dsdv, &dtdu, &dtdv}) a->resize(n);
  }
};

// Edge (vertex pair) -> midpoint index, or -1 for an edge kept whole. Open addressing with
// generation stamps: clearing between triangles is O(1), and nothing is allocated per edge (the
// node allocations of std::unordered_map dominated fills).
class EdgeMap {
 public:
  void clear() {
    if (++generation_ == 0) {  // stamps wrapped: really clear
      for (Slot& slot : slots_) slot.stamp = 0;
      generation_ = 1;
    }
    size_ = 0;
  }
  // Returns the value slot for `key` and whether it was just inserted (then holding -1).
  std::pair<int32_t*, bool> tryEmplace(uint64_t key) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    size_t i = hash(key);
    while (slots_[i].stamp == generation_) {
      if (slots_[i].key == key) return {&slots_[i].value, false};
      i = (i + 1) & (slots_.size() - 1);
    }
    slots_[i] = {key, -1, generation_};
    ++size_;
    return {&slots_[i].value, true};
  }
  // Starts loading `key`'s slot: a fill's tables outgrow the L2 cache, and each probe of them
  // would otherwise wait for memory.
  void prefetch(uint64_t key) const {
    if (!slots_.empty()) __builtin_prefetch(&slots_[hash(key)]);
  }
  int64_t find(uint64_t key) const {
    if (slots_.empty()) return -1;
    size_t i = hash(key);
    while (slots_[i].stamp == generation_) {
      if (slots_[i].key == key) return slots_[i].value;
      i = (i + 1) & (slots_.size() - 1);
    }
    return -1;
  }

 private:
  // Fibonacci hashing: the product's top bits depend on every bit of the key (its low bits would
  // see only the larger vertex index, so the edges around a vertex would share a slot).
  size_t hash(uint64_t k) const { return size_t((k * 0x9E3779B97F4A7C15ull) >> shift_); }
  void grow() {
    std::vector<Slot> old = std::move(slots_);
    const size_t capacity = std::max<size_t>(64, old.size() * 2);
    slots_.assign(capacity, Slot{});
    shift_ = 64 - std::countr_zero(capacity);
    const uint32_t oldGeneration = generation_;
    generation_ = 1;
    size_ = 0;
    for (const Slot& slot : old)
      if (slot.stamp == oldGeneration) *tryEmplace(slot.key).first = slot.value;
  }
  // 16-byte slots: a probe reads one cache line, not one per field.
  struct Slot {
    uint64_t key = 0;
    int32_t value = 0;  // vertex counts stay far below 2^31 (memory runs out first)
    uint32_t stamp = 0;
  };
  std::vector<Slot> slots_;
  uint32_t generation_ = 1;
  size_t size_ = 0;
  int shift_ = 63;
};

// The edge map's key of edge (a, b) either way round: (min << 32) | max, as the smaller of the two
// packings, which compiles to a conditional move (half the edges come each way round, so a branch
// on the order mispredicts often).
inline uint64_t edgeKey(uint32_t a, uint32_t b) {
  return std::min((uint64_t(a) << 32) | b, (uint64_t(b) << 32) | a);
}

struct Scratch {
  Vertices vertices;
  Batch batch;
  std::vector<uint32_t> active, next;  // 3 indices per triangle
  std::vector<uint32_t> outIndices, outIds;  // the finished triangles (MicroMesh::indices, ids)
  std::vector<uint32_t> activeCodes, nextCodes;  // path code (or ancestor code) per triangle
  std::vector<uint32_t> ranks;                   // finished triangles per ancestor code
  std::vector<int64_t> mids;                     // per active triangle edge: midpoint or < 0
  struct ProbeSlot {
    uint64_t key;  // not a pointer into `edges`: the table may grow while probes are collected
    uint32_t a, b, mid;
    bool flat;
    bool known;  // decided by the memo: no lookahead
  };
  std::vector<ProbeSlot> probes;
  struct Look {
    uint32_t probe, a, b, mid;
  };
  std::vector<Look> looks, nextLooks;
  std::vector<int64_t> centre;  // per active triangle: its centre vertex when split 1-to-3, or -1
  struct Interior {
    uint32_t triangle;  // its index in the active list
    uint32_t v[3];      // its corners
    int depth;          // samples on the uniform subdivision with 2^depth steps per edge
    int sampleLevel;    // the samples' vertex level (their du, dv): the corners' deepest + depth
    bool flat;          // every sample evaluated so far lies within the flatness
    uint32_t firstProbe, numProbes;  // this stage's samples
  };
  std::vector<Interior> interiors;
  EdgeMap edges;  // (min, max) vertex pair -> midpoint, or -1: kept
  std::vector<uint32_t> culledCodes;  // subtrees culled by this subdivision
  std::vector<CullBox> subtreeBoxes;  // per subtree slot: the box of its kept micro-triangles
  std::vector<uint8_t> subtreeCut;    // per subtree slot: some part of it was culled
  std::vector<uint64_t> subtreeDecisions;  // per subtree slot: decisions made, as in SubtreeMemo
  std::vector<uint32_t> candidates;        // this round's interior candidates (active triangle)
  std::vector<std::pair<uint32_t, uint64_t>> edgeCalls;  // this round's split edges: code, key
  std::vector<uint32_t> decisionIndex;     // per subtree slot: decisions met so far
};

// Frame of the input triangle shared by all its vertices: geometric normal, dP/du and dP/dv of its
// (u, v) parameterisation, and the seeds.
struct TriangleFrame {
  glm::vec3 Ng, dPdu, dPdv;
  glm::vec3 dNdu{0}, dNdv{0};  // derivative seeds of N (language.md 6.4): zero on flat faces
  float dsdu = 1, dsdv = 0, dtdu = 0, dtdv = 1;  // seeds of s and t
  bool ngFollowsN = false;  // Mesh::smoothSurface: each vertex's Ng is its N
  // World length of a unit step of (u, v) on meshes without per-vertex derivatives (polygons and
  // subdivision meshes, whose (u, v) is the object-space (x, y)): the object-to-current scale.
  float paramScale = 1.0f;
};

bool finite(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Whether (u, v) corners q map the triangle one to one: degenerate relative to their own edges,
// since polygons take object-space (x, y) as (u, v) and an absolute threshold would depend on units.
bool regularMap(const glm::vec2 q[3]) {
  const glm::vec2 d1 = q[1] - q[0], d2 = q[2] - q[0];
  const float det = d1.x * d2.y - d1.y * d2.x;
  return det != 0.0f && std::fabs(det) > 1e-6f * glm::length(d1) * glm::length(d2) && std::isfinite(det);
}

// `reversed`: the surface's orientation is inside out (Orientation, ReverseOrientation), so its
// geometric normal opposes the winding's, as the corners' normals (cornerData) do.
TriangleFrame makeFrame(const glm::vec3 p[3], const glm::vec3 n[3], const glm::vec2 uvIn[3],
                        const glm::vec2 st[3], bool smoothNormals, bool reversed) {
  // The derivatives (dPdu, dPdv, the s, t and N seeds, du and dv) need a regular map from the
  // triangle. Where (u, v) is degenerate (a polygon seen edge-on from the z axis takes its
  // object-space (x, y) as (u, v), RI spec) they come from st when that is regular, else from
  // the corners' barycentric map; the shader still reads the true u and v.
  static const glm::vec2 corner[3] = {{0, 0}, {1, 0}, {0, 1}};
  const glm::vec2* uv = regularMap(uvIn) ? uvIn : regularMap(st) ? st : corner;
  TriangleFrame f;
  glm::vec3 e1 = p[1] - p[0], e2 = p[2] - p[0];
  glm::vec3 ng = glm::cross(e1, e2);
  float len = glm::length(ng);
  if (len > 0.0f && std::isfinite(len)) {
    f.Ng = (reversed ? -ng : ng) / len;
  } else {
    // Zero-area triangles (sphere poles): fall back to the shading normals so no NaN reaches the
    // shader.
    glm::vec3 sum = n[0] + n[1] + n[2];
    float sl = glm::length(sum);
    f.Ng = sl > 0.0f && std::isfinite(sl) ? sum / sl : glm::vec3(0, 0, 1);
  }
  glm::vec2 d1 = uv[1] - uv[0], d2 = uv[2] - uv[0];
  float det = d1.x * d2.y - d1.y * d2.x;
  if (std::fabs(det) > 1e-12f) {
    f.dPdu = (e1 * d2.y - e2 * d1.y) / det;
    f.dPdv = (e2 * d1.x - e1 * d2.x) / det;
    // s, t and N vary linearly over the triangle: the same inverse of the (u, v) map gives their
    // derivatives. Without it (degenerate uv) the defaults say st = uv and N is constant.
    const glm::vec2 s1 = st[1] - st[0], s2 = st[2] - st[0];
    f.dsdu = (s1.x * d2.y - s2.x * d1.y) / det, f.dsdv = (s2.x * d1.x - s1.x * d2.x) / det;
    f.dtdu = (s1.y * d2.y - s2.y * d1.y) / det, f.dtdv = (s2.y * d1.x - s1.y * d2.x) / det;
    if (smoothNormals) {
      const glm::vec3 n1 = n[1] - n[0], n2 = n[2] - n[0];
      f.dNdu = (n1 * d2.y - n2 * d1.y) / det;
      f.dNdv = (n2 * d1.x - n1 * d2.x) / det;
    }
    if (!std::isfinite(f.dsdu + f.dsdv + f.dtdu + f.dtdv)) f.dsdu = 1, f.dsdv = 0, f.dtdu = 0, f.dtdv = 1;
    if (!finite(f.dNdu) || !finite(f.dNdv)) f.dNdu = f.dNdv = glm::vec3(0);
  } else {
    glm::vec3 a = std::fabs(f.Ng.x) > 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
    f.dPdu = glm::normalize(glm::cross(a, f.Ng));
    f.dPdv = glm::cross(f.Ng, f.dPdu);
  }
  if (!finite(f.dPdu) || !finite(f.dPdv)) f.dPdu = f.dPdv = glm::vec3(0);
  return f;
}

// The frame of triangle corners p of `mesh` under `disp`.
TriangleFrame makeFrame(const Mesh& mesh, const glm::vec3 p[3], const glm::vec3 n[3], const glm::vec2 uv[3],
                        const glm::vec2 st[3], const Displacement& disp) {
  const bool smoothNormals = mesh.N.size() == mesh.P.size();
  TriangleFrame f = makeFrame(p, n, uv, st, smoothNormals, disp.reverseOrientation);
  f.ngFollowsN = mesh.smoothSurface && smoothNormals;
  const float* m = disp.spaces.currentFromObject;  // column-major
  const glm::mat3 linear(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
  const float scale = std::cbrt(std::fabs(glm::determinant(linear)));
  f.paramScale = scale > 0.0f && std::isfinite(scale) ? scale : 1.0f;
  return f;
}

// Points per shader call. A round of a fine subdivision makes hundreds of thousands of vertices,
// and a batch for all of them held ~110 bytes a point per thread (9 MB of a 10%-budget render's
// peak on the 5M-triangle facade); the call's own cost is negligible at this size.
constexpr uint32_t kShaderBatchPoints = 4096;

// Displaces vertices [first, end) in one shader call; falls back to the undisplaced P where the
// shader returns a non-finite position.
// `shading`: an evaluation for the shading normal at a hit (displacedShadingNormal), kept out of
// the shader's problem counts (they count displaced vertices); its status goes to *shadingStatus.
void displaceBatch(const Displacement& disp, const TriangleFrame& frame, Vertices& vs, uint32_t first,
                   uint32_t end, Batch& batch, SubdivideCounters& counters, RlfStatus* shadingStatus) {
  const uint32_t n = end - first;
  if (n == 0) return;
  batch.grow(n);
  for (uint32_t i = batch.constCount; i < n; ++i) {
    batch.Ng.set(i, frame.Ng);
    batch.dPdu.set(i, frame.dPdu);
    batch.dPdv.set(i, frame.dPdv);
    batch.dNdu.set(i, frame.dNdu);
    batch.dNdv.set(i, frame.dNdv);
    batch.dsdu[i] = frame.dsdu, batch.dsdv[i] = frame.dsdv;
    batch.dtdu[i] = frame.dtdu, batch.dtdv[i] = frame.dtdv;
  }
  batch.constCount = std::max(batch.constCount, n);
  // du and dv: the parametric step that moves the undisplaced surface by the target edge length,
  // the spacing of the finished tessellation. A function of the vertex alone (its own dPdu and
  // dPdv where the mesh has them, else the mesh's scale), never of its level or of the input
  // triangle: filtered lookups (filterwidth, area, texture footprints) then vary smoothly and agree
  // on both sides of every shared edge, so a shader displacing by them neither cracks nor jumps
  // between levels. Where a derivative vanishes (a pole), the other one's step stands in.
  const float edge = disp.edgeLength > 0.0f && std::isfinite(disp.edgeLength) ? disp.edgeLength : 1.0f;
  auto step = [edge](float own, float other) {
    const float length = own > 0.0f ? own : other > 0.0f ? other : 1.0f;
    const float d = edge / length;
    return d > 0.0f && std::isfinite(d) ? d : edge;
  };
  if (vs.derivatives) {
    for (uint32_t i = 0; i < n; ++i) {
      const float lu = glm::length(vs.dPdu.get(first + i)), lv = glm::length(vs.dPdv.get(first + i));
      batch.du[i] = step(lu, lv), batch.dv[i] = step(lv, lu);
    }
  } else {
    const float d = step(frame.paramScale, 0.0f);
    std::fill_n(batch.du.data(), n, d), std::fill_n(batch.dv.data(), n, d);
  }
  // The ABI has the shader write every output; preset them anyway so a shader that does not
  // cannot leak an earlier batch's values (thread-dependent) into the geometry.
  const size_t bytes = size_t(n) * sizeof(float);
  std::memcpy(batch.Pout.x.data(), &vs.P.x[first], bytes), std::memcpy(batch.Pout.y.data(), &vs.P.y[first], bytes);
  std::memcpy(batch.Pout.z.data(), &vs.P.z[first], bytes), std::memcpy(batch.Nout.x.data(), &vs.N.x[first], bytes);
  std::memcpy(batch.Nout.y.data(), &vs.N.y[first], bytes), std::memcpy(batch.Nout.z.data(), &vs.N.z[first], bytes);
  RlfShadingBatch b{};
  b.count = n;
  b.P = vs.P.view(first), b.N = vs.N.view(first), b.Ng = frame.ngFollowsN ? vs.N.view(first) : batch.Ng.view();
  if (vs.derivatives)
    b.dPdu = vs.dPdu.view(first), b.dPdv = vs.dPdv.view(first);
  else
    b.dPdu = batch.dPdu.view(), b.dPdv = batch.dPdv.view();
  b.u = &vs.u[first], b.v = &vs.v[first], b.s = &vs.s[first], b.t = &vs.t[first];
  b.du = batch.du.data(), b.dv = batch.dv.data();
  b.dsdu = batch.dsdu.data(), b.dsdv = batch.dsdv.data();
  b.dtdu = batch.dtdu.data(), b.dtdv = batch.dtdv.data();
  b.dNdu = batch.dNdu.view(), b.dNdv = batch.dNdv.view();
  b.spaces = &disp.spaces;
  // printf output comes from the displaced vertices only: a shading-time evaluation may repeat
  // (a pixel put aside and traced again), which would make the output depend on the threads.
  b.services = shadingStatus ? nullptr : disp.services;
  b.Pout = batch.Pout.view(), b.Nout = batch.Nout.view();
  RlfStatus status{};
  const uint64_t start = readTicks();
  disp.shader->evaluate(b, status);
  if (shadingStatus) {
    *shadingStatus = status;
    return;
  }
  const uint64_t stop = readTicks();
  if (stop > start) counters.displaceTicks += stop - start;  // cores' counters may disagree by a little
  counters.shaderPoints += n;
  counters.status.loopLimit += status.loopLimit;
  counters.status.indexClamped += status.indexClamped;
  counters.status.unknownSpace += status.unknownSpace;
  counters.status.textureErrors += status.textureErrors;
  counters.status.splineBasis += status.splineBasis;
  uint32_t replaced = 0, outOfBound = 0;
  // Squared, with a relative slack so that rounding on a point displaced exactly by the bound
  // does not count.
  const float bound2 = disp.boundWorld * disp.boundWorld * (1.0f + 1e-5f);
  float maxMove = 0.0f, anyMove2 = 0.0f;
  for (uint32_t i = 0; i < n; ++i) {
    glm::vec3 p = batch.Pout.get(i);
    if (finite(p)) {
      vs.displaced[first + i] = p;
      const glm::vec3 d = p - vs.P.get(first + i);
      const float move2 = glm::dot(d, d);
      anyMove2 = std::max(anyMove2, move2);
      if (move2 > bound2) {
        // In double where the square overflows (a move of 1e20 was reported as "inf").
        ++outOfBound;
        maxMove = std::max(maxMove, std::isfinite(move2) ? std::sqrt(move2) : float(glm::length(glm::dvec3(d))));
      }
    } else {
      vs.displaced[first + i] = vs.P.get(first + i);
      ++replaced;
    }
  }
  if (ShaderProblemCounts* pc = disp.problems.get(); pc && n > 0 && !pc->evaluated.load(std::memory_order_relaxed))
    pc->evaluated.store(true, std::memory_order_relaxed);
  if (ShaderProblemCounts* pc = disp.problems.get(); pc && anyMove2 > 0.0f) {
    // Only the bound's order of magnitude is compared against it: an overflowed square is as good.
    const float move = std::sqrt(anyMove2);
    uint32_t bits;
    std::memcpy(&bits, &move, 4);
    if (bits > pc->maxMoveBits.load(std::memory_order_relaxed)) atomicMax(pc->maxMoveBits, bits);
  }
  if (outOfBound) {
    if (ShaderProblemCounts* pc = disp.problems.get()) {
      pc->outOfBound.fetch_add(outOfBound, std::memory_order_relaxed);
      const float excess = maxMove - disp.boundWorld;
      uint32_t bits;
      std::memcpy(&bits, &excess, 4);
      atomicMax(pc->maxExcessBits, bits);
    }
  }
  // The shader may count the points it knows are non-finite and the host counts what it had to
  // replace; they are the same points, so take the larger rather than the sum.
  counters.status.nonFinite += std::max(status.nonFinite, replaced);
  if (ShaderProblemCounts* pc = disp.problems.get()) {
    auto add = [](std::atomic<uint64_t>& to, uint32_t n) {
      if (n) to.fetch_add(n, std::memory_order_relaxed);
    };
    add(pc->nonFinite, std::max(status.nonFinite, replaced));
    add(pc->badNormal, status.badNormal);
    add(pc->loopLimit, status.loopLimit), add(pc->indexClamped, status.indexClamped);
    if (status.loopLimit && pc->pointLimit && pc->loopLimit.load(std::memory_order_relaxed) > kLoopLimitStop) {
      pc->loopRunaway.store(true, std::memory_order_relaxed);
      pc->runaway.store(true, std::memory_order_relaxed);
    }
    add(pc->unknownSpace, status.unknownSpace), add(pc->textureErrors, status.textureErrors);
    add(pc->splineBasis, status.splineBasis);
  }
}

// Displaces vertices [first, vs.size()) in calls of at most kShaderBatchPoints.
void displace(const Displacement& disp, const TriangleFrame& frame, Vertices& vs, uint32_t first,
              Batch& batch, SubdivideCounters& counters, RlfStatus* shadingStatus = nullptr) {
  const uint32_t end = vs.size();
  const ShaderProblemCounts* pc = disp.problems.get();
  for (uint32_t from = first; from < end;) {
    if (pc && pc->runaway.load(std::memory_order_relaxed)) {
      // The render is stopping: the points left keep their undisplaced positions (nothing of
      // this subdivision is used).
      for (uint32_t i = from; i < end; ++i) vs.displaced[i] = vs.P.get(i);
      break;
    }
    const bool looping = pc && pc->loopLimit.load(std::memory_order_relaxed) != 0;
    const uint32_t to = from + std::min(end - from, looping ? kLoopLimitBatchPoints : kShaderBatchPoints);
    displaceBatch(disp, frame, vs, from, to, batch, counters, shadingStatus);
    from = to;
  }
}

// Appends the midpoint of edge (a, b). Every attribute is 0.5 * (x_a + x_b): addition commutes
// exactly, so both triangles sharing the edge get the same bits whichever way round they see it.
uint32_t addMidpoint(Vertices& vs, uint32_t a, uint32_t b) {
  const uint32_t m = vs.append();
  vs.P.set(m, 0.5f * (vs.P.get(a) + vs.P.get(b)));
  glm::vec3 n = vs.N.get(a) + vs.N.get(b);
  float len = glm::length(n);
  vs.N.set(m, len > 0.0f && std::isfinite(len) ? n / len : vs.N.get(std::min(a, b)));
  vs.setUv(m, 0.5f * (vs.uv(a) + vs.uv(b)));
  vs.setSt(m, 0.5f * (vs.st(a) + vs.st(b)));
  if (vs.derivatives) {
    vs.dPdu.set(m, 0.5f * (vs.dPdu.get(a) + vs.dPdu.get(b)));
    vs.dPdv.set(m, 0.5f * (vs.dPdv.get(a) + vs.dPdv.get(b)));
  }
  vs.bary[m] = 0.5f * (vs.bary[a] + vs.bary[b]);
  vs.level[m] = uint8_t(std::max(vs.level[a], vs.level[b]) + 1);
  vs.decided[m] = kUndecided;
  vs.displaced[m] = glm::vec3(0.0f);
  return m;
}

void push(std::vector<uint32_t>& list, uint32_t a, uint32_t b, uint32_t c) {
  list.push_back(a), list.push_back(b), list.push_back(c);
}

// Hard limit on Displacement::maxDepth: 4^16 micro-triangles per input triangle is already beyond
// any memory; vertex levels are stored in 8 bits.
constexpr int kMaxSubdivisionDepth = 16;

// Interior flatness samples a triangle on the points of its uniform subdivision to at most this
// depth ((2^d - 1)(2^d - 2) / 2 points: 465 at 5).
constexpr int kMaxInteriorDepth = 5;

// Appends the point with barycentric weights (wa, wb, wc) of triangle (a, b, c) at `level`. Used
// for interior samples and centres only, which no other triangle sees, so no symmetry is needed.
uint32_t addInteriorPoint(Vertices& vs, uint32_t a, uint32_t b, uint32_t c, float wa, float wb,
                          float wc, int level) {
  const uint32_t m = vs.append();
  vs.P.set(m, wa * vs.P.get(a) + wb * vs.P.get(b) + wc * vs.P.get(c));
  const glm::vec3 n = wa * vs.N.get(a) + wb * vs.N.get(b) + wc * vs.N.get(c);
  const float len = glm::length(n);
  vs.N.set(m, len > 0.0f && std::isfinite(len) ? n / len : vs.N.get(a));
  vs.setUv(m, wa * vs.uv(a) + wb * vs.uv(b) + wc * vs.uv(c));
  vs.setSt(m, wa * vs.st(a) + wb * vs.st(b) + wc * vs.st(c));
  if (vs.derivatives) {
    vs.dPdu.set(m, wa * vs.dPdu.get(a) + wb * vs.dPdu.get(b) + wc * vs.dPdu.get(c));
    vs.dPdv.set(m, wa * vs.dPdv.get(a) + wb * vs.dPdv.get(b) + wc * vs.dPdv.get(c));
  }
  vs.bary[m] = wa * vs.bary[a] + wb * vs.bary[b] + wc * vs.bary[c];
  vs.level[m] = uint8_t(level);
  vs.decided[m] = kUndecided;
  vs.displaced[m] = glm::vec3(0.0f);
  return m;
}

float distanceToSegment2(glm::vec3 p, glm::vec3 q, glm::vec3 m) {
  const glm::vec3 e = q - p, d = m - p;
  const float ee = glm::dot(e, e);
  const float t = ee > 0.0f ? std::clamp(glm::dot(d, e) / ee, 0.0f, 1.0f) : 0.0f;
  const glm::vec3 off = d - t * e;
  return glm::dot(off, off);
}

// Whether `m` lies within `tolerance` of the (closed) triangle (a, b, c).
bool nearTriangle(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 m, float tolerance) {
  const glm::vec3 n = glm::cross(b - a, c - a);
  const float nn = glm::dot(n, n);
  if (nn > 0.0f) {
    const float h = glm::dot(m - a, n);
    const glm::vec3 q = m - (h / nn) * n;  // projection onto the plane
    const bool inside = glm::dot(glm::cross(b - a, q - a), n) >= 0.0f &&
                        glm::dot(glm::cross(c - b, q - b), n) >= 0.0f &&
                        glm::dot(glm::cross(a - c, q - c), n) >= 0.0f;
    if (inside) return h * h <= tolerance * tolerance * nn;
  }
  const float d2 = std::min({distanceToSegment2(a, b, m), distanceToSegment2(b, c, m),
                             distanceToSegment2(c, a, m)});
  return d2 <= tolerance * tolerance;
}

// Whether `m` lies within `tolerance` of segment (p, q); symmetric in p and q bit for bit, as the
// end points are put in a canonical (lexicographic) order first.
bool nearChord(glm::vec3 p, glm::vec3 q, glm::vec3 m, float tolerance) {
  if (std::tie(q.x, q.y, q.z) < std::tie(p.x, p.y, p.z)) std::swap(p, q);
  return distanceToSegment2(p, q, m) <= tolerance * tolerance;
}

bool boxesOverlap(const CullBox& a, const CullBox& b) {
  return a.lo.x <= b.hi.x && b.lo.x <= a.hi.x && a.lo.y <= b.hi.y && b.lo.y <= a.hi.y &&
         a.lo.z <= b.hi.z && b.lo.z <= a.hi.z;
}

// Whether the displaced descendants of triangle (a, b, c) may reach `box`: they lie within
// `bound` of the undisplaced triangle (the displacement bound the contributor grid relies on too).
bool mayReach(const Vertices& vs, uint32_t a, uint32_t b, uint32_t c, float bound, const CullBox& box) {
  const glm::vec3 pa = vs.P.get(a), pb = vs.P.get(b), pc = vs.P.get(c);
  glm::vec3 lo = glm::min(pa, glm::min(pb, pc)) - glm::vec3(bound);
  glm::vec3 hi = glm::max(pa, glm::max(pb, pc)) + glm::vec3(bound);
  lo = glm::min(lo, glm::min(vs.displaced[a], glm::min(vs.displaced[b], vs.displaced[c])));
  hi = glm::max(hi, glm::max(vs.displaced[a], glm::max(vs.displaced[b], vs.displaced[c])));
  return boxesOverlap({lo, hi}, box);
}

// What this subdivision found and `known` lacks: the boxes of the subtrees `out` holds whole (no
// part culled), and the decisions of the subtrees it processed.
void learnSubtrees(const MicroMesh& out, const std::vector<glm::vec3>& P, Scratch& scratch,
                   const SubtreeMemo* known, std::vector<LearntSubtree>& learnt) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  // Only the rounds this subdivision reached (most input triangles of a fine mesh stop early).
  uint32_t deepest = 1;
  for (uint32_t id : out.ids) deepest = std::max(deepest, id >> kMicroRankBits);
  for (uint32_t code : scratch.culledCodes) deepest = std::max(deepest, code);
  const int rounds = (31 - __builtin_clz(deepest)) / 2;
  const uint32_t slots = subtreeSlots(rounds);
  scratch.subtreeBoxes.assign(slots, CullBox{glm::vec3(kInf), glm::vec3(-kInf)});
  scratch.subtreeCut.assign(slots, 0);
  for (uint32_t code : scratch.culledCodes)
    for (uint32_t c = code; c != 0; c >>= 2) scratch.subtreeCut[subtreeSlot(c)] = 1;
  // Each triangle into its own subtree's box, then each box into its parent's, deepest first.
  for (size_t i = 0; i < out.ids.size(); ++i) {
    const uint32_t* tri = &out.indices[3 * i];
    CullBox& b = scratch.subtreeBoxes[subtreeSlot(out.ids[i] >> kMicroRankBits)];
    b.lo = glm::min(b.lo, glm::min(P[tri[0]], glm::min(P[tri[1]], P[tri[2]])));
    b.hi = glm::max(b.hi, glm::max(P[tri[0]], glm::max(P[tri[1]], P[tri[2]])));
  }
  for (int round = rounds; round > 0; --round)
    for (uint32_t code = 1u << (2 * round); code < 2u << (2 * round); ++code) {
      const CullBox& b = scratch.subtreeBoxes[subtreeSlot(code)];
      CullBox& parent = scratch.subtreeBoxes[subtreeSlot(code >> 2)];
      parent.lo = glm::min(parent.lo, b.lo), parent.hi = glm::max(parent.hi, b.hi);
    }
  // A subtree's box needs the whole subtree; its decisions only the subtree's own triangles: for a
  // subtree of an earlier round, the one triangle, decided before any child could be culled (and
  // a culled subtree made none).
  CullBox ignored;
  for (int round = 0; round <= rounds; ++round)
    for (uint32_t code = 1u << (2 * round); code < 2u << (2 * round); ++code) {
      const uint32_t slot = subtreeSlot(code);
      const CullBox& b = scratch.subtreeBoxes[slot];
      const bool newBox = !scratch.subtreeCut[slot] && b.lo.x <= b.hi.x && !(known && known->box(code, ignored));
      uint64_t decisions = slot < scratch.subtreeDecisions.size() ? scratch.subtreeDecisions[slot] : 0;
      if (decisions == ~uint64_t(0) || (known && known->decisions(code))) decisions = 0;
      if (newBox || decisions) learnt.push_back({code, newBox, b, decisions});
    }
}

}  // namespace

SubtreeMemo::SubtreeMemo(const CullBox& reference, int rounds)
    : lo_(reference.lo),
      // 254 steps across the reference: the lattice's last point lies a step beyond its top, so
      // rounding cannot leave a box touching the top unrepresentable.
      step_((reference.hi - reference.lo) / 254.0f),
      slots_(subtreeSlots(std::clamp(rounds, 0, kCullRounds))),
      boxes_(std::make_unique<std::atomic<uint64_t>[]>(slots_)),
      decisions_(std::make_unique<std::atomic<uint64_t>[]>(slots_)) {
  for (uint32_t i = 0; i < slots_; ++i) {
    boxes_[i].store(0, std::memory_order_relaxed);
    decisions_[i].store(0, std::memory_order_relaxed);
  }
}

bool SubtreeMemo::box(uint32_t code, CullBox& box) const {
  const uint32_t slot = subtreeSlot(code);
  const uint64_t w = slot < slots_ ? boxes_[slot].load(std::memory_order_relaxed) : 0;
  if (w == 0) return false;
  for (int a = 0; a < 3; ++a) {
    box.lo[a] = decode(a, uint32_t(w >> (8 * a)) & 255u);
    box.hi[a] = decode(a, uint32_t(w >> (8 * (a + 3))) & 255u);
  }
  return true;
}

void SubtreeMemo::learn(uint32_t code, const CullBox* box, uint64_t decisions) {
  const uint32_t slot = subtreeSlot(code);
  if (slot >= slots_) return;
  if (decisions) decisions_[slot].store(decisions, std::memory_order_relaxed);
  if (!box) return;
  uint64_t w = uint64_t(1) << 63;
  for (int a = 0; a < 3; ++a) {
    // The lattice point at or below lo, and the one at or above hi; a box the lattice cannot hold
    // (outside the reference, or not finite) is not kept.
    if (!(box->lo[a] >= decode(a, 0)) || !(box->hi[a] <= decode(a, 255))) return;
    const float scale = step_[a] > 0.0f ? 1.0f / step_[a] : 0.0f;
    if (!std::isfinite(scale)) return;  // a subnormal step: the lattice is useless
    // Both products are finite and non-negative here (the box lies on the lattice's span).
    uint32_t qlo = uint32_t(std::clamp((box->lo[a] - lo_[a]) * scale, 0.0f, 255.0f));
    while (qlo > 0 && decode(a, qlo) > box->lo[a]) --qlo;
    uint32_t qhi = uint32_t(std::clamp(std::ceil((box->hi[a] - lo_[a]) * scale), 0.0f, 255.0f));
    while (qhi < 255 && decode(a, qhi) < box->hi[a]) ++qhi;
    if (decode(a, qlo) > box->lo[a] || decode(a, qhi) < box->hi[a]) return;
    w |= uint64_t(qlo) << (8 * a) | uint64_t(qhi) << (8 * (a + 3));
  }
  boxes_[slot].store(w, std::memory_order_relaxed);
}

namespace {

// The corners of input triangle `triangle` as the shader sees them at level 0. A shader displaces
// along the normals the RI spec gives the surface: on a surface whose orientation is reversed (`Displacement::reverseOrientation`)
// its own normals point inward, so `P += Km * N` dents what it raises on the outside-facing twin;
// normals the scene gave (Mesh::givenNormals) stay as given.
void cornerData(const Mesh& mesh, uint32_t triangle, const Displacement* disp, glm::vec3 p[3], glm::vec3 n[3],
                glm::vec2 uv[3], glm::vec2 st[3]) {
  const glm::vec2 cornerBary[3] = {{0, 0}, {1, 0}, {0, 1}};
  for (int c = 0; c < 3; ++c) {
    const uint32_t i = mesh.indices[3 * size_t(triangle) + c];
    p[c] = mesh.P[i];
    // Attribute arrays of the wrong length are treated as absent (the reader should reject them;
    // here they must not be read out of bounds).
    uv[c] = mesh.uv.size() != mesh.P.size() ? cornerBary[c] : mesh.uv[i];
    st[c] = mesh.st.size() != mesh.P.size() ? uv[c] : mesh.st[i];
  }
  glm::vec3 faceN = glm::cross(p[1] - p[0], p[2] - p[0]);
  float faceLen = glm::length(faceN);
  faceN = faceLen > 0.0f && std::isfinite(faceLen) ? faceN / faceLen : glm::vec3(0, 0, 1);
  const bool reversed = disp && shaderNormalsReversed(mesh, *disp);
  for (int c = 0; c < 3; ++c) {
    n[c] = mesh.N.size() != mesh.P.size() ? faceN : mesh.N[mesh.indices[3 * size_t(triangle) + c]];
    if (reversed) n[c] = -n[c];
  }
}

// The three corners as the first vertices of a subdivision (level 0, displaced = undisplaced until
// the shader runs).
void pushCorners(Vertices& vs, const Mesh& mesh, uint32_t triangle, const glm::vec3 p[3], const glm::vec3 n[3],
                 const glm::vec2 uv[3], const glm::vec2 st[3]) {
  const glm::vec2 cornerBary[3] = {{0, 0}, {1, 0}, {0, 1}};
  vs.derivatives = mesh.dPdu.size() == mesh.P.size() && mesh.dPdv.size() == mesh.P.size();
  for (int c = 0; c < 3; ++c) {
    const uint32_t k = vs.append();
    vs.P.set(k, p[c]), vs.N.set(k, n[c]), vs.setUv(k, uv[c]), vs.setSt(k, st[c]);
    if (vs.derivatives) {
      const uint32_t i = mesh.indices[3 * size_t(triangle) + size_t(c)];
      vs.dPdu.set(k, mesh.dPdu[i]), vs.dPdv.set(k, mesh.dPdv[i]);
    }
    vs.bary[k] = cornerBary[c], vs.level[k] = 0, vs.displaced[k] = p[c];
    vs.decided[k] = kUndecided;
  }
}

}  // namespace

bool displacedShadingNormal(const Mesh& mesh, uint32_t triangle, const Displacement& disp, glm::vec2 bary,
                            glm::vec3* normal) {
  if (!disp.shader || triangle >= mesh.numTriangles()) return false;
  glm::vec3 p[3], n[3];
  glm::vec2 uv[3], st[3];
  cornerData(mesh, triangle, &disp, p, n, uv, st);
  // One vertex where the hit is, made from the corners as subdivision makes its interior points,
  // at the level the subdivision of the undisplaced triangle reaches; only it is evaluated.
  thread_local Vertices vs;
  thread_local Batch batch;
  vs.clear();
  batch.constCount = 0;
  pushCorners(vs, mesh, triangle, p, n, uv, st);
  const int target = undisplacedLevels(p, disp.edgeLength, std::clamp(disp.maxDepth, 0, kMaxSubdivisionDepth));
  addInteriorPoint(vs, 0, 1, 2, 1.0f - bary.x - bary.y, bary.x, bary.y, target);
  const TriangleFrame frame = makeFrame(mesh, p, n, uv, st, disp);
  SubdivideCounters counters;  // shading-time evaluations stay out of the fill statistics
  RlfStatus status{};
  displace(disp, frame, vs, 3, batch, counters, &status);
  // As language.md §7 says, a bad final N (the shader then returns the input N) shades with the
  // micro-triangle's own normal, and so does an invocation that hit the loop limit.
  if (status.badNormal || status.nonFinite || status.loopLimit) return false;
  const glm::vec3 out = batch.Nout.get(0);
  const float outLen = glm::length(out);
  if (!(outLen > 0.0f) || !std::isfinite(outLen)) return false;
  *normal = out / outLen;
  return true;
}

void subdivideTriangle(const Mesh& mesh, uint32_t triangle, const Displacement* displacement,
                       MicroMesh& out, SubdivideCounters& counters, const CullBox* cull,
                       const SubtreeMemo* known, std::vector<LearntSubtree>* learnt) {
  thread_local Scratch scratch;
  scratch.batch.constCount = 0;  // a new triangle: its uniform fields must be filled again
  Vertices& vs = scratch.vertices;
  vs.clear();
  glm::vec3 p[3], n[3];
  glm::vec2 uv[3], st[3];
  cornerData(mesh, triangle, displacement, p, n, uv, st);
  pushCorners(vs, mesh, triangle, p, n, uv, st);

  const bool displaced = displacement != nullptr && displacement->shader != nullptr;
  out.indices.clear();
  out.ids.clear();
  scratch.outIndices.clear();
  scratch.outIds.clear();
  if (learnt) learnt->clear();
  scratch.culledCodes.clear();
  scratch.edgeCalls.clear();
  scratch.subtreeDecisions.clear();
  // Simplification decisions are numbered per subtree when they may be read from or written to a
  // memo (only simplification makes any).
  const bool memoize = (known || learnt) && displaced && displacement->flatness > 0.0f;
  if (memoize) {
    scratch.decisionIndex.assign(kSubtreeSlots, 0);
    if (learnt) scratch.subtreeDecisions.assign(kSubtreeSlots, 0);
  }
  if (displaced) {
    const Displacement& disp = *displacement;
    const int maxDepth = std::clamp(disp.maxDepth, 0, kMaxSubdivisionDepth);
    const TriangleFrame frame = makeFrame(mesh, p, n, uv, st, disp);
    const float edgeLength2 = disp.edgeLength * disp.edgeLength;
    const uint64_t pointsBefore = counters.shaderPoints;
    displace(disp, frame, vs, 0, scratch.batch, counters);

    std::vector<uint32_t>& active = scratch.active;
    std::vector<uint32_t>& next = scratch.next;
    auto& edges = scratch.edges;
    active.assign({0, 1, 2});
    std::vector<uint32_t>& activeCodes = scratch.activeCodes;
    std::vector<uint32_t>& nextCodes = scratch.nextCodes;
    activeCodes.assign({1});
    const float cullGrow = std::max(0.0f, disp.boundWorld);
    // Whether this subdivision can teach `known` anything: a subtree of the last cull round, or
    // one finished earlier, kept without a known box, or a decision made afresh. (Boxes of
    // coarser subtrees are learnt only along with one of these.)
    bool learnable = !cull || !known;
    uint64_t samplePoints = 0;  // interior samples, evaluated and dropped
    uint64_t depthLimited = 0;  // edges that wanted splitting at the depth guard
    edges.clear();
    // Edge-map values: a midpoint (>= 0), -1 (short or at the depth limit), or kFlat (wanted
    // splitting, but simplification found the whole edge flat).
    constexpr int64_t kFlat = -2;
    const bool simplify = disp.flatness > 0.0f;
    using Probe = Scratch::ProbeSlot;
    std::vector<Probe>& probes = scratch.probes;
    // Returns the midpoint of edge (a, b), creating it if the edge wants splitting (its displaced
    // end points farther apart than edgeLength, and depth left); kKept otherwise. Reads only the
    // edge's two end vertices, so both sides of a shared edge get the same answer.
    auto expand = [&](uint32_t a, uint32_t b) -> int64_t {
      const uint64_t key = edgeKey(a, b);
      auto [value, inserted] = edges.tryEmplace(key);
      if (inserted) {
        const glm::vec3 d = vs.displaced[a] - vs.displaced[b];
        const bool wants = glm::dot(d, d) > edgeLength2;
        const bool allowed = std::max(vs.level[a], vs.level[b]) + 1 <= maxDepth;
        if (wants && allowed) *value = int32_t(addMidpoint(vs, a, b));
        depthLimited += wants && !allowed;
      }
      return *value;
    };
    // A triangle's edge: as expand, and with simplification the first sight of a split edge
    // queues its flatness decision (the midpoint may already exist from a lookahead).
    // Each subtree's simplification decisions (edges as its triangles ask for them, then its
    // interior candidates, round by round) are numbered for the memo; a decision the memo holds
    // is taken from it (applied with the round's others, so later asks see the same edge map).
    auto memoDecision = [&](uint32_t code, bool& flat) {
      const uint32_t index = scratch.decisionIndex[subtreeSlot(code)]++;
      const uint64_t memo = known ? known->decisions(code) : 0;
      if (!memo || index >= ((memo >> 56) & 127u)) {
        learnable = true;
        return false;
      }
      flat = (memo >> index) & 1u;
      return true;
    };
    auto recordDecision = [&](uint32_t code, bool flat) {
      uint64_t& w = scratch.subtreeDecisions[subtreeSlot(code)];
      const uint32_t count = uint32_t(w >> 56) & 127u;
      if (count >= uint32_t(SubtreeMemo::kMaxDecisions)) {
        w = ~uint64_t(0);  // overflowed: not memoized
        return;
      }
      w = (w & ((uint64_t(1) << 56) - 1)) | (uint64_t(flat) << count) | (uint64_t(count + 1) << 56) |
          (uint64_t(1) << 63);
    };
    auto midpoint = [&](uint32_t a, uint32_t b, uint32_t code) -> int64_t {
      const int64_t mid = expand(a, b);
      if (simplify && mid >= 0) {
        const uint64_t key = edgeKey(a, b);
        bool flat = false;
        const bool memoized = memoize && memoDecision(code, flat);
        if (learnt) scratch.edgeCalls.push_back({code, key});
        if (vs.decided[size_t(mid)] == kUndecided) {
          vs.decided[size_t(mid)] = kQueued;
          probes.push_back({key, a, b, uint32_t(mid), memoized ? flat : true, memoized});
        }
      }
      return mid;
    };
    // What the edge map holds now for an edge whose answer `mid` came from midpoint() earlier in
    // this round: the only change since can be its decision that the edge stays whole
    // (decideFlatEdges), which marks its midpoint; this spares a second hash lookup per edge.
    auto settled = [&](int64_t mid) -> int64_t {
      return mid >= 0 && vs.decided[size_t(mid)] == kFlatEdge ? kFlat : mid;
    };
    // Simplification, edge part (paper 3.1, made crack-free): an edge that wants splitting is kept
    // whole when every point its own recursive subdivision would create along it (the points the
    // unsimplified mesh has on it) lies within `flatness` of its displaced chord. The lookahead
    // walks only the edge's own descendants, each split by the same rule as everywhere, so the
    // decision depends on the edge alone and both sides of a shared edge agree. The points it
    // evaluates are real midpoints (kept in the edge map): when the edge does split, its halves
    // reuse them.
    auto decideFlatEdges = [&]() {
      auto& looks = scratch.looks;
      auto& nextLooks = scratch.nextLooks;
      looks.clear();
      for (uint32_t i = 0; i < probes.size(); ++i) {
        const Probe& pr = probes[i];
        if (!pr.known) looks.push_back({i, pr.a, pr.mid, 0}), looks.push_back({i, pr.mid, pr.b, 0});
      }
      // The first wave checks the probes' own midpoints (already displaced).
      for (Probe& pr : probes)
        if (!pr.known)
          pr.flat = nearChord(vs.displaced[pr.a], vs.displaced[pr.b], vs.displaced[pr.mid], disp.flatness);
      while (!looks.empty()) {
        const uint32_t first = vs.size();
        nextLooks.clear();
        for (Scratch::Look& l : looks) {
          if (!probes[l.probe].flat) continue;
          const int64_t mid = expand(l.a, l.b);
          if (mid >= 0) nextLooks.push_back({l.probe, l.a, l.b, uint32_t(mid)});
        }
        displace(disp, frame, vs, first, scratch.batch, counters);
        looks.clear();
        for (const Scratch::Look& l : nextLooks) {
          Probe& pr = probes[l.probe];
          if (!pr.flat) continue;
          if (!nearChord(vs.displaced[pr.a], vs.displaced[pr.b], vs.displaced[l.mid], disp.flatness)) {
            pr.flat = false;
            continue;
          }
          looks.push_back({l.probe, l.a, l.mid, 0}), looks.push_back({l.probe, l.mid, l.b, 0});
        }
      }
      for (const Probe& pr : probes)
        if (pr.flat) {
          *edges.tryEmplace(pr.key).first = kFlat;  // its points stay unreferenced
          vs.decided[pr.mid] = kFlatEdge;
        }
      probes.clear();
    };
    // Simplification, interior part: a triangle left with three whole edges of which at least one
    // was kept whole for flatness has lost interior detail unless its interior is flat too. It is
    // sampled on the interior points of its uniform subdivision down to the target edge length
    // (at most kMaxInteriorDepth levels) plus its centre; when all lie within `flatness` of the
    // displaced triangle it is final (the paper's merge of all its descendants), else it is split
    // 1-to-3 at its displaced centre (no new point on its edges, whose decisions are final) and
    // the children carry on. Interior points are not shared, so this cannot crack.
    auto decideInteriors = [&]() {
      auto& centre = scratch.centre;
      auto& interiors = scratch.interiors;
      centre.assign(active.size() / 3, -1);
      interiors.clear();
      scratch.candidates.clear();
      const uint32_t firstCentre = vs.size();
      for (size_t k = 0; k < active.size(); k += 3) {
        const uint32_t a = active[k], b = active[k + 1], c = active[k + 2];
        const int64_t m[3] = {settled(scratch.mids[k]), settled(scratch.mids[k + 1]), settled(scratch.mids[k + 2])};
        if (m[0] >= 0 || m[1] >= 0 || m[2] >= 0) continue;
        if (m[0] != kFlat && m[1] != kFlat && m[2] != kFlat) continue;
        const int level = std::max({vs.level[a], vs.level[b], vs.level[c]});
        if (level + 1 > maxDepth) continue;
        const float longest = std::sqrt(std::max({glm::dot(vs.displaced[a] - vs.displaced[b], vs.displaced[a] - vs.displaced[b]),
                                                  glm::dot(vs.displaced[b] - vs.displaced[c], vs.displaced[b] - vs.displaced[c]),
                                                  glm::dot(vs.displaced[c] - vs.displaced[a], vs.displaced[c] - vs.displaced[a])}));
        int depth = 1;
        while (depth < kMaxInteriorDepth && depth < maxDepth - level &&
               longest > disp.edgeLength * float(1 << depth))
          ++depth;
        // The unsimplified mesh has every point of the finest lattice, evaluated or not.
        const uint64_t steps = uint64_t(1) << depth;
        samplePoints += (steps - 1) * (steps - 2) / 2;
        scratch.candidates.push_back(uint32_t(k / 3));
        // Decided by the memo: flat (final, its centre never evaluated) or split at its centre,
        // with no samples either way.
        bool flat = false;
        if (memoize && memoDecision(activeCodes[k / 3], flat)) {
          if (flat) {
            ++samplePoints;  // the centre, unevaluated
            continue;
          }
          centre[k / 3] = addInteriorPoint(vs, a, b, c, 1.0f / 3, 1.0f / 3, 1.0f / 3, level + 1);
          continue;
        }
        centre[k / 3] = addInteriorPoint(vs, a, b, c, 1.0f / 3, 1.0f / 3, 1.0f / 3, level + 1);
        interiors.push_back({uint32_t(k / 3), {a, b, c}, depth, level + depth, true, 0, 0});
      }
      // The samples come in stages, coarse to fine: the lattice of 2^s steps per edge holds the
      // one of 2^(s-1), so stage s evaluates only the points new at s, for the triangles still
      // flat. A triangle that is not flat usually shows it at the centre or the first stages, and
      // the stages of finer samples it would have failed anyway are never evaluated. The decision
      // (every sample of the finest lattice and the centre within `flatness`) is the same as
      // evaluating them all at once: the points are the same bits (dyadic weights), and each is
      // displaced on its own.
      const uint32_t firstSample = vs.size();
      displace(disp, frame, vs, firstCentre, scratch.batch, counters);
      int deepest = 0;
      for (Scratch::Interior& in : interiors) {
        in.flat = nearTriangle(vs.displaced[in.v[0]], vs.displaced[in.v[1]], vs.displaced[in.v[2]],
                               vs.displaced[size_t(centre[in.triangle])], disp.flatness);
        if (in.flat) deepest = std::max(deepest, in.depth);
      }
      // Two steps per edge have no interior point; stages start at four.
      for (int stage = 2; stage <= deepest; ++stage) {
        const int steps = 1 << stage;
        for (Scratch::Interior& in : interiors) {
          in.numProbes = 0;
          if (!in.flat || in.depth < stage) continue;
          in.firstProbe = vs.size();
          for (int i = 1; i < steps; ++i)
            for (int j = 1; i + j < steps; ++j)
              if ((i | j) & 1)  // not on the previous stage's lattice
                addInteriorPoint(vs, in.v[0], in.v[1], in.v[2], float(steps - i - j) / float(steps),
                                 float(i) / float(steps), float(j) / float(steps), in.sampleLevel);
          in.numProbes = vs.size() - in.firstProbe;
        }
        if (vs.size() == firstSample) break;  // nothing left flat at this depth
        displace(disp, frame, vs, firstSample, scratch.batch, counters);
        for (Scratch::Interior& in : interiors) {
          const glm::vec3 A = vs.displaced[in.v[0]], B = vs.displaced[in.v[1]], C = vs.displaced[in.v[2]];
          for (uint32_t i = 0; in.flat && i < in.numProbes; ++i)
            in.flat = nearTriangle(A, B, C, vs.displaced[in.firstProbe + i], disp.flatness);
        }
        vs.truncate(firstSample);  // samples are never referenced; centres may be
      }
      for (const Scratch::Interior& in : interiors)
        if (in.flat) centre[in.triangle] = -1;  // final: the centre stays unreferenced
      if (learnt)
        for (uint32_t t : scratch.candidates) recordDecision(activeCodes[t], centre[t] < 0);
    };
    // A finished triangle's id: its own path code while rounds < kCullRounds, else its ancestor's
    // code and its rank among that ancestor's finished descendants.
    auto finish = [&](uint32_t a, uint32_t b, uint32_t c, uint32_t code, int round) {
      push(scratch.outIndices, a, b, c);
      if (round < kCullRounds && !learnable && learnt) {
        CullBox ignored;
        learnable = !known->box(code, ignored);
      }
      // Ranks saturate rather than spill into the code bits: beyond 2^23 descendants of one
      // ancestor (only near kMaxSubdivisionDepth) ids may repeat, which only weakens tie-breaks.
      const uint32_t rank =
          round > kCullRounds ? std::min(scratch.ranks[code]++, (1u << kMicroRankBits) - 1) : 0;
      scratch.outIds.push_back((code << kMicroRankBits) | rank);
    };
    // The work guard (setSubdivisionLimits): points beyond kRunawayAllowance times what the
    // undisplaced triangle asks for are this subdivision's excess, checked a round at a time (one
    // runaway subdivision takes seconds).
    const uint64_t allowance =
        kRunawayAllowance << (2 * undisplacedLevels(p, disp.edgeLength, maxDepth));
    uint64_t pointsCounted = allowance;  // points of this subdivision counted so far, past the allowance
    auto countGuardWork = [&] {
      ShaderProblemCounts* pc = disp.problems.get();
      const uint64_t spent = counters.shaderPoints - pointsBefore;
      if (!pc || !pc->pointLimit || spent <= pointsCounted) return;
      const uint64_t excess = spent - pointsCounted;
      pointsCounted = spent;
      bool runaway = spent - allowance > pc->pointLimit;
      if (spent > kGrossExcess * allowance) {
        const uint64_t total = pc->excessPoints.fetch_add(excess, std::memory_order_relaxed) + excess;
        runaway = runaway || total > kRunawaySubdivisions * pc->pointLimit;
      }
      if (runaway) pc->runaway.store(true, std::memory_order_relaxed);
    };
    for (int round = 0; !active.empty(); ++round) {
      // Ranks are counted from the first round past the cull rounds (most triangles of a fine
      // mesh finish before it).
      if (round == kCullRounds + 1) scratch.ranks.assign(size_t(1) << (1 + 2 * kCullRounds), 0);
      countGuardWork();
      if (disp.problems && disp.problems->runaway.load(std::memory_order_relaxed)) {
        // The render is stopping (setSubdivisionLimits): leave the rest, learn nothing.
        active.clear();
        learnable = false;
        break;
      }
      if (cull && round <= kCullRounds) {
        // Drop whole subtrees that cannot reach the box; ids of the kept ones do not change.
        size_t kept = 0;
        for (size_t k = 0; k < active.size(); k += 3) {
          CullBox exact;
          const bool isKnown = known && known->box(activeCodes[k / 3], exact);
          const bool reach = isKnown ? boxesOverlap(exact, *cull)
                                     : mayReach(vs, active[k], active[k + 1], active[k + 2], cullGrow, *cull);
          if (!reach) {
            if (learnt) scratch.culledCodes.push_back(activeCodes[k / 3]);
            continue;
          }
          learnable |= !isKnown && round == kCullRounds;
          for (int c = 0; c < 3; ++c) active[kept * 3 + c] = active[k + c];
          activeCodes[kept++] = activeCodes[k / 3];
        }
        active.resize(kept * 3);
        activeCodes.resize(kept);
      }
      const uint32_t firstNew = vs.size();
      // Each triangle's three answers are kept: final but for the flatness decisions, which
      // `settled` reads from the midpoints, so no edge is looked up twice a round.
      std::vector<int64_t>& mids = scratch.mids;
      mids.resize(active.size());
      constexpr size_t kPrefetchAhead = 3 * 4;  // triangles ahead, in indices
      for (size_t k = 0; k < active.size(); k += 3) {
        if (k + kPrefetchAhead + 2 < active.size()) {
          const uint32_t* f = &active[k + kPrefetchAhead];
          edges.prefetch(edgeKey(f[0], f[1])), edges.prefetch(edgeKey(f[1], f[2]));
          edges.prefetch(edgeKey(f[2], f[0]));
        }
        for (int e = 0; e < 3; ++e)
          mids[k + size_t(e)] = midpoint(active[k + e], active[k + (e + 1) % 3], activeCodes[k / 3]);
      }
      displace(disp, frame, vs, firstNew, scratch.batch, counters);
      if (simplify) {
        decideFlatEdges();
        for (const auto& [code, key] : scratch.edgeCalls) recordDecision(code, edges.find(key) == kFlat);
        scratch.edgeCalls.clear();
        decideInteriors();
      }
      next.clear();
      nextCodes.clear();
      for (size_t k = 0; k < active.size(); k += 3) {
        uint32_t v[3] = {active[k], active[k + 1], active[k + 2]};
        const uint32_t code = activeCodes[k / 3];
        const size_t firstChild = next.size() / 3;
        int64_t m[3];  // m[e] on edge (v[e], v[e+1])
        int numSplit = 0;
        for (int e = 0; e < 3; ++e) {
          m[e] = settled(mids[k + size_t(e)]);
          numSplit += m[e] >= 0;
        }
        if (numSplit == 0 && simplify && scratch.centre[k / 3] >= 0) {
          const uint32_t g = uint32_t(scratch.centre[k / 3]);
          push(next, v[0], v[1], g);
          push(next, v[1], v[2], g);
          push(next, v[2], v[0], g);
        } else if (numSplit == 0) {
          finish(v[0], v[1], v[2], code, round);
        } else if (numSplit == 3) {
          const uint32_t m0 = uint32_t(m[0]), m1 = uint32_t(m[1]), m2 = uint32_t(m[2]);
          push(next, v[0], m0, m2);
          push(next, m0, v[1], m1);
          push(next, m2, m1, v[2]);
          push(next, m0, m1, m2);
        } else if (numSplit == 1) {
          // Rotate so the split edge is (a, b).
          int e = m[0] >= 0 ? 0 : m[1] >= 0 ? 1 : 2;
          uint32_t a = v[e], b = v[(e + 1) % 3], c = v[(e + 2) % 3], mab = uint32_t(m[e]);
          push(next, a, mab, c);
          push(next, mab, b, c);
        } else {
          // Rotate so the kept edge is (c, a); split edges are (a, b) and (b, c).
          int kept = m[0] < 0 ? 0 : m[1] < 0 ? 1 : 2;
          int e = (kept + 1) % 3;
          uint32_t a = v[e], b = v[(e + 1) % 3], c = v[(e + 2) % 3];
          uint32_t mab = uint32_t(m[e]), mbc = uint32_t(m[(e + 1) % 3]);
          push(next, mab, b, mbc);
          // The quad (a, mab, mbc, c) is interior to this triangle, so any diagonal keeps the
          // mesh conforming; the shorter displaced one gives better-shaped triangles.
          glm::vec3 d1 = vs.displaced[a] - vs.displaced[mbc], d2 = vs.displaced[mab] - vs.displaced[c];
          if (glm::dot(d1, d1) <= glm::dot(d2, d2)) {
            push(next, a, mab, mbc);
            push(next, a, mbc, c);
          } else {
            push(next, a, mab, c);
            push(next, mab, mbc, c);
          }
        }
        for (size_t c = firstChild; c < next.size() / 3; ++c)
          nextCodes.push_back(round < kCullRounds ? code * 4 + uint32_t(c - firstChild) : code);
      }
      std::swap(active, next);
      std::swap(activeCodes, nextCodes);
    }
    // Built in scratch and copied once: the side cache's micro-meshes are new each time, and
    // growing their arrays triangle by triangle cost several allocations per contributor.
    out.indices.assign(scratch.outIndices.begin(), scratch.outIndices.end());
    out.ids.assign(scratch.outIds.begin(), scratch.outIds.end());
    const uint64_t after = out.indices.size() / 3;
    uint64_t before = after;
    if (simplify) {
      // A conforming triangulation of V points, B of them on the input triangle's border, has
      // 2V - B - 2 triangles (Euler); the unsimplified mesh triangulates (about) every point
      // evaluated here: the points along flat edges exactly, interiors as sampled.
      uint64_t border = 0;
      for (uint32_t i = 0; i < vs.size(); ++i) {
        const glm::vec2 b = vs.bary[i];
        border += b.x == 0.0f || b.y == 0.0f || b.x + b.y == 1.0f;
      }
      const int64_t points = int64_t(vs.size() + samplePoints);
      before = uint64_t(std::max(int64_t(after), 2 * points - int64_t(border) - 2));
    }
    counters.trianglesBeforeSimplification += before;
    counters.trianglesAfterSimplification += after;
    countGuardWork();
    if (depthLimited && disp.problems) disp.problems->depthLimited.fetch_add(depthLimited, std::memory_order_relaxed);
    // Only subtrees kept whole and still unknown are learnt: when every kept one was known (a
    // refill of a voxel whose neighbourhood was filled before) there is nothing to learn.
    if (learnt && learnable) learnSubtrees(out, vs.displaced, scratch, known, *learnt);
  } else {
    push(out.indices, 0, 1, 2);
    out.ids.push_back(kWholeTriangleId);
    ++counters.trianglesBeforeSimplification, ++counters.trianglesAfterSimplification;
  }
  out.P.assign(vs.displaced.begin(), vs.displaced.begin() + vs.size());
  out.bary.assign(vs.bary.begin(), vs.bary.begin() + vs.size());
  out.level.assign(vs.level.begin(), vs.level.begin() + vs.size());
}

int undisplacedLevels(const glm::vec3 p[3], float edgeLength, int maxDepth) {
  const float longest = std::max({glm::length(p[1] - p[0]), glm::length(p[2] - p[1]), glm::length(p[0] - p[2])});
  if (!std::isfinite(longest) || !(edgeLength > 0.0f)) return maxDepth;
  int k = 0;
  for (float l = longest; l > edgeLength && k < maxDepth; l *= 0.5f) ++k;
  return k;
}

double estimatedMicroTriangles(const Mesh& mesh, uint32_t t, const Displacement& disp) {
  const int maxDepth = std::clamp(disp.maxDepth, 0, kMaxSubdivisionDepth);
  const glm::vec3 p[3] = {mesh.P[mesh.indices[3 * size_t(t)]], mesh.P[mesh.indices[3 * size_t(t) + 1]],
                          mesh.P[mesh.indices[3 * size_t(t) + 2]]};
  return std::ldexp(1.0, 2 * undisplacedLevels(p, disp.edgeLength, maxDepth));
}

double estimatedMicroTriangles(const Mesh& mesh, const Displacement& disp) {
  double sum = 0.0;
  for (uint32_t t = 0; t < mesh.numTriangles(); ++t) sum += estimatedMicroTriangles(mesh, t, disp);
  return sum;
}

std::vector<double> setSubdivisionLimits(Scene& scene) {
  std::vector<double> estimate(scene.displacements.size(), 0.0);
  for (const Mesh& mesh : scene.meshes) {
    if (mesh.displacementIndex >= scene.displacements.size()) continue;
    const Displacement& d = scene.displacements[mesh.displacementIndex];
    if (d.shader) estimate[mesh.displacementIndex] += estimatedMicroTriangles(mesh, d);
  }
  for (Displacement& d : scene.displacements)
    if (d.problems) d.problems->pointLimit = kRunawayPoints;
  return estimate;
}

}  // namespace relief
