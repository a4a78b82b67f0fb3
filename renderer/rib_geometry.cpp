// Polygon triangulation and cubic bases for the RIB reader (see rib_geometry.h).
#include "renderer/rib_geometry.h"

#include <unordered_map>
#include <algorithm>
#include <cmath>
#include <numeric>

namespace relief {

namespace {

double cross2(glm::dvec2 a, glm::dvec2 b, glm::dvec2 c) {
  return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

double signedArea(const std::vector<glm::dvec2>& pts, const std::vector<uint32_t>& loop) {
  double area = 0;
  for (size_t i = 0; i < loop.size(); ++i) {
    const glm::dvec2 a = pts[loop[i]], b = pts[loop[(i + 1) % loop.size()]];
    area += a.x * b.y - a.y * b.x;
  }
  return area * 0.5;
}

// True when segments pq and rs cross at a point interior to both (touching endpoints do not count).
bool segmentsCross(glm::dvec2 p, glm::dvec2 q, glm::dvec2 r, glm::dvec2 s) {
  const double d1 = cross2(p, q, r), d2 = cross2(p, q, s);
  const double d3 = cross2(r, s, p), d4 = cross2(r, s, q);
  return ((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0));
}

bool insideOrOnTriangle(glm::dvec2 p, glm::dvec2 a, glm::dvec2 b, glm::dvec2 c) {
  return cross2(a, b, p) >= 0 && cross2(b, c, p) >= 0 && cross2(c, a, p) >= 0;
}

// Joins `hole` into `outer` through a bridge from the hole's rightmost vertex to the nearest
// outer vertex that sees it (a bridge crossing no edge of the outer loop or of any hole).
void bridgeHole(const std::vector<glm::dvec2>& pts, std::vector<uint32_t>* outer,
                const std::vector<uint32_t>& hole,
                const std::vector<std::vector<uint32_t>>& allHoles) {
  size_t m = 0;
  for (size_t i = 1; i < hole.size(); ++i)
    if (pts[hole[i]].x > pts[hole[m]].x) m = i;
  const glm::dvec2 M = pts[hole[m]];
  std::vector<size_t> order(outer->size());
  std::iota(order.begin(), order.end(), size_t(0));
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    const double da = glm::dot(pts[(*outer)[a]] - M, pts[(*outer)[a]] - M);
    const double db = glm::dot(pts[(*outer)[b]] - M, pts[(*outer)[b]] - M);
    return da < db || (da == db && a < b);
  });
  auto crossesLoop = [&](glm::dvec2 v, const std::vector<uint32_t>& loop) {
    for (size_t i = 0; i < loop.size(); ++i) {
      if (segmentsCross(M, v, pts[loop[i]], pts[loop[(i + 1) % loop.size()]])) return true;
    }
    return false;
  };
  size_t best = order.empty() ? 0 : order[0];
  for (size_t candidate : order) {
    const glm::dvec2 v = pts[(*outer)[candidate]];
    bool blocked = crossesLoop(v, *outer);
    for (const std::vector<uint32_t>& h : allHoles) blocked = blocked || crossesLoop(v, h);
    if (!blocked) {
      best = candidate;
      break;
    }
  }
  std::vector<uint32_t> joined(outer->begin(), outer->begin() + ptrdiff_t(best) + 1);
  for (size_t k = 0; k <= hole.size(); ++k) joined.push_back(hole[(m + k) % hole.size()]);
  joined.push_back((*outer)[best]);
  joined.insert(joined.end(), outer->begin() + ptrdiff_t(best) + 1, outer->end());
  *outer = std::move(joined);
}

}  // namespace

