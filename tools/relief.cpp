// relief: renders a RIB scene with displacement shaders compiled on the fly, by a reliefc child
// process (shader_process.h: relief links no LLVM), for the renderer (reader, accelerator, render
// loop, film). Exit codes: 0 images written, 1 scene/shader/render error, 2 usage error.
#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string_view>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <new>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <streambuf>
#include <string>
#include <utility>
#include <vector>

#include "compiler/json_text.h"
#include "renderer/accel.h"
#include "renderer/embree_accelerator.h"
#include "renderer/film.h"
#include "renderer/grid_accelerator.h"
#include "renderer/render.h"
#include "renderer/rib_reader.h"
#include "renderer/subdivide.h"
#include "runtime/abi.h"
#include "runtime/builtins_texture.h"
#include "tools/shader_process.h"

namespace {

constexpr const char* kVersion = "0.1.0";
// What a resident displaced triangle costs the process with everything around it (voxel records,
// memos, side cache, scratch): the fine facade peaks at 36 bytes per triangle unlimited. Sizes the
// budget that keeps an "unlimited" cache within the machine's memory.
constexpr double kBytesPerCachedTriangle = 48;
// Side-cache capacity (shared by the threads) used when the cache budget is unlimited (--side-cache).
constexpr uint64_t kDefaultSideCache = 1000000;

constexpr const char* kUsage =
    "usage: relief [options] scene.rib\n"
    "\n"
    "Renders a RenderMan RIB scene whose displacement shaders (.disp) are compiled on the fly.\n"
    "A scene of '-' is read from standard input (its relative paths are the working directory's).\n"
    "\n"
    "options (--name VALUE or --name=VALUE):\n"
    "  -I, --shader-path DIR     search DIR for shaders (repeatable; before RELIEF_SHADER_PATH)\n"
    "  -o FILE                   write the image to FILE instead of the scene's Display\n"
    "                            (the scene's further displays go to FILE's directory)\n"
    "                            (format from the extension: png, exr, tif, ...)\n"
    "  --frame N                 render only the frame of 'FrameBegin N' (default: every frame)\n"
    "  --resolution WxH          override the scene's Format\n"
    "  --spp N                   samples per pixel (overrides PixelSamples, whose default is 2 2)\n"
    "  --threads N               render threads, 1 to 256 (default: all cores)\n"
    "  --order ORDER             pixel order: scanline, bucket or hilbert (default)\n"
    "  --max-depth N             reflection/refraction depth (default 5; overrides the scene's\n"
    "                            Option \"relief\" \"maxdepth\"; 0: no secondary rays)\n"
    "  --filter NAME             pixel filter: gaussian (default, 2x2), blackman-harris (3x3)\n"
    "                            or box (1x1)\n"
    "  --cache-triangles N       geometry cache budget in displaced triangles, or 'unlimited'\n"
    "  --grid-resolution N       contributor-grid voxels along the longest axis, 1 to 1024\n"
    "                            (default: automatic, finer under a tight --cache-triangles)\n"
    "  --no-refine               keep contributors that reached nothing in their voxels' lists\n"
    "  --side-cache N            cache of N micro-triangles of whole subdivisions, shared by\n"
    "                            the threads and reused by neighbouring voxel fills (0: off;\n"
    "                            default: 1000000 with an unlimited cache budget, off with\n"
    "                            a budget)\n"
    "  --no-displacement         render the undisplaced surfaces\n"
    "  --edge-length L           target micro-triangle edge length in world units for every\n"
    "                            Displacement (overrides Attribute \"relief\" \"edgelength\")\n"
    "  --accel grid|embree|embree-compact\n"
    "                            geometry cache (default), or the baseline: everything displaced\n"
    "                            up front into one Embree BVH (compact: smaller, slower)\n"
    "  --print-limit N           show at most N printf messages from shaders (default 100;\n"
    "                            a shader prints at every point it displaces; 0: none)\n"
    "  --stats                   print cache statistics and timings\n"
    "  --stats-json FILE         write the same statistics as JSON (for benchmark scripts)\n"
    "  -q, --quiet               no warnings or progress, only errors and the image path\n"
    "  -h, --help                show this help\n"
    "  --version                 show the version\n"
    "\n"
    "Command-line flags override the scene's settings (Format, PixelSamples, Option \"relief\").\n"
    "Displays: the first Display is the image (-o replaces its file name); further displays of\n"
    "mode \"z\" (depth), \"N\" (normal) or \"cachemiss\" (cache misses per pixel) are written\n"
    "too. EXR files hold linear floats and render metadata; png/tif/jpg hold 8-bit sRGB.\n"
    "Progress: a bar on a terminal, otherwise a plain line as each further tenth is done, nothing with --quiet.\n"
    "Frames: a scene with several FrameBegin blocks renders each in turn, each writing its own\n"
    "Displays; a failed frame writes nothing and stops the run (earlier frames stay). With\n"
    "several frames, -o FILE, --stats-json FILE and the default image name get the frame\n"
    "number before the extension: -o out.png writes out.0001.png, out.0002.png, ...\n"
    "\n"
    "environment:\n"
    "  RELIEF_SHADER_PATH        ':'-separated shader directories, searched after -I\n"
    "  RELIEF_SUBVOXEL=grid      dense voxels get the paper's sub-voxel grid instead of a BVH\n"
    "                            (for measurements; the image is the same)\n"
    "  RELIEF_SUBTREES=0         no subtree memos (exact boxes and simplification decisions\n"
    "                            kept per input triangle), RELIEF_PROXIES=0 no voxel proxies\n"
    "                            (kept BVH roots): for measurements; the image is the same\n"
    "  RELIEF_WALK=shared|stretches  how threads share the pixels (default: shared under a\n"
    "                            cache budget, stretches otherwise): for measurements; the image\n"
    "                            is the same\n"
    "  RELIEF_OUTSIDE=0          every triangle in the grid, undisplaced ones reaching beyond the\n"
    "                            displaced geometry too (for measurements; the image is the same)\n"
    "  RELIEF_CHECK_BUDGET=1     check the cache budget after every fill (debug)\n"
    "  RELIEF_COMPILER=FILE      the reliefc that compiles the shaders, in a child process\n"
    "                            (default: the reliefc beside relief, else the build tree's,\n"
    "                            else on PATH)\n"
    "  RELIEF_IMAGE_LIBRARY=FILE the OpenImageIO plugin (textures, formats other than\n"
    "                            png/ppm/pgm), loaded on first use (default: <libdir>/relief/)\n"
    "\n"
    "The shader search path is the scene's Option \"searchpath\" \"shader\" if given ('@' in it\n"
    "stands for the default path, '&' for the previous value), otherwise the default: the -I directories, then the\n"
    "RELIEF_SHADER_PATH directories, then the scene file's directory. Texture names are looked up\n"
    "from the working directory, then along Option \"searchpath\" \"texture\" (default: the\n"
    "scene file's directory).\n"
    "\n"
    "exit status: 0 images written, 1 scene/shader/render/output error, 2 usage error (also a\n"
    "--frame the scene does not have)\n";

struct CommandLine {
  std::string scene;  // "-": standard input
  // The scene as messages name it.
  std::string label() const { return scene == "-" ? std::string("<stdin>") : scene; }
  std::vector<std::string> shaderDirs;
  std::string output;
  std::optional<int> frame;  // --frame: the n of a `FrameBegin n`; unset: every frame
  int width = 0, height = 0;
  int spp = 0;
  int threads = 0;
  relief::PixelOrder order = relief::PixelOrder::Hilbert;
  bool orderSet = false;
  int maxDepth = -1;  // -1: the scene's or the default
  relief::FilterType filter = relief::FilterType::Gaussian;
  bool filterSet = false;
  uint64_t cacheTriangles = UINT64_MAX;
  bool cacheTrianglesSet = false;
  int gridResolution = 0;  // 0: automatic
  bool refine = true;
  std::optional<uint64_t> sideCache;  // unset: the default that suits the budget
  bool displace = true;
  float edgeLength = 0.0f;  // 0: the scene's
  std::string accel = "grid";
  bool stats = false;
  std::string statsJson;
  bool quiet = false;
  uint64_t printLimit = 100;  // shader printf messages shown
};

int usageError(const std::string& message) {
  std::cerr << "relief: error: " << message << "\n"
            << "usage: relief [options] scene.rib (see relief --help)\n";
  return 2;
}

bool parsePositive(const std::string& text, long long max, long long* value) {
  if (text.empty() || text.size() > 19) return false;
  for (char c : text)
    if (c < '0' || c > '9') return false;
  *value = std::stoll(text);
  return *value > 0 && *value <= max;
}

// A frame number: RIB numbers frames with any integer, though exporters start at 0 or 1.
bool parseFrameNumber(const std::string& text, int* value) {
  const size_t digits = text.rfind('-', 0) == 0 ? 1 : 0;
  if (text.size() <= digits || text.size() > digits + 9) return false;
  for (size_t i = digits; i < text.size(); ++i)
    if (text[i] < '0' || text[i] > '9') return false;
  *value = std::stoi(text);
  return true;
}

// Returns -1 when parsing succeeded and the program should go on, else the exit code.
int parseCommandLine(int argc, char** argv, CommandLine* cl) {
  std::vector<std::string> args(argv + 1, argv + argc);
  for (size_t i = 0; i < args.size(); ++i) {
    // GNU style "--name=value" as well as "--name value".
    std::string a = args[i];
    std::optional<std::string> attached;
    if (const size_t eq = a.find('='); a.rfind("--", 0) == 0 && eq != std::string::npos) {
      attached = a.substr(eq + 1);
      a.resize(eq);
    }
    auto value = [&](std::string* out) {
      if (attached) {
        *out = *attached;
        attached.reset();
        return true;
      }
      if (i + 1 >= args.size()) return false;
      *out = args[++i];
      return true;
    };
    std::string v;
    long long n = 0;
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "--version") {
      std::cout << "relief " << kVersion << " (shader ABI " << kRlfAbiVersion << ")\n";
      return 0;
    } else if (a == "-I" || a == "--shader-path") {
      if (!value(&v)) return usageError("'" + a + "' needs a directory");
      cl->shaderDirs.push_back(v);
    } else if (a.size() > 2 && a.rfind("-I", 0) == 0) {
      cl->shaderDirs.push_back(a.substr(2));
    } else if (a == "-o") {
      if (!value(&v) || v.empty()) return usageError("'-o' needs a file name");
      cl->output = v;
    } else if (a == "--frame") {
      int frame = 0;
      if (!value(&v) || !parseFrameNumber(v, &frame))
        return usageError("'--frame' needs a frame number (the n of 'FrameBegin n')");
      cl->frame = frame;
    } else if (a == "--resolution") {
      if (!value(&v)) return usageError("'--resolution' needs WxH");
      const size_t x = v.find('x');
      long long w = 0, h = 0;
      if (x == std::string::npos || !parsePositive(v.substr(0, x), 65536, &w) ||
          !parsePositive(v.substr(x + 1), 65536, &h))
        return usageError("invalid resolution '" + v + "' (expected WxH, each from 1 to 65536, e.g. 640x480)");
      if (uint64_t(w) * uint64_t(h) > relief::kMaxPixels)
        return usageError("resolution '" + v + "' has more than " +
                          std::to_string(relief::kMaxPixels) + " pixels");
      cl->width = int(w);
      cl->height = int(h);
    } else if (a == "--spp") {
      if (!value(&v) || !parsePositive(v, 4096, &n))
        return usageError("'--spp' needs a sample count between 1 and 4096");
      cl->spp = int(n);
    } else if (a == "--print-limit") {
      if (!value(&v) || (v != "0" && !parsePositive(v, UINT32_MAX, &n)))
        return usageError("'--print-limit' needs a message count (0 for none)");
      cl->printLimit = v == "0" ? 0 : uint64_t(n);
    } else if (a == "--threads") {
      if (!value(&v) || !parsePositive(v, 256, &n))
        return usageError("'--threads' needs a thread count between 1 and 256");
      cl->threads = int(n);
    } else if (a == "--order") {
      if (!value(&v) || !relief::parsePixelOrder(v, &cl->order))
        return usageError("'--order' needs scanline, bucket or hilbert");
      cl->orderSet = true;
    } else if (a == "--max-depth") {
      if (!value(&v) || (v != "0" && !parsePositive(v, 100, &n)))
        return usageError("'--max-depth' needs a depth between 0 and 100");
      cl->maxDepth = v == "0" ? 0 : int(n);
    } else if (a == "--filter") {
      if (!value(&v) || !relief::parseFilter(v, &cl->filter))
        return usageError("'--filter' needs gaussian, blackman-harris or box");
      cl->filterSet = true;
    } else if (a == "--cache-triangles") {
      if (!value(&v)) return usageError("'--cache-triangles' needs a count or 'unlimited'");
      cl->cacheTrianglesSet = true;
      if (v == "unlimited") {
        cl->cacheTriangles = UINT64_MAX;
      } else if (parsePositive(v, (1LL << 62), &n)) {
        cl->cacheTriangles = uint64_t(n);
      } else {
        return usageError("invalid triangle budget '" + v + "'");
      }
    } else if (a == "--grid-resolution") {
      if (!value(&v) || !parsePositive(v, relief::kMaxGridResolution, &n))
        return usageError("'--grid-resolution' needs a voxel count between 1 and " +
                          std::to_string(relief::kMaxGridResolution));
      cl->gridResolution = int(n);
    } else if (a == "--side-cache") {
      if (!value(&v) || !(v == "0" || parsePositive(v, (1LL << 40), &n)))
        return usageError("'--side-cache' needs a micro-triangle count (0: off)");
      cl->sideCache = v == "0" ? 0 : uint64_t(n);
    } else if (a == "--no-refine") {
      cl->refine = false;
    } else if (a == "--no-displacement") {
      cl->displace = false;
    } else if (a == "--edge-length") {
      char* end = nullptr;
      const float l = value(&v) ? std::strtof(v.c_str(), &end) : 0.0f;
      if (v.empty() || end != v.c_str() + v.size() || !(l > 0.0f) || !std::isfinite(l))
        return usageError("'--edge-length' needs a positive length");
      cl->edgeLength = l;
    } else if (a == "--accel") {
      if (!value(&v) || (v != "grid" && v != "embree" && v != "embree-compact"))
        return usageError("'--accel' needs grid, embree or embree-compact");
      cl->accel = v;
    } else if (a == "--stats-json") {
      if (!value(&v) || v.empty()) return usageError("'--stats-json' needs a file name");
      cl->statsJson = v;
    } else if (a == "--stats") {
      cl->stats = true;
    } else if (a == "--quiet" || a == "-q") {
      cl->quiet = true;
    } else if (a.size() > 1 && a[0] == '-') {
      return usageError("unknown option '" + a + "'");
    } else if (cl->scene.empty()) {
      cl->scene = a;
    } else {
      return usageError("more than one scene given ('" + cl->scene + "' and '" + a + "')");
    }
    if (attached) return usageError("'" + a + "' takes no value (given '" + args[i] + "')");
  }
  if (cl->scene.empty()) return usageError("no scene file given");
  if (std::filesystem::path(cl->scene).extension() == ".disp")
    return usageError("'" + cl->scene + "' is a shader: relief renders a RIB scene that names it "
                      "(Displacement \"" + std::filesystem::path(cl->scene).stem().string() +
                      "\"); reliefc checks and evaluates shaders");
  // Options that cannot take effect are said to, not silently dropped.
  if (!cl->quiet && cl->accel != "grid" && cl->cacheTrianglesSet)
    std::cerr << "relief: warning: --cache-triangles has no effect with --accel " << cl->accel
              << " (the baseline holds all of its geometry)\n";
  for (const std::string& dir : cl->shaderDirs) {
    std::error_code ec;
    if (!cl->quiet && !std::filesystem::is_directory(dir, ec))
      std::cerr << "relief: warning: shader directory '" << dir << "' does not exist\n";
  }
  return -1;
}

