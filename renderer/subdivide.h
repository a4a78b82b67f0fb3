// Adaptive, crack-free subdivision and displacement of one input triangle into micro-triangles.
// Used by the geometry cache (geometry_cache.*, grid_accelerator.cpp) and by geometry tests; reaches
// the displacement shader only through runtime::ShaderInstance.
//
// The scheme (architecture.md, "Subdivision"): an edge is split when its two *displaced* end points
// are farther apart than Displacement::edgeLength and its midpoint's level would not exceed
// Displacement::maxDepth. The decision reads only the edge's two end vertices, and a midpoint's
// attributes are 0.5 * (a + b), which is symmetric in IEEE arithmetic, so the two triangles sharing
// an edge (also across input triangles, when the mesh shares the vertex) split it identically and
// compute bit-identical midpoints. Only edges that want splitting are split: a triangle with one,
// two or three split edges becomes two, three or four children, so neighbours share every vertex
// (no T-junctions) and, with the watertight ray test of intersect.h, nothing leaks.
//
// Evaluation is breadth first: each round's new vertices are displaced in one shader batch.
//
// Culling for per-voxel fills: given a box, triangles of the first kCullRounds rounds whose
// undisplaced box grown by the displacement bound misses it are dropped with their whole subtree.
// The kept micro-triangles are exactly those of the full subdivision (decisions are per edge), and
// each carries an id independent of culling: its first kCullRounds split choices (a path code,
// 2 bits per round behind a leading 1) in the high bits, and its rank among the finished
// descendants of that ancestor in the low kMicroRankBits bits.
// Determinism rule 1: the result depends only on the input triangle, its shader and settings.
// Simplification (Displacement::flatness > 0, paper 3.1; docs/subdivision.md): an edge that wants
// splitting is kept whole when every point its own recursive subdivision would put on it lies
// within `flatness` of its displaced chord (a lookahead along the edge alone, so both sides agree).
// A triangle left with three whole edges, one of them kept for flatness, is final when its
// interior samples (its uniform subdivision to the target length, at most kMaxInteriorDepth
// levels, and its centre) lie within `flatness` of it, and is split 1-to-3 at its centre
// otherwise. Simplification costs shader evaluations (the lookahead and samples) and saves
// micro-triangles; SubdivideCounters reports both counts.
// Ng is each vertex's N on smooth surfaces (Mesh::smoothSurface), and dPdu/dPdv are per vertex
// where the mesh has them (Mesh::dPdu), so shared exactly there; du/dv are the parametric step
// that moves the surface by the edge length (from the vertex's own dPdu/dPdv, or the mesh's
// scale), so shared exactly too.
// Known limit: a shader reading dNdu/dNdv, the s/t seeds or a polygon's Ng or dPdu/dPdv (per
// input triangle) may displace a shared edge differently from its two sides; P, N, u, v, s, t, du
// and dv are shared exactly.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "renderer/scene.h"