std::vector<uint32_t> triangulatePolygon(const std::vector<std::vector<glm::vec3>>& loops, bool* fanned,
                                         size_t* outsideHoles) {
  if (fanned) *fanned = false;
  if (outsideHoles) *outsideHoles = 0;
  std::vector<uint32_t> triangles;
  if (loops.empty() || loops[0].size() < 3) return triangles;
  if (loops.size() == 1 && loops[0].size() == 3) return {0, 1, 2};

  // Newell's normal of the outer loop picks the projection plane and keeps the loop
  // counter-clockwise in it, so emitted triangles wind like the input.
  const std::vector<glm::vec3>& outer3 = loops[0];
  glm::dvec3 normal(0.0);
  for (size_t i = 0; i < outer3.size(); ++i) {
    const glm::dvec3 a(outer3[i]), b(outer3[(i + 1) % outer3.size()]);
    normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x),
                         (a.x - b.x) * (a.y + b.y));
  }
  const glm::dvec3 absN = glm::abs(normal);
  const int k = absN.x >= absN.y && absN.x >= absN.z ? 0 : absN.y >= absN.z ? 1 : 2;
  int ia = (k + 1) % 3, ib = (k + 2) % 3;
  if (normal[k] < 0) std::swap(ia, ib);

  std::vector<glm::dvec2> pts;
  std::vector<std::vector<uint32_t>> loopIndices;
  for (const std::vector<glm::vec3>& loop : loops) {
    std::vector<uint32_t> indices;
    for (const glm::vec3& p : loop) {
      indices.push_back(uint32_t(pts.size()));
      pts.emplace_back(double(p[ia]), double(p[ib]));
    }
    loopIndices.push_back(std::move(indices));
  }

  // A convex boundary without holes is its own fan (and the common case: skip the O(n^2) search).
  auto fan = [&]() {
    for (uint32_t k = 1; k + 1 < uint32_t(loopIndices[0].size()); ++k)
      triangles.insert(triangles.end(), {0u, k, k + 1});
    return triangles;
  };
  // A convex boundary of many points (a disk of 300,000) is split in halves instead: triangle
  // (a, middle, b) and each half again, so triangles shrink toward the boundary rather than all
  // reaching from corner 0. A fan's slivers each crossed the scene (40 us apiece to place in the
  // grid, deep subdivision when displaced). Any corners of a convex loop make a triangle inside
  // it, wound as the loop; small polygons keep their fan (the quads' diagonal stays 0-2).
  auto halves = [&]() {
    const uint32_t n = uint32_t(loopIndices[0].size());
    std::vector<std::pair<uint32_t, uint32_t>> arcs = {{0, n / 3}, {n / 3, 2 * n / 3}, {2 * n / 3, n}};
    triangles.insert(triangles.end(), {0u, n / 3, 2 * n / 3});
    while (!arcs.empty()) {
      const auto [a, b] = arcs.back();
      arcs.pop_back();
      if (b - a < 2) continue;
      const uint32_t mid = a + (b - a) / 2;
      triangles.insert(triangles.end(), {a, mid, b % n});
      arcs.push_back({a, mid});
      arcs.push_back({mid, b});
    }
    return triangles;
  };
  if (loopIndices.size() == 1) {
    bool convex = true;
    const std::vector<uint32_t>& loop = loopIndices[0];
    for (size_t i = 0; i < loop.size() && convex; ++i)
      convex = cross2(pts[loop[i]], pts[loop[(i + 1) % loop.size()]],
                      pts[loop[(i + 2) % loop.size()]]) > 0;
    if (convex) return loop.size() > kBalancedConvexPoints ? halves() : fan();
  }
  // Ear clipping is quadratic or worse; beyond this size the halves are the bounded-time answer
  // (exact for a convex loop whose float corners lost their strict convexity, as a disk of 300,000
  // points does; a concave one may get triangles outside it, as a fan would, but no slivers).
  if (pts.size() > kMaxEarClippingPoints) {
    if (fanned) *fanned = true;
    return halves();
  }

  std::vector<uint32_t> polygon = loopIndices[0];
  std::vector<std::vector<uint32_t>> holes;
  // Even-odd containment in the boundary; points on it count as inside (a hole may touch it).
  auto inside = [&](glm::dvec2 q) {
    bool in = false;
    for (size_t a = 0, b = polygon.size() - 1; a < polygon.size(); b = a++) {
      const glm::dvec2 pa = pts[polygon[a]], pb = pts[polygon[b]];
      const double cross = (pb.x - pa.x) * (q.y - pa.y) - (pb.y - pa.y) * (q.x - pa.x);
      const bool between = std::min(pa.y, pb.y) <= q.y && q.y <= std::max(pa.y, pb.y) &&
                           std::min(pa.x, pb.x) <= q.x && q.x <= std::max(pa.x, pb.x);
      if (cross == 0.0 && between) return true;
      if ((pa.y > q.y) != (pb.y > q.y) && q.x < pa.x + (q.y - pa.y) * (pb.x - pa.x) / (pb.y - pa.y)) in = !in;
    }
    return in;
  };
  for (size_t i = 1; i < loopIndices.size(); ++i) {
    if (loopIndices[i].size() < 3) continue;
    // Up to 16 of its vertices are checked (the whole check stays linear in the points).
    const std::vector<uint32_t>& loop = loopIndices[i];
    const size_t stride = std::max<size_t>(1, loop.size() / 16);
    bool contained = true;
    for (size_t v = 0; v < loop.size() && contained; v += stride) contained = inside(pts[loop[v]]);
    if (!contained) {
      if (outsideHoles) ++*outsideHoles;
      continue;
    }
    std::vector<uint32_t> hole = loopIndices[i];
    if (signedArea(pts, hole) > 0) std::reverse(hole.begin(), hole.end());  // holes run clockwise
    holes.push_back(std::move(hole));
  }
  // Rightmost hole first, so each bridge sees only holes not yet joined.
  std::sort(holes.begin(), holes.end(), [&](const auto& a, const auto& b) {
    double ma = -INFINITY, mb = -INFINITY;
    for (uint32_t i : a) ma = std::max(ma, pts[i].x);
    for (uint32_t i : b) mb = std::max(mb, pts[i].x);
    return ma > mb;
  });
  for (size_t h = 0; h < holes.size(); ++h) {
    const std::vector<std::vector<uint32_t>> rest(holes.begin() + ptrdiff_t(h) + 1, holes.end());
    bridgeHole(pts, &polygon, holes[h], rest);
  }

  // Ear clipping over a circular doubly linked list of polygon positions.
  const size_t n = polygon.size();
  std::vector<size_t> prev(n), next(n);
  for (size_t i = 0; i < n; ++i) {
    prev[i] = (i + n - 1) % n;
    next[i] = (i + 1) % n;
  }
  // Starting at the second corner makes a convex polygon come out as the fan around corner 0.
  size_t remaining = n, current = 1;
  auto at = [&](size_t node) { return pts[polygon[node]]; };
  auto isEar = [&](size_t node) {
    const glm::dvec2 a = at(prev[node]), b = at(node), c = at(next[node]);
    if (cross2(a, b, c) <= 0) return false;
    for (size_t other = next[next[node]]; other != prev[node]; other = next[other]) {
      const glm::dvec2 p = at(other);
      if (p == a || p == b || p == c) continue;  // bridge copies and repeated points
      if (insideOrOnTriangle(p, a, b, c)) return false;
    }
    return true;
  };
  auto clip = [&](size_t node) {
    triangles.push_back(polygon[prev[node]]);
    triangles.push_back(polygon[node]);
    triangles.push_back(polygon[next[node]]);
    next[prev[node]] = next[node];
    prev[next[node]] = prev[node];
    current = next[node];
    --remaining;
  };
  while (remaining > 3) {
    size_t node = current;
    bool clipped = false;
    for (size_t tries = 0; tries < remaining; ++tries, node = next[node]) {
      if (isEar(node)) {
        clip(node);
        clipped = true;
        break;
      }
    }
    if (clipped) continue;
    // No clean ear (degenerate or self-intersecting input): clip the most convex corner so the
    // loop always shrinks.
    size_t best = current;
    double bestCross = -INFINITY;
    node = current;
    for (size_t tries = 0; tries < remaining; ++tries, node = next[node]) {
      const double c = cross2(at(prev[node]), at(node), at(next[node]));
      if (c > bestCross) bestCross = c, best = node;
    }
    clip(best);
  }
  triangles.push_back(polygon[prev[current]]);
  triangles.push_back(polygon[current]);
  triangles.push_back(polygon[next[current]]);
  return triangles;
}

