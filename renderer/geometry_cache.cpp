// Lookup-or-fill, pinning and LRU eviction of voxel geometry (see geometry_cache.h).
#include "renderer/geometry_cache.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstring>
#include <functional>

#include "renderer/accel.h"

namespace relief {

int cacheThreadShard() {
  static std::atomic<int> nextThread{0};
  thread_local const int shard = nextThread.fetch_add(1, std::memory_order_relaxed);
  return shard;
}

uint64_t VoxelGeometry::bytes() const {
  return sizeof(VoxelGeometry) + P.size() * sizeof(glm::vec3) + packedP.size() + bary16.size() * 2 + packedBary.size() +
         baryF.size() * sizeof(glm::vec2) + indices16.size() * 2 + indices32.size() * 4 + packedIndices.size() +
         micro32.size() * 4 + packedMicro.size() + segments.size() * sizeof(Segment) + packedIds.size() + subOffsets16.size() * 2 + subOffsets32.size() * 4 +
         subTriangles16.size() * 2 + subTriangles32.size() * 4 + bvhNodes.size() * sizeof(BvhNode);
}

namespace {

// Field i of a bit stream of `bits`-bit fields (at most 32; the stream ends in 8 bytes of pad).
uint32_t readBits(const std::vector<uint8_t>& stream, uint32_t bits, uint32_t i) {
  const uint64_t bit = uint64_t(bits) * i;
  uint64_t word;
  std::memcpy(&word, stream.data() + (bit >> 3), sizeof word);
  return uint32_t((word >> (bit & 7)) & ((uint64_t(1) << bits) - 1));
}

// A bit stream of (values[i] - base) >> shift in `bits` bits each, with the pad readBits needs.
// The stream forms of VoxelGeometry (indices, barycentrics, micro ids, input triangles) are all
// written here.
template <typename Value>
std::vector<uint8_t> writeBits(const Value* values, size_t count, uint32_t base, uint32_t bits, uint32_t shift = 0) {
  std::vector<uint8_t> stream((uint64_t(bits) * count + 7) / 8 + sizeof(uint64_t), 0);
  for (size_t i = 0; i < count; ++i) {
    const uint64_t bit = uint64_t(bits) * i;
    uint64_t word;
    std::memcpy(&word, stream.data() + (bit >> 3), sizeof word);
    word |= uint64_t((uint32_t(values[i]) - base) >> shift) << (bit & 7);
    std::memcpy(stream.data() + (bit >> 3), &word, sizeof word);
  }
  return stream;
}

}  // namespace

std::pair<uint32_t, uint32_t> VoxelGeometry::key(uint32_t i) const {
  uint32_t triangleId;
  if (!packedIds.empty()) {
    triangleId = idBase + readBits(packedIds, idBits, i);
  } else {
    const auto it = std::upper_bound(segments.begin(), segments.end(), i,
                                     [](uint32_t t, const Segment& s) { return t < s.first; });
    triangleId = (it - 1)->triangleId;
  }
  return {triangleId, unpackMicro(microBits ? readBits(packedMicro, microBits, i) : micro32[i])};
}

void VoxelGeometry::packKeys() {
  segments.shrink_to_fit();
  if constexpr (std::endian::native != std::endian::little) return;
  if (microBits || micro32.empty()) return;
  uint32_t any = 0;
  for (uint32_t m : micro32) any |= m;
  const uint32_t bits = std::max(1, int(std::bit_width(any)));
  packedMicro = writeBits(micro32.data(), micro32.size(), 0, bits);
  microBits = uint8_t(bits);
  micro32.clear(), micro32.shrink_to_fit();
  // Input triangles per triangle instead of segments, where that takes fewer bytes: voxels of
  // small input triangles (furniture, undisplaced meshes) start a segment at nearly every triangle.
  uint32_t lo = UINT32_MAX, hi = 0;
  for (const Segment& s : segments) lo = std::min(lo, s.triangleId), hi = std::max(hi, s.triangleId);
  const uint32_t idWidth = uint32_t(std::bit_width(hi - lo));
  const uint64_t streamBytes = (uint64_t(idWidth) * triangleCount + 7) / 8 + sizeof(uint64_t);
  if (streamBytes >= segments.size() * sizeof(Segment)) return;
  std::vector<uint32_t> ids(triangleCount);
  for (size_t k = 0; k < segments.size(); ++k) {
    const uint32_t end = k + 1 < segments.size() ? segments[k + 1].first : triangleCount;
    std::fill(ids.begin() + segments[k].first, ids.begin() + end, segments[k].triangleId);
  }
  packedIds = writeBits(ids.data(), ids.size(), lo, idWidth);
  idBase = lo, idBits = uint8_t(idWidth);
  segments.clear(), segments.shrink_to_fit();
}

void VoxelGeometry::packPositions(float step, const glm::vec3& centre) {
  if constexpr (std::endian::native != std::endian::little) return;
  assert(!baryPacked && !indexBits && "packPositions renumbers the build forms only");
  if (!(step > 0.0f) || P.empty() || packedCount) return;
  // The window's corner: a lattice point 2^18 steps below the centre's.
  constexpr uint32_t kWindow = 1u << kMaxStepBits;
  const glm::vec3 corner = snapToLattice(centre, step) - glm::vec3(float(kWindow / 2) * step);
  const uint32_t n = uint32_t(P.size());
  // Steps from the corner of every vertex that decodes from them exactly (UINT32_MAX: a float).
  // Exact for lattice points within 2^24 steps: the difference of two multiples of a power of
  // two, scaled by its inverse (also a power of two, so multiplying is dividing). Taken only if
  // it decodes to the vertex's own bits (which also rules out points off the lattice, -0 and NaN).
  // Per-thread scratch up to kScratchVertices (a render's voxels are far smaller), so that one
  // huge voxel does not leave its arrays behind on the thread.
  constexpr uint32_t kScratchVertices = 1u << 16;
  thread_local std::vector<glm::uvec3> stepsScratch;
  std::vector<glm::uvec3> stepsLarge;
  std::vector<glm::uvec3>& steps = n <= kScratchVertices ? stepsScratch : stepsLarge;
  steps.resize(n);
  const float inverse = 1.0f / step;
  glm::uvec3 lo(UINT32_MAX), hi(0);
  uint32_t fitting = 0;
  for (uint32_t i = 0; i < n; ++i) {
    glm::uvec3 q;
    bool fits = true;
    for (int k = 0; k < 3; ++k) {
      const float s = (P[i][k] - corner[k]) * inverse;
      const bool inWindow = s >= 0.0f && s < float(kWindow);
      q[k] = inWindow ? uint32_t(s) : 0u;
      fits &= inWindow && std::bit_cast<uint32_t>(corner[k] + float(q[k]) * step) == std::bit_cast<uint32_t>(P[i][k]);
    }
    if (!fits) {
      steps[i] = glm::uvec3(UINT32_MAX);
      continue;
    }
    steps[i] = q;
    lo = glm::min(lo, q), hi = glm::max(hi, q);
    ++fitting;
  }
  if (fitting == 0) return;
  // A few far-reaching corners can cost every vertex of the voxel bits on an axis: consider
  // narrower windows centred on the voxel (by 1-3 bits on each axis), the corners they leave out
  // kept as floats, and take whichever stores the voxel in the fewest bytes. Windows of one
  // axis nest, so a vertex's place on it, the narrowest it is in, is the number of them it is
  // in (a 4 x 4 x 4 histogram).
  int width[3];
  uint32_t windowLo[3][3], windowSpan[3][3];  // [axis][window t - 1]; span 0: no such window
  for (int k = 0; k < 3; ++k) {
    width[k] = std::bit_width(hi[k] - lo[k]);
    for (int t = 1; t <= 3; ++t) {
      const bool exists = width[k] - t >= 1;
      const uint32_t half = exists ? 1u << (width[k] - t - 1) : 0u;
      windowLo[k][t - 1] = kWindow / 2 - half, windowSpan[k][t - 1] = 2 * half;
    }
  }
  auto narrowest = [&](int k, uint32_t q) {
    return int(q - windowLo[k][0] < windowSpan[k][0]) + int(q - windowLo[k][1] < windowSpan[k][1]) +
           int(q - windowLo[k][2] < windowSpan[k][2]);
  };
  // Estimated on at most about 256 of the vertices, evenly spaced (the choice only trades bytes:
  // any choice decodes exactly, and the sample is a pure function of the voxel's vertices).
  uint32_t histogram[4][4][4] = {};
  const uint32_t stride = std::max(1u, n / 256);
  uint32_t sampled = 0;
  for (uint32_t i = 0; i < n; i += stride, ++sampled)
    if (steps[i].x != UINT32_MAX) ++histogram[narrowest(0, steps[i].x)][narrowest(1, steps[i].y)][narrowest(2, steps[i].z)];
  uint64_t bestBytes = UINT64_MAX;
  int cut[3] = {0, 0, 0};
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b)
      for (int c = 0; c < 4; ++c) {
        uint64_t inside = 0;
        for (int x = a; x < 4; ++x)
          for (int y = b; y < 4; ++y)
            for (int z = c; z < 4; ++z) inside += histogram[x][y][z];
        const uint64_t bytes = inside * uint64_t((width[0] + width[1] + width[2] - a - b - c + 7) / 8) + (sampled - inside) * 12;
        if (bytes < bestBytes) bestBytes = bytes, cut[0] = a, cut[1] = b, cut[2] = c;
      }
  if (cut[0] | cut[1] | cut[2]) {
    lo = glm::uvec3(UINT32_MAX), hi = glm::uvec3(0);
    fitting = 0;
    for (uint32_t i = 0; i < n; ++i) {
      if (steps[i].x == UINT32_MAX) continue;
      if (narrowest(0, steps[i].x) < cut[0] || narrowest(1, steps[i].y) < cut[1] || narrowest(2, steps[i].z) < cut[2]) {
        steps[i] = glm::uvec3(UINT32_MAX);
        continue;
      }
      lo = glm::min(lo, steps[i]), hi = glm::max(hi, steps[i]);
      ++fitting;
    }
    if (fitting == 0) return;
  }
  // Steps from the smallest on each axis. The base is that vertex's own coordinate (corner +
  // lo * step is exact, being a float the check above produced), so every decode below is the
  // exact sum of two lattice points whose result is a float: the vertex's bits again. Checked
  // all the same, since a vertex that would not decode must stay a float.
  const glm::vec3 base = corner + glm::vec3(lo) * step;
  uint32_t total = 0;
  for (int k = 0; k < 3; ++k) pBits[k] = uint8_t(std::bit_width(hi[k] - lo[k])), total += pBits[k];
  pBytes = uint8_t((total + 7) / 8);
  std::vector<uint8_t> stream(size_t(pBytes) * fitting + sizeof(uint64_t), 0);
  thread_local std::vector<uint32_t> orderScratch;
  std::vector<uint32_t> orderLarge;
  std::vector<uint32_t>& order = n <= kScratchVertices ? orderScratch : orderLarge;  // old -> new vertex
  order.assign(n, UINT32_MAX);
  uint32_t next = 0;
  for (uint32_t i = 0; i < n; ++i) {
    if (steps[i].x == UINT32_MAX) continue;
    const glm::uvec3 d = steps[i] - lo;
    const glm::vec3 decoded = base + glm::vec3(d) * step;
    if (std::memcmp(&decoded, &P[i], sizeof decoded) != 0) continue;
    uint64_t word;
    std::memcpy(&word, stream.data() + size_t(pBytes) * next, sizeof word);
    word |= uint64_t(d.x) | uint64_t(d.y) << pBits[0] | uint64_t(d.z) << (pBits[0] + pBits[1]);
    std::memcpy(stream.data() + size_t(pBytes) * next, &word, sizeof word);
    order[i] = next++;
  }
  if (next == 0) {
    pBits[0] = pBits[1] = pBits[2] = 0, pBytes = 0;
    return;
  }
  std::vector<glm::vec3> rest;
  // Usually every vertex fits, the order stays, and nothing needs renumbering.
  if (next < n) {
    rest.reserve(n - next);
    for (uint32_t i = 0; i < n; ++i)
      if (order[i] == UINT32_MAX) order[i] = next + uint32_t(rest.size()), rest.push_back(P[i]);
    for (uint16_t& v : indices16) v = uint16_t(order[v]);
    for (uint32_t& v : indices32) v = order[v];
    if (!bary16.empty()) {
      std::vector<uint16_t> b(bary16.size());
      for (uint32_t i = 0; i < n; ++i) b[2 * size_t(order[i])] = bary16[2 * size_t(i)], b[2 * size_t(order[i]) + 1] = bary16[2 * size_t(i) + 1];
      bary16.swap(b);
    } else if (!baryF.empty()) {
      std::vector<glm::vec2> b(baryF.size());
      for (uint32_t i = 0; i < n; ++i) b[order[i]] = baryF[i];
      baryF.swap(b);
    }
    stream.resize(size_t(pBytes) * next + sizeof(uint64_t));
  }
  packedP = std::move(stream);
  packedP.shrink_to_fit();
  packedCount = next;
  pBase = base, pStep = step;
  P = std::move(rest);
  P.shrink_to_fit();
}

