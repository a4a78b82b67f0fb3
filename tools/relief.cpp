// relief: renders a RIB scene with displacement shaders compiled on the fly. The only place where
// the compiler (ShaderLibrary, the ShaderProvider) meets the renderer (reader, accelerator, render
// loop, film). Exit codes: 0 image written, 1 scene/shader/render error, 2 usage error.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "compiler/shader_library.h"
#include "renderer/accel.h"
#include "renderer/embree_accelerator.h"
#include "renderer/film.h"
#include "renderer/grid_accelerator.h"
#include "renderer/render.h"
#include "renderer/rib_reader.h"
#include "runtime/abi.h"

namespace {

constexpr const char* kVersion = "0.1.0";

constexpr const char* kUsage =
    "usage: relief [options] scene.rib\n"
    "\n"
    "Renders a RenderMan RIB scene whose displacement shaders (.disp) are compiled on the fly.\n"
    "\n"
    "options:\n"
    "  -I, --shader-path DIR     search DIR for shaders (repeatable; before RELIEF_SHADER_PATH)\n"
    "  -o FILE                   write the image to FILE instead of the scene's Display\n"
    "                            (format from the extension: png, exr, tif, ...)\n"
    "  --resolution WxH          override the scene's Format\n"
    "  --spp N                   samples per pixel (overrides PixelSamples)\n"
    "  --threads N               render threads (default: all cores)\n"
    "  --order ORDER             pixel order: scanline, bucket or hilbert (default)\n"
    "  --cache-triangles N       geometry cache budget in displaced triangles, or 'unlimited'\n"
    "  --no-displacement         render the undisplaced surfaces\n"
    "  --accel grid|embree|embree-compact\n"
    "                            geometry cache (default), or the baseline: everything displaced\n"
    "                            up front into one Embree BVH (compact: smaller, slower)\n"
    "  --stats                   print cache statistics and timings\n"
    "  --stats-json FILE         write the same statistics as JSON (for benchmark scripts)\n"
    "  --quiet                   no warnings or progress, only errors and the image path\n"
    "  --help                    show this help\n"
    "  --version                 show the version\n"
    "\n"
    "The shader search path is the scene's Option \"searchpath\" \"shader\" if given ('@' in it\n"
    "stands for the default path), otherwise the default: the -I directories, then the\n"
    "':'-separated RELIEF_SHADER_PATH, then the scene file's directory.\n";

struct CommandLine {
  std::string scene;
  std::vector<std::string> shaderDirs;
  std::string output;
  int width = 0, height = 0;
  int spp = 0;
  int threads = 0;
  relief::PixelOrder order = relief::PixelOrder::Hilbert;
  uint64_t cacheTriangles = UINT64_MAX;
  bool displace = true;
  std::string accel = "grid";
  bool stats = false;
  std::string statsJson;
  bool quiet = false;
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

// Returns -1 when parsing succeeded and the program should go on, else the exit code.
int parseCommandLine(int argc, char** argv, CommandLine* cl) {
  std::vector<std::string> args(argv + 1, argv + argc);
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&](std::string* out) {
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
      if (!value(&v)) return usageError("'-o' needs a file name");
      cl->output = v;
    } else if (a == "--resolution") {
      if (!value(&v)) return usageError("'--resolution' needs WxH");
      const size_t x = v.find('x');
      long long w = 0, h = 0;
      if (x == std::string::npos || !parsePositive(v.substr(0, x), 65536, &w) ||
          !parsePositive(v.substr(x + 1), 65536, &h))
        return usageError("invalid resolution '" + v + "' (expected WxH, e.g. 640x480)");
      if (uint64_t(w) * uint64_t(h) > relief::kMaxPixels)
        return usageError("resolution '" + v + "' has more than " +
                          std::to_string(relief::kMaxPixels) + " pixels");
      cl->width = int(w);
      cl->height = int(h);
    } else if (a == "--spp") {
      if (!value(&v) || !parsePositive(v, 4096, &n))
        return usageError("'--spp' needs a sample count between 1 and 4096");
      cl->spp = int(n);
    } else if (a == "--threads") {
      if (!value(&v) || !parsePositive(v, 256, &n))
        return usageError("'--threads' needs a thread count between 1 and 256");
      cl->threads = int(n);
    } else if (a == "--order") {
      if (!value(&v) || !relief::parsePixelOrder(v, &cl->order))
        return usageError("'--order' needs scanline, bucket or hilbert");
    } else if (a == "--cache-triangles") {
      if (!value(&v)) return usageError("'--cache-triangles' needs a count or 'unlimited'");
      if (v == "unlimited") {
        cl->cacheTriangles = UINT64_MAX;
      } else if (parsePositive(v, (1LL << 62), &n)) {
        cl->cacheTriangles = uint64_t(n);
      } else {
        return usageError("invalid triangle budget '" + v + "'");
      }
    } else if (a == "--no-displacement") {
      cl->displace = false;
    } else if (a == "--accel") {
      if (!value(&v) || (v != "grid" && v != "embree" && v != "embree-compact"))
        return usageError("'--accel' needs grid, embree or embree-compact");
      cl->accel = v;
    } else if (a == "--stats-json") {
      if (!value(&v)) return usageError("'--stats-json' needs a file name");
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
  }
  if (cl->scene.empty()) return usageError("no scene file given");
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

void printStats(const relief::AccelStats& a, const relief::RenderStats& r, double loadSeconds,
                double buildSeconds, uint64_t inputTriangles) {
  const double accesses = a.accesses ? double(a.accesses) : 1.0;
  std::printf("scene:      %llu input triangles, loaded in %.3f s\n",
              (unsigned long long)inputTriangles, loadSeconds);
  std::printf("accel:      built in %.3f s\n", buildSeconds);
  std::printf("render:     %.3f s on %d threads, %d spp\n", r.seconds, r.threads,
              r.samplesPerPixel);
  std::printf("rays:       %llu camera (%llu hit), %llu shadow\n",
              (unsigned long long)r.cameraRays, (unsigned long long)r.cameraHits,
              (unsigned long long)r.shadowRays);
  std::printf("cache:      %llu accesses, %.2f%% hits, %llu compulsory + %llu capacity misses\n",
              (unsigned long long)a.accesses, 100.0 * double(a.hits) / accesses,
              (unsigned long long)a.compulsoryMisses, (unsigned long long)a.capacityMisses);
  std::printf("triangles:  %llu displaced created, %llu unique, peak %llu resident (%llu now)\n",
              (unsigned long long)a.displacedTrianglesCreated,
              (unsigned long long)a.uniqueDisplacedTriangles,
              (unsigned long long)a.peakResidentTriangles,
              (unsigned long long)a.residentTriangles);
  std::printf("shading:    %llu shader points; subdivide %.3f s, displace %.3f s\n",
              (unsigned long long)a.shaderPoints, a.subdivideSeconds, a.displaceSeconds);
}

// Runtime problems inside displacement shaders are counted, not thrown (abi.h); say so once.
void reportShaderProblems(const relief::Accelerator& accel, std::ostream& out) {
  const auto* grid = dynamic_cast<const relief::GridAccelerator*>(&accel);
  if (!grid) return;
  const RlfStatus s = grid->shaderStatus();
  auto report = [&](uint32_t count, const char* what) {
    if (count) out << "relief: warning: displacement shaders: " << count << " " << what << "\n";
  };
  report(s.nonFinite, "points produced NaN or infinity (left undisplaced)");
  report(s.loopLimit, "invocations hit the loop-iteration limit");
  report(s.indexClamped, "array or component indices were clamped into range");
  report(s.unknownSpace, "unknown coordinate space names were treated as 'current'");
  report(s.textureErrors, "texture lookups failed");
}

std::string jsonString(const std::string& text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", c);
      out += escaped;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

bool writeStatsJson(const std::string& path, const CommandLine& cl, const relief::Scene& scene,
                    const relief::AccelStats& a, const relief::RenderStats& r, double loadSeconds,
                    double buildSeconds, uint64_t inputTriangles) {
  std::ofstream out(path);
  if (!out) return false;
  auto u = [](uint64_t v) { return std::to_string(v); };
  out << "{\n"
      << "  \"scene\": " << jsonString(cl.scene) << ",\n"
      << "  \"width\": " << scene.width << ", \"height\": " << scene.height << ",\n"
      << "  \"samplesPerPixel\": " << r.samplesPerPixel << ", \"threads\": " << r.threads << ",\n"
      << "  \"order\": \"" << relief::pixelOrderName(cl.order) << "\",\n"
      << "  \"cacheBudgetTriangles\": "
      << (cl.cacheTriangles == UINT64_MAX ? std::string("null") : u(cl.cacheTriangles)) << ",\n"
      << "  \"displacement\": " << (cl.displace ? "true" : "false") << ",\n"
      << "  \"inputTriangles\": " << u(inputTriangles) << ",\n"
      << "  \"loadSeconds\": " << loadSeconds << ", \"buildSeconds\": " << buildSeconds
      << ", \"renderSeconds\": " << r.seconds << ",\n"
      << "  \"cameraRays\": " << u(r.cameraRays) << ", \"cameraHits\": " << u(r.cameraHits)
      << ", \"shadowRays\": " << u(r.shadowRays) << ",\n"
      << "  \"accesses\": " << u(a.accesses) << ", \"hits\": " << u(a.hits)
      << ", \"compulsoryMisses\": " << u(a.compulsoryMisses)
      << ", \"capacityMisses\": " << u(a.capacityMisses) << ",\n"
      << "  \"displacedTrianglesCreated\": " << u(a.displacedTrianglesCreated)
      << ", \"uniqueDisplacedTriangles\": " << u(a.uniqueDisplacedTriangles) << ",\n"
      << "  \"peakResidentTriangles\": " << u(a.peakResidentTriangles)
      << ", \"residentTriangles\": " << u(a.residentTriangles) << ",\n"
      << "  \"shaderPoints\": " << u(a.shaderPoints) << ", \"subdivideSeconds\": "
      << a.subdivideSeconds << ", \"displaceSeconds\": " << a.displaceSeconds << "\n"
      << "}\n";
  return bool(out);
}

int run(const CommandLine& cl) {
  std::ostream* warnings = cl.quiet ? nullptr : &std::cerr;
  // The shader directories double as #include directories, so shaders can share headers.
  relief::compiler::CompileOptions compileOptions;
  compileOptions.includeDirs = cl.shaderDirs;
  compileOptions.noWarnings = cl.quiet;  // errors are still printed
  relief::compiler::ShaderLibrary shaders(compileOptions, &std::cerr);

  const auto loadStart = std::chrono::steady_clock::now();
  relief::RibReadOptions readOptions;
  readOptions.shaders = &shaders;
  readOptions.defaultShaderPath = defaultShaderPath(cl);
  readOptions.warnings = warnings;
  relief::SceneError error;
  std::optional<relief::Scene> loaded = relief::readRibFile(cl.scene, readOptions, &error);
  if (!loaded) {
    std::cerr << error.format() << "\n";
    return 1;
  }
  const double loadSeconds = secondsSince(loadStart);
  relief::Scene& scene = *loaded;
  if (cl.width > 0) {
    scene.width = cl.width;
    scene.height = cl.height;
  }

  std::vector<std::string> outputs;
  std::vector<bool> alpha;
  if (!cl.output.empty()) {
    outputs.push_back(cl.output);
    alpha.push_back(!scene.displayModes.empty() && scene.displayModes[0] == "rgba");
  } else if (!scene.displays.empty()) {
    outputs = scene.displays;
    for (size_t i = 0; i < outputs.size(); ++i)
      alpha.push_back(i < scene.displayModes.size() && scene.displayModes[i] == "rgba");
  } else {
    alpha.push_back(false);
    outputs.push_back(std::filesystem::path(cl.scene).stem().string() + ".png");
    if (warnings)
      *warnings << cl.scene << ": warning: no Display in the scene; writing '" << outputs[0]
                << "'\n";
  }

  uint64_t inputTriangles = 0;
  for (const relief::Mesh& m : scene.meshes) inputTriangles += m.numTriangles();

  const auto buildStart = std::chrono::steady_clock::now();
  relief::AccelOptions accelOptions;
  accelOptions.cacheBudgetTriangles = cl.cacheTriangles;
  accelOptions.displace = cl.displace;
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

  relief::RenderOptions renderOptions;
  renderOptions.order = cl.order;
  renderOptions.threads = cl.threads;
  renderOptions.samplesPerPixel = cl.spp;
  const bool showProgress = !cl.quiet && ::isatty(STDERR_FILENO);
  if (showProgress) {
    renderOptions.progress = [](int percent) {
      std::fprintf(stderr, "\rrendering %3d%%", percent);
      std::fflush(stderr);
    };
  }
  relief::Film film(scene.width, scene.height);
  const relief::RenderStats renderStats = relief::render(scene, *accel, renderOptions, &film);
  if (showProgress) std::fprintf(stderr, "\r               \r");

  for (size_t i = 0; i < outputs.size(); ++i) {
    const std::string& path = outputs[i];
    // `-o out/image.png` into a fresh checkout should just work; a failure surfaces in write().
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    std::error_code ignored;
    if (!parent.empty()) std::filesystem::create_directories(parent, ignored);
    std::string writeError;
    if (!film.write(path, &writeError, alpha[i])) {
      std::cerr << "relief: error: " << writeError << "\n";
      return 1;
    }
  }
  if (warnings) reportShaderProblems(*accel, *warnings);
  if (!cl.statsJson.empty() &&
      !writeStatsJson(cl.statsJson, cl, scene, accel->stats(), renderStats, loadSeconds,
                      buildSeconds, inputTriangles)) {
    std::cerr << "relief: error: cannot write statistics to '" << cl.statsJson << "'\n";
    return 1;
  }
  if (cl.stats) printStats(accel->stats(), renderStats, loadSeconds, buildSeconds, inputTriangles);
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
