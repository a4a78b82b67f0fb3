// Watertightness of displaced geometry: a closed sphere displaced by the paper's bumpy shader, with
// an edge length that makes neighbouring triangles subdivide to different depths, must stop every
// ray that enters it, including rays aimed exactly at micro-vertices (where cracks would open).
#include <map>
#include <set>
#include <utility>

#include <gtest/gtest.h>

#include "geometry_test_util.h"
#include "renderer/grid_accelerator.h"

namespace relief {
namespace {

using testing::makeSphereScene;
using testing::SphereOptions;

SphereOptions watertightOptions(float flatness = 0.0f) {
  SphereOptions o;
  o.flatness = flatness;
  o.nu = 24, o.nv = 12;
  o.km = 0.1f, o.freq = 4.0f;
  o.edgeLength = 0.04f;
  o.maxDepth = 10;
  return o;
}

// The precondition that makes the test meaningful: some pairs of input triangles sharing an edge
// are subdivided to different depths, so their shared edges see 1- and 2-edge splits.
TEST(Watertight, NeighboursSubdivideToDifferentDepths) {
  Scene scene = makeSphereScene(watertightOptions());
  const Mesh& mesh = scene.meshes[0];
  std::vector<int> depth(mesh.numTriangles());
  for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
    MicroMesh mm;
    SubdivideCounters counters;
    subdivideTriangle(mesh, t, &scene.displacements[0], mm, counters);
    depth[t] = *std::max_element(mm.level.begin(), mm.level.end());
  }
  std::map<std::pair<uint32_t, uint32_t>, std::vector<uint32_t>> edgeTriangles;
  for (uint32_t t = 0; t < mesh.numTriangles(); ++t)
    for (int e = 0; e < 3; ++e) {
      uint32_t a = mesh.indices[3 * t + e], b = mesh.indices[3 * t + (e + 1) % 3];
      edgeTriangles[{std::min(a, b), std::max(a, b)}].push_back(t);
    }
  int differing = 0, shared = 0;
  for (const auto& [edge, tris] : edgeTriangles) {
    if (tris.size() != 2) continue;
    ++shared;
    differing += depth[tris[0]] != depth[tris[1]];
  }
  EXPECT_GT(shared, 300);
  EXPECT_GT(differing, 10) << "of " << shared << " shared edges";
}

class WatertightSphere : public ::testing::TestWithParam<float> {};

TEST_P(WatertightSphere, TenThousandRaysAtTheCentreAllHit) {
  Scene scene = makeSphereScene(watertightOptions(GetParam()));
  auto accel = makeGridAccelerator(scene, AccelOptions{});
  int misses = 0;
  for (const Ray& ray : testing::randomRays(10000, 20261122, 3.0f, 0.0f)) {
    auto hit = accel->intersect(ray);
    // A ray slipping through a crack would still hit the far side from inside: count that too.
    misses += !hit || glm::dot(ray.origin + hit->t * ray.direction, ray.direction) > 0.0f;
    if (hit) {
      // Outer surface, entered from outside: radius within the displacement bound of the
      // tessellated sphere, less the sag of flat (micro-)triangles under the curved surface.
      const float r = glm::length(ray.origin + hit->t * ray.direction);
      EXPECT_GT(r, 0.88f);
      EXPECT_LT(r, 1.1f + 1e-4f);
    }
  }
  EXPECT_EQ(misses, 0);
  EXPECT_GT(accel->stats().uniqueDisplacedTriangles,
            GetParam() > 0.005f ? 1000u : GetParam() > 0 ? 3000u : 40000u);
}

// Rays through micro-vertices and micro-edge midpoints: where neighbouring micro-triangles meet.
TEST_P(WatertightSphere, RaysThroughVerticesAndEdgesAllHit) {
  Scene scene = makeSphereScene(watertightOptions(GetParam()));
  auto accel = makeGridAccelerator(scene, AccelOptions{});
  const Mesh& mesh = scene.meshes[0];
  std::mt19937 rng(99);
  int numRays = 0, misses = 0;
  for (uint32_t t = 0; t < mesh.numTriangles(); t += 3) {
    MicroMesh mm;
    SubdivideCounters counters;
    subdivideTriangle(mesh, t, &scene.displacements[0], mm, counters);
    std::uniform_int_distribution<uint32_t> pick(0, mm.numTriangles() - 1);
    for (int k = 0; k < 8; ++k) {
      const uint32_t* tri = &mm.indices[3 * size_t(pick(rng))];
      const glm::vec3 a = mm.P[tri[0]], b = mm.P[tri[1]];
      for (glm::vec3 target : {a, 0.5f * (a + b)}) {
        const glm::vec3 origin = 3.0f * target;  // radially outside: the surface is star-shaped
        const Ray ray{origin, target - origin, 0.0f, 1e30f};
        ++numRays;
        auto hit = accel->intersect(ray);
        // Slipping through would hit the far side, beyond the target (t = 1).
        misses += !hit || hit->t > 1.01f;
        misses += !accel->occluded(ray);
      }
    }
  }
  EXPECT_GT(numRays, 1000);
  EXPECT_EQ(misses, 0);
}

// Flatness 0: plain adaptive subdivision; 0.002: simplified (flat edges kept whole).
// 0.01: whole runs of long edges kept whole and interiors split 1-to-3.
INSTANTIATE_TEST_SUITE_P(Flatness, WatertightSphere, ::testing::Values(0.0f, 0.002f, 0.01f));

// Displacing along Ng, or along a tangent (dPdu): on a smooth surface (a quadric, patch, NURBS or
// subdivision surface) the shader's Ng at a vertex is its N and its dPdu the mean of the
// triangles' around it (smoothSurfaceDerivatives), both shared by every triangle there, so the
// displaced sphere stays closed. With the facets' own Ng and dPdu (as polygons keep) the same
// shaders tear it apart, which is what makes the test meaningful.
void ngEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  for (uint32_t i = 0; i < b->count; ++i) {
    const glm::vec3 ng(b->Ng.x[i], b->Ng.y[i], b->Ng.z[i]);
    const glm::vec3 p = glm::vec3(b->P.x[i], b->P.y[i], b->P.z[i]) + 0.1f * glm::normalize(ng);
    b->Pout.x[i] = p.x, b->Pout.y[i] = p.y, b->Pout.z[i] = p.z;
    b->Nout.x[i] = b->N.x[i], b->Nout.y[i] = b->N.y[i], b->Nout.z[i] = b->N.z[i];
  }
}
void tangentEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  for (uint32_t i = 0; i < b->count; ++i) {
    const glm::vec3 t(b->dPdu.x[i], b->dPdu.y[i], b->dPdu.z[i]), n(b->N.x[i], b->N.y[i], b->N.z[i]);
    const float len = glm::length(t);
    const glm::vec3 p = glm::vec3(b->P.x[i], b->P.y[i], b->P.z[i]) + 0.05f * n +
                        (len > 0.0f ? 0.05f * std::sin(8.0f * b->v[i]) / len : 0.0f) * t;
    b->Pout.x[i] = p.x, b->Pout.y[i] = p.y, b->Pout.z[i] = p.z;
    b->Nout.x[i] = n.x, b->Nout.y[i] = n.y, b->Nout.z[i] = n.z;
  }
}