std::vector<std::string> defaultShaderPath(const CommandLine& cl) {
  std::vector<std::string> path = cl.shaderDirs;
  if (const char* env = std::getenv("RELIEF_SHADER_PATH")) {
    std::string s = env;
    size_t start = 0;
    while (start <= s.size()) {
      const size_t colon = s.find(':', start);
      const size_t end = colon == std::string::npos ? s.size() : colon;
      if (end > start) path.push_back(s.substr(start, end - start));
      if (colon == std::string::npos) break;
      start = colon + 1;
    }
  }
  const std::filesystem::path sceneDir = std::filesystem::path(cl.scene).parent_path();
  path.push_back(sceneDir.empty() ? std::string(".") : sceneDir.string());
  // Later duplicates only cost a second failed lookup and clutter error messages.
  std::vector<std::string> unique;
  for (const std::string& dir : path) {
    const std::string normal = std::filesystem::path(dir).lexically_normal().string();
    bool seen = false;
    for (const std::string& u : unique)
      seen = seen || std::filesystem::path(u).lexically_normal().string() == normal;
    if (!seen) unique.push_back(dir);
  }
  return unique;
}

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The statistics of docs/statistics.md, in order, as (dotted key, JSON value) pairs: one list
// feeds both --stats and --stats-json so they cannot drift apart.
using StatList = std::vector<std::pair<std::string, std::string>>;

float maxExcess(const relief::ShaderProblemCounts& p);

// The Displacements with a shader whose problem counts no earlier one shares (copies of a
// Displacement share theirs): what the warnings and the statistics count, each once.
std::vector<const relief::Displacement*> distinctShaderProblems(const relief::Scene& scene) {
  std::vector<const relief::Displacement*> out;
  for (const relief::Displacement& d : scene.displacements) {
    const relief::ShaderProblemCounts* p = d.problems.get();
    if (p && d.shader && std::none_of(out.begin(), out.end(), [&](const auto* e) { return e->problems.get() == p; }))
      out.push_back(&d);
  }
  return out;
}

// Process start, for time.total_s.
const auto gProcessStart = std::chrono::steady_clock::now();

// RUSAGE_SELF: relief alone; RUSAGE_CHILDREN: the largest of the reliefc processes that compiled
// its shaders (shader_process.h), which exited before the render.
uint64_t peakRssBytes(int who = RUSAGE_SELF) {
  struct rusage usage {};
  if (::getrusage(who, &usage) != 0) return 0;
  return uint64_t(usage.ru_maxrss) * 1024;  // kilobytes on Linux
}