void CubicBasis::weights(float u, float w[4]) const {
  const float U[4] = {u * u * u, u * u, u, 1.0f};
  for (int c = 0; c < 4; ++c)
    w[c] = U[0] * matrix[0][c] + U[1] * matrix[1][c] + U[2] * matrix[2][c] + U[3] * matrix[3][c];
}

void CubicBasis::derivativeWeights(float u, float w[4]) const {
  const float dU[3] = {3.0f * u * u, 2.0f * u, 1.0f};
  for (int c = 0; c < 4; ++c)
    w[c] = dU[0] * matrix[0][c] + dU[1] * matrix[1][c] + dU[2] * matrix[2][c];
}

bool namedCubicBasis(const std::string& name, CubicBasis* basis) {
  auto set = [basis](std::initializer_list<float> values, float scale, int step) {
    auto it = values.begin();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) basis->matrix[r][c] = *it++ * scale;
    basis->step = step;
  };
  if (name == "bezier") {
    set({-1, 3, -3, 1, 3, -6, 3, 0, -3, 3, 0, 0, 1, 0, 0, 0}, 1.0f, 3);
  } else if (name == "b-spline" || name == "bspline") {
    set({-1, 3, -3, 1, 3, -6, 3, 0, -3, 0, 3, 0, 1, 4, 1, 0}, 1.0f / 6.0f, 1);
  } else if (name == "catmull-rom" || name == "catmullrom") {
    set({-1, 3, -3, 1, 2, -5, 4, -1, -1, 0, 1, 0, 0, 2, 0, 0}, 0.5f, 1);
  } else if (name == "hermite") {
    set({2, 1, -2, 1, -3, -2, 3, -1, 0, 1, 0, 0, 1, 0, 0, 0}, 1.0f, 2);
  } else if (name == "power") {
    set({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}, 1.0f, 4);
  } else {
    return false;
  }
  return true;
}