void VoxelGeometry::packIndices() {
  if constexpr (std::endian::native != std::endian::little) return;
  const uint32_t n = numTriangles();
  if (indexBits || n == 0 || (indices16.empty() && indices32.empty())) return;
  const uint32_t vertices = numVertices();
  const uint32_t bits = std::max(1, int(std::bit_width(vertices > 0 ? vertices - 1 : 0u)));
  if (bits > 19 || (bits == 16 && !indices16.empty())) return;  // no room, or no gain
  // Triangle i's corners are fields 3i, 3i + 1 and 3i + 2: one 64-bit load reads all three.
  packedIndices = indices16.empty() ? writeBits(indices32.data(), indices32.size(), 0, bits)
                                    : writeBits(indices16.data(), indices16.size(), 0, bits);
  indexBits = bits;
  indices16.clear(), indices16.shrink_to_fit();
  indices32.clear(), indices32.shrink_to_fit();
}

void VoxelGeometry::setBary(const std::vector<glm::vec2>& b) {
  bary16.clear(), baryF.clear(), packedBary.clear();
  baryPacked = false, baryShift = 0;
  bary16.reserve(2 * b.size());
  for (const glm::vec2& v : b) {
    for (int c = 0; c < 2; ++c) {
      // Midpoint subdivision's barycentrics are dyadic and stay exact (a power-of-two scale);
      // simplification's 1-to-3 centre splits make thirds, which round to the nearest 2^-15.
      const float scaled = v[c] * 32768.0f;
      if (!(scaled >= 0.0f && scaled <= 32768.0f)) {  // outside the triangle, or NaN: floats
        bary16.clear();
        baryF = b;
        baryF.shrink_to_fit();
        return;
      }
      bary16.push_back(uint16_t(std::nearbyint(scaled)));
    }
  }
}

