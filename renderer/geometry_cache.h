// The geometry cache (paper, phase 2): per voxel, the displaced micro-triangles that overlap it,
// filled lazily on first use, budgeted in triangles and recycled least-recently-used. Owned by the
// grid accelerator; the only shared mutable state of the renderer.
//
// Fill granularity: per voxel. A fill subdivides each contributor of the voxel and keeps only the
// micro-triangles overlapping that voxel. Voxels are then independent (a fill touches one slot, so
// the state machine below needs no cross-voxel locking) and the budget counts exactly what is
// resident; the price is re-subdividing the parts of a contributor that lie within the
// displacement bound of each voxel it reaches. Subdivision culls to the voxel (subdivide.h) and the
// automatic grid keeps voxels several bounds wide (contributor_grid.h), which holds that repeated
// work to a small factor. Measured on a bumpy sphere (4096 input triangles, 831K micro-triangles,
// all voxels filled): subdividing each triangle once, whole, evaluates 506K shader points; per-voxel
// fills evaluate 1.72M at the automatic 10^3 grid, 3.07M at 16^3 and 8.85M at 32^3, and store
// 897K triangles (8% duplicates across voxel borders). With costly shaders this factor is the
// price of independent voxels. Because a voxel's content is a pure function of the voxel
// (determinism rule 1), a refill after eviction is identical. The paper's fill-once scheme and a
// side cache of whole subdivisions (AccelOptions::sideCacheTriangles, off by default) were measured
// against this on the facade; docs/cache.md records why per-voxel fills stay the default.
//
// Thread safety: each slot has one atomic word holding its state (empty, filling, ready) and a pin
// count. Readers pin a ready slot with a compare-and-swap; exactly one thread wins empty -> filling
// and the others wait on the word; eviction moves ready -> empty only from a pin count of zero (by
// compare-and-swap), so memory is never freed under a reader. Recency is a per-slot stamp written
// with a relaxed store once per ray and voxel (no lock on the ray path); the budget bookkeeping and
// the eviction scan take one mutex, only when a fill completes.
#pragma once

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>
#include <vector>

#include <glm/glm.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "renderer/contributor_grid.h"
#include "renderer/subdivide.h"

