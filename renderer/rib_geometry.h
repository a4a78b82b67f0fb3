// Geometry helpers of the RIB reader that do not depend on its parser state: polygon
// triangulation (ear clipping, with holes) and bicubic patch bases. Used by rib_reader.cpp and
// tested on their own; depends only on GLM.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
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
// Polygons of more than kMaxEarClippingPoints points in all (holes included) are fanned from their
// first corner instead, holes ignored: ear clipping's quadratic cost would otherwise let one
// polygon stall the load. `fanned`, if given, says whether that happened to a polygon that is
// not a convex loop (so that the caller can warn). A hole with a vertex outside the boundary
// (in the projection plane) is left out rather than bridged, which would draw a spike out to it;
// `outsideHoles`, if given, counts them.
constexpr size_t kMaxEarClippingPoints = 20000;
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

// A polygon mesh under Catmull-Clark subdivision (RI SubdivisionMesh "catmull-clark"): points,
// faces as point lists, and per-point data channels that subdivide with the points (`smooth`:
// by the Catmull-Clark masks, as "vertex" primitive variables; otherwise bilinearly, as "varying"
// ones). Boundaries follow the crease rule (RenderMan's "interpolateboundary"): boundary edges
// split at their midpoints, boundary points take (M1 + 6 S + M2) / 8 of their two boundary
// neighbours (a point of a single face, a corner, stays), so the surface reaches the boundary.
// `parent` names each face's face of the input.
struct SubdivisionSurface {
  std::vector<glm::vec3> P;
  std::vector<std::vector<uint32_t>> faces;
  std::vector<uint32_t> parent;
  struct Channel {
    int components = 1;
    bool smooth = true;
    std::vector<float> values;  // components per point
  };
  std::vector<Channel> channels;
};
// One level: every face of n sides becomes n quads. Faces whose points are out of range are
// dropped beforehand by the caller.
SubdivisionSurface subdivideCatmullClark(const SubdivisionSurface& in);
// Area-weighted point normals of a mesh of faces (Newell normals of each face summed per point).
std::vector<glm::vec3> pointNormals(const SubdivisionSurface& s);

}  // namespace relief