StatList collectStats(const CommandLine& cl, const relief::Scene& scene,
                      const relief::AccelStats& a, const relief::RenderStats& r, relief::PixelOrder order,
                      double loadSeconds, double buildSeconds, uint64_t inputTriangles) {
  auto u = [](uint64_t v) { return std::to_string(v); };
  auto f = [](double v) {
    if (!std::isfinite(v)) return std::string("null");
    char text[32];
    std::snprintf(text, sizeof text, "%.6g", v);
    return std::string(text);
  };
  auto ratio = [&](double num, double den) { return den > 0 ? f(num / den) : std::string("null"); };
  // Shader problems over every Displacement (copies share their counts): the numbers behind the
  // warnings, for scripts that run with --quiet.
  uint64_t nonFinite = 0, badNormal = 0, loopLimit = 0, indexClamped = 0, unknownSpace = 0, textureErrors = 0,
           splineBasis = 0, outOfBound = 0;
  double maxBoundExcess = 0.0;
  for (const relief::Displacement* d : distinctShaderProblems(scene)) {
    const relief::ShaderProblemCounts* p = d->problems.get();
    nonFinite += p->nonFinite.load(), badNormal += p->badNormal.load(), loopLimit += p->loopLimit.load();
    indexClamped += p->indexClamped.load(), unknownSpace += p->unknownSpace.load();
    textureErrors += p->textureErrors.load(), splineBasis += p->splineBasis.load();
    outOfBound += p->outOfBound.load();
    if (p->outOfBound.load()) maxBoundExcess = std::max(maxBoundExcess, double(maxExcess(*p)));
  }
  const uint64_t misses = a.compulsoryMisses + a.capacityMisses;
  // Fill and ray times are summed over threads; dividing by the thread count makes the four
  // parts add up to the render's wall time, with shading (the integrator) the remainder.
  const double threads = r.threads > 0 ? double(r.threads) : 1.0;
  const double subdivide = a.subdivideSeconds / threads, displace = a.displaceSeconds / threads;
  const double intersect = a.intersectSeconds / threads;
  // The Embree baseline displaces everything during the build (time.build_s), not the render.
  const double shade = std::max(0.0, r.seconds - (a.upFront ? 0.0 : subdivide + displace) - intersect);
  const double simplificationSaved =
      a.trianglesBeforeSimplification > 0
          ? 1.0 - double(a.trianglesAfterSimplification) / double(a.trianglesBeforeSimplification)
          : 0.0;
  StatList s = {
      {"scene.file", relief::compiler::jsonQuoted(cl.label())},
      {"scene.frame", scene.frameNumbers.empty()
                          ? std::string("null")
                          : std::to_string(scene.frameNumbers[size_t(scene.frameIndex)])},
      {"scene.input_triangles", u(inputTriangles)},
      {"image.width", u(uint64_t(scene.width))},
      {"image.height", u(uint64_t(scene.height))},
      {"render.samples_per_pixel", u(uint64_t(r.samplesPerPixel))},
      {"render.threads", u(uint64_t(r.threads))},
      {"render.order", relief::compiler::jsonQuoted(relief::pixelOrderName(order))},
      {"render.displacement", cl.displace ? "true" : "false"},
      {"render.walk", r.sharedWalk ? "\"shared\"" : "\"stretches\""},
      {"render.deferred_pixels", u(r.deferredPixels)},
      {"render.peak_sample_bytes", u(r.peakSampleBytes)},
      {"rays.camera", u(r.cameraRays)},
      {"rays.camera_hits", u(r.cameraHits)},
      {"rays.shadow", u(r.shadowRays)},
      {"rays.reflection", u(r.reflectionRays)},
      {"rays.refraction", u(r.refractionRays)},
      {"grid.resolution_x", u(uint64_t(a.gridResolution.x))},
      {"grid.resolution_y", u(uint64_t(a.gridResolution.y))},
      {"grid.resolution_z", u(uint64_t(a.gridResolution.z))},
      {"grid.contributor_entries", u(a.contributorEntries)},
      {"grid.outside_triangles", u(a.outsideTriangles)},
      {"grid.refinement", cl.refine ? "true" : "false"},
      {"grid.dropped_contributors", u(a.droppedContributors)},
      {"cache.budget_triangles",
       a.budgetTriangles == UINT64_MAX ? std::string("null") : u(a.budgetTriangles)},
      {"cache.accesses", u(a.accesses)},
      {"cache.hits", u(a.hits)},
      {"cache.misses", u(misses)},
      {"cache.compulsory_misses", u(a.compulsoryMisses)},
      {"cache.capacity_misses", u(a.capacityMisses)},
      {"cache.hit_percent", ratio(100.0 * double(a.hits), double(a.accesses))},
      {"cache.capacity_miss_share", ratio(double(a.capacityMisses), double(misses))},
      {"cache.evictions", u(a.evictions)},
      {"cache.peak_resident_triangles", u(a.peakResidentTriangles)},
      {"cache.resident_triangles", u(a.residentTriangles)},
      {"cache.max_voxel_triangles", u(a.maxVoxelTriangles)},
      {"cache.peak_resident_bytes", u(a.peakResidentBytes)},
      {"cache.unique_displaced_triangles", u(a.uniqueDisplacedTriangles)},
      {"cache.displaced_triangles_created", u(a.displacedTrianglesCreated)},
      {"cache.created_per_unique",
       ratio(double(a.displacedTrianglesCreated), double(a.uniqueDisplacedTriangles))},
      {"cache.created_bytes", u(a.createdBytes)},
      {"cache.bytes_per_triangle", ratio(double(a.createdBytes), double(a.displacedTrianglesCreated))},
      {"cache.simplification_saved_fraction", f(simplificationSaved)},
      {"cache.triangles_before_simplification", u(a.trianglesBeforeSimplification)},
      {"cache.triangles_after_simplification", u(a.trianglesAfterSimplification)},
      {"cache.shader_points", u(a.shaderPoints)},
      {"cache.side_cache_hits", u(a.sideCacheHits)},
      {"cache.side_cache_misses", u(a.sideCacheMisses)},
      {"cache.side_cache_peak_triangles", u(a.sideCachePeakTriangles)},
      {"cache.proxy_skips", u(a.proxySkips)},
      {"cache.memo_bytes", u(a.memoBytes)},
      {"cache.budget_violations", u(a.budgetViolations)},
      {"shader.nonfinite_points", u(nonFinite)},
      {"shader.bad_normals", u(badNormal)},
      {"shader.loop_limit_hits", u(loopLimit)},
      {"shader.clamped_indices", u(indexClamped)},
      {"shader.unknown_spaces", u(unknownSpace)},
      {"shader.texture_errors", u(textureErrors)},
      {"shader.spline_basis_errors", u(splineBasis)},
      {"shader.out_of_bound_points", u(outOfBound)},
      {"shader.max_bound_excess", f(maxBoundExcess)},
      {"time.load_s", f(loadSeconds)},
      {"time.build_s", f(buildSeconds)},
      {"time.render_s", f(r.seconds)},
      {"time.subdivide_s", f(subdivide)},
      {"time.displace_s", f(displace)},
      {"time.intersect_s", f(intersect)},
      {"time.shade_s", f(shade)},
      {"time.total_s", f(secondsSince(gProcessStart))},
      {"memory.peak_rss_bytes", u(peakRssBytes())},
      {"memory.compiler_peak_rss_bytes", u(peakRssBytes(RUSAGE_CHILDREN))},
  };
  return s;
}

void printStats(const StatList& stats) {
  size_t width = 0;
  for (const auto& [key, value] : stats) width = std::max(width, key.size());
  for (const auto& [key, value] : stats)
    std::printf("%-*s  %s\n", int(width), key.c_str(), value.c_str());
}

// The largest distance beyond its bound a shader moved a point (kept as float bits, scene.h).
float maxExcess(const relief::ShaderProblemCounts& p) {
  float excess;
  const uint32_t bits = p.maxExcessBits.load();
  std::memcpy(&excess, &bits, 4);
  return excess;
}

// Where the edge length of a Displacement came from, for the remedies of the work guard's errors.
const char* edgeLengthSetting(bool fromCommandLine) {
  return fromCommandLine ? "--edge-length" : "Attribute \"relief\" \"float edgelength\"";
}

// How far from the camera geometry may lie before the float intersection tests overflow.
constexpr float kFarthestRenderable = 2e14f;

// A displacement bound this many times the farthest any point moved is called loose (when it is
// also large against the scene).
constexpr float kLooseBoundRatio = 16.0f;