namespace relief {

constexpr int kCullRounds = 4;
constexpr int kMicroRankBits = 32 - (1 + 2 * kCullRounds);
// The id of an input triangle left whole (undisplaced, or never split): the root's path code.
constexpr uint32_t kWholeTriangleId = 1u << kMicroRankBits;

// An axis-aligned world box restricting a subdivision (see culling above).
struct CullBox {
  glm::vec3 lo, hi;
};

// Culling subtrees are the triangles of rounds 0..kCullRounds, named by their path codes; slot
// numbering packs the codes of each round after those of the rounds before it.
constexpr uint32_t subtreeSlots(int rounds) { return ((1u << (2 * (rounds + 1))) - 1) / 3; }
constexpr uint32_t kSubtreeSlots = subtreeSlots(kCullRounds);
inline uint32_t subtreeSlot(uint32_t code) {
  const int round = (31 - __builtin_clz(code)) / 2;
  const uint32_t first = 1u << (2 * round);
  return (first - 1) / 3 + code - first;
}

// What earlier subdivisions of one input triangle learnt about its culling subtrees, so that
// per-voxel fills stop repeating work (docs/cache.md, "Subtree memo"):
// - the exact box of every subtree a subdivision kept whole. A culled subdivision must otherwise
//   keep each subtree whose undisplaced box grown by the displacement bound reaches the cull box,
//   and that margin is most of what per-voxel fills repeat; once a subtree's displaced box is
//   known, fills of voxels it does not reach skip it.
// - its interior flatness decisions (simplification), in the order the subdivision makes them:
//   proving a triangle's interior flat takes up to hundreds of shader samples, and a refill would
//   take them all again to reach the same answer.
// Both are pure functions of the input triangle and its settings (determinism rule 1): culling
// keeps or drops whole subtrees, and a kept subtree is processed identically whatever else is
// kept. So the memo never changes the micro-triangles, only the work of finding them. Boxes are
// bytes on a lattice over `reference`, rounded outwards; each slot is one atomic word, and a word,
// once set, is the same whichever thread sets it, so relaxed order suffices.
class SubtreeMemo {
 public:
  // The most decisions one subtree's word holds (a subtree with more is not memoized).
  static constexpr int kMaxDecisions = 56;
  // Slots for the subtrees of rounds 0..rounds (at most kCullRounds): a triangle that subdivides
  // only a few rounds deep needs only a few (what deeper subdivisions learn is then not kept).
  SubtreeMemo(const CullBox& reference, int rounds = kCullRounds);
  // The box of subtree `code`, if learnt.
  bool box(uint32_t code, CullBox& box) const;
  // The simplification decisions (edges and interiors, in order) of subtree `code`: 0 if not
  // learnt, else bit 63, the count in bits 56..62 and decision i (1: flat) in bit i.
  uint64_t decisions(uint32_t code) const {
    const uint32_t slot = subtreeSlot(code);
    return slot < slots_ ? decisions_[slot].load(std::memory_order_relaxed) : 0;
  }
  // Keeps `box` (if not null) for subtree `code` when the lattice can hold it conservatively, and
  // its decisions (if not 0). Codes beyond the memo's rounds are ignored.
  void learn(uint32_t code, const CullBox* box, uint64_t decisions);
  size_t bytes() const { return sizeof(SubtreeMemo) + 2 * size_t(slots_) * sizeof(uint64_t); }