void VoxelGeometry::packBary() {
  if constexpr (std::endian::native != std::endian::little) return;
  if (baryPacked || bary16.empty()) return;
  uint16_t any = 0;
  for (uint16_t v : bary16) any |= v;
  const uint32_t shift = any ? uint32_t(std::countr_zero(any)) : 16u;
  const uint32_t bits = 16 - shift;
  // Vertex v's (b1, b2) are fields 2v and 2v + 1.
  packedBary = writeBits(bary16.data(), bary16.size(), 0, bits, shift);
  baryShift = uint8_t(shift);
  baryPacked = true;
  bary16.clear(), bary16.shrink_to_fit();
}

GeometryCache::GeometryCache(uint32_t numVoxels, uint64_t budgetTriangles)
    : slots_(numVoxels), budget_(budgetTriangles) {}

GeometryCache::~GeometryCache() {
  for (Slot& slot : slots_) delete slot.geometry;
}

const VoxelGeometry* GeometryCache::tryPin(uint32_t voxel, bool& mustFill) {
  Slot& slot = slots_[voxel];
  for (;;) {
    uint32_t word = slot.word.load(std::memory_order_acquire);
    const uint32_t state = word >> kStateShift;
    if (state == kReady) {
      if (slot.word.compare_exchange_weak(word, word + 1, std::memory_order_acquire)) {
        // Waiting for another thread's fill costs no work here: count it as a hit.
        hitShards_[cacheThreadShard() % kHitShards].hits.fetch_add(1, std::memory_order_relaxed);
        return slot.geometry;
      }
    } else if (state == kEmpty) {
      if (slot.word.compare_exchange_weak(word, kFilling << kStateShift, std::memory_order_acquire)) {
        const bool refill = slot.everFilled.exchange(true, std::memory_order_relaxed);
        (refill ? capacity_ : compulsory_).fetch_add(1, std::memory_order_relaxed);
        mustFill = true;
        return nullptr;
      }
    } else {
      if (threadDefersBusyVoxels()) throw VoxelBusy{voxel};
      slot.word.wait(word, std::memory_order_acquire);
    }
  }
}

