// The loaded scene: camera, lights, materials and input triangle meshes with their displacement.
// Built once by the scene reader (rib_reader.*) and immutable afterwards; every later stage (the
// contributor grid, the cache, the integrator) reads it. Parts refer to each other by index.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "runtime/abi.h"
#include "runtime/shader.h"

namespace relief {

struct Camera {
  glm::mat4 worldFromCamera{1.0f};  // camera looks down +z in its own space (RenderMan, left-handed)
  bool perspective = true;
  float fovDegrees = 90.0f;  // RenderMan: the full angle across the shorter image dimension
  float screenWindow[4] = {-1, 1, -1, 1};  // left right bottom top; set from the aspect by default
  bool screenWindowSet = false;
  float nearClip = 1e-4f, farClip = 1e30f;
};

struct DistantLight {
  glm::vec3 directionToLight{0, 0, 1};  // world space, unit: light travels along -this
  glm::vec3 color{1, 1, 1};             // colour times intensity
};

struct Material {
  glm::vec3 color{1, 1, 1};  // Cs
  float Ka = 0.1f, Kd = 0.9f;  // matte defaults are RenderMan's 1 and 1; see the reader
};

// Everything needed to displace one mesh: the bound shader instance and the subdivision settings.
struct Displacement {
  std::shared_ptr<const runtime::ShaderInstance> shader;  // null: undisplaced
  float boundWorld = 0.0f;     // displacement bound, already converted to world units
  float edgeLength = 0.05f;    // target world-space edge length of displaced micro-triangles
  float flatness = 0.0f;       // simplification tolerance in world units (0: off)
  int maxDepth = 12;           // subdivision depth guard
  RlfSpaces spaces{};          // object/shader/camera transforms for the shader
  std::string sourceFile;      // where the Displacement call was (for warnings)
  int sourceLine = 0;
};

// Input triangles in world space. Per-vertex attributes; seams (e.g. a sphere's u = 0 / 1) are
// split into distinct vertices so each vertex has one (u, v, s, t).
struct Mesh {
  std::vector<glm::vec3> P;
  std::vector<glm::vec3> N;   // unit shading normals; empty: use the face normal
  std::vector<glm::vec2> uv;  // surface parameters (u, v); empty: barycentric-derived per face
  std::vector<glm::vec2> st;  // texture coordinates; empty: equal to uv
  std::vector<glm::vec3> Cs;  // per-vertex colour (RIB "Cs"); empty: the material's colour
  std::vector<uint32_t> indices;  // 3 per triangle
  uint32_t materialIndex = 0;
  uint32_t displacementIndex = UINT32_MAX;  // into Scene::displacements; UINT32_MAX: none
  uint32_t numTriangles() const { return uint32_t(indices.size() / 3); }
};

struct Scene {
  int width = 640, height = 480;
  int pixelSamples = 1;
  Camera camera;
  std::vector<DistantLight> distantLights;
  float ambient = 0.0f;                // grey level of ambientColor
  glm::vec3 ambientColor{0.0f};        // sum of ambient lights, colour times intensity
  std::vector<Material> materials;
  std::vector<Displacement> displacements;
  std::vector<Mesh> meshes;
  std::vector<std::string> displays;  // output file names, first is the main image
  std::vector<std::string> displayModes;  // parallel to displays: "rgb" or "rgba"
};

}  // namespace relief