int nurbsBasis(const std::vector<float>& knots, int order, int count, float t, float* value, float* derivative) {
  const int p = order - 1;
  const float lo = knots[size_t(p)], hi = knots[size_t(count)];
  if (!(lo < hi)) return -1;
  t = std::clamp(t, lo, hi);
  // The span [knots[i], knots[i + 1]) holding t, nonempty, with i in [p, count - 1].
  int i = p;
  while (i < count - 1 && knots[size_t(i) + 1] <= t) ++i;
  while (i > p && knots[size_t(i)] == knots[size_t(i) + 1]) --i;
  // Cox-de Boor, degree by degree; `lower` keeps the degree p - 1 functions for the derivatives.
  float left[kMaxNurbsOrder], right[kMaxNurbsOrder], lower[kMaxNurbsOrder];
  value[0] = 1.0f;
  lower[0] = 1.0f;
  for (int j = 1; j <= p; ++j) {
    if (j == p) std::copy(value, value + p, lower);
    left[j] = t - knots[size_t(i + 1 - j)];
    right[j] = knots[size_t(i + j)] - t;
    float saved = 0.0f;
    for (int r = 0; r < j; ++r) {
      const float denominator = right[r + 1] + left[j - r];
      const float term = denominator != 0.0f ? value[r] / denominator : 0.0f;
      value[r] = saved + right[r + 1] * term;
      saved = left[j - r] * term;
    }
    value[j] = saved;
  }
  // N'_{k,p} = p (N_{k,p-1} / (u_{k+p} - u_k) - N_{k+1,p-1} / (u_{k+p+1} - u_{k+1})), with the
  // degree p - 1 functions of this span being lower[0..p-1] for k = i - p + 1 .. i.
  for (int r = 0; r <= p; ++r) {
    if (p == 0) {
      derivative[r] = 0.0f;
      continue;
    }
    const int k = i - p + r;
    float d = 0.0f;
    if (r > 0) {
      const float span = knots[size_t(k + p)] - knots[size_t(k)];
      if (span != 0.0f) d += lower[r - 1] / span;
    }
    if (r < p) {
      const float span = knots[size_t(k + p + 1)] - knots[size_t(k + 1)];
      if (span != 0.0f) d -= lower[r] / span;
    }
    derivative[r] = float(p) * d;
  }
  return i - p;
}

