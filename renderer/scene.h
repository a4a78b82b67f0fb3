// The loaded scene: camera, lights, materials and input triangle meshes with their displacement.
// Built once by the scene reader (rib_reader.*) and immutable afterwards; every later stage (the
// contributor grid, the cache, the integrator) reads it. Parts refer to each other by index.
#pragma once

#include <algorithm>
#include <cmath>
#include <atomic>
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
  // Format's pixel aspect ratio: without a ScreenWindow or FrameAspectRatio, the frame's aspect
  // ratio is width * pixelAspect / height (RI spec), for whatever resolution is finally rendered.
  float pixelAspect = 1.0f;
  float nearClip = 1e-10f, farClip = 1e30f;  // RI_EPSILON and RI_INFINITY (RI spec defaults)
  // The transforms given before Projection (RI spec: they act on screen space, after the
  // projection): screen coordinates from projected ones, within the screen plane.
  glm::mat4 screenFromProjected{1.0f};
};

struct DistantLight {
  glm::vec3 directionToLight{0, 0, 1};  // world space, unit: light travels along -this
  glm::vec3 color{1, 1, 1};             // colour times intensity
};

// Every light source of the scene, in world space, with RenderMan's standard light shaders'
// parameters already resolved (colour is lightcolor * intensity). Scene::distantLights and
// ambientColor are the older view of the distant and ambient entries, kept until every reader of
// them moves to `lights`.
enum class LightType : uint8_t { Ambient, Distant, Point, Spot, Area };
enum class AreaShape : uint8_t { Rectangle, Disk };

struct Light {
  LightType type = LightType::Distant;
  glm::vec3 color{1, 1, 1};      // lightcolor * intensity
  glm::vec3 position{0};         // point, spot: the light's position ("from")
  glm::vec3 direction{0, 0, 1};  // distant, spot: unit direction the light travels ("to" - "from")
  // spot: RenderMan's spotlight shader parameters (radians; beamdistribution is the cosine power)
  float coneAngle = 0.5236f, coneDeltaAngle = 0.0873f, beamDistribution = 2.0f;
  // area: an emitting rectangle (corner + edgeU + edgeV) or disk (position, normal `direction`,
  // radius), sampled with `samples` shadow rays (stratified, seeded per pixel: deterministic)
  AreaShape shape = AreaShape::Rectangle;
  glm::vec3 corner{0}, edgeU{1, 0, 0}, edgeV{0, 1, 0};
  float radius = 1.0f;
  int samples = 16;
  bool shadows = true;     // traces shadow rays (Attribute "light" "shadows" "off": it does not)
  std::string handle;      // for Illuminate; empty if the RIB gave none
  std::string sourceFile;  // where the LightSource call was
  int sourceLine = 0;
};

// RenderMan's standard surface shaders; anything else is matte (with a warning by the reader).
enum class SurfaceType : uint8_t { Matte, Plastic, Metal, Mirror, Glass, Constant };

struct Material {
  SurfaceType type = SurfaceType::Matte;
  glm::vec3 color{1, 1, 1};    // Cs
  glm::vec3 opacity{1, 1, 1};  // Os
  float Ka = 0.1f, Kd = 0.9f;  // matte defaults are RenderMan's 1 and 1; see the reader
  float Ks = 0.5f, roughness = 0.1f;   // plastic, metal
  glm::vec3 specularColor{1, 1, 1};    // plastic
  float Kr = 1.0f, Kt = 1.0f, eta = 1.5f;  // mirror/shinymetal (Kr), glass (Kr Kt eta)
  glm::vec3 transmitColor{1, 1, 1};  // glass: colour filter of transmitted light
  bool twoSided = true;             // Sides 2 (default) or 1
  bool reverseOrientation = false;  // Orientation "inside"/"rh" relative to the default
  bool castsShadows = true;  // Attribute "visibility" "transmission": false lets shadow rays pass
  // "string transmission" ["opaque"]: a full shadow whatever the opacity ("Os", the default, lets
  // 1 - Os through).
  bool opaqueShadows = false;
};

