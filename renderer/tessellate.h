// Turns RenderMan quadrics into input triangle meshes (world space) for the contributor grid, and
// gives tessellated smooth surfaces their per-vertex derivatives. Used by the scene reader
// (rib_reader.*) and by geometry tests; depends only on scene.h.
#pragma once

#include <glm/glm.hpp>

#include "renderer/scene.h"

namespace relief {

// RenderMan Sphere radius zmin zmax thetamax (degrees), tessellated into nu x nv quads split into
// triangles, with per-vertex P, N (outward; inward for a negative thetamax, RI's inside-out sphere), uv = (phi/thetamax, (theta-thetamin)/(thetamax-thetamin))
// as RenderMan's parametric u,v, st = uv; seam vertices duplicated; poles handled without
// degenerate-triangle NaNs. Positions transformed by worldFromObject (normals by its inverse
// transpose).
//
// Seam copies of a full sphere get bit-identical positions and normals, and pole vertices are
// exactly on the axis, so the mesh is closed in floating point. At a pole each quad keeps its
// zero-area triangle (two pole vertices and one ring vertex): after displacement it becomes the
// sliver that joins the pole edges of neighbouring columns, whose midpoints get different u and so
// different displacements; dropping it would open a crack there. Subdivision and intersection
// treat zero-area triangles without NaNs (no hit, a finite fallback normal).
//
// dPdu and dPdv are the sphere's own derivatives at each vertex, not yet shared between a seam's
// or a pole's copies: smoothSurfaceDerivatives does that (the RIB reader's addMesh, once per mesh).
Mesh tessellateSphere(float radius, float zmin, float zmax, float thetamaxDeg, int nu, int nv,
                      const glm::mat4& worldFromObject);

// Fills mesh.dPdu and mesh.dPdv of a tessellated smooth surface (Mesh::smoothSurface, with a
// global (u, v) parameterisation: quadrics, patches, NURBS), the same for every vertex at the same
// position with the same normal (so a seam's two copies and a pole's get one value): the mean of
// the surface's own derivatives where the tessellator gave them per vertex (mesh.dPdu and dPdv
// sized as P), else of the derivatives of the (u, v) maps of the triangles around them. Triangles
// whose map is degenerate add nothing; a vertex with nothing keeps zero vectors.
void smoothSurfaceDerivatives(Mesh& mesh);

}  // namespace relief
