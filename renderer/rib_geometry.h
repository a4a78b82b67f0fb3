// Geometry helpers of the RIB reader that do not depend on its parser state: polygon
// triangulation (ear clipping, with holes) and bicubic patch bases. Used by rib_reader.cpp and
// tested on their own; depends only on GLM.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include <glm/glm.hpp>

namespace relief {

// Triangulates one planar-ish polygon given as loops of points: loops[0] is the outer boundary,
// any further loops are holes. Returns triangles as indices into the concatenation of the loops
// (loop 0's points first), wound like the outer loop as given (so the caller's orientation is
// kept). Handles convex and concave loops and holes by bridging each hole to the outer boundary
// and ear clipping in the polygon's dominant projection plane. Never fails: degenerate input
// (collinear or repeated points, self-intersections) still yields loop.size() - 2 triangles per
// loop when possible, some of them possibly zero-area, rather than an error or an endless loop.
//
// Polygons of more than kMaxEarClippingPoints points in all (holes included) are split in halves
// (as large convex ones are) instead, holes ignored: ear clipping's quadratic cost would otherwise
// let one polygon stall the load. `fanned`, if given, says whether that happened to a polygon that is
// not a convex loop (so that the caller can warn). A hole with a vertex outside the boundary
// (in the projection plane) is left out rather than bridged, which would draw a spike out to it;
// `outsideHoles`, if given, counts them.
constexpr size_t kMaxEarClippingPoints = 20000;
// Convex polygons of more than kBalancedConvexPoints points are split in halves recursively rather
// than fanned, so their triangles are not slivers from the first corner; smaller ones are fans.
constexpr size_t kBalancedConvexPoints = 32;
std::vector<uint32_t> triangulatePolygon(const std::vector<std::vector<glm::vec3>>& loops,
                                         bool* fanned = nullptr, size_t* outsideHoles = nullptr);

// A cubic basis as RenderMan defines it: weights of the 4 control points at parameter u are
// [u^3 u^2 u 1] * matrix (row-major, matrix[row][column]), and `step` control points separate
// consecutive patches of a patch mesh.
struct CubicBasis {
  float matrix[4][4];
  int step = 3;

  // Weights of the four control points at u, and their derivatives with respect to u.
  void weights(float u, float w[4]) const;
  void derivativeWeights(float u, float w[4]) const;
};

// The named bases of RiBasis: "bezier", "b-spline", "catmull-rom", "hermite", "power". False for
// an unknown name.
bool namedCubicBasis(const std::string& name, CubicBasis* basis);

// The B-spline basis of RI NuPatch: `order` (degree + 1, at most kMaxNurbsOrder) over `knots`
// (count + order non-decreasing values) for `count` control points. At parameter t, writes the
// `order` functions that may be nonzero, with their first derivatives, and returns the index of
// the first of them; t is clamped to [knots[order - 1], knots[count]], and the last knot belongs
// to the span before it. Returns -1 when that range is empty.
constexpr int kMaxNurbsOrder = 16;
int nurbsBasis(const std::vector<float>& knots, int order, int count, float t, float* value, float* derivative);

// A polygon mesh under Catmull-Clark subdivision (RI SubdivisionMesh "catmull-clark"): points,
// faces as point lists, and per-point data channels that subdivide with the points (`smooth`:
// by the Catmull-Clark masks, as "vertex" primitive variables; otherwise bilinearly, as "varying"
// ones). Boundaries follow the crease rule (RenderMan's "interpolateboundary"): boundary edges
// split at their midpoints, boundary points take (M1 + 6 S + M2) / 8 of their two boundary
// neighbours (a point of a single face, a corner, stays), so the surface reaches the boundary.
// `parent` names each face's face of the input.
//
// Sharpness (the "crease" and "corner" tags) follows the semi-sharp rules of DeRose, Kass and
// Truong (1998): an edge of sharpness s >= 1 splits at its midpoint and its two halves keep s - 1;
// 0 < s < 1 blends the smooth and sharp rules by s. A point on two sharp edges takes the crease
// rule, on three or more the corner rule (it stays), blended by their mean sharpness when below 1;
// a point's own sharpness blends towards staying. Sharpness of kInfiniteSharpness or more never
// wears off (RI_INFINITY is 1e38). Faces marked as holes subdivide like the others (they shape
// their neighbours) and their children stay holes.
constexpr float kInfiniteSharpness = 1e30f;
struct SubdivisionSurface {
  std::vector<glm::vec3> P;
  std::vector<std::vector<uint32_t>> faces;
  std::vector<uint32_t> parent;
  struct Channel {
    int components = 1;
    bool smooth = true;
    std::vector<float> values;  // components per point (per face corner for faceVarying)
  };
  std::vector<Channel> channels;
  // Values per face corner, faces in order ("facevarying" primitive variables): interpolated
  // linearly over each face, as RenderMan does without facevarying boundary rules.
  std::vector<Channel> faceVarying;
  std::unordered_map<uint64_t, float> creases;  // edge key (edgeKey) -> sharpness
  std::vector<float> corners;                   // per point, or empty: none sharp
  std::vector<uint8_t> holes;                   // per face, or empty: none

  static uint64_t edgeKey(uint32_t a, uint32_t b) { return uint64_t(std::min(a, b)) << 32 | std::max(a, b); }
};
// One level: every face of n sides becomes n quads. Faces whose points are out of range are
// dropped beforehand by the caller.
SubdivisionSurface subdivideCatmullClark(const SubdivisionSurface& in);
// Moves the points (and the smooth channels) of a subdivided mesh of quads to their limit
// positions: Catmull-Clark's limit masks for smooth points, (M1 + 4 S + M2) / 6 on creases and
// boundaries, corners staying, blended as the subdivision rules are for fractional sharpness.
// Points of faces that are not quads stay.
void projectToLimit(SubdivisionSurface& s);
// Area-weighted point normals of a mesh of faces (Newell normals of each face summed per point).
std::vector<glm::vec3> pointNormals(const SubdivisionSurface& s);

}  // namespace relief