// Runtime problems of one Displacement's shader (abi.h's RlfStatus), counted by whatever
// evaluates it (cache fills, the Embree baseline) so the renderer can warn naming the shader and
// the RIB line that bound it. Shared by copies of the Displacement.
struct ShaderProblemCounts {
  std::atomic<uint64_t> nonFinite{0}, badNormal{0}, loopLimit{0}, indexClamped{0}, unknownSpace{0},
      textureErrors{0}, splineBasis{0};
  // language.md §7: points moved farther than the declared displacement bound are not clamped
  // (rays may miss them); the host warns with the largest excess. Counted and kept as float bits,
  // which order like the floats for non-negative values, so an atomic max needs no lock.
  std::atomic<uint64_t> outOfBound{0};
  std::atomic<uint32_t> maxExcessBits{0};
  // The largest distance the shader moved any point (float bits, as above): a bound far beyond it
  // coarsens the contributor grid for nothing, which the host says after the render.
  std::atomic<uint32_t> maxMoveBits{0};
  std::atomic<bool> evaluated{false};  // some point was displaced (maxMoveBits 0 then means no move)
  // Edges that still wanted splitting at the subdivision depth guard. Not a warning of its own:
  // every step in a displacement (grooves) leaves such edges; it names the cause of a runaway.
  std::atomic<uint64_t> depthLimited{0};
  // Work guard (setSubdivisionLimits in subdivide.h): shader points evaluated beyond what each
  // subdivision's undisplaced triangle could justify (summed over grossly excessive ones), the
  // excess past which one subdivision is deemed runaway (0: unguarded), and whether one passed
  // it. Once set, subdivisions stop early and the render loop stops; the caller reports it.
  std::atomic<uint64_t> excessPoints{0};
  uint64_t pointLimit = 0;
  std::atomic<bool> runaway{false};
  // The guard stopped the render because too many invocations hit the loop limit (kLoopLimitStop
  // in subdivide.h), not for runaway subdivision.
  std::atomic<bool> loopRunaway{false};
};

// Everything needed to displace one mesh: the bound shader instance and the subdivision settings.
struct Displacement {
  std::shared_ptr<const runtime::ShaderInstance> shader;  // null: undisplaced
  float boundWorld = 0.0f;     // displacement bound, already converted to world units
  float edgeLength = 0.05f;    // target world-space edge length of displaced micro-triangles
  float flatness = 0.0f;       // simplification tolerance in world units (0: off)
  int maxDepth = 12;           // subdivision depth guard
  // The surface's orientation is reversed (Orientation "inside", ReverseOrientation): the shader's
  // Ng, and N unless the scene gave it (Mesh::givenNormals), point to the other side of the
  // winding, as the RI spec has them.
  bool reverseOrientation = false;
  RlfSpaces spaces{};          // object/shader/camera transforms for the shader
  // What the shader may call back into (its printf output); null: nothing (printf is dropped).
  const RlfHostServices* services = nullptr;
  std::string sourceFile;      // where the Displacement call was (for warnings)
  int sourceLine = 0;
  std::shared_ptr<ShaderProblemCounts> problems = std::make_shared<ShaderProblemCounts>();
};

// Input triangles in world space. Per-vertex attributes; seams (e.g. a sphere's u = 0 / 1) are
// split into distinct vertices so each vertex has one (u, v, s, t).
struct Mesh {
  std::vector<glm::vec3> P;
  std::vector<glm::vec3> N;   // unit shading normals; empty: use the face normal
  // N came from the scene ("N" of a polygon or patch, an OBJ file's normals) rather than from the
  // surface (quadrics, patches): the RI spec flips the surface's normals on a reversed orientation,
  // never the ones the user gave.
  bool givenNormals = false;
  // The triangles sample a smooth surface whose own normal N is (quadrics, patches, NURBS,
  // subdivision surfaces; not polygons): as the RI spec's Ng of such a surface is smooth, the
  // displacement shader's Ng at a vertex is its N, shared by the triangles around it, so that
  // displacing along Ng cannot crack the surface. Polygons keep their facets' Ng (as RenderMan).
  bool smoothSurface = false;
  // Per vertex, world space, on smooth surfaces (smoothSurfaceDerivatives, subdivide.h): dP/du and
  // dP/dv shared by the triangles around a vertex, so a shader displacing along them (a tangent
  // frame) cannot crack the surface. Empty: each triangle's own (u, v) map gives them.
  std::vector<glm::vec3> dPdu, dPdv;
  std::vector<glm::vec2> uv;  // surface parameters (u, v); empty: barycentric-derived per face
  std::vector<glm::vec2> st;  // texture coordinates; empty: equal to uv
  std::vector<glm::vec3> Cs;  // per-vertex colour (RIB "Cs"); empty: the material's colour
  std::vector<uint32_t> indices;  // 3 per triangle
  uint32_t materialIndex = 0;
  // Indices into Scene::lights of the lights that illuminate this mesh (Illuminate state at the
  // time the geometry was declared); ambient lights are listed too.
  std::vector<uint32_t> lights;
  // True when `lights` is the whole truth even if empty (the RIB reader sets it: geometry declared
  // before any light, or after Illuminate turned its lights off, is unlit). False with an empty
  // list: every light, for meshes built in code.
  bool lightsSet = false;
  uint32_t displacementIndex = UINT32_MAX;  // into Scene::displacements; UINT32_MAX: none
  uint32_t numTriangles() const { return uint32_t(indices.size() / 3); }
};