TEST(Watertight, DisplacingAlongNgOrATangentKeepsASmoothSurfaceClosed) {
  for (RlfShaderEntry entry : {ngEntry, tangentEntry}) {
    SphereOptions o = watertightOptions();
    o.entry = entry;
    for (bool smooth : {true, false}) {
      Scene scene = makeSphereScene(o);
      scene.meshes[0].smoothSurface = smooth;
      if (smooth)
        smoothSurfaceDerivatives(scene.meshes[0]);
      else
        scene.meshes[0].dPdu.clear(), scene.meshes[0].dPdv.clear();  // each facet's own, as on polygons
      auto accel = makeGridAccelerator(scene, AccelOptions{});
      int misses = 0;
      for (const Ray& ray : testing::randomRays(4000, 20261129, 3.0f, 0.0f)) {
        auto hit = accel->intersect(ray);
        misses += !hit || glm::dot(ray.origin + hit->t * ray.direction, ray.direction) > 0.0f;
      }
      if (smooth)
        EXPECT_EQ(misses, 0) << (entry == ngEntry ? "Ng" : "dPdu");
      else
        EXPECT_GT(misses, entry == ngEntry ? 20 : 0) << (entry == ngEntry ? "Ng" : "dPdu");
    }
  }
}

// Displacing by a filter width, as antialiased shaders do (sqrt(area(P)) = the footprint of
// du and dv): du and dv are a function of the vertex alone (the parametric step of the edge
// length along its own dPdu and dPdv), so both sides of every edge agree and the sphere stays
// closed. They were 2^-level of each input triangle's extents, which differ between a coarse
// corner and its fine neighbours and across input triangles: such shaders cracked.
void footprintEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  for (uint32_t i = 0; i < b->count; ++i) {
    const glm::vec3 dpdu(b->dPdu.x[i], b->dPdu.y[i], b->dPdu.z[i]), dpdv(b->dPdv.x[i], b->dPdv.y[i], b->dPdv.z[i]);
    const glm::vec3 n(b->N.x[i], b->N.y[i], b->N.z[i]);
    const float width = std::sqrt(glm::length(glm::cross(dpdu * b->du[i], dpdv * b->dv[i])));
    const glm::vec3 p = glm::vec3(b->P.x[i], b->P.y[i], b->P.z[i]) + (0.02f + 2.0f * width) * n;
    b->Pout.x[i] = p.x, b->Pout.y[i] = p.y, b->Pout.z[i] = p.z;
    b->Nout.x[i] = n.x, b->Nout.y[i] = n.y, b->Nout.z[i] = n.z;
  }
}

