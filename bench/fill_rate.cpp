// Fill-rate benchmarks, on the example scenes' own meshes and JIT-compiled shaders, and with a
// trivial hand-written shader (P unchanged) that isolates the host's own cost. The target is
// 40 M displaced triangles/s on 2 cores.
// - Voxels/<scene>/<shader>/threads:N: whole voxel fills as the cache makes them (culled
//   subdivision, shader, the voxel's BVH and packing), every voxel of the scene once, in index
//   order, N threads taking runs of voxels in turn from one accelerator (made afresh, untimed, per
//   iteration; unlimited budget with the side cache relief uses then). tris/s counts the triangles
//   stored in voxels, a triangle overlapping two voxels counting twice, as it costs twice.
// - Fill/<scene>/...: subdivideTriangle alone (shader + subdivision), whole input triangles.
// - Trace/<scene>: intersection alone. The scene with a C++ bumps shader (so that valgrind, which
//   cannot run the JIT's AVX-512 code, can count its instructions) is filled by one untimed pass
//   of its camera rays at its resolution; the timed loop traces the same rays again, every voxel
//   resident. rays/s counts closest-hit queries.
// Counters of Fill/:
//   tris/s             micro-triangles produced per second (all threads)
//   shader_points/s    shader points per second spent inside evaluate (the shader's own ceiling)
//   shader_share       fraction of the time spent inside the shader
// The scenes are loaded once; each iteration subdivides a fixed, evenly spaced sample of the scene's
// displaced input triangles (threads take every other one), with no culling box.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "compiler/shader_library.h"
#include "renderer/camera.h"
#include "renderer/grid_accelerator.h"
#include "renderer/rib_reader.h"
#include "renderer/subdivide.h"
#include "renderer/ticks.h"
#include "runtime/shader.h"

