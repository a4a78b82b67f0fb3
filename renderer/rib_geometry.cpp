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
  if (loopIndices.size() == 1) {
    bool convex = true;
    const std::vector<uint32_t>& loop = loopIndices[0];
    for (size_t i = 0; i < loop.size() && convex; ++i)
      convex = cross2(pts[loop[i]], pts[loop[(i + 1) % loop.size()]],
                      pts[loop[(i + 2) % loop.size()]]) > 0;
    if (convex) return fan();
  }
  // Ear clipping is quadratic or worse; beyond this size a fan is the bounded-time answer.
  if (pts.size() > kMaxEarClippingPoints) {
    if (fanned) *fanned = true;
    return fan();
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

SubdivisionSurface subdivideCatmullClark(const SubdivisionSurface& in) {
  const size_t numPoints = in.P.size();
  // Edges by their point pair, with the faces on each side (a third face makes it non-manifold:
  // it is treated as a boundary, which keeps the surface whole).
  struct Edge {
    uint32_t a, b;
    uint32_t faces[2] = {UINT32_MAX, UINT32_MAX};
    int count = 0;
  };
  std::vector<Edge> edges;
  std::unordered_map<uint64_t, uint32_t> edgeOf;
  std::vector<std::vector<uint32_t>> faceEdges(in.faces.size());
  for (uint32_t f = 0; f < in.faces.size(); ++f) {
    const std::vector<uint32_t>& face = in.faces[f];
    for (size_t k = 0; k < face.size(); ++k) {
      const uint32_t a = face[k], b = face[(k + 1) % face.size()];
      const uint64_t key = uint64_t(std::min(a, b)) << 32 | std::max(a, b);
      auto [it, fresh] = edgeOf.emplace(key, uint32_t(edges.size()));
      if (fresh) edges.push_back(Edge{std::min(a, b), std::max(a, b)});
      Edge& e = edges[it->second];
      if (e.count < 2) e.faces[e.count] = f;
      ++e.count;
      faceEdges[f].push_back(it->second);
    }
  }
  auto boundary = [](const Edge& e) { return e.count != 2; };
  // New points: the old ones (moved), then one per face, then one per edge.
  const size_t facesBase = numPoints, edgesBase = numPoints + in.faces.size();
  const size_t total = edgesBase + edges.size();
  SubdivisionSurface out;
  out.P.assign(total, glm::vec3(0.0f));
  out.channels = in.channels;
  for (SubdivisionSurface::Channel& c : out.channels) c.values.assign(total * size_t(c.components), 0.0f);
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
      const Edge& edge = edges[e];
      edgeMid[e] = (get(edge.a) + get(edge.b)) * 0.5f;
      V point = edgeMid[e];
      if (smooth && !boundary(edge))
        point = (get(edge.a) + get(edge.b) + facePoint[edge.faces[0]] + facePoint[edge.faces[1]]) * 0.25f;
      put(edgesBase + e, point);
    }
    // Old points: interior ones by (Q + 2R + (n - 3) S) / n, boundary ones by the crease rule.
    std::vector<V> faceSum(numPoints, zero), midSum(numPoints, zero), boundarySum(numPoints, zero);
    std::vector<int> valence(numPoints, 0), faceCount(numPoints, 0), boundaryCount(numPoints, 0);
    for (uint32_t f = 0; f < in.faces.size(); ++f)
      for (uint32_t p : in.faces[f]) faceSum[p] = faceSum[p] + facePoint[f], ++faceCount[p];
    for (uint32_t e = 0; e < edges.size(); ++e) {
      const Edge& edge = edges[e];
      for (uint32_t p : {edge.a, edge.b}) {
        midSum[p] = midSum[p] + edgeMid[e], ++valence[p];
        if (boundary(edge)) boundarySum[p] = boundarySum[p] + get(p == edge.a ? edge.b : edge.a), ++boundaryCount[p];
      }
    }
    for (uint32_t p = 0; p < numPoints; ++p) {
      V point = get(p);
      if (smooth && faceCount[p] > 0) {
        if (boundaryCount[p] == 2 && faceCount[p] == 1) {
          // A corner of one face (a grid's corner) stays: "interpolateboundary" makes it sharp.
        } else if (boundaryCount[p] == 2) {
          point = (boundarySum[p] + get(p) * 6.0f) * 0.125f;
        } else if (boundaryCount[p] == 0 && valence[p] >= 3) {
          const float n = float(valence[p]);
          const V Q = faceSum[p] * (1.0f / float(faceCount[p]));
          const V R = midSum[p] * (1.0f / n);
          point = (Q + R * 2.0f + get(p) * (n - 3.0f)) * (1.0f / n);
        }  // corners and non-manifold points stay where they are
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
  // Faces: corner i of face f becomes (p_i, edge i, face point, edge i - 1), wound as the face.
  for (uint32_t f = 0; f < in.faces.size(); ++f) {
    const std::vector<uint32_t>& face = in.faces[f];
    const size_t n = face.size();
    for (size_t i = 0; i < n; ++i) {
      out.faces.push_back({face[i], uint32_t(edgesBase + faceEdges[f][i]), uint32_t(facesBase + f),
                           uint32_t(edgesBase + faceEdges[f][(i + n - 1) % n])});
      out.parent.push_back(in.parent.empty() ? f : in.parent[f]);
    }
  }
  return out;
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
