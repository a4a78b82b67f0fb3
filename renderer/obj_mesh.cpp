// OBJ loading for Geometry "objmesh" (see obj_mesh.h).
#include "renderer/obj_mesh.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <tuple>

#include <tiny_obj_loader.h>

#include "renderer/rib_geometry.h"

namespace relief {

namespace {

// tinyobjloader reads "nan", "inf" and missing coordinates as 0, so a broken file would render as
// a plausible one: vertex lines ("v", "vn", "vt") are checked here first. Empty if all are fine.
std::string checkVertexLines(const std::string& text) {
  std::istringstream lines(text);
  std::string line;
  for (size_t number = 1; std::getline(lines, line); ++number) {
    if (const size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);  // a comment
    std::istringstream words(line);
    std::string kind;
    if (!(words >> kind) || (kind != "v" && kind != "vn" && kind != "vt")) continue;
    const size_t minimum = kind == "vt" ? 1 : 3;
    size_t count = 0;
    for (std::string word; words >> word; ++count) {
      char* end = nullptr;
      const double d = std::strtod(word.c_str(), &end);
      if (end == word.c_str() || *end || !std::isfinite(d) || !std::isfinite(float(d)))
        return "line " + std::to_string(number) + ": '" + word + "' is not a finite number";
    }
    if (count < minimum)
      return "line " + std::to_string(number) + ": '" + kind + "' needs at least " + std::to_string(minimum) +
             " numbers, got " + std::to_string(count);
    if (kind == "vn" && count >= 3) {
      std::istringstream again(line);
      double x = 0, y = 0, z = 0;
      again >> kind >> x >> y >> z;
      if (x == 0 && y == 0 && z == 0) return "line " + std::to_string(number) + ": zero-length normal";
    }
  }
  return {};
}

}  // namespace

bool loadObjMesh(const std::string& path, Mesh* mesh, std::string* error, std::string* warning) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    *error = "cannot open mesh '" + path + "'";
    return false;
  }
  std::ifstream file(path, std::ios::binary);
  std::ostringstream buffer;
  buffer << file.rdbuf();
  if (!file) {
    *error = "cannot read mesh '" + path + "'";
    return false;
  }
  const std::string text = buffer.str();
  if (const std::string problem = checkVertexLines(text); !problem.empty()) {
    *error = "mesh '" + path + "', " + problem;
    return false;
  }
  // Materials are not used (shading comes from the scene), so "mtllib" is not followed: without a
  // material reader tinyobjloader skips it, and a .mtl that is missing, or a device, costs nothing.
  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> materials;
  std::string objWarning, objError;
  std::istringstream in(text);
  if (!tinyobj::LoadObj(&attrib, &shapes, &materials, &objWarning, &objError, &in, nullptr,
                        /*triangulate=*/false, /*default_vcols_fallback=*/false)) {
    *error = "cannot read mesh '" + path + "': " + objError;
    while (!error->empty() && (error->back() == '\n' || error->back() == '\r')) error->pop_back();
    return false;
  }
  *warning = objWarning;
  const size_t numPositions = attrib.vertices.size() / 3;
  const size_t numNormals = attrib.normals.size() / 3;
  const size_t numTexcoords = attrib.texcoords.size() / 2;
  const bool haveColors = !attrib.colors.empty() && attrib.colors.size() == attrib.vertices.size();

  *mesh = Mesh();
  bool allNormals = true;
  std::map<std::tuple<int, int, int>, uint32_t> corners;
  std::vector<glm::vec3> normals;  // per output vertex, zero where a corner had none
  for (const tinyobj::shape_t& shape : shapes) {
    size_t offset = 0;
    for (unsigned char faceSize : shape.mesh.num_face_vertices) {
      std::vector<uint32_t> face;
      std::vector<glm::vec3> loop;
      for (size_t k = 0; k < faceSize; ++k) {
        const tinyobj::index_t idx = shape.mesh.indices[offset + k];
        if (idx.vertex_index < 0 || size_t(idx.vertex_index) >= numPositions ||
            (idx.normal_index >= 0 && size_t(idx.normal_index) >= numNormals) ||
            (idx.texcoord_index >= 0 && size_t(idx.texcoord_index) >= numTexcoords)) {
          *error = "mesh '" + path + "' has a face index out of range";
          return false;
        }
        const auto key = std::make_tuple(idx.vertex_index, idx.normal_index, idx.texcoord_index);
        auto [it, inserted] = corners.emplace(key, uint32_t(mesh->P.size()));
        if (inserted) {
          const size_t v = size_t(idx.vertex_index);
          mesh->P.emplace_back(attrib.vertices[3 * v], attrib.vertices[3 * v + 1],
                               attrib.vertices[3 * v + 2]);
          if (haveColors)
            mesh->Cs.emplace_back(attrib.colors[3 * v], attrib.colors[3 * v + 1],
                                  attrib.colors[3 * v + 2]);
          if (idx.normal_index >= 0) {
            const size_t n = size_t(idx.normal_index);
            normals.emplace_back(attrib.normals[3 * n], attrib.normals[3 * n + 1],
                                 attrib.normals[3 * n + 2]);
            if (glm::length(normals.back()) == 0.0f) allNormals = false;
          } else {
            normals.emplace_back(0.0f);
            allNormals = false;
          }
          if (idx.texcoord_index >= 0) {
            const size_t t = size_t(idx.texcoord_index);
            mesh->st.emplace_back(attrib.texcoords[2 * t], 1.0f - attrib.texcoords[2 * t + 1]);
          } else {
            mesh->st.emplace_back(0.0f, 0.0f);
          }
        }
        face.push_back(it->second);
        loop.push_back(mesh->P[it->second]);
      }
      offset += faceSize;
      if (faceSize < 3) continue;  // points and lines are not surfaces
      for (uint32_t i : triangulatePolygon({loop})) mesh->indices.push_back(face[i]);
    }
  }
  if (mesh->indices.empty()) {
    *error = "mesh '" + path + "' has no faces";
    return false;
  }
  if (allNormals) {
    for (glm::vec3& n : normals) n = glm::normalize(n);
    mesh->N = std::move(normals);
  }
  if (numTexcoords == 0) mesh->st.clear();
  for (const glm::vec3& p : mesh->P)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      *error = "mesh '" + path + "' has non-finite coordinates";
      return false;
    }
  return true;
}

}  // namespace relief