 private:
  float decode(int axis, uint32_t q) const { return lo_[axis] + float(q) * step_[axis]; }
  glm::vec3 lo_, step_;
  uint32_t slots_;
  std::unique_ptr<std::atomic<uint64_t>[]> boxes_, decisions_;
};

// What one subdivision learnt about a subtree it kept whole (SubtreeMemo::learn's arguments).
struct LearntSubtree {
  uint32_t code;
  bool hasBox;  // the subtree was kept whole (else only its own decisions are known)
  CullBox box;
  uint64_t decisions;
};

// The displaced micro-mesh of one input triangle (or of its part reaching a CullBox).
struct MicroMesh {
  std::vector<glm::vec3> P;       // displaced positions, world space
  std::vector<glm::vec2> bary;    // (b1, b2): weights of input corners 1 and 2 (for st at a hit)
  std::vector<uint8_t> level;     // subdivision level of each vertex (corners 0)
  std::vector<uint32_t> indices;  // 3 per micro-triangle, wound as the input triangle
  std::vector<uint32_t> ids;      // per micro-triangle: its culling-independent id (see above)
  uint32_t numTriangles() const { return uint32_t(indices.size() / 3); }
};

struct SubdivideCounters {
  uint64_t shaderPoints = 0;
  uint64_t displaceTicks = 0;  // time spent inside the shader, in readTicks() ticks (ticks.h)
  RlfStatus status{};          // summed over batches; nonFinite also counts host replacements
  // Micro-triangles out (after simplification) and the estimate of what the same points would
  // give unsimplified (equal when flatness is 0): 1 - after / before is the share simplification
  // saved (the paper's "geometry saved by simplification").
  uint64_t trianglesBeforeSimplification = 0;
  uint64_t trianglesAfterSimplification = 0;
};

// Subdivides and displaces triangle `triangle` of `mesh` with `displacement` (null, or a null
// shader: the triangle itself, one micro-triangle). `out` is overwritten. With `cull`, parts that
// cannot reach the box are skipped (the result then also holds some triangles outside it). `known`
// is what earlier subdivisions of this triangle learnt (it may be learning concurrently), and
// `learnt` (cleared) receives what this one found about the subtrees it kept whole and `known`
// lacks.
void subdivideTriangle(const Mesh& mesh, uint32_t triangle, const Displacement* displacement,
                       MicroMesh& out, SubdivideCounters& counters, const CullBox* cull = nullptr,
                       const SubtreeMemo* known = nullptr, std::vector<LearntSubtree>* learnt = nullptr);

// Work guard against runaway subdivision. A tiny edgelength, or a shader whose displaced edges
// never get short (points moved far beyond the bound, detail finer than edgelength everywhere),
// subdivides every input triangle to the depth guard, 4^12 micro-triangles each, and a render
// would run for hours without a word. The guard clamps nothing (that would change the surface,
// and both sides of an edge must decide alike). A triangle whose longest undisplaced edge needs
// k halvings to reach edgelength (k at most the depth guard) asks for 4^k micro-triangles, and
//  - a Displacement whose triangles ask for more than kMaxEstimatedMicroTriangles in all is
//    reported before rendering (the caller stops: no render could make that many);
//  - points a subdivision evaluates beyond kRunawayAllowance * 4^k (a displaced surface 64 times
//    the area of its triangle) are its excess, checked a round at a time. A Displacement is
//    marked runaway when one subdivision's excess passes kRunawayPoints (about a second of
//    work), or when the excess of its grossly excessive subdivisions (more than kGrossExcess
//    times the allowance: a surface over 1000 times its triangle's area) adds up to
//    kRunawaySubdivisions times that; per-voxel fills cull a runaway triangle to pieces that
//    each stay under the first limit. Then subdivisions stop early, the render loop stops, and
//    the caller reports the error. A surface within 1000 times its area never adds up, however
//    often refills under a small budget subdivide it again.
constexpr double kMaxEstimatedMicroTriangles = 68719476736.0;  // 2^36
constexpr uint64_t kRunawayAllowance = 64;
constexpr uint64_t kGrossExcess = 16;
constexpr uint64_t kRunawayPoints = uint64_t(1) << 20;
constexpr uint64_t kRunawaySubdivisions = 8;
// The same guard stops the render once this many invocations of one Displacement's shader hit
// the loop-iteration limit (language.md §7): each costs a million iterations (about a millisecond),
// so a loop that never ends at most points would otherwise take minutes for a thumbnail. A few
// points hitting it (a loop that fails to converge near a singularity) still render, with the
// warning. Once a shader has hit it, its calls take kLoopLimitBatchPoints points at a time, so the
// stop is not held up by a full batch of them.
constexpr uint64_t kLoopLimitStop = 1024;
constexpr uint32_t kLoopLimitBatchPoints = 16;

// The k above: halvings of the longest edge of triangle p to reach edgeLength, at most maxDepth.
int undisplacedLevels(const glm::vec3 p[3], float edgeLength, int maxDepth);

// Whether the shader is given the mesh's normals turned inward: its orientation is reversed and
// the normals are the surface's own, not ones the scene gave (RI spec; Mesh::givenNormals).
inline bool shaderNormalsReversed(const Mesh& mesh, const Displacement& disp) {
  return disp.reverseOrientation && !(mesh.givenNormals && mesh.N.size() == mesh.P.size());
}

// The displacement shader's output N at barycentric `bary` (weights of corners 1 and 2) of input
// triangle `triangle`, evaluated there as subdivision evaluates its vertices (language.md §5: the
// output N is the shading normal). False when it is not a finite, nonzero vector. Thread-safe.
bool displacedShadingNormal(const Mesh& mesh, uint32_t triangle, const Displacement& disp, glm::vec2 bary,
                            glm::vec3* normal);

// The sum of 4^k over the triangles of `mesh`: micro-triangles its undisplaced surface asks for at
// disp's edge length, before simplification (an upper bound of what subdivision keeps).
double estimatedMicroTriangles(const Mesh& mesh, const Displacement& disp);
// The same for triangle `triangle` of `mesh` alone.
double estimatedMicroTriangles(const Mesh& mesh, uint32_t triangle, const Displacement& disp);

// Returns the estimate (the sum of 4^k) for each of scene.displacements, meshes without a shader
// counting nothing, and arms the runaway guard of every Displacement (ShaderProblemCounts).
std::vector<double> setSubdivisionLimits(Scene& scene);

}  // namespace relief
