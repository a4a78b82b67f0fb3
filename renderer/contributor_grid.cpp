// Building the contributor grid (see contributor_grid.h).
#include "renderer/contributor_grid.h"

#include <algorithm>
#include <cmath>

#include <glm/gtx/component_wise.hpp>

#include "renderer/subdivide.h"

namespace relief {
namespace {

bool finite(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Whether triangle (a, b, c) may touch the box [lo, hi]: the separating-axis test on the
// triangle's normal and the nine edge-by-axis directions (the three box axes are the caller's box
// overlap). In double, with a relative slack, so rounding never separates a touching pair: a
// false "may touch" costs a contributor entry, a false "cannot" a hole.
bool triangleMayTouchBox(const glm::dvec3& lo, const glm::dvec3& hi, const glm::dvec3& a,
                         const glm::dvec3& b, const glm::dvec3& c) {
  const glm::dvec3 centre = 0.5 * (lo + hi), half = 0.5 * (hi - lo);
  const glm::dvec3 v[3] = {a - centre, b - centre, c - centre};
  const glm::dvec3 e[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
  auto separated = [&](const glm::dvec3& axis) {
    const double p0 = glm::dot(v[0], axis), p1 = glm::dot(v[1], axis), p2 = glm::dot(v[2], axis);
    const double r = half.x * std::fabs(axis.x) + half.y * std::fabs(axis.y) + half.z * std::fabs(axis.z);
    const double scale = std::fabs(p0) + std::fabs(p1) + std::fabs(p2) + r;
    const double slack = 1e-9 * scale;
    return std::min({p0, p1, p2}) > r + slack || std::max({p0, p1, p2}) < -r - slack;
  };
  if (separated(glm::cross(e[0], e[1]))) return false;
  for (const glm::dvec3& edge : e)
    for (int k = 0; k < 3; ++k) {
      glm::dvec3 unit(0.0);
      unit[k] = 1.0;
      if (separated(glm::cross(edge, unit))) return false;
    }
  return true;
}

}  // namespace

Bounds3 triangleReach(const Mesh& mesh, uint32_t triangle, float grow) {
  Bounds3 box;
  for (int c = 0; c < 3; ++c) {
    const uint32_t i = mesh.indices[3 * size_t(triangle) + c];
    if (i >= mesh.P.size() || !finite(mesh.P[i])) return {};
    box.extend(mesh.P[i]);
  }
  if (!std::isfinite(grow)) return {};
  box.lo -= glm::vec3(grow), box.hi += glm::vec3(grow);
  return box;
}

ContributorGrid::ContributorGrid(const Scene& scene, const AccelOptions& options) {
  meshOffsets_.push_back(0);
  for (const Mesh& mesh : scene.meshes) {
    meshOffsets_.push_back(meshOffsets_.back() + mesh.numTriangles());
    const Displacement* disp = nullptr;
    if (options.displace && mesh.displacementIndex < scene.displacements.size() &&
        scene.displacements[mesh.displacementIndex].shader) {
      disp = &scene.displacements[mesh.displacementIndex];
      anyDisplaced_ = true;
    }
    displacements_.push_back(disp);
  }

  // Triangle boxes grown by the displacement bound. Triangles with non-finite corners are left
  // out: the scene reader reports them; here they must not poison the grid.
  std::vector<Bounds3> boxes(numTriangles());
  Bounds3 core;
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    const Mesh& mesh = scene.meshes[m];
    const float grow = displacements_[m] ? std::max(0.0f, displacements_[m]->boundWorld) : 0.0f;
    for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
      const Bounds3 box = triangleReach(mesh, t, grow);
      if (box.empty()) continue;
      boxes[meshOffsets_[m] + t] = box;
      if (displacements_[m]) core.extend(box.lo), core.extend(box.hi);
    }
  }
  // Without displaced geometry the neighbourhood is that of the triangles of ordinary size: a
  // ground plane a million units wide under a unit sphere would otherwise be intersected in float
  // from voxels the size of the plane, and shadow rays leaving it found it again (self-shadowing
  // speckles on a fifth of the image at 1e5 units).
  if (core.empty() && options.outsideTriangles && numTriangles() > 2) {
    std::vector<float> extents;
    extents.reserve(boxes.size());
    for (const Bounds3& box : boxes)
      if (!box.empty()) extents.push_back(glm::compMax(box.hi - box.lo));
    if (!extents.empty()) {
      std::vector<float> sorted = extents;
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      const float ordinary = kOrdinaryTriangles * sorted[sorted.size() / 2];
      for (const Bounds3& box : boxes)
        if (!box.empty() && glm::compMax(box.hi - box.lo) <= ordinary)
          core.extend(box.lo), core.extend(box.hi);
    }
  }
  // Undisplaced triangles reaching outside the displaced geometry's neighbourhood stay out of the
  // grid (header).
  if (!core.empty()) {
    const glm::vec3 extent = core.hi - core.lo;
    const float grow = kOutsideMargin * std::max({extent.x, extent.y, extent.z});
    core.lo -= glm::vec3(grow), core.hi += glm::vec3(grow);
  }
  for (uint32_t m = 0; options.outsideTriangles && m < scene.meshes.size() && !core.empty(); ++m) {
    if (displacements_[m]) continue;
    for (uint32_t t = 0; t < scene.meshes[m].numTriangles(); ++t) {
      Bounds3& box = boxes[meshOffsets_[m] + t];
      if (box.empty()) continue;
      if (glm::any(glm::lessThan(box.lo, core.lo)) || glm::any(glm::greaterThan(box.hi, core.hi))) {
        outside_.push_back(meshOffsets_[m] + t);
        box = {};
      }
    }
  }
  uint32_t inGrid = 0;
  for (const Bounds3& box : boxes)
    if (!box.empty()) bounds_.extend(box.lo), bounds_.extend(box.hi), ++inGrid;
  if (bounds_.empty()) bounds_ = {glm::vec3(-1), glm::vec3(1)};