namespace relief {

// The displaced geometry resident for one voxel, stored compactly (docs/cache.md, "Density"):
// - shared vertices (lattice steps in as many bits per axis as the voxel's extent needs, or
//   floats; see packedP) with their position in the input triangle as two fixed-point numbers
//   (a vertex shared by whole input triangles, micro id kWholeTriangleId, holds the first one's:
//   a hit on a whole triangle takes its corners' barycentrics by position instead)
//   of at most 16 bits (exact for midpoint subdivision's dyadic barycentrics k / 2^level up to
//   level 15, within 2^-16 for deeper levels and simplification's centre splits; a voxel whose
//   barycentrics are all multiples of 2^-l stores l + 1 bits each; float pairs only where a value
//   lies outside [0, 1]);
// - 3 indices per triangle, as a bit stream of bit_width(vertices - 1) bits each (packIndices;
//   16- or 32-bit numbers while building and where that is no larger);
// - the (input triangle, micro-triangle) key per triangle: the micro id (rotated, see packMicro)
//   per triangle in as many bits as the voxel's largest needs, and the input triangle as a
//   segment table giving it from each segment's first triangle on, or, where that is smaller
//   (voxels of many small input triangles), per triangle in as many bits as the voxel's id range
//   needs. Keys are only needed at a hit (tie-breaking and reporting);
// - the sub-voxel grid over dense voxels with 16-bit cell offsets and triangle references where
//   they fit.
// Face normals are computed at a hit, so no per-vertex normals are stored.
struct VoxelGeometry {
  struct Segment {
    uint32_t first;       // first triangle of the segment
    uint32_t triangleId;  // global input triangle id
  };
  // Vertex positions. Displaced vertices are points of the scene's position lattice (multiples of
  // a power of two, snapToLattice). Those packed come first, as lattice steps from pBase (the
  // smallest on each axis) in pBits[axis] bits each, the bits of their extent on that axis, in
  // records of pBytes bytes read with one unaligned 64-bit load (packedP, pBase, pStep; whole
  // bytes, so that four lanes decode with shifts common to all). They lie in a window of 2^19
  // steps per axis around the voxel, or a narrower one where that stores the voxel in fewer
  // bytes (packPositions). The rest (corners of large simplified triangles reaching far out)
  // follow as floats (P), as every vertex does on big-endian machines. Both forms decode to the
  // same floats: a vertex shared by two voxels is the same bits in both.
  std::vector<uint8_t> packedP;  // vertices [0, numPacked()), then 8 bytes of pad
  std::vector<glm::vec3> P;      // vertices [numPacked(), numVertices())
  glm::vec3 pBase{0};
  float pStep = 0;
  uint32_t packedCount = 0;
  uint8_t pBits[3] = {0, 0, 0};
  uint8_t pBytes = 0;
  // Barycentrics (b1, b2) * 2^15, rounded: 16-bit numbers while building (bary16); a finished
  // voxel keeps them shifted right by baryShift (the trailing zero bits all of them share) as a
  // bit stream of 2 x (16 - baryShift) bits per vertex (packedBary, packBary).
  std::vector<uint16_t> bary16;
  std::vector<uint8_t> packedBary;  // ends in 8 bytes of pad
  uint8_t baryShift = 0;
  bool baryPacked = false;
  std::vector<glm::vec2> baryF;     // where a value lies outside [0, 1]: (b1, b2)
  // Triangles' corners. Built as 16-bit (at most 65536 vertices) or 32-bit numbers; a finished
  // voxel keeps them as a bit stream of 3 x indexBits bits per triangle, indexBits being the bits
  // of its largest vertex number, so one unaligned 64-bit load reads a triangle (packIndices).
  std::vector<uint16_t> indices16;
  std::vector<uint32_t> indices32;
  std::vector<uint8_t> packedIndices;  // ends in 8 bytes of pad for the 64-bit loads
  uint32_t indexBits = 0;              // 0: not packed
  // Per triangle, packMicro(micro id): 32-bit numbers while building (micro32); a finished voxel
  // keeps them as a bit stream of microBits bits each (packedMicro, packKeys).
  std::vector<uint32_t> micro32;
  std::vector<uint8_t> packedMicro;  // ends in 8 bytes of pad
  uint8_t microBits = 0;             // 0: not packed
  uint32_t triangleCount = 0;
  std::vector<Segment> segments;     // empty once packedIds holds the input triangles
  std::vector<uint8_t> packedIds;    // per triangle: input triangle - idBase, in idBits bits
  uint32_t idBase = 0;
  uint8_t idBits = 0;

  // Sub-voxel grid over dense voxels (kSubGridThreshold triangles or more): cells in compressed
  // rows of triangle indices; empty when the voxel is sparse.
  glm::ivec3 subResolution{0};
  glm::vec3 subOrigin{0};
  float subCellSize = 0;
  std::vector<uint16_t> subOffsets16;    // cell c's references: [offset(c), offset(c + 1)),
  std::vector<uint32_t> subOffsets32;    // 16-bit while there are fewer than 65536 references
  std::vector<uint16_t> subTriangles16;  // when numTriangles() <= 65536
  std::vector<uint32_t> subTriangles32;  // otherwise

  // Per-voxel BVH over every voxel with triangles (the default; the sub-grid above is the alternative kept for
  // measurement, docs/cache.md): a binary SAH tree collapsed into 4-wide nodes. Boxes live on a
  // per-voxel lattice of 65536 steps per axis (bvhOrigin + q * bvhStep, rounded outward); a node
  // holds its children's boxes in 8 bits per plane relative to its own frame (BvhFrame: a corner
  // and a step on that lattice, derived from its parent's codes, the root's stored), laid out per
  // axis so one SIMD slab test covers all four. Leaves hold at most kBvhLeafSize triangles. The
  // build stores the triangles (indices and keys) in leaf order, so a leaf is a range of them and
  // needs no references. Node 0 is the root.
  struct BvhNode {
    uint8_t lo[3][4], hi[3][4];  // [axis][child]; an unused slot is lo 255 > hi 0: never entered
    uint32_t child[4];           // leaf: kBvhLeafFlag | count << 24 | first triangle; else a node
  };
  static constexpr uint32_t kBvhLeafFlag = 1u << 31;
  // A node's frame on the voxel's lattice: child i's box is lo + code * step on each axis. The
  // numbers are integers below 2^24 kept as floats, so the arithmetic here is exact, and the
  // traversal turns a frame into slab distances without conversions.
  struct BvhFrame {
    float lo[3], step[3];
    // The frame of child i of `node` (in this frame): its box, in 255 steps of at least one.
    BvhFrame child(const BvhNode& node, int i) const {
      BvhFrame f;
      for (int k = 0; k < 3; ++k) {
        f.lo[k] = lo[k] + float(node.lo[k][i]) * step[k];
        const uint32_t extent = uint32_t(node.hi[k][i] - node.lo[k][i]) * uint32_t(step[k]);
        f.step[k] = float(std::max(1u, (extent + 254) / 255));
      }
      return f;
    }
    // The frame of a box [lo, hi] of the lattice.
    static BvhFrame of(const uint32_t lo[3], const uint32_t hi[3]) {
      BvhFrame f;
      for (int k = 0; k < 3; ++k) f.lo[k] = float(lo[k]), f.step[k] = float(std::max(1u, (hi[k] - lo[k] + 254) / 255));
      return f;
    }
  };
  std::vector<BvhNode> bvhNodes;
  glm::vec3 bvhOrigin{0}, bvhStep{0};
  BvhFrame bvhRoot{};