TEST(Watertight, DisplacingByTheFilterFootprintKeepsASmoothSurfaceClosed) {
  SphereOptions o = watertightOptions();
  o.entry = footprintEntry;
  Scene scene = makeSphereScene(o);
  // u warped, so neighbouring input triangles span different extents of it (as on meshes whose
  // triangles differ in size), which the old spacing could not agree on.
  for (glm::vec2& uv : scene.meshes[0].uv) uv.x *= uv.x;
  scene.meshes[0].smoothSurface = true;
  smoothSurfaceDerivatives(scene.meshes[0]);
  auto accel = makeGridAccelerator(scene, AccelOptions{});
  int misses = 0;
  for (const Ray& ray : testing::randomRays(4000, 20261129, 3.0f, 0.0f)) {
    auto hit = accel->intersect(ray);
    misses += !hit || glm::dot(ray.origin + hit->t * ray.direction, ray.direction) > 0.0f;
  }
  EXPECT_EQ(misses, 0);
}

// Simplification removes a good share of the triangles without moving the surface much.
TEST(Watertight, SimplificationReducesTriangles) {
  const Scene full = makeSphereScene(watertightOptions(0.0f));
  const Scene simple = makeSphereScene(watertightOptions(0.002f));
  const testing::BruteForce fullMesh(full), simpleMesh(simple);
  EXPECT_LT(simpleMesh.numTriangles() * 10, fullMesh.numTriangles() * 9);
  for (const Ray& ray : testing::randomRays(200, 5, 3.0f, 0.0f)) {
    auto a = fullMesh.intersect(ray), b = simpleMesh.intersect(ray);
    ASSERT_TRUE(a && b);
    EXPECT_NEAR(a->t * glm::length(ray.direction), b->t * glm::length(ray.direction), 0.01f);
  }
}

}  // namespace
}  // namespace relief
