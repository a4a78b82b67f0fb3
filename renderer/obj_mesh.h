// Loads Wavefront OBJ files for the RIB reader's `Geometry "objmesh"` through tinyobjloader. The
// result is an object-space Mesh; the reader transforms it and binds material and displacement.
#pragma once

#include <string>

#include "renderer/scene.h"

namespace relief {

// Reads `path` into *mesh (object space): positions, normals (when every corner has one),
// texture coordinates as st = (u, 1 - v) (OBJ's v runs up, RenderMan's t runs down the image)
// and vertex colours when the file has them. Faces of any size are triangulated by ear clipping
// with their winding kept. Groups and materials are ignored. False with *error set when the file
// cannot be read or is malformed (bad indices, no faces); *warning gets tinyobjloader's warnings.
bool loadObjMesh(const std::string& path, Mesh* mesh, std::string* error, std::string* warning);

}  // namespace relief