  uint32_t numTriangles() const { return triangleCount; }
  uint32_t numPacked() const { return packedCount; }
  uint32_t numVertices() const { return numPacked() + uint32_t(P.size()); }
  // The lattice steps of packed vertex i from pBase, per axis.
  glm::uvec3 packedSteps(uint32_t i) const {
    uint64_t word;
    std::memcpy(&word, packedP.data() + size_t(pBytes) * i, sizeof word);
    return {uint32_t(word & ((uint64_t(1) << pBits[0]) - 1)),
            uint32_t((word >> pBits[0]) & ((uint64_t(1) << pBits[1]) - 1)),
            uint32_t((word >> (pBits[0] + pBits[1])) & ((uint64_t(1) << pBits[2]) - 1))};
  }
  glm::vec3 vertex(uint32_t i) const {
    if (i >= packedCount) return P[i - packedCount];
    return pBase + glm::vec3(packedSteps(i)) * pStep;
  }
  // The most bits of steps from pBase a packed vertex may take on each axis: 19, so that a
  // record (three of them) is at most 8 bytes.
  static constexpr int kMaxStepBits = 19;
  // Packs the float vertices in P (all of them, before any are packed) that decode exactly from
  // lattice steps of `step` (a power of two) in the window of 2^19 steps centred on `centre`, or
  // in narrower windows where the far ones take fewer bytes as floats: they move to packedP and
  // to the front of the vertex order (indices16/32, bary16 and baryF renumbered alike, so it
  // comes before packIndices and packBary). No-op for step 0 and on big-endian machines.
  void packPositions(float step, const glm::vec3& centre);
  // Moves indices16 or indices32 into packedIndices (little-endian machines, vertex numbers of
  // at most 19 bits: 3 of them and a 7-bit shift fit one 64-bit word) where that is smaller.
  void packIndices();

