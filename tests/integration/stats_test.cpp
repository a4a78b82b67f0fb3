// End-to-end test of the statistics interface (docs/statistics.md): relief --stats-json writes a
// flat JSON object with the documented dotted keys, and the figures obey the cache's invariants
// (every access is one hit or one miss, the resident set stays within budget plus one voxel, the
// time split adds up) with the budget check mode on and the image unchanged by the budget.
#include <sys/wait.h>

#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "image_compare.h"
#include "scratch_dir.h"

namespace fs = std::filesystem;

namespace {

const std::string kSource = RELIEF_SOURCE_DIR;
const std::string kRelief = RELIEF_BIN;
const std::string kSphereScene = kSource + "/examples/scenes/sphere.rib";

fs::path scratchDir() { return relief::test::scratchDir("relief-stats"); }

int runCommand(const std::string& command, const fs::path& log) {
  const std::string line = command + " >" + log.string() + " 2>&1 </dev/null";
  const int status = std::system(line.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string readFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The raw text of each value of a flat JSON object (strings keep their quotes). Fails the test on
// anything but a flat object of scalars.
std::map<std::string, std::string> parseFlatJson(const std::string& text) {
  std::map<std::string, std::string> out;
  size_t i = 0;
  auto skip = [&] {
    while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
  };
  auto string = [&] {
    std::string s;
    EXPECT_EQ(text[i], '"');
    for (++i; i < text.size() && text[i] != '"'; ++i) {
      if (text[i] == '\\') ++i;
      s += text[i];
    }
    ++i;
    return s;
  };
  skip();
  if (i >= text.size() || text[i] != '{') {
    ADD_FAILURE() << "not a JSON object: " << text;
    return out;
  }
  ++i;
  for (;;) {
    skip();
    if (text[i] == '}') break;
    const std::string key = string();
    skip();
    if (text[i] != ':') {
      ADD_FAILURE() << "expected ':' after " << key;
      return out;
    }
    ++i;
    skip();
    const size_t start = i;
    if (text[i] == '"') {
      string();
    } else {
      while (i < text.size() && text[i] != ',' && text[i] != '}' &&
             !std::isspace(static_cast<unsigned char>(text[i])))
        ++i;
    }
    const std::string value = text.substr(start, i - start);
    EXPECT_TRUE(value.size() && value != "{" && value != "[") << key << " is not a scalar";
    EXPECT_FALSE(out.count(key)) << "duplicate key " << key;
    out[key] = value;
    skip();
    if (text[i] == ',') ++i;
  }
  return out;
}

struct StatsRun {
  std::map<std::string, std::string> stats;
  fs::path image;
  double num(const std::string& key) const {
    const auto it = stats.find(key);
    if (it == stats.end()) {
      ADD_FAILURE() << "missing key " << key;
      return 0;
    }
    return std::strtod(it->second.c_str(), nullptr);
  }
};

StatsRun render(const std::string& name, const std::string& options) {
  const fs::path dir = scratchDir();
  StatsRun r;
  r.image = dir / (name + ".png");
  const fs::path json = dir / (name + ".json"), log = dir / (name + ".log");
  const int code = runCommand("RELIEF_CHECK_BUDGET=1 " + kRelief + " " + kSphereScene +
                                  " --quiet --resolution 96x72 --stats-json " + json.string() +
                                  " -o " + r.image.string() + " " + options,
                              log);
  EXPECT_EQ(code, 0) << readFile(log);
  r.stats = parseFlatJson(readFile(json));
  return r;
}

const char* const kRequiredKeys[] = {
    "cache.budget_triangles",        "cache.accesses",
    "cache.hits",                    "cache.compulsory_misses",
    "cache.capacity_misses",         "cache.peak_resident_triangles",
    "cache.unique_displaced_triangles", "cache.displaced_triangles_created",
    "cache.simplification_saved_fraction", "cache.bytes_per_triangle",
    "cache.hit_percent",             "cache.capacity_miss_share",
    "cache.max_voxel_triangles",     "cache.budget_violations",
    "time.total_s",                  "time.subdivide_s",
    "time.displace_s",               "time.intersect_s",
    "time.shade_s",                  "time.render_s",
    "memory.peak_rss_bytes",         "memory.compiler_peak_rss_bytes",
};

void expectInvariants(const StatsRun& r) {
  for (const char* key : kRequiredKeys) EXPECT_TRUE(r.stats.count(key)) << "missing " << key;
  EXPECT_EQ(r.num("cache.hits") + r.num("cache.compulsory_misses") + r.num("cache.capacity_misses"),
            r.num("cache.accesses"));
  EXPECT_GT(r.num("cache.accesses"), 0);
  EXPECT_GE(r.num("cache.displaced_triangles_created"), r.num("cache.unique_displaced_triangles"));
  EXPECT_GT(r.num("cache.unique_displaced_triangles"), 1000);
  EXPECT_NEAR(r.num("cache.hit_percent"), 100.0 * r.num("cache.hits") / r.num("cache.accesses"), 1e-3);
  EXPECT_EQ(r.num("cache.budget_violations"), 0);
  // Per triangle: at least its three narrow indices and two 32-bit ids.
  EXPECT_GT(r.num("cache.bytes_per_triangle"), 6);
  EXPECT_GE(r.num("cache.simplification_saved_fraction"), 0);
  EXPECT_LT(r.num("cache.simplification_saved_fraction"), 1);
  // The parts of the render time are non-negative and add up to it.
  double parts = 0;
  for (const char* key : {"time.subdivide_s", "time.displace_s", "time.intersect_s", "time.shade_s"}) {
    EXPECT_GE(r.num(key), 0) << key;
    parts += r.num(key);
  }
  EXPECT_NEAR(parts, r.num("time.render_s"), 1e-3 + 1e-3 * r.num("time.render_s"));
  EXPECT_GT(r.num("time.displace_s"), 0);
  EXPECT_GE(r.num("time.total_s"), r.num("time.render_s"));
  EXPECT_GT(r.num("memory.peak_rss_bytes"), r.num("cache.peak_resident_bytes"));
  EXPECT_GT(r.num("memory.compiler_peak_rss_bytes"), 0);  // reliefc compiled the shaders
}

TEST(Stats, JsonHasTheDocumentedKeysAndInvariants) {
  const StatsRun unlimited = render("unlimited", "--threads 1");
  expectInvariants(unlimited);
  EXPECT_EQ(unlimited.stats.at("cache.budget_triangles"), "null");
  EXPECT_EQ(unlimited.num("cache.capacity_misses"), 0);
  EXPECT_EQ(unlimited.num("cache.capacity_miss_share"), 0);
  // Unlimited: everything created stays resident.
  EXPECT_EQ(unlimited.num("cache.peak_resident_triangles"),
            unlimited.num("cache.displaced_triangles_created"));

  // On the unlimited run's grid: a budget alone may raise the automatic resolution (cache.md),
  // and the voxels the rays fill, so the compulsory misses and unique triangles, are the grid's.
  const uint64_t budget = uint64_t(unlimited.num("cache.unique_displaced_triangles") / 20);
  const std::string sameGrid = " --grid-resolution " + std::to_string(int(unlimited.num("grid.resolution_x")));
  const StatsRun small = render("small", "--threads 1 --cache-triangles " + std::to_string(budget) + sameGrid);
  expectInvariants(small);
  EXPECT_EQ(small.num("cache.budget_triangles"), double(budget));
  EXPECT_GT(small.num("cache.capacity_misses"), 0);
  EXPECT_GT(small.num("cache.capacity_miss_share"), 0);
  EXPECT_EQ(small.num("cache.compulsory_misses"), unlimited.num("cache.compulsory_misses"));
  EXPECT_EQ(small.num("cache.unique_displaced_triangles"),
            unlimited.num("cache.unique_displaced_triangles"));
  // One thread pins one voxel at a time: the budget plus the voxel being filled.
  EXPECT_LE(small.num("cache.peak_resident_triangles"),
            double(budget) + small.num("cache.max_voxel_triangles"));
  EXPECT_GT(small.num("cache.displaced_triangles_created"),
            unlimited.num("cache.displaced_triangles_created"));

  const StatsRun threaded = render("threaded", "--threads 2 --order scanline --cache-triangles " +
                                              std::to_string(budget));  // on the grid the budget chose
  expectInvariants(threaded);
  EXPECT_LE(threaded.num("cache.peak_resident_triangles"),
            double(budget) + 2 * threaded.num("cache.max_voxel_triangles"));

  // The budget never reaches the image.
  for (const StatsRun* other : {&small, &threaded}) {
    relief::test::ImageDiff d =
        relief::test::compareImages(other->image.string(), unlimited.image.string(), 0.0f);
    ASSERT_TRUE(d.loaded) << d.error;
    EXPECT_EQ(d.failingPixels, 0) << other->image;
  }
}

TEST(Stats, RefinementSideCacheAndGridResolutionFlags) {
  // Five renders: a quarter of the usual pixels keeps the test quick under the sanitizers (the
  // later --resolution wins).
  const StatsRun refined = render("refined", "--resolution 48x36 --threads 1 --grid-resolution 12 --side-cache 0");
  const StatsRun plain =
      render("plain", "--resolution 48x36 --threads 1 --grid-resolution 12 --no-refine --side-cache 0");
  // The side cache is on by default with an unlimited budget and off under a budget.
  const StatsRun byDefault = render("default", "--resolution 48x36 --threads 1 --grid-resolution 12");
  const StatsRun budgeted =
      render("budgeted", "--resolution 48x36 --threads 1 --grid-resolution 12 --cache-triangles 20000");
  expectInvariants(refined);
  EXPECT_EQ(refined.num("grid.resolution_x"), 12);
  EXPECT_EQ(refined.stats.at("grid.refinement"), "true");
  EXPECT_EQ(plain.stats.at("grid.refinement"), "false");
  EXPECT_GT(refined.num("grid.dropped_contributors"), 0);
  EXPECT_EQ(plain.num("grid.dropped_contributors"), 0);
  const StatsRun side = render("side", "--resolution 48x36 --threads 1 --grid-resolution 12 --side-cache 20000");
  expectInvariants(side);
  EXPECT_GT(side.num("cache.side_cache_hits"), 0);
  EXPECT_GT(side.num("cache.side_cache_peak_triangles"), 0);
  EXPECT_EQ(plain.num("cache.side_cache_hits"), 0);
  EXPECT_EQ(plain.num("cache.side_cache_peak_triangles"), 0);
  EXPECT_GT(byDefault.num("cache.side_cache_hits"), 0);
  EXPECT_LT(byDefault.num("cache.shader_points"), plain.num("cache.shader_points"));
  EXPECT_EQ(budgeted.num("cache.side_cache_peak_triangles"), 0);
  for (const StatsRun* other : {&plain, &side, &byDefault, &budgeted}) {
    relief::test::ImageDiff d =
        relief::test::compareImages(other->image.string(), refined.image.string(), 0.0f);
    ASSERT_TRUE(d.loaded) << d.error;
    EXPECT_EQ(d.failingPixels, 0) << other->image;
  }
}

// The Embree baseline displaces everything while building: its subdivision and shader times are
// reported but are not part of the render's, which splits into ray time and shading; its bytes
// per triangle are those of everything it holds, and simplification is counted as the grid's.
TEST(Stats, EmbreeBaselineReportsItsOwnSplitAndBytes) {
  const fs::path dir = scratchDir();
  // The facade: its Displacements simplify.
  auto run = [&](const std::string& name, const std::string& accel, StatsRun& r) {
    const fs::path json = dir / (name + ".json"), log = dir / (name + ".log");
    const int code = runCommand(kRelief + " " + kSource + "/examples/scenes/facade.rib --quiet --resolution 64x48 --threads 2" +
                                    " --accel " + accel + " --stats-json " + json.string() + " -o " +
                                    (dir / (name + ".png")).string(),
                                log);
    r.stats = parseFlatJson(readFile(json));
    return std::make_pair(code, readFile(log));
  };
  StatsRun r, grid;
  const auto [code, log] = run("embree", "embree", r);
  if (code != 0 && log.find("has no Embree") != std::string::npos) GTEST_SKIP() << "built without Embree";
  ASSERT_EQ(code, 0) << log;
  ASSERT_EQ(run("grid", "grid", grid).first, 0);
  EXPECT_GT(r.num("time.intersect_s"), 0);
  EXPECT_GT(r.num("time.subdivide_s"), 0);
  EXPECT_GT(r.num("time.displace_s"), 0);
  EXPECT_NEAR(r.num("time.intersect_s") + r.num("time.shade_s"), r.num("time.render_s"),
              1e-3 + 1e-3 * r.num("time.render_s"));
  EXPECT_GE(r.num("time.build_s"), r.num("time.subdivide_s") + r.num("time.displace_s") - 1e-3);
  EXPECT_GT(r.num("cache.bytes_per_triangle"), 20);  // indices, floats and Embree's BVH
  EXPECT_GT(r.num("cache.created_bytes"), 0);
  EXPECT_LE(r.num("cache.created_bytes"), r.num("cache.peak_resident_bytes"));
  EXPECT_EQ(r.num("cache.triangles_after_simplification"), r.num("cache.displaced_triangles_created"));
  // Every input triangle subdivided once, whole, as the grid's side cache does at an unlimited
  // budget (which fills only the voxels the rays reach): about the same fraction saved.
  EXPECT_GT(r.num("cache.simplification_saved_fraction"), 0.1);
  EXPECT_NEAR(r.num("cache.simplification_saved_fraction"), grid.num("cache.simplification_saved_fraction"), 0.02);
  // The facade is the paper's Plate 2 as issue #6 framed it: about 1,250 input triangles making at
  // least 1.1 million displaced ones at its edge length (a shader fix once took it to 1.02M).
  EXPECT_NEAR(r.num("scene.input_triangles"), 1250, 50);
  EXPECT_GE(r.num("cache.displaced_triangles_created"), 1.1e6);
}

// A budget holding fewer than four of the largest voxels, walked in scanline order, makes voxels
// evict each other: relief says so after the render, naming the budget and the largest voxel. A
// budget with room to spare says nothing. (The grid is given: an automatic one would be made
// finer for the budget, and not thrash.)
TEST(Stats, ThrashingBudgetIsReported) {
  const fs::path dir = scratchDir();
  const std::string base = kRelief + " " + kSphereScene +
                           " --resolution 64x48 --threads 1 --order scanline --grid-resolution 11 -o " +
                           (dir / "thin.png").string() + " --cache-triangles ";
  ASSERT_EQ(runCommand(base + "30000", dir / "thin.log"), 0) << readFile(dir / "thin.log");
  const std::string thin = readFile(dir / "thin.log");
  EXPECT_NE(thin.find("sphere.rib: warning: the cache budget of 30000 displaced triangles holds fewer than 4 "
                      "of the largest voxels ("),
            std::string::npos)
      << thin;
  EXPECT_NE(thin.find("raise --cache-triangles, or --grid-resolution"), std::string::npos) << thin;
  ASSERT_EQ(runCommand(base + "300000", dir / "roomy.log"), 0) << readFile(dir / "roomy.log");
  EXPECT_EQ(readFile(dir / "roomy.log").find("warning"), std::string::npos) << readFile(dir / "roomy.log");
}

// A budget holding several of the largest voxels can still be smaller than what the rays use
// together: shadow rays toward an area light and rays through a transparent sphere reach voxels
// across the scene, and refills outnumbered first fills tenfold without a word. Now said, without
// the advice about voxel sizes that does not apply; unlimited says nothing.
TEST(Stats, WorkingSetLargerThanTheBudgetIsReported) {
  const fs::path dir = scratchDir();
  const fs::path scene = dir / "shadows.rib";
  std::ofstream(scene) << "Option \"searchpath\" \"string shader\" [\"" << kSource << "/examples/shaders:&\"]\n"
                          "Format 48 36 1\nPixelSamples 1 1\nProjection \"perspective\" \"fov\" [35]\n"
                          "Translate 0 0 6\nRotate -20 1 0 0\nWorldBegin\n"
                          "AttributeBegin\nTranslate 0 3 0\nRotate 90 1 0 0\n"
                          "LightSource \"arealight\" 2 \"intensity\" [6] \"float width\" [2] \"float height\" [2] \"int samples\" [16]\n"
                          "AttributeEnd\nIlluminate 2 1\n"
                          "AttributeBegin\nOpacity [0.5 0.5 0.5]\nAttribute \"displacementbound\" \"float sphere\" [0.06]\n"
                          "Attribute \"relief\" \"float edgelength\" [0.02]\nDisplacement \"bumps\" \"float Km\" [0.05]\n"
                          "Sphere 1 -1 1 360\nAttributeEnd\n"
                          "AttributeBegin\nAttribute \"displacementbound\" \"float sphere\" [0.06]\n"
                          "Attribute \"relief\" \"float edgelength\" [0.04]\n"
                          "Displacement \"sinebumps\" \"float Km\" [0.05] \"float freq\" [8]\n"
                          "Polygon \"P\" [-3 -1.2 -3  -3 -1.2 3  3 -1.2 3  3 -1.2 -3]\nAttributeEnd\nWorldEnd\n";
  const std::string base = kRelief + " " + scene.string() + " --threads 1 --grid-resolution 25 -o " +
                           (dir / "shadows.png").string() + " --stats-json " + (dir / "s.json").string() +
                           " --cache-triangles ";
  ASSERT_EQ(runCommand(base + "33000", dir / "tight.log"), 0) << readFile(dir / "tight.log");
  const std::string tight = readFile(dir / "tight.log");
  StatsRun stats;
  stats.stats = parseFlatJson(readFile(dir / "s.json"));
  ASSERT_GE(33000, 4 * stats.num("cache.max_voxel_triangles"));  // four voxels fit: not the other warning
  EXPECT_NE(tight.find("shadows.rib: warning: the cache budget of 33000 displaced triangles is smaller than the "
                       "voxels the rays use together"),
            std::string::npos)
      << tight;
  EXPECT_EQ(tight.find("--grid-resolution for smaller voxels"), std::string::npos) << tight;
  ASSERT_EQ(runCommand(base + "unlimited", dir / "roomy.log"), 0) << readFile(dir / "roomy.log");
  EXPECT_EQ(readFile(dir / "roomy.log").find("warning"), std::string::npos) << readFile(dir / "roomy.log");
}

// Voxels made coarse by a generous displacement bound thrash a budget from the start: the
// warning comes while the render runs (it may run for minutes), once, and not again after it.
// The coarse grid is given (the automatic one would now be made finer for the budget: the next
// test).
// The example sphere with a displacement bound of 0.5 (its shader needs 0.06), written to
// dir/coarse.rib; its shaders are found with -I kSource/examples/shaders.
fs::path writeCoarseSphere(const fs::path& dir) {
  std::string scene = readFile(kSource + "/examples/scenes/sphere.rib");
  const size_t bound = scene.find("\"float sphere\" [0.06]");
  EXPECT_NE(bound, std::string::npos);
  if (bound != std::string::npos)
    scene.replace(bound, std::string("\"float sphere\" [0.06]").size(), "\"float sphere\" [0.5]");
  const size_t path = scene.find("Option \"searchpath\"");
  EXPECT_NE(path, std::string::npos);
  if (path != std::string::npos) scene.erase(path, scene.find('\n', path) - path);
  std::ofstream(dir / "coarse.rib") << scene;
  return dir / "coarse.rib";
}

TEST(Stats, ClearThrashingIsSaidDuringTheRender) {
  const fs::path dir = scratchDir();
  writeCoarseSphere(dir);
  const fs::path log = dir / "coarse.log";
  ASSERT_EQ(runCommand(kRelief + " " + (dir / "coarse.rib").string() + " -I " + kSource +
                           "/examples/shaders --resolution 48x36 --threads 1 --grid-resolution 3 --cache-triangles 60000 -o " +
                           (dir / "coarse.png").string(),
                       log),
            0)
      << readFile(log);
  const std::string text = readFile(log);
  const size_t warning = text.find("so far (the render goes on, slowly): raise --cache-triangles");
  ASSERT_NE(warning, std::string::npos) << text;
  EXPECT_LT(warning, text.find("rendering 100%")) << text;
  EXPECT_EQ(text.find("holds fewer than", text.find("holds fewer than") + 1), std::string::npos) << text;
}

// The same scene and budget on the automatic grid: the budget makes it finer than the bound
// alone would (3 voxels across, 134K triangles in the heaviest), so it does not thrash, and the
// image is the unlimited one.
TEST(Stats, ATightBudgetGetsAGridItCanHold) {
  const fs::path dir = scratchDir();
  const std::string base = kRelief + " " + writeCoarseSphere(dir).string() + " -I " + kSource +
                           "/examples/shaders --resolution 48x36 --threads 1 ";
  ASSERT_EQ(runCommand(base + "-o " + (dir / "full.png").string(), dir / "full.log"), 0) << readFile(dir / "full.log");
  const fs::path json = dir / "tight.json";
  ASSERT_EQ(runCommand(base + "--cache-triangles 60000 --stats-json " + json.string() + " -o " +
                           (dir / "tight.png").string(),
                       dir / "tight.log"),
            0)
      << readFile(dir / "tight.log");
  EXPECT_EQ(readFile(dir / "tight.log").find("warning"), std::string::npos) << readFile(dir / "tight.log");
  const std::map<std::string, std::string> stats = parseFlatJson(readFile(json));
  EXPECT_GT(std::stod(stats.at("grid.resolution_x")), 3);
  EXPECT_LT(std::stod(stats.at("cache.max_voxel_triangles")), 60000 / 2);
  EXPECT_LT(std::stod(stats.at("cache.created_per_unique")), 20);  // 1,400 on the coarse grid
  relief::test::ImageDiff d =
      relief::test::compareImages((dir / "tight.png").string(), (dir / "full.png").string(), 0.0f);
  ASSERT_TRUE(d.loaded) << d.error;
  EXPECT_EQ(d.failingPixels, 0);
}

TEST(Stats, HumanReadableStatsShowTheSameKeys) {
  const fs::path dir = scratchDir(), log = dir / "stats.txt";
  ASSERT_EQ(runCommand(kRelief + " " + kSphereScene + " --quiet --resolution 32x24 --stats -o " +
                           (dir / "s.png").string(),
                       log),
            0);
  const std::string text = readFile(log);
  for (const char* key : kRequiredKeys) EXPECT_NE(text.find(key), std::string::npos) << key;
}

}  // namespace