// Runtime problems inside displacement shaders are counted, not thrown (abi.h); say so once per
// Displacement call, naming the shader and where the scene bound it.
// `sceneBox` bounds the undisplaced scene, against whose size a displacement bound is loose
// enough to matter.
void reportShaderProblems(const relief::Scene& scene, const relief::Bounds3& sceneBox, std::ostream& out) {
  const glm::vec3 sceneExtent = sceneBox.empty() ? glm::vec3(0.0f) : sceneBox.hi - sceneBox.lo;
  const float sceneSize = std::max({sceneExtent.x, sceneExtent.y, sceneExtent.z});
  struct LooseBound {
    std::string shader;
    float maxMove = 0.0f, bound = 0.0f;
  };
  std::map<std::pair<std::string, int>, LooseBound> loose;  // by the Displacement call's file and line
  for (const relief::Displacement* shader : distinctShaderProblems(scene)) {
    const relief::Displacement& d = *shader;
    const relief::ShaderProblemCounts* p = d.problems.get();
    auto warn = [&]() -> std::ostream& {
      return out << d.sourceFile << ":" << d.sourceLine << ": warning: displacement shader '"
                 << d.shader->name() << "'";
    };
    auto report = [&](const std::atomic<uint64_t>& count, const char* what) {
      if (const uint64_t n = count.load()) warn() << ": " << n << " " << what << "\n";
    };
    report(p->nonFinite, "points produced a NaN or infinite P (left undisplaced)");
    report(p->badNormal, "points produced a NaN, infinite or zero N (the displaced surface's own normal is used)");
    report(p->loopLimit, "invocations hit the loop-iteration limit");
    report(p->indexClamped, "array or component indices were clamped into range");
    report(p->unknownSpace,
           "lookups of a coordinate space name other than \"current\", \"world\", \"common\", \"object\", "
           "\"shader\" or \"camera\" were treated as 'current' (spaces named by CoordinateSystem do not reach "
           "shaders, docs/language-reference.md §2.3)");
    report(p->textureErrors, "texture lookups failed");
    report(p->splineBasis, "spline calls named an unknown basis or one unfit for their knots (catmull-rom was used; with fewer than 4 knots, the first knot)");
    if (const uint64_t n = p->outOfBound.load()) {
      warn() << " moved " << n << " points beyond the displacement bound "
          << d.boundWorld << " (world units), by up to " << maxExcess(*p)
          << "; rays may miss those parts, and which ones depends on the contributor grid (so the image may"
             " change with --cache-triangles or --grid-resolution): raise Attribute \"displacementbound\"\n";
    }
    // Gathered per Displacement call, whose primitives under different transforms have entries
    // (and counts) of their own: one warning per call, as for the others.
    float move;
    const uint32_t moveBits = p->maxMoveBits.load();
    std::memcpy(&move, &moveBits, 4);
    if (p->evaluated.load()) {
      LooseBound& l = loose[{d.sourceFile, d.sourceLine}];
      l.shader = d.shader->name();
      l.maxMove = std::max(l.maxMove, move);
      l.bound = std::max(l.bound, d.boundWorld);
    }
  }
  // A bound far beyond what the shader does, and large against the scene, makes voxels that large
  // (kVoxelsPerBound) and their BVHs loose: a sphere of radius 1 under a bound of 1e4 rendered 5x
  // slower than under 0.06, for the same image.
  for (const auto& [where, l] : loose) {
    if (!(l.bound > kLooseBoundRatio * l.maxMove && l.bound > 0.05f * sceneSize)) continue;
    out << where.first << ":" << where.second << ": warning: displacement shader '" << l.shader << "'";
    if (l.maxMove > 0.0f)
      out << " moved no point farther than " << l.maxMove << " (world units), against a displacement bound of "
          << l.bound << "; a bound that loose coarsens the contributor grid and slows the render: lower "
          << "Attribute \"displacementbound\" toward " << l.maxMove << "\n";
    else
      out << " moved no point at all, under a displacement bound of " << l.bound
          << "; a bound coarsens the contributor grid and slows the render, and a shader that only "
             "bends N needs none: lower Attribute \"displacementbound\" to 0\n";
  }
}

// "3.4e+12" reads badly next to "68719476736": counts in the work guard's messages.
std::string formatCount(double n) {
  char text[32];
  std::snprintf(text, sizeof text, n < 1e7 ? "%.0f" : "%.2g", n);
  return text;
}

// The work guard stopped the render (subdivide.h, setSubdivisionLimits): name each Displacement
// that ran away, with the likeliest cause from what its shader did.
void reportRunaway(const relief::Scene& scene, const std::vector<double>& estimates, bool edgeFromCli,
                   std::ostream& out) {
  for (size_t i = 0; i < scene.displacements.size(); ++i) {
    const relief::Displacement& d = scene.displacements[i];
    const relief::ShaderProblemCounts* p = d.problems.get();
    if (!p || !p->runaway.load() || !d.shader) continue;
    if (p->loopRunaway.load()) {
      out << d.sourceFile << ":" << d.sourceLine << ": error: displacement shader '" << d.shader->name()
          << "': " << p->loopLimit.load()
          << " invocations hit the loop-iteration limit (a loop that does not end; each costs its "
             "whole limit of iterations); rendering stopped: fix the shader's loops\n";
      continue;
    }
    out << d.sourceFile << ":" << d.sourceLine << ": error: displacement shader '" << d.shader->name()
        << "': subdivision ran away: its input triangles split into over "
        << relief::kRunawayAllowance
        << " times as many micro-triangles as their size and the edge length ask for (about "
        << formatCount(i < estimates.size() ? estimates[i] : 0.0) << " in all)";
    if (p->outOfBound.load()) {
      out << "; it moves points up to " << maxExcess(*p) << " beyond its displacement bound of "
          << d.boundWorld << ", so its edges never get as short as " << d.edgeLength;
    } else if (p->depthLimited.load()) {
      out << "; its edges stay longer than " << d.edgeLength
          << " down to the subdivision depth limit of " << d.maxDepth
          << " (detail finer than the edge length everywhere)";
    }
    out << "; rendering stopped: fix the shader or raise " << edgeLengthSetting(edgeFromCli) << "\n";
  }
}

// Filling the cache ran out of memory: say so at the scene, and name the Displacement that asks
// for the most micro-triangles (the likeliest cause: a scene in large units at the default
// world-space edge length) with what would lower it.
void reportOutOfMemory(const std::string& sceneFile, const relief::Scene& scene, const std::vector<double>& estimates,
                       bool edgeFromCli, bool budgeted, std::ostream& out) {
  out << sceneFile << ": error: out of memory while rendering\n";
  size_t heaviest = estimates.size();
  for (size_t i = 0; i < estimates.size() && i < scene.displacements.size(); ++i)
    if (scene.displacements[i].shader && (heaviest == estimates.size() || estimates[i] > estimates[heaviest]))
      heaviest = i;
  if (heaviest == estimates.size()) return;
  const relief::Displacement& d = scene.displacements[heaviest];
  out << d.sourceFile << ":" << d.sourceLine << ": note: displacement shader '" << d.shader->name()
      << "' asks for about " << formatCount(estimates[heaviest]) << " micro-triangles at an edge length of "
      << d.edgeLength << " (world units): raise " << edgeLengthSetting(edgeFromCli)
      << (budgeted ? ", or lower --cache-triangles\n" : ", or give --cache-triangles a budget\n");
}

// A budget that holds only a few of the largest voxels makes voxels evict each other in turn
// (sphere_box at 50K triangles: its largest voxel holds 38K, and 79K refills took 475 s against
// 0.7 s unlimited; a generous displacement bound makes such voxels too). Said once: during the
// render as soon as refills clearly outnumber first fills (Progress), since such a render may run
// for minutes, else after it when refills outnumbered first fills at all.
// A budget that holds several of the largest voxels may still be smaller than what the rays use
// together: shadow, reflection and transparency rays reach voxels all over the scene (a displaced
// glass scene at a 10% budget refilled 60 times per first fill and ran 35 times slower than
// unlimited, without a word). Said when refills outnumber first fills kThrashRefills times.
constexpr uint64_t kThinBudgetVoxels = 4;
constexpr uint64_t kThrashRefills = 4;
bool fewVoxelsFit(const relief::AccelStats& a) {
  return a.budgetTriangles != UINT64_MAX && a.maxVoxelTriangles != 0 &&
         a.budgetTriangles < kThinBudgetVoxels * a.maxVoxelTriangles;
}
bool workingSetThrashes(const relief::AccelStats& a) {
  return a.budgetTriangles != UINT64_MAX && a.capacityMisses > kThrashRefills * a.compulsoryMisses + 64;
}
bool thinBudget(const relief::AccelStats& a) {
  return (fewVoxelsFit(a) && a.capacityMisses > a.compulsoryMisses) || workingSetThrashes(a);
}
void reportThinBudget(const std::string& scene, const relief::AccelStats& a, std::ostream& out, bool sofar = false) {
  if (!thinBudget(a)) return;
  out << scene << ": warning: the cache budget of " << a.budgetTriangles << " displaced triangles ";
  if (fewVoxelsFit(a))
    out << "holds fewer than " << kThinBudgetVoxels << " of the largest voxels (" << a.maxVoxelTriangles
        << " triangles)";
  else
    out << "is smaller than the voxels the rays use together (shadow, reflection and transparency rays "
           "reach across the scene)";
  out << ", and voxels were refilled " << a.capacityMisses << " times after " << a.compulsoryMisses
      << " first fills" << (sofar ? " so far (the render goes on, slowly)" : "") << ": raise --cache-triangles"
      << (fewVoxelsFit(a) ? ", or --grid-resolution for smaller voxels" : "") << "\n";
}

// Whether a file can be made at `path`: its directory is created if missing (as -o promises),
// and a probe file is created in it and removed. Only trying tells: permissions, read-only or
// pseudo file systems, a regular file where a directory should be.
bool canCreateFile(const std::string& path, std::string* error) {
  const std::filesystem::path file(path);
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) {
    *error = "cannot write '" + path + "': it is a directory";
    return false;
  }
  const std::filesystem::path parent = file.parent_path().empty() ? std::filesystem::path(".") : file.parent_path();
  std::filesystem::create_directories(parent, ec);
  const std::error_code created = ec;
  if (!std::filesystem::is_directory(parent, ec)) {
    *error = "cannot write '" + path + "': " +
             (std::filesystem::exists(parent, ec) ? "'" + parent.string() + "' is not a directory"
                                                  : "cannot create directory '" + parent.string() + "'" +
                                                        (created ? " (" + created.message() + ")" : std::string()));
    return false;
  }
  // A fresh name each time (mkstemp), so a probe left behind by a crash cannot get in the way.
  std::string probe = (parent / ".relief-probe-XXXXXX").string();
  const int fd = ::mkstemp(probe.data());
  if (fd < 0) {
    *error = "cannot write '" + path + "': " + std::strerror(errno);
    return false;
  }
  ::close(fd);
  ::unlink(probe.c_str());
  return true;
}