  glm::uvec3 triangle(uint32_t i) const {
    if (indexBits) {
      const uint64_t bit = uint64_t(3 * indexBits) * i;
      uint64_t word;
      std::memcpy(&word, packedIndices.data() + (bit >> 3), sizeof word);
      word >>= bit & 7;
      const uint64_t mask = (uint64_t(1) << indexBits) - 1;
      return {uint32_t(word & mask), uint32_t((word >> indexBits) & mask), uint32_t((word >> (2 * indexBits)) & mask)};
    }
    if (!indices16.empty()) return {indices16[3 * i], indices16[3 * i + 1], indices16[3 * i + 2]};
    return {indices32[3 * i], indices32[3 * i + 1], indices32[3 * i + 2]};
  }
  uint32_t subOffset(size_t cell) const {
    return subOffsets16.empty() ? subOffsets32[cell] : subOffsets16[cell];
  }
  uint32_t subTriangle(uint32_t k) const {
    return subTriangles16.empty() ? subTriangles32[k] : subTriangles16[k];
  }
  // The vertex's barycentrics on its input triangle (for a vertex of whole triangles, on the
  // first of them to store it; see the comment at the top).
  glm::vec2 bary(uint32_t vertex) const {
    if (!baryF.empty()) return baryF[vertex];
    if (!baryPacked)
      return glm::vec2(float(bary16[2 * vertex]), float(bary16[2 * vertex + 1])) * (1.0f / 32768.0f);
    const uint32_t bits = 16u - baryShift;
    const uint64_t bit = uint64_t(2 * bits) * vertex;
    uint64_t word;
    std::memcpy(&word, packedBary.data() + (bit >> 3), sizeof word);
    word >>= bit & 7;
    const uint64_t mask = (uint64_t(1) << bits) - 1;
    return glm::vec2(float(uint32_t(word & mask) << baryShift), float(uint32_t((word >> bits) & mask) << baryShift)) *
           (1.0f / 32768.0f);
  }
  // Appends the key of the next triangle (keys must be appended in triangle order).
  void appendKey(uint32_t triangleId, uint32_t microId) {
    assert(!microBits && "keys are appended before packKeys");
    if (segments.empty() || segments.back().triangleId != triangleId) segments.push_back({triangleCount, triangleId});
    micro32.push_back(packMicro(microId));
    ++triangleCount;
  }
  // Once every key is appended: moves micro32 into packedMicro (little-endian machines), and
  // the segment table into packedIds where that is smaller (else trims it).
  void packKeys();
  // Micro ids are (path code << kMicroRankBits) | rank (subdivide.h), ranks are small and path
  // codes short; rotated so the path code sits in the low bits, the ids of a voxel need only
  // kMicroRankBits' complement plus the bits of its largest rank.
  static uint32_t packMicro(uint32_t id) {
    return (id << (32 - kMicroRankBits)) | (id >> kMicroRankBits);
  }
  static uint32_t unpackMicro(uint32_t packed) {
    return (packed >> (32 - kMicroRankBits)) | (packed << kMicroRankBits);
  }
  // The key of triangle i: (global input triangle id, micro id).
  std::pair<uint32_t, uint32_t> key(uint32_t i) const;
  // Stores vertex bary (b1, b2) in the compact form if every one lies in [0, 1].
  void setBary(const std::vector<glm::vec2>& b);
  // Moves bary16 into packedBary (little-endian machines; after packPositions, which renumbers).
  void packBary();
  uint64_t bytes() const;
};

// The point of the position lattice of step `step` (a power of two; 0: no lattice) nearest to p,
// with -0 made +0: a pure function of p, so every voxel holding a vertex stores the same point.
// Exact: p / step is a power-of-two scaling, and a coordinate 2^24 steps or more from 0 (where the
// floats are no finer than the lattice), infinite or NaN is already as good as it gets, and kept.
inline float snapToLattice(float x, float step) {
  const float q = x / step;
#if defined(__SSE2__)
  // cvtss2si rounds as nearbyint does in the default mode (to nearest, ties to even), exactly
  // below 2^24, without libm's call (SSE2 has no inline nearbyint); -0 becomes +0 either way.
  return (std::fabs(q) < 16777216.0f ? float(_mm_cvtss_si32(_mm_set_ss(q))) * step : x) + 0.0f;
#else
  return (std::fabs(q) < 16777216.0f ? std::nearbyint(q) * step : x) + 0.0f;
#endif
}
inline glm::vec3 snapToLattice(const glm::vec3& p, float step) {
  if (!(step > 0.0f)) return p;
  return glm::vec3(snapToLattice(p.x, step), snapToLattice(p.y, step), snapToLattice(p.z, step));
}

// Above this many triangles a voxel gets a sub-voxel grid or BVH (the paper's "more than about 100").
constexpr uint32_t kSubGridThreshold = 100;
// Triangles per BVH leaf at most (at most 127: the count has 7 bits; docs/cache.md gives the
// measured trade of speed against bytes).
constexpr uint32_t kBvhLeafSize = 32;

struct CacheStats {
  uint64_t accesses = 0, hits = 0, compulsoryMisses = 0, capacityMisses = 0;
  uint64_t createdTriangles = 0;  // summed over fills, refills included
  uint64_t residentTriangles = 0, peakResidentTriangles = 0;
  uint64_t residentBytes = 0, peakResidentBytes = 0;
  uint64_t evictions = 0;
  uint64_t createdBytes = 0;      // summed over fills, refills included
  uint64_t budgetViolations = 0;  // only counted when checking (setCheckBudget)
};

// A small per-thread number, for spreading per-thread counters over cache lines.
int cacheThreadShard();

class GeometryCache {
 public:
  GeometryCache(uint32_t numVoxels, uint64_t budgetTriangles);
  ~GeometryCache();
  GeometryCache(const GeometryCache&) = delete;
  GeometryCache& operator=(const GeometryCache&) = delete;