namespace {

// The edges of a face mesh and what each point's rule needs to know of them.
struct SubdivisionTopology {
  struct Edge {
    uint32_t a, b;
    uint32_t faces[2] = {UINT32_MAX, UINT32_MAX};
    int count = 0;          // faces on it: not 2 makes it a boundary (a third: non-manifold)
    float sharpness = 0.0f;  // its crease tag's, infinite on boundaries
  };
  std::vector<Edge> edges;
  std::vector<std::vector<uint32_t>> faceEdges;  // edge k of face f joins its corners k and k + 1
  // Per point: edges, faces, boundary edges, sharp edges (boundaries included) and the mean of
  // their sharpness, the other ends of its first two sharp edges, and whether every face is a quad.
  struct Point {
    int valence = 0, faces = 0, boundary = 0, sharp = 0;
    float sharpnessSum = 0.0f;
    uint32_t sharpEnds[2] = {0, 0};
    bool quads = true;
  };
  std::vector<Point> points;

  explicit SubdivisionTopology(const SubdivisionSurface& s) : faceEdges(s.faces.size()), points(s.P.size()) {
    std::unordered_map<uint64_t, uint32_t> edgeOf;
    for (uint32_t f = 0; f < s.faces.size(); ++f) {
      const std::vector<uint32_t>& face = s.faces[f];
      for (size_t k = 0; k < face.size(); ++k) {
        const uint32_t a = face[k], b = face[(k + 1) % face.size()];
        auto [it, fresh] = edgeOf.emplace(SubdivisionSurface::edgeKey(a, b), uint32_t(edges.size()));
        if (fresh) edges.push_back(Edge{std::min(a, b), std::max(a, b)});
        Edge& e = edges[it->second];
        if (e.count < 2) e.faces[e.count] = f;
        ++e.count;
        faceEdges[f].push_back(it->second);
        ++points[face[k]].faces;
        points[face[k]].quads = points[face[k]].quads && face.size() == 4;
      }
    }
    for (Edge& e : edges) {
      if (e.count != 2) {
        e.sharpness = kInfiniteSharpness;
      } else if (auto it = s.creases.find(SubdivisionSurface::edgeKey(e.a, e.b)); it != s.creases.end()) {
        e.sharpness = std::max(it->second, 0.0f);
      }
      for (uint32_t p : {e.a, e.b}) {
        Point& q = points[p];
        ++q.valence;
        q.boundary += e.count != 2;
        if (e.sharpness > 0.0f) {
          if (q.sharp < 2) q.sharpEnds[q.sharp] = p == e.a ? e.b : e.a;
          ++q.sharp;
          q.sharpnessSum += std::min(e.sharpness, 1e6f);  // the mean is clamped to 1 (DeRose et al.)
        }
      }
    }
  }