// A flat JSON object whose keys are the dotted names (docs/statistics.md). Its directory exists:
// canCreateFile made it before the render.
bool writeStatsJson(const std::string& path, const StatList& stats) {
  std::ofstream out(path);
  if (!out) return false;
  out << "{\n";
  for (size_t i = 0; i < stats.size(); ++i)
    out << "  " << relief::compiler::jsonQuoted(stats[i].first) << ": " << stats[i].second
        << (i + 1 < stats.size() ? ",\n" : "\n");
  out << "}\n";
  // Written out before the check: a full disk (or /dev/full) fails only at the flush.
  out.close();
  return !out.fail();
}

std::string clock(double seconds) {
  const long s = long(std::max(0.0, seconds) + 0.5);
  char text[32];
  if (s >= 3600)
    std::snprintf(text, sizeof text, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
  else
    std::snprintf(text, sizeof text, "%ld:%02ld", s / 60, s % 60);
  return text;
}

// Render progress on stderr: a bar redrawn at most 10 times a second on a terminal, a plain line
// every 10% otherwise (logs, CI). Reads the cache statistics only to print them.
class Progress {
 public:
  // `thinBudgetTo`: where to say early that the budget thrashes (reportThinBudget), or null.
  Progress(const relief::Accelerator& accel, bool terminal, const std::string& scene = "",
           std::ostream* thinBudgetTo = nullptr)
      : accel_(accel), terminal_(terminal), start_(std::chrono::steady_clock::now()), scene_(scene),
        thinBudgetTo_(thinBudgetTo) {}
  bool warnedThinBudget() const { return warnedThin_; }

  void update(int percent) {
    // Called at each further percent: a thrashing budget is said as soon as it shows.
    if (thinBudgetTo_ && !warnedThin_) {
      const relief::AccelStats a = accel_.stats();
      if (thinBudget(a) && a.capacityMisses > 2 * a.compulsoryMisses + 64) {
        if (terminal_ && drawn_) std::fprintf(stderr, "\r%*s\r", 100, "");
        std::fflush(stderr);
        reportThinBudget(scene_, a, *thinBudgetTo_, true);
        warnedThin_ = true;
        drawn_ = false;
      }
    }
    const auto now = std::chrono::steady_clock::now();
    if (terminal_) {
      if (percent < 100 && drawn_ && now - lastDraw_ < std::chrono::milliseconds(100)) return;
    } else if (percent / 10 <= lastDecile_) {
      return;
    }
    lastDraw_ = now;
    drawn_ = true;
    lastDecile_ = percent / 10;
    const double elapsed = secondsSince(start_);
    const std::string eta =
        percent > 0 ? clock(elapsed * double(100 - percent) / double(percent)) : std::string("?");
    const relief::AccelStats a = accel_.stats();
    char hits[32] = "-";
    if (a.accesses) std::snprintf(hits, sizeof hits, "%.1f%%", 100.0 * double(a.hits) / double(a.accesses));
    if (terminal_) {
      constexpr int kWidth = 30;
      const int filled = percent * kWidth / 100;
      const std::string bar = std::string(size_t(filled), '#') + std::string(size_t(kWidth - filled), '.');
      std::fprintf(stderr, "\r[%s] %3d%%  %s elapsed  ETA %s  cache hits %s   ", bar.c_str(), percent,
                   clock(elapsed).c_str(), eta.c_str(), hits);
    } else {
      std::fprintf(stderr, "relief: rendering %3d%%, %s elapsed, ETA %s, cache hits %s\n", percent,
                   clock(elapsed).c_str(), eta.c_str(), hits);
    }
    std::fflush(stderr);
  }

  void finish() {
    if (terminal_ && drawn_) std::fprintf(stderr, "\r%*s\r", 100, "");
    std::fflush(stderr);
  }

 private:
  const relief::Accelerator& accel_;
  bool terminal_;
  std::chrono::steady_clock::time_point start_, lastDraw_;
  bool drawn_ = false;
  int lastDecile_ = -1;
  std::string scene_;
  std::ostream* thinBudgetTo_;
  bool warnedThin_ = false;
};

enum class OutputKind { Colour, Alpha, Depth, Normal, CacheMiss };

// RenderMan's colour modes: rgb, rgba, rgbz, rgbaz; alpha alone: a, az. A "z" in them adds a
// depth channel ("z" alone is the depth AOV).
bool modeHasAlpha(const std::string& mode) { return mode == "rgba" || mode == "rgbaz" || mode == "a" || mode == "az"; }
bool modeAddsDepth(const std::string& mode) { return mode == "rgbz" || mode == "rgbaz" || mode == "az"; }

OutputKind outputKind(const std::string& mode) {
  if (mode == "a" || mode == "az") return OutputKind::Alpha;
  if (mode == "z") return OutputKind::Depth;
  if (mode == "N") return OutputKind::Normal;
  if (mode == "cachemiss") return OutputKind::CacheMiss;
  return OutputKind::Colour;
}

// `out.png` -> `out.0007.png`: the frames of one run must not overwrite each other's files.
std::string withFrameNumber(const std::string& path, int number) {
  // Four digits whatever the sign: frame -3 is "-0003", as 3 is "0003" ("%04d" gave "-003").
  char digits[16];
  std::snprintf(digits, sizeof digits, number < 0 ? "-%04lld" : "%04lld", std::llabs(static_cast<long long>(number)));
  const std::filesystem::path p(path);
  return (p.parent_path() / (p.stem().string() + "." + digits + p.extension().string())).string();
}

// Each frame is read from the whole file, so the calls outside frame blocks warn again for every
// frame. This stream buffer passes a line on unless an earlier frame printed it.
class FrameWarnings : public std::streambuf {
 public:
  explicit FrameWarnings(std::ostream& out) : out_(out) {}
  ~FrameWarnings() override {
    if (!line_.empty()) out_ << line_ << std::flush;
  }

  // The lines printed so far become an earlier frame's.
  void nextFrame() {
    earlier_.insert(current_.begin(), current_.end());
    current_.clear();
  }

 protected:
  int_type overflow(int_type c) override {
    if (traits_type::eq_int_type(c, traits_type::eof())) return traits_type::not_eof(c);
    line_ += traits_type::to_char_type(c);
    if (line_.back() == '\n') {
      if (!earlier_.count(line_)) {
        out_ << line_ << std::flush;
        current_.insert(line_);
      }
      line_.clear();
    }
    return c;
  }

 private:
  std::ostream& out_;
  std::string line_;
  std::set<std::string> earlier_, current_;
};

// The files written by the frames rendered so far, to warn once when a frame would overwrite one.
struct WrittenFiles {
  std::set<std::string> paths;  // absolute, normalized
  bool warned = false;
};

int renderFrame(const CommandLine& cl, relief::Scene& scene, double loadSeconds, bool severalFrames,
                std::ostream* warnings, WrittenFiles* written);

// "no 'FrameBegin 5' in 'anim.rib' (its frames: 1, 2)": says which numbers exist, briefly.
std::string missingFrameMessage(const CommandLine& cl, const std::vector<int>& numbers) {
  const std::string frame = std::to_string(*cl.frame);
  if (numbers.empty())
    return "'--frame " + frame + "': '" + cl.label() + "' has no FrameBegin blocks (it is one frame)";
  constexpr size_t kListed = 8;
  std::string list;
  for (size_t i = 0; i < numbers.size() && i < kListed; ++i)
    list += (i ? ", " : "") + std::to_string(numbers[i]);
  if (numbers.size() > kListed) list += ", ... " + std::to_string(numbers.back());
  return "no 'FrameBegin " + frame + "' in '" + cl.label() + "' (its frames: " + list + ")";
}

int run(const CommandLine& cl) {
  FrameWarnings frameWarnings(std::cerr);
  std::ostream warningStream(&frameWarnings);
  std::ostream* warnings = cl.quiet ? nullptr : &warningStream;
  // The shader directories double as #include directories, so shaders can share headers. One
  // library serves every frame: it compiles each shader file once.
  relief::tools::ShaderCompilerOptions compileOptions;
  compileOptions.includeDirs = cl.shaderDirs;
  compileOptions.noWarnings = cl.quiet;  // errors are still printed
  relief::tools::ShaderCompilerProcess shaders(compileOptions);

  relief::RibReadOptions readOptions;
  readOptions.shaders = &shaders;
  readOptions.defaultShaderPath = defaultShaderPath(cl);
  {
    const std::filesystem::path sceneDir = std::filesystem::path(cl.scene).parent_path();
    readOptions.defaultTexturePath = {sceneDir.empty() ? std::string(".") : sceneDir.string()};
  }
  readOptions.warnings = warnings;
  readOptions.mainDisplayReplaced = !cl.output.empty();
  relief::SceneError error;
  // --frame names a FrameBegin number; listing the numbers reads no frame, so a broken frame
  // elsewhere in the file does not stop this one.
  int first = 0;
  if (cl.frame) {
    std::optional<std::vector<int>> numbers =
        relief::readRibFrameNumbers(cl.scene, readOptions, &error);
    if (!numbers) {
      std::cerr << error.format() << "\n";
      return 1;
    }
    const auto found = std::find(numbers->begin(), numbers->end(), *cl.frame);
    if (found == numbers->end()) return usageError(missingFrameMessage(cl, *numbers));
    first = int(found - numbers->begin());
    frameWarnings.nextFrame();
  }
  WrittenFiles written;
  for (int index = first;; ++index) {
    const auto loadStart = std::chrono::steady_clock::now();
    readOptions.frame = index;
    std::optional<relief::Scene> scene = relief::readRibFile(cl.scene, readOptions, &error);
    if (!scene) {
      std::cerr << error.format() << "\n";
      return 1;
    }
    const double loadSeconds = secondsSince(loadStart);
    const int numFrames = scene->numFrames();
    const bool severalFrames = !cl.frame && numFrames > 1;
    if (severalFrames && !cl.quiet)
      std::cerr << "relief: frame " << scene->frameNumbers[size_t(index)] << " (" << index + 1
                << " of " << numFrames << ")\n";
    const int code = renderFrame(cl, *scene, loadSeconds, severalFrames, warnings, &written);
    if (code != 0 || cl.frame || index + 1 >= numFrames) return code;
    frameWarnings.nextFrame();
  }
}

// Shaders' printf output (language.md 6.8: for debugging): standard output, a message at a time
// (messages from different threads never mix within one), at most --print-limit messages per run.
// A shader prints at every point it displaces, so an unlimited stream would bury everything else.
class ShaderPrinter {
 public:
  void setLimit(uint64_t limit) { limit_ = limit; }
  // The services for a shader bound at `origin` ("file:line") as `subject`, which runtime errors
  // name: one per distinct pair for the whole run, so frames that bind the same shaders reuse them.
  const RlfHostServices* services(const std::string& origin, const std::string& subject) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto [it, added] = bound_.try_emplace({origin, subject});
    RlfHostServices& s = it->second;
    if (added) {
      s.context = this, s.print = &ShaderPrinter::print;
      s.origin = it->first.first.c_str(), s.subject = it->first.second.c_str();
    }
    return &s;
  }
  uint64_t dropped() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return dropped_;
  }

 private:
  static void print(void* context, const char* text) {
    auto* self = static_cast<ShaderPrinter*>(context);
    std::lock_guard<std::mutex> lock(self->mutex_);
    if (self->shown_ >= self->limit_) {
      ++self->dropped_;
      return;
    }
    ++self->shown_;
    std::fputs(text, stdout);
  }
  std::map<std::pair<std::string, std::string>, RlfHostServices> bound_;  // nodes stay where they are
  mutable std::mutex mutex_;
  uint64_t limit_ = 0, shown_ = 0, dropped_ = 0;
};
ShaderPrinter& shaderPrinter() {
  static ShaderPrinter printer;
  return printer;
}