  const glm::vec3 extent = bounds_.hi - bounds_.lo;
  // Relative to the scene's place, not an absolute length: a floor of 1e-6 world units made a
  // scene of 1e-11 units one voxel (and its render 100x slower). The floor only keeps a scene of
  // one point (or degenerate triangles) off a zero-sized grid.
  const float far = std::max({std::fabs(bounds_.lo.x), std::fabs(bounds_.lo.y), std::fabs(bounds_.lo.z),
                              std::fabs(bounds_.hi.x), std::fabs(bounds_.hi.y), std::fabs(bounds_.hi.z)});
  const float longest = std::max({extent.x, extent.y, extent.z, far * 1e-6f, 1e-30f});
  padding_ = longest * 1e-5f;
  bounds_.lo -= glm::vec3(2 * padding_), bounds_.hi += glm::vec3(2 * padding_);
  int n = options.gridResolution;
  if (n <= 0) {
    n = int(std::lround(kAutoGridFactor * std::cbrt(double(std::max(1u, inGrid)))));
    float maxBound = 0.0f;
    for (const Displacement* d : displacements_)
      if (d) maxBound = std::max(maxBound, d->boundWorld);
    // Divided in double and clamped before the conversion: a scene 2^31 bounds across (a floor
    // of 1e9 units under a bound of 0.06) overflowed int and made one voxel of the whole scene.
    auto voxelsAcross = [&](double perBound) { return int(std::min(1e9, double(longest) / (perBound * maxBound))); };
    if (maxBound > 0.0f && std::isfinite(maxBound)) n = std::min(n, voxelsAcross(kVoxelsPerBound));
    // Fine displacement: as many voxels again as keep a voxel's share of the micro-triangles
    // small, however few input triangles carry them (header).
    double micro = 0.0;
    for (uint32_t m = 0; m < scene.meshes.size(); ++m)
      if (displacements_[m]) micro += estimatedMicroTriangles(scene.meshes[m], *displacements_[m]);
    int byMicro = int(std::min(1e9, std::round(std::cbrt(micro / kMicroTrianglesPerCell))));
    if (maxBound > 0.0f && std::isfinite(maxBound)) byMicro = std::min(byMicro, voxelsAcross(kMinVoxelBounds));
    n = std::clamp(std::max(n, byMicro), 1, kMaxAutoGridResolution);
  }
  n = std::clamp(n, 1, kMaxGridResolution);
  const Bounds3 reach = bounds_;
  auto layOut = [&](int along) {
    bounds_ = reach;
    voxelSize_ = (longest + 4 * padding_) / float(along);
    for (int a = 0; a < 3; ++a) {
      const float span = bounds_.hi[a] - bounds_.lo[a];
      resolution_[a] = std::clamp(int(std::ceil(span / voxelSize_)), 1, along);
      bounds_.hi[a] = bounds_.lo[a] + float(resolution_[a]) * voxelSize_;
    }
  };
  layOut(n);
  // A budget holding only a few voxels thrashes: a ray's neighbourhood then needs more voxels
  // than fit, and every refill remakes a whole heavy voxel (header, kVoxelsPerBudget). So an
  // automatic resolution under a budget is raised until the heaviest voxel's estimate fits the
  // budget that many times, whatever the displacement bound says.
  const uint64_t budget = options.cacheBudgetTriangles;
  if (options.gridResolution <= 0 && anyDisplaced_ && budget != UINT64_MAX && budget > 0) {
    const double fits = double(budget) / kVoxelsPerBudget;
    for (int attempt = 0; attempt < 4 && n < kMaxBudgetGridResolution; ++attempt) {
      const double heaviest = heaviestVoxelEstimate(scene);
      if (heaviest <= fits) break;
      // A voxel's share of a surface falls as the square of the resolution.
      const int raised = int(std::ceil(double(n) * std::sqrt(heaviest / fits)));
      n = std::clamp(raised, n + 1, kMaxBudgetGridResolution);
      layOut(n);
      ++budgetRefinements_;
    }
  }
  auto voxels = [&] { return uint64_t(resolution_.x) * uint64_t(resolution_.y) * uint64_t(resolution_.z); };
  while (voxels() > kMaxGridVoxels && n > 1) {
    n = std::max(1, std::min(n - 1, int(double(n) * std::cbrt(double(kMaxGridVoxels) / double(voxels())))));
    layOut(n);
  }
  auto cellRange = [&](const Bounds3& box, glm::ivec3& lo, glm::ivec3& hi) {
    const glm::vec3 a = (box.lo - glm::vec3(padding_) - bounds_.lo) / voxelSize_;
    const glm::vec3 b = (box.hi + glm::vec3(padding_) - bounds_.lo) / voxelSize_;
    lo = glm::clamp(glm::ivec3(glm::floor(a)), glm::ivec3(0), resolution_ - 1);
    hi = glm::clamp(glm::ivec3(glm::floor(b)), glm::ivec3(0), resolution_ - 1);
  };
  // A triangle spanning several voxels is listed only in those its plane-and-edges shape may
  // reach (the voxel grown by the padding and the displacement bound: the grown triangle lies
  // within the triangle swept by a cube of that half-size), not in every voxel of its box: a
  // sliver across the scene (a fan of a 100,000-point polygon) would otherwise fill whole planes
  // of voxels. Blocks of voxels [lo, hi] are tested whole and halved until single voxels, so a
  // big triangle costs tests near its surface only (the 100,000-point fan: 9.5 s of tests voxel
  // by voxel); a block's grown box holds its voxels' grown boxes, so a block ruled out rules
  // them all out.
  struct Block {
    glm::ivec3 lo, hi;
  };
  std::vector<Block> blocks;
  auto forEachVoxel = [&](uint32_t id, glm::ivec3 lo, glm::ivec3 hi, auto&& emit) {
    if (lo == hi) return emit(lo);
    const auto [m, t] = split(id);
    const Mesh& mesh = scene.meshes[m];
    const double reach = double(padding_) + double(displacements_[m] ? std::max(0.0f, displacements_[m]->boundWorld) : 0.0f);
    const glm::dvec3 a = mesh.P[mesh.indices[3 * size_t(t)]], b = mesh.P[mesh.indices[3 * size_t(t) + 1]],
                     c = mesh.P[mesh.indices[3 * size_t(t) + 2]];
    blocks.assign(1, Block{lo, hi});
    while (!blocks.empty()) {
      const Block k = blocks.back();
      blocks.pop_back();
      const glm::dvec3 boxLo = glm::dvec3(bounds_.lo) + glm::dvec3(k.lo) * double(voxelSize_) - reach;
      const glm::dvec3 boxHi = glm::dvec3(bounds_.lo) + glm::dvec3(k.hi + 1) * double(voxelSize_) + reach;
      if (!triangleMayTouchBox(boxLo, boxHi, a, b, c)) continue;
      const glm::ivec3 size = k.hi - k.lo;
      if (size == glm::ivec3(0)) {
        emit(k.lo);
        continue;
      }
      const int axis = size.x >= size.y && size.x >= size.z ? 0 : size.y >= size.z ? 1 : 2;
      Block first = k, second = k;
      first.hi[axis] = k.lo[axis] + size[axis] / 2;
      second.lo[axis] = first.hi[axis] + 1;
      blocks.push_back(second);
      blocks.push_back(first);
    }
  };
  // The (voxel, triangle) pairs in triangle order, then a counting sort by voxel: each voxel's
  // row lists its triangles in id order. An automatic resolution is halved while the pairs
  // exceed kMaxEntriesPerTriangle per triangle (and kMinEntryLimit): big triangles stacked on one
  // another (30,000 copies of one quad) otherwise list each in thousands of voxels, a grid
  // quadratic in time and memory (19 s and 724 MB for those copies; 300,000 ran out of memory).
  // Finding that out costs at most one limit's worth of pairs per halving.
  const size_t entryLimit = std::max(kMinEntryLimit, size_t(kMaxEntriesPerTriangle) * inGrid);
  const size_t explicitLimit = std::max(kMinExplicitEntryLimit, size_t(kMaxExplicitEntriesPerTriangle) * inGrid);
  // A first guess from a sample of 64 triangles spread over the ids, so that a scene of big
  // triangles rarely pays for a full attempt at a resolution far too fine.
  // A resolution raised for the budget may have gone far past the limit where the bound is
  // large against the voxels: entries then grow as the cube of the resolution (the bound's
  // volume), not the square, so it steps down by cube roots, guess after guess, until the sample
  // fits.
  // An explicit resolution takes the same guesses against its own, larger limit (a full pass
  // up to that limit costs seconds).
  const bool explicitResolution = options.gridResolution > 0;
  const size_t guessLimit = explicitResolution ? explicitLimit : entryLimit;
  for (int guess = 0; n > 1 && inGrid > 64 && guess < 8; ++guess) {
    uint64_t sampled = 0, counted = 0;
    const uint32_t stride = numTriangles() / 64;
    for (uint32_t id = 0; id < numTriangles() && counted < 64; id += std::max(1u, stride)) {
      if (boxes[id].empty()) continue;
      ++counted;
      glm::ivec3 lo, hi;
      cellRange(boxes[id], lo, hi);
      forEachVoxel(id, lo, hi, [&](glm::ivec3) { ++sampled; });
    }
    const double expected = double(sampled) * double(inGrid) / double(std::max<uint64_t>(1, counted));
    if (expected <= double(guessLimit)) break;
    const double ratio = double(guessLimit) / expected;
    const bool byVolume = budgetRefinements_ || explicitResolution;
    n = std::clamp(int(double(n) * (byVolume ? std::cbrt(ratio) : std::sqrt(ratio))), 1, n - 1);
    layOut(n);
    ++coarsenings_;
    if (!byVolume) break;
  }
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  for (;;) {
    pairs.clear();
    bool over = false;
    uint32_t seen = 0;
    for (uint32_t id = 0; id < numTriangles() && !over; ++id) {
      if (boxes[id].empty()) continue;
      ++seen;
      glm::ivec3 lo, hi;
      cellRange(boxes[id], lo, hi);
      forEachVoxel(id, lo, hi, [&](glm::ivec3 cell) { pairs.emplace_back(voxelIndex(cell), id); });
      over = n > 1 && pairs.size() > (options.gridResolution <= 0 ? entryLimit : explicitLimit);
    }
    if (!over) break;
    if (options.gridResolution > 0) {
      // An explicit resolution is lowered only to keep memory bounded (a generous bound at 128
      // voxels across made 819M entries and 9.6 GB): by cube roots, as the entries of a bound
      // large against the voxels grow as its volume.
      const double expected = double(pairs.size()) * double(inGrid) / double(std::max(1u, seen));
      n = std::clamp(int(double(n) * std::cbrt(double(explicitLimit) / expected)), 1, n - 1);
      layOut(n);
      ++coarsenings_;
      continue;
    }
    // Entries grow about as the square of the resolution (triangles are surfaces): from the
    // rate so far, the resolution that fits, at most half the last (30,000 stacked quads: 4.6 s
    // of halvings, then one step).
    const double expected = double(pairs.size()) * double(inGrid) / double(std::max(1u, seen));
    const int fits = int(double(n) * std::sqrt(double(entryLimit) / expected));
    // A resolution raised for the budget gives up only what the entries demand: halving it
    // would bring back the heavy voxels it was raised to avoid.
    n = std::clamp(fits, 1, std::max(1, budgetRefinements_ ? n - 1 : n / 2));
    layOut(n);
    ++coarsenings_;
  }
  const size_t numVoxels = size_t(resolution_.x) * resolution_.y * resolution_.z;
  offsets_.assign(numVoxels + 1, 0);
  for (const auto& [v, id] : pairs) ++offsets_[v + 1];
  for (size_t v = 0; v < numVoxels; ++v) offsets_[v + 1] += offsets_[v];
  ids_.resize(offsets_[numVoxels]);
  std::vector<uint32_t> cursor(offsets_.begin(), offsets_.end() - 1);
  for (const auto& [v, id] : pairs) ids_[cursor[v]++] = id;
  live_ = std::make_unique<std::atomic<uint32_t>[]>(numVoxels);
  for (size_t v = 0; v < numVoxels; ++v)
    live_[v].store(offsets_[v + 1] - offsets_[v], std::memory_order_relaxed);
}

uint32_t ContributorGrid::refine(uint32_t voxel, const std::vector<uint8_t>& keep) {
  const uint32_t live = live_[voxel].load(std::memory_order_relaxed);
  uint32_t* row = ids_.data() + offsets_[voxel];
  // Stable partition, kept first; the dropped ids move behind the live count, in order.
  thread_local std::vector<uint32_t> dropped;
  dropped.clear();
  uint32_t kept = 0;
  for (uint32_t i = 0; i < live; ++i) {
    if (keep[i]) row[kept++] = row[i];
    else dropped.push_back(row[i]);
  }
  if (kept == live) return 0;
  std::copy(dropped.begin(), dropped.end(), row + kept);
  // Release: a reader that sees the new count (hasContributors) also sees the new row.
  live_[voxel].store(kept, std::memory_order_release);
  return live - kept;
}

std::pair<uint32_t, uint32_t> ContributorGrid::split(uint32_t globalId) const {
  const auto it = std::upper_bound(meshOffsets_.begin(), meshOffsets_.end(), globalId);
  const uint32_t mesh = uint32_t(it - meshOffsets_.begin()) - 1;
  return {mesh, globalId - meshOffsets_[mesh]};
}

Bounds3 ContributorGrid::voxelBounds(uint32_t voxel) const {
  const int x = int(voxel % uint32_t(resolution_.x));
  const int y = int((voxel / uint32_t(resolution_.x)) % uint32_t(resolution_.y));
  const int z = int(voxel / (uint32_t(resolution_.x) * uint32_t(resolution_.y)));
  Bounds3 b;
  b.lo = bounds_.lo + glm::vec3(x, y, z) * voxelSize_ - glm::vec3(padding_);
  b.hi = bounds_.lo + glm::vec3(x + 1, y + 1, z + 1) * voxelSize_ + glm::vec3(padding_);
  return b;
}

double ContributorGrid::heaviestVoxelEstimate(const Scene& scene) const {
  // Each displaced triangle's estimate (below) is spread evenly over the voxels of its
  // undisplaced box: displaced geometry stays near its surface however generous its bound (the
  // bound is what made the voxels too big). Per voxel, in float: an estimate.
  std::vector<float> load(size_t(resolution_.x) * resolution_.y * resolution_.z, 0.0f);
  float heaviest = 0.0f;
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    const Displacement* d = displacements_[m];
    if (!d) continue;
    const Mesh& mesh = scene.meshes[m];
    for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
      const Bounds3 box = triangleReach(mesh, t, 0.0f);
      if (box.empty()) continue;
      const glm::ivec3 lo = glm::clamp(glm::ivec3(glm::floor((box.lo - bounds_.lo) / voxelSize_)), glm::ivec3(0), resolution_ - 1);
      const glm::ivec3 hi = glm::clamp(glm::ivec3(glm::floor((box.hi - bounds_.lo) / voxelSize_)), glm::ivec3(0), resolution_ - 1);
      const glm::ivec3 cells = hi - lo + 1;
      // 4^k overstates slivers (a UV sphere's poles): capped by the triangles its area and
      // its longest edge ask for at the edge length.
      const glm::vec3 a = mesh.P[mesh.indices[3 * size_t(t)]], b = mesh.P[mesh.indices[3 * size_t(t) + 1]],
                      c = mesh.P[mesh.indices[3 * size_t(t) + 2]];
      const float l = std::max(d->edgeLength, 1e-30f);
      const float area = 0.5f * glm::length(glm::cross(b - a, c - a));
      const float longest = std::sqrt(std::max({glm::dot(b - a, b - a), glm::dot(c - b, c - b), glm::dot(a - c, a - c)}));
      const float byShape = std::max({1.0f, area / (0.25f * l * l), 2.0f * longest / l});
      const float estimate = std::min(float(estimatedMicroTriangles(mesh, t, *d)), byShape);
      const float share = estimate / float(cells.x * cells.y * cells.z);
      for (int z = lo.z; z <= hi.z; ++z)
        for (int y = lo.y; y <= hi.y; ++y)
          for (int x = lo.x; x <= hi.x; ++x) {
            float& v = load[voxelIndex({x, y, z})];
            v += share;
            heaviest = std::max(heaviest, v);
          }
    }
  }
  return double(heaviest);
}

}  // namespace relief