  // How point p's new value mixes the smooth rule's, the sharp rule's (the crease rule on two
  // sharp edges, else staying) and its own: the sharp rule's weight against the smooth (1 where
  // the smooth rule is undefined: boundaries, valence below 3, no faces), then the weight of
  // staying against that (its own sharpness).
  struct Rule {
    float sharpWeight = 0.0f, stayWeight = 0.0f;
    bool crease = false;
  };
  Rule rule(uint32_t p, const std::vector<float>& corners) const {
    const Point& q = points[p];
    Rule r;
    if (q.faces == 1 && q.boundary == 2) {
      r.sharpWeight = 1.0f;  // a corner of one face stays: "interpolateboundary" makes it sharp
    } else if (q.sharp >= 2) {
      r.sharpWeight = std::min(q.sharpnessSum / float(q.sharp), 1.0f);
      r.crease = q.sharp == 2;
    }
    if (q.faces == 0 || q.boundary > 0 || q.valence < 3) r.sharpWeight = 1.0f;
    if (p < corners.size() && corners[p] > 0.0f) r.stayWeight = std::min(corners[p], 1.0f);
    return r;
  }
};

float wornSharpness(float s) { return s >= kInfiniteSharpness ? s : s - 1.0f; }

}  // namespace

SubdivisionSurface subdivideCatmullClark(const SubdivisionSurface& in) {
  const size_t numPoints = in.P.size();
  const SubdivisionTopology topo(in);
  const std::vector<SubdivisionTopology::Edge>& edges = topo.edges;
  // New points: the old ones (moved), then one per face, then one per edge.
  const size_t facesBase = numPoints, edgesBase = numPoints + in.faces.size();
  const size_t total = edgesBase + edges.size();
  SubdivisionSurface out;
  out.P.assign(total, glm::vec3(0.0f));
  out.channels = in.channels;
  for (SubdivisionSurface::Channel& c : out.channels) c.values.assign(total * size_t(c.components), 0.0f);
  std::vector<SubdivisionTopology::Rule> rules(numPoints);
  for (uint32_t p = 0; p < numPoints; ++p) rules[p] = topo.rule(p, in.corners);
  // Each quantity (P and every channel) goes through the same masks; `get`/`put` address one.
  auto apply = [&](auto get, auto put, auto zero, bool smooth) {
    using V = decltype(zero);
    std::vector<V> facePoint(in.faces.size(), zero);
    for (uint32_t f = 0; f < in.faces.size(); ++f) {
      V sum = zero;
      for (uint32_t p : in.faces[f]) sum = sum + get(p);
      facePoint[f] = sum * (1.0f / float(in.faces[f].size()));
      put(facesBase + f, facePoint[f]);
    }
    std::vector<V> edgeMid(edges.size(), zero);
    for (uint32_t e = 0; e < edges.size(); ++e) {
      const SubdivisionTopology::Edge& edge = edges[e];
      edgeMid[e] = (get(edge.a) + get(edge.b)) * 0.5f;
      V point = edgeMid[e];
      if (smooth && edge.sharpness < 1.0f) {
        const V smoothPoint = (get(edge.a) + get(edge.b) + facePoint[edge.faces[0]] + facePoint[edge.faces[1]]) * 0.25f;
        point = smoothPoint + (edgeMid[e] - smoothPoint) * edge.sharpness;
      }
      put(edgesBase + e, point);
    }
    // Old points: smooth ones by (Q + 2R + (n - 3) S) / n, creases by (M1 + 6 S + M2) / 8.
    std::vector<V> faceSum(numPoints, zero), midSum(numPoints, zero);
    for (uint32_t f = 0; f < in.faces.size(); ++f)
      for (uint32_t p : in.faces[f]) faceSum[p] = faceSum[p] + facePoint[f];
    for (uint32_t e = 0; e < edges.size(); ++e)
      for (uint32_t p : {edges[e].a, edges[e].b}) midSum[p] = midSum[p] + edgeMid[e];
    for (uint32_t p = 0; p < numPoints; ++p) {
      const V here = get(p);
      V point = here;
      const SubdivisionTopology::Point& q = topo.points[p];
      const SubdivisionTopology::Rule& r = rules[p];
      if (smooth && q.faces > 0) {
        V smoothPoint = here;
        if (r.sharpWeight < 1.0f) {
          const float n = float(q.valence);
          smoothPoint = (faceSum[p] * (1.0f / float(q.faces)) + midSum[p] * (2.0f / n) + here * (n - 3.0f)) * (1.0f / n);
        }
        const V sharpPoint = r.crease ? (get(q.sharpEnds[0]) + get(q.sharpEnds[1]) + here * 6.0f) * 0.125f : here;
        point = smoothPoint + (sharpPoint - smoothPoint) * r.sharpWeight;
        point = point + (here - point) * r.stayWeight;
      }
      put(p, point);
    }
  };
  apply([&](uint32_t p) { return in.P[p]; }, [&](size_t p, glm::vec3 v) { out.P[p] = v; }, glm::vec3(0.0f), true);
  for (size_t c = 0; c < in.channels.size(); ++c) {
    const int n = in.channels[c].components;
    for (int k = 0; k < n; ++k)
      apply([&](uint32_t p) { return in.channels[c].values[size_t(p) * size_t(n) + size_t(k)]; },
            [&](size_t p, float v) { out.channels[c].values[p * size_t(n) + size_t(k)] = v; }, 0.0f,
            in.channels[c].smooth);
  }
  // Sharpness wears off by one a level on both halves of an edge and on a point; new points and
  // the edges inside faces are smooth.
  for (uint32_t e = 0; e < edges.size(); ++e) {
    const SubdivisionTopology::Edge& edge = edges[e];
    if (edge.count != 2 || edge.sharpness <= 0.0f) continue;
    const float s = wornSharpness(edge.sharpness);
    if (s <= 0.0f) continue;
    out.creases[SubdivisionSurface::edgeKey(edge.a, uint32_t(edgesBase + e))] = s;
    out.creases[SubdivisionSurface::edgeKey(edge.b, uint32_t(edgesBase + e))] = s;
  }
  if (!in.corners.empty()) {
    out.corners.assign(total, 0.0f);
    for (size_t p = 0; p < numPoints; ++p)
      if (in.corners[p] > 0.0f) out.corners[p] = std::max(wornSharpness(in.corners[p]), 0.0f);
  }
  // Faces: corner i of face f becomes (p_i, edge i, face point, edge i - 1), wound as the face;
  // facevarying values follow linearly.
  out.faceVarying = in.faceVarying;
  for (SubdivisionSurface::Channel& c : out.faceVarying) c.values.clear();
  size_t corner = 0;  // the face's first corner in the facevarying arrays
  for (uint32_t f = 0; f < in.faces.size(); ++f) {
    const std::vector<uint32_t>& face = in.faces[f];
    const size_t n = face.size();
    for (size_t i = 0; i < n; ++i) {
      out.faces.push_back({face[i], uint32_t(edgesBase + topo.faceEdges[f][i]), uint32_t(facesBase + f),
                           uint32_t(edgesBase + topo.faceEdges[f][(i + n - 1) % n])});
      out.parent.push_back(in.parent.empty() ? f : in.parent[f]);
      if (!in.holes.empty()) out.holes.push_back(in.holes[f]);
    }
    for (size_t c = 0; c < in.faceVarying.size(); ++c) {
      const size_t m = size_t(in.faceVarying[c].components);
      const std::vector<float>& v = in.faceVarying[c].values;
      std::vector<float>& o = out.faceVarying[c].values;
      for (size_t i = 0; i < n; ++i) {
        const size_t next = (i + 1) % n, prev = (i + n - 1) % n;
        for (size_t k = 0; k < m; ++k) o.push_back(v[(corner + i) * m + k]);
        for (size_t k = 0; k < m; ++k) o.push_back(0.5f * (v[(corner + i) * m + k] + v[(corner + next) * m + k]));
        for (size_t k = 0; k < m; ++k) {
          float sum = 0.0f;
          for (size_t j = 0; j < n; ++j) sum += v[(corner + j) * m + k];
          o.push_back(sum / float(n));
        }
        for (size_t k = 0; k < m; ++k) o.push_back(0.5f * (v[(corner + i) * m + k] + v[(corner + prev) * m + k]));
      }
    }
    corner += n;
  }
  return out;
}