// Renders the frame `scene` is and writes its displays, all or none. severalFrames: this run
// renders more than one, so names from -o, --stats-json and the default get the frame number.
int renderFrame(const CommandLine& cl, relief::Scene& scene, double loadSeconds, bool severalFrames,
                std::ostream* warnings, WrittenFiles* written) {
  const bool numbered = !scene.frameNumbers.empty();  // the file has FrameBegin blocks
  const int frameNumber = numbered ? scene.frameNumbers[size_t(scene.frameIndex)] : 0;
  auto perFrame = [&](const std::string& path) {
    return severalFrames ? withFrameNumber(path, frameNumber) : path;
  };
  relief::runtime::setTextureSearchPath(scene.texturePath);
  if (cl.width > 0) {
    scene.width = cl.width;
    scene.height = cl.height;
  }
  if (cl.edgeLength > 0.0f)
    for (relief::Displacement& d : scene.displacements) d.edgeLength = cl.edgeLength;
  shaderPrinter().setLimit(cl.printLimit);
  for (relief::Displacement& d : scene.displacements)
    d.services = shaderPrinter().services(d.sourceFile.empty() ? std::string("relief")
                                                              : d.sourceFile + ":" + std::to_string(d.sourceLine),
                                          "displacement shader '" + (d.shader ? d.shader->name() : std::string()) + "'");
  const uint64_t droppedBefore = shaderPrinter().dropped();

  // -o replaces the main display's file; the scene's other displays (AOVs) are still written.
  std::vector<std::string> outputs;
  std::vector<std::string> modes;
  std::vector<std::string> sources;  // per output: the Display call's "file:line", or empty
  if (!scene.displays.empty()) {
    outputs = scene.displays;
    for (size_t i = 0; i < outputs.size(); ++i) {
      modes.push_back(i < scene.displayModes.size() ? scene.displayModes[i] : "rgb");
      sources.push_back(i < scene.displaySources.size() && !(i == 0 && !cl.output.empty()) ? scene.displaySources[i]
                                                                                          : std::string());
    }
    if (!cl.output.empty()) {
      // The AOVs follow the image: relative names land beside the -o file, so that
      // `-o out/x.png` never scatters outputs into the working directory.
      const std::filesystem::path dir = std::filesystem::path(cl.output).parent_path();
      for (size_t i = 1; i < outputs.size(); ++i)
        if (!dir.empty() && std::filesystem::path(outputs[i]).is_relative())
          outputs[i] = (dir / outputs[i]).string();
      outputs[0] = perFrame(cl.output);
    }
  } else if (!cl.output.empty()) {
    outputs.push_back(perFrame(cl.output));
    modes.push_back("rgb");
  } else {
    modes.push_back("rgb");
    const std::string stem = cl.scene == "-" ? std::string("stdin") : std::filesystem::path(cl.scene).stem().string();
    outputs.push_back(perFrame(stem + ".png"));
    if (warnings)
      *warnings << cl.label() << ": warning: no Display in the scene; writing '" << outputs[0]
                << "'\n";
  }
  // RenderMan's default surface needs no light; Relief's matte does: say why the image is black.
  const bool anyLight = !scene.lights.empty() || !scene.distantLights.empty() || scene.ambient > 0.0f;
  const bool anyLitSurface = std::any_of(scene.meshes.begin(), scene.meshes.end(), [&](const relief::Mesh& m) {
    return m.materialIndex >= scene.materials.size() || scene.materials[m.materialIndex].type != relief::SurfaceType::Constant;
  });
  if (!anyLight && anyLitSurface && warnings) {
    if (scene.skippedLights)
      *warnings << cl.label() << ": warning: none of the scene's light sources is one Relief renders (see the "
                << "warnings above), so its surfaces (other than Surface \"constant\") render black\n";
    else
      *warnings << cl.label() << ": warning: the scene has no LightSource, so its surfaces (other than "
                << "Surface \"constant\") render black\n";
  }
  // Single-precision ray-triangle tests multiply coordinates (relative to the ray's origin), and
  // far enough out that overflows float: the example sphere scaled by 1e13 (geometry 1.26e14 from
  // the camera) renders as at scale 1, by 1e14 it tears and by 1e15 it vanishes, in the Embree
  // baseline too. Said, rather than left to look like a rendering bug.
  relief::Bounds3 sceneBox;  // of the undisplaced input (also for reportShaderProblems)
  for (const relief::Mesh& m : scene.meshes)
    for (const glm::vec3& p : m.P) sceneBox.extend(p);
  if (warnings && !sceneBox.empty()) {
    // The farthest corner of the box: at most a little past the farthest vertex.
    const glm::vec3 eye(scene.camera.worldFromCamera[3]);
    const glm::vec3 far = glm::max(glm::abs(sceneBox.lo - eye), glm::abs(sceneBox.hi - eye));
    const float farthest = glm::length(far);
    if (farthest > kFarthestRenderable)
      *warnings << cl.label() << ": warning: the scene reaches about " << farthest
                << " units from the camera; beyond about " << kFarthestRenderable
                << " single-precision intersection overflows and surfaces tear or vanish: scale the scene down\n";
  }
  std::vector<std::string> outputKeys;
  for (size_t i = 0; i < outputs.size(); ++i) {
    std::error_code ignored;
    outputKeys.push_back(std::filesystem::absolute(outputs[i], ignored).lexically_normal().string());
    if (written->paths.count(outputKeys.back()) && !written->warned && warnings) {
      written->warned = true;
      const bool numberedName = i == 0 && severalFrames && !cl.output.empty();
      *warnings << cl.label() << ": warning: frame " << frameNumber << " writes '" << outputs[i]
                << "' again, over an earlier frame's image"
                << (numberedName ? " (two frames have the same number)\n"
                                 : "; give each frame its own Display\n");
    }
  }
  // Two outputs of one frame on one file (two Displays, or the statistics over an image) would
  // leave only the last written: an error before the render, naming both.
  {
    std::vector<std::pair<std::string, std::string>> claims;  // (key, what writes it)
    for (size_t i = 0; i < outputs.size(); ++i)
      claims.emplace_back(outputKeys[i], i == 0 ? "the image" : "the \"" + modes[i] + "\" display");
    if (!cl.statsJson.empty()) {
      std::error_code ignored;
      claims.emplace_back(std::filesystem::absolute(perFrame(cl.statsJson), ignored).lexically_normal().string(),
                          "--stats-json");
    }
    for (size_t i = 0; i < claims.size(); ++i)
      for (size_t j = 0; j < i; ++j)
        if (claims[i].first == claims[j].first) {
          const std::string where = i < sources.size() && !sources[i].empty() ? sources[i] : std::string("relief");
          std::cerr << where << ": error: " << claims[j].second << " and " << claims[i].second << " would both write '"
                    << claims[i].first << "'\n";
          return 1;
        }
  }
  written->paths.insert(outputKeys.begin(), outputKeys.end());
  // A format nothing can write, or a place nothing can be written to, fails now, not after the
  // render.
  for (size_t i = 0; i < outputs.size(); ++i) {
    std::string error;
    // Whether the mode is what the format cannot hold (an unknown format or an unwritable place
    // is not the mode's fault).
    bool modeRefused = false;
    const bool alpha = modes[i] == "rgba" || modes[i] == "rgbaz";
    if (modeAddsDepth(modes[i]) && !relief::isFloatFormat(outputs[i])) {
      error = "cannot write '" + outputs[i] + "': display mode '" + modes[i] +
              "' has a depth channel, which needs a float format (exr)";
      modeRefused = true;
    } else if (!relief::canWriteFormat(outputs[i], alpha, &error)) {
      std::string ignored;
      modeRefused = alpha && relief::canWriteFormat(outputs[i], false, &ignored);
    }
    if (!error.empty() || !canCreateFile(outputs[i], &error)) {
      // Located at the Display call when the scene named the file. When -o named it, the mode
      // may still be the scene's: say where it came from.
      const bool modeFromScene = modeRefused && (sources.size() <= i || sources[i].empty()) &&
                                 i < scene.displaySources.size() && !scene.displaySources[i].empty() &&
                                 modes[i] != "rgb";
      std::cerr << (i < sources.size() && !sources[i].empty() ? sources[i] : std::string("relief")) << ": error: "
                << error
                << (modeFromScene ? " (display mode '" + modes[i] + "' from the Display at " + scene.displaySources[i] + ")"
                                  : std::string())
                << "\n";
      return 1;
    }
  }
  if (!cl.statsJson.empty()) {
    std::string error;
    if (!canCreateFile(perFrame(cl.statsJson), &error)) {
      std::cerr << "relief: error: cannot write statistics: " << error << "\n";
      return 1;
    }
  }

  uint64_t inputTriangles = 0;
  for (const relief::Mesh& m : scene.meshes) inputTriangles += m.numTriangles();

  // The work guard (subdivide.h): a scene asking for absurdly many micro-triangles stops here,
  // before hours of subdivision, at the Displacement that asks.
  std::vector<double> estimates;
  if (cl.displace) {
    estimates = relief::setSubdivisionLimits(scene);
    bool tooMuch = false;
    for (size_t i = 0; i < estimates.size(); ++i) {
      const relief::Displacement& d = scene.displacements[i];
      // Far below the guard but slow and large: the default edge length is in world units, so a
      // scene modelled in large units (a sphere of radius 100) asks for this without saying so.
      // So does a smaller scene asking for far more micro-triangles than the image has pixels
      // (a 400-unit ground plane at 0.05 for a thumbnail: 33M, and gigabytes of subdivision).
      constexpr double kManyMicroTriangles = 5e7, kManyForTheImage = 1e7, kPerPixel = 1000;
      const double pixels = double(scene.width) * double(scene.height);
      const bool many = estimates[i] > kManyMicroTriangles ||
                        (estimates[i] > kManyForTheImage && estimates[i] > kPerPixel * pixels);
      // Beyond the guard, or beyond any use for the image: a pixel cannot show 100,000
      // micro-triangles, and such a scene would fill memory for hours before its first pixels
      // (an edge length of 1e-4 on a unit sphere asks for 1.5e10).
      constexpr double kErrorFloor = 1e9, kErrorPerPixel = 1e5;
      const double limit =
          std::min(relief::kMaxEstimatedMicroTriangles, std::max(kErrorFloor, kErrorPerPixel * pixels));
      if (estimates[i] <= limit) {
        if (many && warnings)
          *warnings << d.sourceFile << ":" << d.sourceLine << ": warning: displacement shader '"
                    << d.shader->name() << "': an edge length of " << d.edgeLength << " (world units) asks for about "
                    << formatCount(estimates[i]) << " micro-triangles on the whole undisplaced surface; "
                    << "rendering may be slow and large: " << edgeLengthSetting(cl.edgeLength > 0.0f)
                    << " sets it\n";
        continue;
      }
      std::cerr << d.sourceFile << ":" << d.sourceLine << ": error: displacement shader '"
                << d.shader->name() << "': an edge length of " << d.edgeLength << " asks for about "
                << formatCount(estimates[i]) << " micro-triangles on the undisplaced surface alone, more than "
                << formatCount(limit)
                << (limit < relief::kMaxEstimatedMicroTriangles
                        ? " (" + formatCount(kErrorPerPixel) + " per pixel of a " + std::to_string(scene.width) +
                              "x" + std::to_string(scene.height) + " image, at least " + formatCount(kErrorFloor) + ")"
                        : std::string())
                << "; raise " << edgeLengthSetting(cl.edgeLength > 0.0f) << "\n";
      tooMuch = true;
    }
    if (tooMuch) return 1;
  }

  const auto buildStart = std::chrono::steady_clock::now();
  relief::AccelOptions accelOptions;
  accelOptions.cacheBudgetTriangles = cl.cacheTrianglesSet || scene.cacheBudgetTriangles == 0
                                          ? cl.cacheTriangles
                                          : scene.cacheBudgetTriangles;
  // A budget left unset is no licence to outgrow the machine: a scene asking for more
  // micro-triangles than half the memory holds gets a budget of that much (the image is the same
  // under any budget), where it would otherwise grow until the kernel kills it. An explicit
  // `--cache-triangles unlimited` is taken at its word.
  if (!cl.cacheTrianglesSet && scene.cacheBudgetTriangles == 0 && cl.accel == "grid") {
    double asked = 0;
    for (double e : estimates) asked += e;
    const long pages = sysconf(_SC_PHYS_PAGES), pageSize = sysconf(_SC_PAGESIZE);
    if (pages > 0 && pageSize > 0) {
      // The memory: physical, or the address space the process may use if that is less.
      double memory = double(pages) * double(pageSize);
      struct rlimit limit {};
      if (getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY)
        memory = std::min(memory, double(limit.rlim_cur));
      const double cap = std::floor(0.5 * memory / kBytesPerCachedTriangle);
      if (asked > cap) {
        accelOptions.cacheBudgetTriangles = uint64_t(cap);
        if (warnings)
          *warnings << cl.label() << ": warning: the displacements ask for about " << formatCount(asked)
                    << " micro-triangles, more than half the memory holds; the cache keeps at most "
                    << formatCount(cap) << " (--cache-triangles sets another budget)\n";
      }
    }
  }
  accelOptions.displace = cl.displace;
  accelOptions.gridResolution = cl.gridResolution;
  accelOptions.refineContributors = cl.refine;
  // With an unlimited budget memory is not what the user is saving, so neighbouring fills share
  // whole subdivisions instead of repeating them (facade: half the shader points, docs/cache.md).
  // Under a budget the side cache would hold displaced triangles beyond it: off unless asked for.
  accelOptions.sideCacheTriangles =
      cl.sideCache.value_or(accelOptions.cacheBudgetTriangles == UINT64_MAX ? kDefaultSideCache : 0);
  // The measurement switches: a value that is none of a switch's is said, not taken silently.
  auto environment = [&](const char* name, std::initializer_list<std::string_view> values) -> const char* {
    const char* env = std::getenv(name);
    if (!env) return nullptr;
    for (std::string_view v : values)
      if (v == env) return env;
    if (warnings) {
      *warnings << "relief: warning: " << name << "='" << env << "' is not one of";
      for (std::string_view v : values) *warnings << " '" << v << "'";
      *warnings << "; ignored\n";
    }
    return nullptr;
  };
  if (const char* env = environment("RELIEF_SUBVOXEL", {"grid", "bvh"})) accelOptions.subVoxelGrid = std::string_view(env) == "grid";
  if (const char* env = environment("RELIEF_SUBTREES", {"0", "1"})) accelOptions.learnSubtrees = std::string_view(env) != "0";
  if (const char* env = environment("RELIEF_PROXIES", {"0", "1"})) accelOptions.voxelProxies = std::string_view(env) != "0";
  if (const char* env = environment("RELIEF_OUTSIDE", {"0", "1"})) accelOptions.outsideTriangles = std::string_view(env) != "0";
  std::unique_ptr<relief::Accelerator> accel;
  if (cl.accel == "grid") {
    accel = relief::makeGridAccelerator(scene, accelOptions);
  } else {
    relief::EmbreeOptions embree;
    embree.compact = cl.accel == "embree-compact";
    embree.threads = cl.threads;
    accel = relief::makeEmbreeAccelerator(scene, accelOptions, embree);
  }
  const double buildSeconds = secondsSince(buildStart);
  if (cl.accel == "grid" && cl.gridResolution > 0) {
    const glm::ivec3 r = accel->stats().gridResolution;
    const int longest = std::max({r.x, r.y, r.z});
    if (longest < cl.gridResolution && warnings)
      *warnings << "relief: warning: --grid-resolution " << cl.gridResolution << " would make more than "
                << relief::kMaxGridVoxels << " voxels, or list too many contributors (a displacement bound "
                << "large against such voxels), in this scene; using " << longest << " along its longest axis\n";
  }

  relief::RenderOptions renderOptions;
  renderOptions.order = cl.order;
  if (!cl.orderSet && !scene.order.empty() && !relief::parsePixelOrder(scene.order, &renderOptions.order)) {
    if (warnings)
      *warnings << cl.label() << ": warning: unknown pixel order '" << scene.order
                << "'; using hilbert\n";
    renderOptions.order = relief::PixelOrder::Hilbert;
  }
  renderOptions.threads = cl.threads;
  renderOptions.samplesPerPixel = cl.spp;
  renderOptions.maxDepth = cl.maxDepth;
  renderOptions.filter = cl.filter;
  if (!cl.filterSet && !scene.pixelFilter.empty())
    relief::parseFilter(scene.pixelFilter, &renderOptions.filter);
  renderOptions.displaced = cl.displace;
  // Under a budget a shared walk keeps one working set for all threads (render.h).
  renderOptions.sharedWalk = cl.accel == "grid" && accelOptions.cacheBudgetTriangles != UINT64_MAX;
  if (const char* env = environment("RELIEF_WALK", {"shared", "stretches"}); env && cl.accel == "grid")
    renderOptions.sharedWalk = std::string_view(env) == "shared";
  Progress progress(*accel, ::isatty(STDERR_FILENO) != 0, cl.label(), warnings);
  if (!cl.quiet) renderOptions.progress = [&progress](int percent) { progress.update(percent); };

  // RI CropWindow: the film and the images written hold the crop only.
  const relief::PixelRect crop = relief::cropPixels(scene.cropWindow, scene.width, scene.height);
  if (crop.w == 0 || crop.h == 0) {
    std::cerr << (scene.cropSource.empty() ? cl.label() : scene.cropSource) << ": error: the 'CropWindow' covers no pixel of the "
              << scene.width << "x" << scene.height << " image\n";
    return 1;
  }
  const bool cropped = crop.w != scene.width || crop.h != scene.height;
  if (cropped) {
    renderOptions.fullWidth = scene.width, renderOptions.fullHeight = scene.height;
    renderOptions.cropX = crop.x, renderOptions.cropY = crop.y;
  }
  relief::Film film(crop.w, crop.h);
  std::optional<relief::Film> depth, normal, cacheMiss;
  relief::AovFilms aovs;
  for (const std::string& mode : modes) {
    if (modeAddsDepth(mode) && !depth) depth.emplace(crop.w, crop.h), aovs.depth = &*depth;
    switch (outputKind(mode)) {
      case OutputKind::Depth:
        if (!depth) depth.emplace(crop.w, crop.h), aovs.depth = &*depth;
        break;
      case OutputKind::Normal:
        if (!normal) normal.emplace(crop.w, crop.h), aovs.normal = &*normal;
        break;
      case OutputKind::CacheMiss:
        if (!cacheMiss) cacheMiss.emplace(crop.w, crop.h), aovs.cacheMiss = &*cacheMiss;
        break;
      case OutputKind::Colour:
      case OutputKind::Alpha:
        break;
    }
  }
  relief::RenderStats renderStats;
  try {
    renderStats = relief::render(scene, *accel, renderOptions, &film, aovs);
  } catch (const std::bad_alloc&) {
    if (!cl.quiet) progress.finish();
    reportOutOfMemory(cl.label(), scene, estimates, cl.edgeLength > 0.0f,
                      accelOptions.cacheBudgetTriangles != UINT64_MAX, std::cerr);
    return 1;
  }
  if (!cl.quiet) progress.finish();
  std::fflush(stdout);  // shader printf output before what follows
  if (const uint64_t dropped = shaderPrinter().dropped() - droppedBefore; dropped > 0 && warnings)
    *warnings << "relief: " << dropped << " more printf message" << (dropped == 1 ? "" : "s")
              << " from shaders not shown (--print-limit " << cl.printLimit << ")\n";
  if (renderStats.stopped) {
    reportRunaway(scene, estimates, cl.edgeLength > 0.0f, std::cerr);
    return 1;
  }

  const relief::AccelStats finalStats = accel->stats();
  std::vector<std::pair<std::string, std::string>> metadata = {
      {"relief:version", kVersion},
      {"relief:scene", cl.label()},
      {"relief:renderSeconds", std::to_string(renderStats.seconds)},
      {"relief:samplesPerPixel", std::to_string(renderStats.samplesPerPixel)},
      {"relief:filter", std::string(relief::filterName(renderOptions.filter))},
      {"relief:order", std::string(relief::pixelOrderName(renderOptions.order))},
      {"relief:cacheAccesses", std::to_string(finalStats.accesses)},
      {"relief:cacheHits", std::to_string(finalStats.hits)},
      {"relief:cacheCompulsoryMisses", std::to_string(finalStats.compulsoryMisses)},
      {"relief:cacheCapacityMisses", std::to_string(finalStats.capacityMisses)},
      {"relief:peakResidentTriangles", std::to_string(finalStats.peakResidentTriangles)},
      {"relief:displacedTrianglesCreated", std::to_string(finalStats.displacedTrianglesCreated)},
  };
  if (numbered) metadata.emplace_back("relief:frame", std::to_string(frameNumber));
  if (scene.camera.pixelAspect != 1.0f) {
    char aspect[32];
    std::snprintf(aspect, sizeof aspect, "%.9g", double(scene.camera.pixelAspect));
    metadata.emplace_back("relief:pixelAspectRatio", aspect);
  }
  // Where the crop lies in the whole image: formats with a data window (EXR, TIFF) record it.
  if (cropped)
    metadata.emplace_back("relief:dataWindow", std::to_string(crop.x) + " " + std::to_string(crop.y) + " " +
                                                   std::to_string(scene.width) + " " + std::to_string(scene.height));

  // Every image is staged under a temporary name first and renamed into place only when all were
  // written: a failed display must not leave the others behind, looking like a finished render.
  film.applyExposure(scene.exposureGain, scene.exposureGamma);  // RI Exposure: colour outputs only
  std::vector<std::string> staged;
  auto discardStaged = [&staged](size_t from) {
    std::error_code ignored;
    for (size_t i = from; i < staged.size(); ++i) std::filesystem::remove(staged[i], ignored);
  };
  for (size_t i = 0; i < outputs.size(); ++i) {
    const std::string& path = outputs[i];  // its directory exists: canCreateFile made it
    const bool floats = relief::isFloatFormat(path);
    relief::ImageWriteOptions writeOptions;
    writeOptions.metadata = metadata;
    writeOptions.threads = std::max(1, int(renderStats.threads));  // as many as rendered
    const relief::Film* image = &film;
    std::optional<relief::Film> mapped;  // AOVs made viewable for 8-bit formats
    switch (outputKind(modes[i])) {
      case OutputKind::Colour:
        writeOptions.alpha = modeHasAlpha(modes[i]);
        writeOptions.srgb = scene.exposureGamma == 1.0f;  // Exposure's gamma is the display transfer
        writeOptions.gamma = scene.exposureGamma;
        break;
      case OutputKind::Alpha:  // coverage as the one channel, linear
        image = &mapped.emplace(relief::alphaForDisplay(film));
        writeOptions.channels = 1;
        writeOptions.channelNames = {"A"};
        writeOptions.srgb = false;
        break;
      case OutputKind::Depth:
        writeOptions.metadata.emplace_back("relief:aov", "z");
        if (floats) {
          image = &*depth;
          writeOptions.channels = 1;
          writeOptions.channelNames = {"Z"};
        } else {
          image = &mapped.emplace(relief::depthForDisplay(*depth));
          writeOptions.srgb = false;
        }
        break;
      case OutputKind::Normal:
        writeOptions.metadata.emplace_back("relief:aov", "N");
        if (floats) {
          image = &*normal;
          writeOptions.channelNames = {"N.X", "N.Y", "N.Z"};
        } else {
          image = &mapped.emplace(relief::normalForDisplay(*normal));
          writeOptions.srgb = false;
        }
        break;
      case OutputKind::CacheMiss:
        writeOptions.metadata.emplace_back("relief:aov", "cachemiss");
        if (floats) {
          image = &*cacheMiss;
          writeOptions.channels = 1;
          writeOptions.channelNames = {"cachemiss"};
        } else {
          image = &mapped.emplace(relief::heatMapForDisplay(*cacheMiss));
          writeOptions.srgb = false;
        }
        break;
    }
    if (modeAddsDepth(modes[i])) {
      writeOptions.depth = &*depth;
      writeOptions.channelNames = outputKind(modes[i]) == OutputKind::Alpha
                                      ? std::vector<std::string>{"A", "Z"}
                                      : modeHasAlpha(modes[i]) ? std::vector<std::string>{"R", "G", "B", "A", "Z"}
                                                               : std::vector<std::string>{"R", "G", "B", "Z"};
    }
    std::string writeError, stagedPath;
    if (!image->writeStaged(path, &stagedPath, &writeError, writeOptions)) {
      discardStaged(0);
      std::cerr << "relief: error: " << writeError << "\n";
      return 1;
    }
    staged.push_back(stagedPath);
  }
  for (size_t i = 0; i < outputs.size(); ++i) {
    std::string renameError;
    if (!relief::commitStagedImage(staged[i], outputs[i], &renameError)) {
      discardStaged(i + 1);
      std::cerr << "relief: error: " << renameError << "\n";
      return 1;
    }
  }
  const relief::AccelStats accelStats = accel->stats();
  if (warnings) {
    reportShaderProblems(scene, sceneBox, *warnings);
    if (!progress.warnedThinBudget()) reportThinBudget(cl.label(), accelStats, *warnings);
  }
  const StatList stats =
      collectStats(cl, scene, accelStats, renderStats, renderOptions.order, loadSeconds, buildSeconds, inputTriangles);
  const std::string statsJson = cl.statsJson.empty() ? std::string() : perFrame(cl.statsJson);
  if (!statsJson.empty() && !writeStatsJson(statsJson, stats)) {
    std::cerr << "relief: error: cannot write statistics to '" << statsJson << "'\n";
    return 1;
  }
  if (cl.stats) printStats(stats);
  for (const std::string& path : outputs) std::cout << path << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CommandLine cl;
  const int parsed = parseCommandLine(argc, argv, &cl);
  if (parsed >= 0) return parsed;
  try {
    return run(cl);
  } catch (const std::exception& e) {
    std::cerr << "relief: error: " << e.what() << "\n";
    return 1;
  }
}