const VoxelGeometry* GeometryCache::publish(uint32_t voxel, std::unique_ptr<VoxelGeometry> geometry) {
  Slot& slot = slots_[voxel];
  const uint64_t n = geometry->numTriangles(), bytes = geometry->bytes();
  created_.fetch_add(n, std::memory_order_relaxed);
  createdBytes_.fetch_add(bytes, std::memory_order_relaxed);
  {
    std::lock_guard lock(mutex_);
    residentTriangles_ += n;
    residentBytes_ += bytes;
    uint64_t skippedPinned = 0;
    if (residentTriangles_ > budget_) {
      // Evict least recently used first, just down to the budget: every triangle of headroom is
      // a voxel kept (a low-water mark of 7/8, to spread the scan over several fills, cost the
      // facade at a 10% budget 9% more capacity misses). A heap finds the oldest in O(resident)
      // rather than sorting them all. The slot being filled is not in resident_ yet: it survives.
      std::vector<std::pair<uint64_t, uint32_t>>& order = evictionOrder_;
      order.clear();
      for (uint32_t v : resident_) order.emplace_back(slots_[v].lastUse.load(std::memory_order_relaxed), v);
      std::make_heap(order.begin(), order.end(), std::greater<>());
      while (!order.empty() && residentTriangles_ > budget_) {
        std::pop_heap(order.begin(), order.end(), std::greater<>());
        const uint32_t v = order.back().second;
        order.pop_back();
        Slot& victim = slots_[v];
        uint32_t expected = kReady << kStateShift;  // ready with no pins
        if (!victim.word.compare_exchange_strong(expected, kEmpty << kStateShift,
                                                 std::memory_order_acq_rel)) {
          skippedPinned += victim.geometry->numTriangles();
          continue;
        }
        residentTriangles_ -= victim.geometry->numTriangles();
        residentBytes_ -= victim.geometry->bytes();
        delete victim.geometry;
        victim.geometry = nullptr;
        const uint32_t pos = victim.residentPosition;
        resident_[pos] = resident_.back();
        slots_[resident_[pos]].residentPosition = pos;
        resident_.pop_back();
        ++evictions_;
      }
    }
    // The scan above runs whenever this is over budget and stops only within it, so what it left
    // beyond the budget was pinned by readers when it tried.
    if (checkBudget_ && residentTriangles_ - n > budget_ &&
        residentTriangles_ - n - skippedPinned > budget_) {
      ++budgetViolations_;
      std::fprintf(stderr,
                   "relief: geometry cache over budget after filling voxel %u: %llu resident "
                   "(%llu pinned, %llu just filled), budget %llu\n",
                   voxel, (unsigned long long)residentTriangles_, (unsigned long long)skippedPinned,
                   (unsigned long long)n, (unsigned long long)budget_);
    }
    // The peak is taken once the fill's evictions are done: the resident set any reader can see.
    // (For a moment the new geometry and its victims coexist in memory; peak RSS shows that.)
    peakResidentTriangles_ = std::max(peakResidentTriangles_, residentTriangles_);
    peakResidentBytes_ = std::max(peakResidentBytes_, residentBytes_);
    slot.residentPosition = uint32_t(resident_.size());
    resident_.push_back(voxel);
    slot.geometry = geometry.release();
  }
  // Ready with the filler's own pin.
  slot.word.store((kReady << kStateShift) | 1, std::memory_order_release);
  slot.word.notify_all();
  return slot.geometry;
}