void projectToLimit(SubdivisionSurface& s) {
  const SubdivisionTopology topo(s);
  // Per point: the sum of its edge neighbours and of the corners across its quads.
  const size_t numPoints = s.P.size();
  std::vector<SubdivisionTopology::Rule> rules(numPoints);
  for (uint32_t p = 0; p < numPoints; ++p) rules[p] = topo.rule(p, s.corners);
  auto project = [&](auto get, auto put, auto zero) {
    using V = decltype(zero);
    std::vector<V> edgeSum(numPoints, zero), diagonalSum(numPoints, zero);
    for (const SubdivisionTopology::Edge& e : topo.edges)
      edgeSum[e.a] = edgeSum[e.a] + get(e.b), edgeSum[e.b] = edgeSum[e.b] + get(e.a);
    for (const std::vector<uint32_t>& face : s.faces)
      if (face.size() == 4)
        for (size_t i = 0; i < 4; ++i) diagonalSum[face[i]] = diagonalSum[face[i]] + get(face[(i + 2) % 4]);
    std::vector<V> limit(numPoints, zero);
    for (uint32_t p = 0; p < numPoints; ++p) {
      const SubdivisionTopology::Point& q = topo.points[p];
      const SubdivisionTopology::Rule& r = rules[p];
      const V here = get(p);
      limit[p] = here;
      if (q.faces == 0 || !q.quads) continue;
      V smoothLimit = here;
      if (r.sharpWeight < 1.0f) {
        const float n = float(q.valence);
        smoothLimit = (here * (n * n) + edgeSum[p] * 4.0f + diagonalSum[p]) * (1.0f / (n * (n + 5.0f)));
      }
      const V sharpLimit = r.crease ? (get(q.sharpEnds[0]) + get(q.sharpEnds[1]) + here * 4.0f) * (1.0f / 6.0f) : here;
      limit[p] = smoothLimit + (sharpLimit - smoothLimit) * r.sharpWeight;
      limit[p] = limit[p] + (here - limit[p]) * r.stayWeight;
    }
    for (uint32_t p = 0; p < numPoints; ++p) put(p, limit[p]);
  };
  project([&](uint32_t p) { return s.P[p]; }, [&](uint32_t p, glm::vec3 v) { s.P[p] = v; }, glm::vec3(0.0f));
  for (SubdivisionSurface::Channel& c : s.channels) {
    if (!c.smooth) continue;
    const size_t n = size_t(c.components);
    for (size_t k = 0; k < n; ++k)
      project([&](uint32_t p) { return c.values[p * n + k]; }, [&](uint32_t p, float v) { c.values[p * n + k] = v; }, 0.0f);
  }
}

std::vector<glm::vec3> pointNormals(const SubdivisionSurface& s) {
  std::vector<glm::vec3> normals(s.P.size(), glm::vec3(0.0f));
  for (const std::vector<uint32_t>& face : s.faces) {
    glm::vec3 n(0.0f);
    for (size_t k = 0; k < face.size(); ++k) {
      const glm::vec3& a = s.P[face[k]];
      const glm::vec3& b = s.P[face[(k + 1) % face.size()]];
      n += glm::cross(a, b);
    }
    for (uint32_t p : face) normals[p] += n;
  }
  for (glm::vec3& n : normals) {
    const float l = glm::length(n);
    n = l > 0.0f && std::isfinite(l) ? n / l : glm::vec3(0.0f);
  }
  return normals;
}

}  // namespace relief