namespace relief::bench {
namespace {

// Input triangles per iteration: enough to cover the scene's variety, small enough to iterate.
constexpr size_t kSampleTriangles = 96;

struct Work {
  const Mesh* mesh;
  uint32_t triangle;
  const Displacement* displacement;
};

struct LoadedScene {
  Scene scene;
  Scene bumpsScene;                   // the scene with bumpsEntry in every displacement
  std::vector<Displacement> trivial;  // the scene's displacements with the identity shader
  std::vector<Work> work, trivialWork;
  std::vector<Work> box;  // every triangle of the roundedbox-displaced meshes (simplification)
  Scene identityScene;    // the scene with the identity shader in every displacement
};

// Leaves P and N as they are: the cost of a shader call that does nothing.
void identityEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  std::memcpy(b->Pout.x, b->P.x, b->count * sizeof(float));
  std::memcpy(b->Pout.y, b->P.y, b->count * sizeof(float));
  std::memcpy(b->Pout.z, b->P.z, b->count * sizeof(float));
  std::memcpy(b->Nout.x, b->N.x, b->count * sizeof(float));
  std::memcpy(b->Nout.y, b->N.y, b->count * sizeof(float));
  std::memcpy(b->Nout.z, b->N.z, b->count * sizeof(float));
}

// P += 0.02 * sin(30 x) sin(30 y) sin(30 z) * N: bumps within the example scenes' bounds.
void bumpsEntry(const RlfShadingBatch* b, const void*, RlfStatus*) {
  for (uint32_t i = 0; i < b->count; ++i) {
    const float h = 0.02f * std::sin(30.0f * b->P.x[i]) * std::sin(30.0f * b->P.y[i]) * std::sin(30.0f * b->P.z[i]);
    b->Pout.x[i] = b->P.x[i] + h * b->N.x[i];
    b->Pout.y[i] = b->P.y[i] + h * b->N.y[i];
    b->Pout.z[i] = b->P.z[i] + h * b->N.z[i];
  }
  std::memcpy(b->Nout.x, b->N.x, b->count * sizeof(float));
  std::memcpy(b->Nout.y, b->N.y, b->count * sizeof(float));
  std::memcpy(b->Nout.z, b->N.z, b->count * sizeof(float));
}

const LoadedScene* loadScene(const std::string& name) {
  static std::mutex mutex;
  static std::map<std::string, std::unique_ptr<LoadedScene>> scenes;
  static compiler::ShaderLibrary library;
  std::lock_guard<std::mutex> lock(mutex);
  auto& slot = scenes[name];
  if (slot) return slot.get();
  RibReadOptions options;
  options.shaders = &library;
  options.defaultShaderPath = {RELIEF_EXAMPLES_DIR "/shaders"};
  SceneError error;
  std::optional<Scene> scene =
      readRibFile(RELIEF_EXAMPLES_DIR "/scenes/" + name + ".rib", options, &error);
  if (!scene) {
    std::fprintf(stderr, "%s\n", error.format().c_str());
    return nullptr;
  }
  auto loaded = std::make_unique<LoadedScene>();
  loaded->scene = std::move(*scene);
  auto identity = std::make_shared<const runtime::CompiledShader>(
      "identity", identityEntry, std::vector<runtime::ParamInfo>{}, 0, nullptr);
  for (const Displacement& d : loaded->scene.displacements) {
    Displacement t = d;
    t.shader = std::make_shared<const runtime::ShaderInstance>(identity);
    loaded->trivial.push_back(std::move(t));
  }
  loaded->identityScene = loaded->scene;
  loaded->identityScene.displacements = loaded->trivial;
  // Without simplification: an identity shader leaves every surface flat, and simplification
  // would merge it back to the input triangles; this measures what the host spends on each
  // displaced triangle.
  // Its own problem counts too: the shared ones would carry one benchmark's runaway guard state
  // into the others.
  for (Displacement& d : loaded->identityScene.displacements) {
    d.flatness = 0.0f;
    if (d.problems) d.problems = std::make_shared<ShaderProblemCounts>();
  }
  auto bumps = std::make_shared<const runtime::CompiledShader>(
      "bumps", bumpsEntry, std::vector<runtime::ParamInfo>{}, 0, nullptr);
  loaded->bumpsScene = loaded->scene;
  for (Displacement& d : loaded->bumpsScene.displacements) {
    d.shader = std::make_shared<const runtime::ShaderInstance>(bumps);
    if (d.problems) d.problems = std::make_shared<ShaderProblemCounts>();
  }
  setSubdivisionLimits(loaded->scene);
  setSubdivisionLimits(loaded->identityScene);
  setSubdivisionLimits(loaded->bumpsScene);
  std::vector<Work> all, allTrivial;
  for (const Mesh& mesh : loaded->scene.meshes) {
    if (mesh.displacementIndex == UINT32_MAX) continue;
    for (uint32_t t = 0; t < mesh.numTriangles(); ++t) {
      all.push_back({&mesh, t, &loaded->scene.displacements[mesh.displacementIndex]});
      allTrivial.push_back({&mesh, t, &loaded->trivial[mesh.displacementIndex]});
      if (all.back().displacement->shader->name() == "roundedbox") loaded->box.push_back(all.back());
    }
  }
  const size_t n = std::min(all.size(), kSampleTriangles);
  for (size_t i = 0; i < n; ++i) {
    loaded->work.push_back(all[i * all.size() / n]);
    loaded->trivialWork.push_back(allTrivial[i * all.size() / n]);
  }
  slot = std::move(loaded);
  return slot.get();
}

void fill(benchmark::State& state, const std::string& sceneName, bool trivial, float flatness,
          bool boxOnly = false) {
  const LoadedScene* scene = loadScene(sceneName);
  if (!scene) {
    state.SkipWithError("scene failed to load");
    return;
  }
  std::vector<Work> work = boxOnly ? scene->box : trivial ? scene->trivialWork : scene->work;
  std::vector<Displacement> flat;
  if (flatness > 0) {
    flat.reserve(work.size());
    for (Work& w : work) {
      flat.push_back(*w.displacement);
      flat.back().flatness = flatness;
      w.displacement = &flat.back();
    }
  }
  MicroMesh mm;
  SubdivideCounters counters;
  uint64_t triangles = 0;
  for (auto _ : state) {
    for (size_t i = size_t(state.thread_index()); i < work.size(); i += size_t(state.threads())) {
      subdivideTriangle(*work[i].mesh, work[i].triangle, work[i].displacement, mm, counters);
      triangles += mm.numTriangles();
    }
    benchmark::DoNotOptimize(mm.P.data());
  }
  state.counters["tris/s"] = benchmark::Counter(double(triangles), benchmark::Counter::kIsRate);
  state.counters["shader_points/s"] = benchmark::Counter(
      counters.displaceTicks ? 1e9 * double(counters.shaderPoints) / (double(counters.displaceTicks) * nanosPerTick()) : 0.0,
      benchmark::Counter::kAvgThreads);
  state.counters["shader_points"] =
      benchmark::Counter(double(counters.shaderPoints), benchmark::Counter::kAvgIterations);
  state.counters["tris"] = benchmark::Counter(double(triangles), benchmark::Counter::kAvgIterations);
  if (counters.trianglesBeforeSimplification)
    state.counters["saved"] = 1.0 - double(counters.trianglesAfterSimplification) /
                                        double(counters.trianglesBeforeSimplification);
}

void fillVoxels(benchmark::State& state, const std::string& sceneName, bool trivial) {
  const LoadedScene* loaded = loadScene(sceneName);
  if (!loaded) {
    state.SkipWithError("scene failed to load");
    return;
  }
  const Scene& scene = trivial ? loaded->identityScene : loaded->scene;
  const int threads = int(state.range(0));
  AccelOptions options;
  options.sideCacheTriangles = 1000000;  // relief's default at an unlimited budget
  uint64_t triangles = 0, voxels = 0, sideMisses = 0, sideHits = 0;
  for (auto _ : state) {
    state.PauseTiming();
    auto accel = std::make_unique<GridAccelerator>(scene, options);
    std::vector<uint32_t> work;
    for (uint32_t v = 0; v < accel->grid().numVoxels(); ++v)
      if (accel->grid().hasContributors(v)) work.push_back(v);
    std::atomic<size_t> next{0};
    std::atomic<uint64_t> made{0};
    state.ResumeTiming();
    // Threads take runs of kChunk voxels, as a render's threads work in different parts of
    // the image; taking neighbouring voxels in turn, both would keep missing the side cache on
    // the same contributors at once.
    constexpr size_t kChunk = 32;
    auto run = [&] {
      uint64_t mine = 0;
      for (size_t first; (first = next.fetch_add(kChunk, std::memory_order_relaxed)) < work.size();)
        for (size_t i = first; i < std::min(first + kChunk, work.size()); ++i)
          mine += accel->buildVoxelUncached(work[i])->numTriangles();
      made.fetch_add(mine, std::memory_order_relaxed);
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t) pool.emplace_back(run);
    run();
    for (std::thread& t : pool) t.join();
    state.PauseTiming();
    triangles += made.load();
    voxels += work.size();
    const AccelStats stats = accel->stats();
    sideMisses += stats.sideCacheMisses, sideHits += stats.sideCacheHits;
    accel.reset();
    state.ResumeTiming();
  }
  state.counters["tris/s"] = benchmark::Counter(double(triangles), benchmark::Counter::kIsRate);
  state.counters["tris"] = benchmark::Counter(double(triangles), benchmark::Counter::kAvgIterations);
  state.counters["voxels"] = benchmark::Counter(double(voxels), benchmark::Counter::kAvgIterations);
  // Side-cache misses: subdivisions of whole contributors (more with 2 threads: duplicated work).
  state.counters["side_misses"] = benchmark::Counter(double(sideMisses), benchmark::Counter::kAvgIterations);
  state.counters["side_hits"] = benchmark::Counter(double(sideHits), benchmark::Counter::kAvgIterations);
}

void trace(benchmark::State& state, const std::string& sceneName) {
  const LoadedScene* loaded = loadScene(sceneName);
  if (!loaded) {
    state.SkipWithError("scene failed to load");
    return;
  }
  const Scene& scene = loaded->bumpsScene;
  AccelOptions options;
  options.sideCacheTriangles = 1000000;
  GridAccelerator accel(scene, options);
  const CameraRays camera(scene.camera, scene.width, scene.height);
  std::vector<Ray> rays;
  for (int y = 0; y < scene.height; ++y)
    for (int x = 0; x < scene.width; ++x) rays.push_back(camera.generate(float(x) + 0.5f, float(y) + 0.5f));
  uint64_t hits = 0, queries = 0;
  for (const Ray& ray : rays) hits += accel.intersect(ray).has_value();  // fills every voxel the rays need
  for (auto _ : state) {
    for (const Ray& ray : rays) hits += accel.intersect(ray).has_value();
    queries += rays.size();
  }
  state.counters["rays/s"] = benchmark::Counter(double(queries), benchmark::Counter::kIsRate);
  state.counters["hits"] = benchmark::Counter(double(hits), benchmark::Counter::kAvgIterations);
}

void registerAll() {
  for (const char* scene : {"sphere", "facade"}) {
    for (bool trivial : {false, true}) {
      const std::string name = std::string("Voxels/") + scene + (trivial ? "/identity" : "/shader");
      benchmark::RegisterBenchmark(name.c_str(), [scene, trivial](benchmark::State& s) {
        fillVoxels(s, scene, trivial);
      })->ArgName("threads")->Arg(1)->Arg(2)->UseRealTime()->Unit(benchmark::kMillisecond);
    }
  }
  for (const char* scene : {"sphere", "facade"})
    benchmark::RegisterBenchmark((std::string("Trace/") + scene).c_str(), [scene](benchmark::State& s) {
      trace(s, scene);
    })->UseRealTime()->Unit(benchmark::kMillisecond);
  for (const char* scene : {"sphere", "facade", "sphere_box"}) {
    for (bool trivial : {false, true}) {
      const std::string name = std::string("Fill/") + scene + (trivial ? "/identity" : "/shader");
      benchmark::RegisterBenchmark(name.c_str(), [scene, trivial](benchmark::State& s) {
        fill(s, scene, trivial, 0.0f);
      })->Threads(1)->Threads(2)->UseRealTime()->Unit(benchmark::kMillisecond);
    }
  }
  // Simplification: its cost, and the share it saves ("saved", from the counters' estimate of
  // the unsimplified count); the bevelled box alone is where it pays most.
  for (float flatness : {0.0f, 0.001f}) {
    const std::string suffix = flatness > 0 ? "/flatness" : "";
    benchmark::RegisterBenchmark(("Fill/sphere_box/shader" + suffix + "/all").c_str(),
                                 [flatness](benchmark::State& s) { fill(s, "sphere_box", false, flatness); })
        ->Threads(1)->UseRealTime()->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark(("Fill/sphere_box/shader" + suffix + "/box").c_str(),
                                 [flatness](benchmark::State& s) {
                                   fill(s, "sphere_box", false, flatness, true);
                                 })
        ->Threads(1)->UseRealTime()->Unit(benchmark::kMillisecond);
  }
}

}  // namespace
}  // namespace relief::bench

int main(int argc, char** argv) {
  relief::bench::registerAll();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