  // Returns the voxel's geometry pinned for the caller, building it with `build(voxel)` (which
  // returns a unique_ptr<VoxelGeometry>) if not resident. Every acquire must be paired with
  // release(voxel). `stamp` orders uses for LRU (later is more recent).
  template <typename Build>
  const VoxelGeometry* acquire(uint32_t voxel, uint64_t stamp, Build&& build);
  void release(uint32_t voxel);

  // Whether another thread is filling the voxel now (a hint: it may finish at any moment).
  bool filling(uint32_t voxel) const {
    return slots_[voxel].word.load(std::memory_order_relaxed) >> kStateShift == kFilling;
  }

  CacheStats stats() const;
  uint64_t budget() const { return budget_; }
  // Debug mode: after every fill, check that the resident set without the voxel just filled is
  // within the budget, apart from voxels pinned by other threads (which eviction must skip).
  void setCheckBudget(bool check) { checkBudget_ = check; }

 private:
  // Slot word: state in the top two bits, pin count below.
  static constexpr uint32_t kStateShift = 30;
  static constexpr uint32_t kEmpty = 0, kFilling = 1, kReady = 2;
  static constexpr uint32_t kPinMask = (1u << kStateShift) - 1;
  static constexpr uint64_t kStampSlack = 32;

  struct Slot {
    std::atomic<uint32_t> word{0};
    std::atomic<uint64_t> lastUse{0};
    std::atomic<bool> everFilled{false};
    VoxelGeometry* geometry = nullptr;  // written only by the filler (filling) or evictor (pins 0)
    uint32_t residentPosition = 0;      // index in resident_, under mutex_
  };

  // Slow paths of acquire: returns the pinned geometry, or null if the caller must fill.
  const VoxelGeometry* tryPin(uint32_t voxel, bool& mustFill);
  const VoxelGeometry* publish(uint32_t voxel, std::unique_ptr<VoxelGeometry> geometry);
  void abandon(uint32_t voxel);

  std::vector<Slot> slots_;
  uint64_t budget_;
  mutable std::mutex mutex_;  // guards resident_, the eviction scan and the budget counters
  std::vector<uint32_t> resident_;
  std::vector<std::pair<uint64_t, uint32_t>> evictionOrder_;  // scratch of the eviction scan (lastUse, voxel)
  uint64_t residentTriangles_ = 0, peakResidentTriangles_ = 0;
  uint64_t residentBytes_ = 0, peakResidentBytes_ = 0;
  uint64_t evictions_ = 0;
  uint64_t budgetViolations_ = 0;
  bool checkBudget_ = false;
  // Hits are counted on every voxel visit of every ray, so they are sharded by thread to keep
  // threads off one cache line; misses and fills are rare enough for plain atomics. Every access
  // ends as exactly one hit or miss, so accesses are their sum.
  static constexpr int kHitShards = 16;
  struct alignas(64) HitShard {
    std::atomic<uint64_t> hits{0};
  };
  HitShard hitShards_[kHitShards];
  std::atomic<uint64_t> compulsory_{0}, capacity_{0}, created_{0}, createdBytes_{0};
};

template <typename Build>
const VoxelGeometry* GeometryCache::acquire(uint32_t voxel, uint64_t stamp, Build&& build) {
  Slot& slot = slots_[voxel];
  // Only raise the stamp, and only when it is kStampSlack rays stale: a voxel many threads visit
  // then stays a shared cache line, at the price of LRU order within a few dozen rays.
  if (slot.lastUse.load(std::memory_order_relaxed) + kStampSlack < stamp)
    slot.lastUse.store(stamp, std::memory_order_relaxed);
  bool mustFill = false;
  if (const VoxelGeometry* g = tryPin(voxel, mustFill)) return g;
  std::unique_ptr<VoxelGeometry> geometry;
  try {
    geometry = build(voxel);
  } catch (...) {
    abandon(voxel);  // e.g. bad_alloc: let waiting threads retry instead of waiting forever
    throw;
  }
  return publish(voxel, std::move(geometry));
}

}  // namespace relief