// The pixels a crop window covers in a width x height image, as the RI spec counts them: columns
// ceil(width * xmin) to ceil(width * xmax) - 1, rows likewise. Empty (w or h 0) if it covers none.
struct PixelRect {
  int x = 0, y = 0, w = 0, h = 0;
};
inline PixelRect cropPixels(const float window[4], int width, int height) {
  // A fraction read from text is off by a float rounding (0.3f * 480 = 144.0000048): a hundredth
  // of a pixel is far more than that error and far less than a pixel.
  auto edge = [](float f, int n) { return std::clamp(int(std::ceil(double(n) * double(f) - 0.01)), 0, n); };
  PixelRect r;
  r.x = edge(window[0], width), r.y = edge(window[2], height);
  r.w = std::max(0, edge(window[1], width) - r.x), r.h = std::max(0, edge(window[3], height) - r.y);
  return r;
}

struct Scene {
  int width = 640, height = 480;
  // RI CropWindow xmin xmax ymin ymax, fractions of the image: only that part is rendered and
  // written (cropPixels).
  float cropWindow[4] = {0.0f, 1.0f, 0.0f, 1.0f};
  std::string cropSource;  // "file:line" of the CropWindow call, for its errors; empty: none
  int pixelSamples = 1;
  // RI Exposure: colour outputs are (colour * gain)^(1 / gamma). A gamma other than 1 is the
  // display transfer the scene asks for, so 8-bit outputs then take it instead of sRGB.
  float exposureGain = 1.0f, exposureGamma = 1.0f;
  Camera camera;
  std::vector<Light> lights;
  std::vector<DistantLight> distantLights;  // older view of `lights` (see Light)
  float ambient = 0.0f;                // grey level of ambientColor
  glm::vec3 ambientColor{0.0f};        // sum of ambient lights, colour times intensity
  uint32_t skippedLights = 0;          // light sources the reader skipped (unsupported, singular)
  std::vector<Material> materials;
  std::vector<Displacement> displacements;
  std::vector<Mesh> meshes;
  std::vector<std::string> displays;  // output file names, first is the main image
  // parallel to displays: "rgb", "rgba", or an AOV: "z" (depth), "N" (world normal), "cachemiss"
  // (per-pixel count of geometry-cache misses: where geometry was rebuilt)
  std::vector<std::string> displayModes;
  // parallel to displays: "file:line" of the Display call, for errors about the output
  std::vector<std::string> displaySources;
  // Option "relief": render settings a scene may carry; command-line flags override them.
  uint64_t cacheBudgetTriangles = 0;  // 0: not set
  std::string order;                  // "": not set
  int maxDepth = -1;                  // reflection/refraction depth; -1: not set
  std::string pixelFilter;            // PixelFilter "gaussian"|"blackman-harris"|"box"; "": not set
  // Option "searchpath" "string texture": directories searched for texture files, in order
  // (relative entries already resolved against the scene file's directory).
  std::vector<std::string> texturePath;
  // The n of each `FrameBegin n` block of the file, in order (empty: no FrameBegin, one frame), and
  // which of them this scene is (RibReadOptions::frame).
  std::vector<int> frameNumbers;
  int frameIndex = 0;
  int numFrames() const { return frameNumbers.empty() ? 1 : int(frameNumbers.size()); }
};

// True once a Displacement of the scene passed its work guard (subdivide.h,
// setSubdivisionLimits): the render stops and its caller reports the error.
inline bool subdivisionRanAway(const Scene& scene) {
  for (const Displacement& d : scene.displacements)
    if (d.problems && d.problems->runaway.load(std::memory_order_relaxed)) return true;
  return false;
}

}  // namespace relief