void GeometryCache::abandon(uint32_t voxel) {
  Slot& slot = slots_[voxel];
  slot.word.store(kEmpty << kStateShift, std::memory_order_release);
  slot.word.notify_all();
}

void GeometryCache::release(uint32_t voxel) {
  slots_[voxel].word.fetch_sub(1, std::memory_order_release);
}

CacheStats GeometryCache::stats() const {
  CacheStats s;
  for (const HitShard& shard : hitShards_) s.hits += shard.hits.load(std::memory_order_relaxed);
  s.compulsoryMisses = compulsory_.load(std::memory_order_relaxed);
  s.capacityMisses = capacity_.load(std::memory_order_relaxed);
  s.accesses = s.hits + s.compulsoryMisses + s.capacityMisses;
  s.createdTriangles = created_.load(std::memory_order_relaxed);
  s.createdBytes = createdBytes_.load(std::memory_order_relaxed);
  std::lock_guard lock(mutex_);
  s.residentTriangles = residentTriangles_;
  s.peakResidentTriangles = peakResidentTriangles_;
  s.residentBytes = residentBytes_;
  s.peakResidentBytes = peakResidentBytes_;
  s.evictions = evictions_;
  s.budgetViolations = budgetViolations_;
  return s;
}

}  // namespace relief
