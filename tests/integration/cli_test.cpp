// End-to-end tests of the executables: reliefc's exit codes and clang-style diagnostics, and relief
// rendering the default example scene against a stored reference image, deterministically across
// orders and thread counts, and refusing bad input without writing an image; the command-line
// experience (help, version, progress, flags, RELIEF_SHADER_PATH precedence, AOV displays), and
// RIB files with several frames.
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include "image_compare.h"
#include "scratch_dir.h"

namespace fs = std::filesystem;

namespace {

struct RunResult {
  int exitCode = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};

std::string readFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

fs::path scratchDir() { return relief::test::scratchDir("relief-it"); }

// Runs a shell command line with stdout and stderr captured separately.
RunResult run(const std::string& command) {
  const fs::path dir = scratchDir();
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string line = command + " >" + out.string() + " 2>" + err.string() + " </dev/null";
  const int status = std::system(line.c_str());
  RunResult r;
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = readFile(out);
  r.err = readFile(err);
  return r;
}

fs::path writeFile(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

const std::string kSource = RELIEF_SOURCE_DIR;
const std::string kRelief = RELIEF_BIN;
const std::string kReliefc = RELIEFC_BIN;
const std::string kSphereScene = kSource + "/examples/scenes/sphere.rib";
const std::string kShaders = kSource + "/examples/shaders";

TEST(Reliefc, AcceptsTheExampleShader) {
  RunResult r = run(kReliefc + " " + kShaders + "/bumps.disp");
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err, "");
}

TEST(Reliefc, ReportsAnErrorWithLocationSourceLineAndCaret) {
  const fs::path file = writeFile(scratchDir() / "broken.disp",
                                  "displacement broken(float Km = 0.1)\n"
                                  "{\n"
                                  "    P += N * Kn;\n"
                                  "}\n");
  RunResult r = run(kReliefc + " " + file.string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find(file.string() + ":3:14: error: use of undeclared identifier 'Kn'\n"
                                       "    P += N * Kn;\n"
                                       "             ^~\n"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("1 error generated."), std::string::npos) << r.err;
}

TEST(Reliefc, ReportsSeveralErrorsInOneRun) {
  const fs::path file = writeFile(scratchDir() / "two.disp",
                                  "displacement two(float Km = 0.1)\n"
                                  "{\n"
                                  "    float a = Km * ;\n"
                                  "    P += N * b;\n"
                                  "}\n");
  RunResult r = run(kReliefc + " " + file.string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find(":3:20: error:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(":4:14: error: use of undeclared identifier 'b'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("2 errors generated."), std::string::npos) << r.err;
}

TEST(Reliefc, MissingInputIsAUsageError) {
  RunResult r = run(kReliefc + " /nonexistent/nothing.disp");
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("nothing.disp"), std::string::npos) << r.err;
}

// The reference image test. Tolerance: a pixel fails when a channel differs by more than 2% of
// full scale; at most 0.5% of the pixels may fail (documented in docs/testing.md). Regenerate the
// reference with RELIEF_UPDATE_REFERENCE=1 and look at it before committing.
TEST(Relief, RendersTheDefaultSceneLikeTheReference) {
  const fs::path image = scratchDir() / "sphere.png";
  const std::string reference = kSource + "/tests/images/sphere_160x120.png";
  RunResult r = run(kRelief + " " + kSphereScene + " --quiet --resolution 160x120 -o " +
                    image.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  ASSERT_TRUE(fs::exists(image));
  if (std::getenv("RELIEF_UPDATE_REFERENCE")) fs::copy_file(image, reference, fs::copy_options::overwrite_existing);
  relief::test::ImageDiff d = relief::test::compareImages(image.string(), reference, 0.02f);
  ASSERT_TRUE(d.loaded) << d.error;
  EXPECT_LE(d.failFraction, 0.005) << d.failingPixels << " pixels differ; max " << d.maxDifference;
}

TEST(Relief, ImageIsIdenticalAcrossOrdersAndThreads) {
  const fs::path dir = scratchDir();
  const std::string base = kRelief + " " + kSphereScene + " --quiet --resolution 96x72";
  const std::string a = (dir / "a.png").string(), b = (dir / "b.png").string(),
                    c = (dir / "c.png").string();
  ASSERT_EQ(run(base + " --order hilbert --threads 1 -o " + a).exitCode, 0);
  ASSERT_EQ(run(base + " --order scanline --threads 2 -o " + b).exitCode, 0);
  ASSERT_EQ(run(base + " --order bucket --threads 2 -o " + c).exitCode, 0);
  for (const std::string& other : {b, c}) {
    relief::test::ImageDiff d = relief::test::compareImages(other, a, 0.0f);
    ASSERT_TRUE(d.loaded) << d.error;
    EXPECT_EQ(d.failingPixels, 0) << other;
  }
}

// language.md §5: the shader's output N is the shading normal. A bump-only shader (N bent, P kept)
// changes the shading, not the silhouette, and stays deterministic across threads and budgets; a
// shader that only recomputes the surface's own normal shades like the micro-triangles.
TEST(Relief, BumpOnlyShadersShadeWithTheirNormal) {
  const fs::path dir = scratchDir();
  writeFile(dir / "bumponly.disp",
            "displacement bumponly(float Km = 0.05; float freq = 12) {\n"
            "  N = normalize(calculatenormal(P + Km * noise(P * freq) * normalize(N)));\n"
            "}\n");
  writeFile(dir / "flat.disp", "displacement flat(float Km = 0.05; float freq = 12) { P += 0 * Km * freq * N; }\n");
  writeFile(dir / "renormal.disp",
            "displacement renormal(float Km = 0.05; float freq = 12) {\n"
            "  P += 0 * Km * freq * N;\n"
            "  N = normalize(calculatenormal(P));\n"
            "}\n");
  const std::string sphere = readFile(kSphereScene);
  const size_t at = sphere.find("Displacement \"");
  ASSERT_NE(at, std::string::npos);
  const size_t nameEnd = sphere.find('"', at + 14);
  auto sceneWith = [&](const std::string& shader) {
    return writeFile(dir / (shader + ".rib"), sphere.substr(0, at + 14) + shader + sphere.substr(nameEnd));
  };
  const std::string base = " --quiet --resolution 96x72 -I " + dir.string() + " -I " + kSource + "/examples/shaders";
  auto render = [&](const std::string& shader, const std::string& extra) {
    const std::string image = (dir / (shader + std::to_string(extra.size()) + ".png")).string();
    const RunResult r = run(kRelief + " " + sceneWith(shader).string() + base + extra + " -o " + image);
    EXPECT_EQ(r.exitCode, 0) << r.err;
    return image;
  };
  const std::string bumped = render("bumponly", " --threads 1");
  const std::string flat = render("flat", " --threads 1");
  relief::test::ImageDiff d = relief::test::compareImages(bumped, flat, 0.02f);
  ASSERT_TRUE(d.loaded) << d.error;
  EXPECT_GT(d.failingPixels, 500) << "the bump is not shaded";
  d = relief::test::compareImages(render("renormal", " --threads 1"), flat, 0.0f);
  EXPECT_EQ(d.failingPixels, 0);
  for (const std::string extra : {" --threads 2", " --threads 2 --cache-triangles 3000 --order scanline"}) {
    d = relief::test::compareImages(render("bumponly", extra), bumped, 0.0f);
    ASSERT_TRUE(d.loaded) << d.error;
    EXPECT_EQ(d.failingPixels, 0) << extra;
  }
  // Given normals opposite the winding define the outside, bumped or not: the bent N is lit
  // from the camera's side like the undisplaced quad, not turned away into black.
  writeFile(dir / "tilt.disp", "displacement tilt(float Km = 0.2) { N = normalize(normalize(N) + Km * (vector noise(P * 8) - 0.5)); }\n");
  const std::string quad =
      "Format 16 12 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\nWorldBegin\n"
      "LightSource \"distantlight\" 1 \"from\" [0 0 -1] \"to\" [0 0 0]\n"
      "Attribute \"displacementbound\" \"float sphere\" [0.06]\nAttribute \"relief\" \"float edgelength\" [0.5]\n";
  const std::string patch = "PointsPolygons [4] [0 1 2 3] \"P\" [-1 -1 0  -1 1 0  1 1 0  1 -1 0] \"N\" [0 0 1  0 0 1  0 0 1  0 0 1]\nWorldEnd\n";
  auto centre = [&](const std::string& name, const std::string& scene) {
    const std::string image = (dir / (name + ".ppm")).string();
    const RunResult r = run(kRelief + " " + writeFile(dir / (name + ".rib"), scene).string() + " --quiet -I " +
                            dir.string() + " -o " + image);
    EXPECT_EQ(r.exitCode, 0) << r.err;
    const std::string ppm = readFile(image);
    return ppm.size() > 3 ? static_cast<unsigned char>(ppm[ppm.size() - 3 * (6 * 16 + 8) - 2]) : 0;  // a centre pixel's green
  };
  EXPECT_GT(centre("plain", quad + patch), 100);
  EXPECT_GT(centre("tilted", quad + "Displacement \"tilt\"\n" + patch), 100);
}

// A scene without lights renders black matte surfaces (RenderMan's default surface would need no
// light): relief says so. A main Display that -o replaces gets no warning about its name.
TEST(Relief, SceneWithoutLightsAndReplacedDisplayName) {
  const fs::path dir = scratchDir();
  const fs::path scene = writeFile(dir / "dark.rib",
                                   "Format 16 12 1\nDisplay \"RenderMan\" \"framebuffer\" \"rgb\"\n"
                                   "WorldBegin\nTranslate 0 0 5\nSphere 1 -1 1 360\nWorldEnd\n");
  RunResult r = run(kRelief + " " + scene.string() + " -o " + (dir / "dark.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find(scene.string() + ": warning: the scene has no LightSource"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("no image extension"), std::string::npos) << r.err;
  // Lights that are all unsupported: it is not that the scene has none.
  const fs::path spot = writeFile(dir / "spot.rib",
                                  "Format 16 12 1\nWorldBegin\nLightSource \"shadowspot\" 1\n"
                                  "Translate 0 0 5\nSphere 1 -1 1 360\nWorldEnd\n");
  r = run(kRelief + " " + spot.string() + " -o " + (dir / "spot.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err.find("has no LightSource"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("light source 'shadowspot' is not supported"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(spot.string() + ": warning: none of the scene's light sources is one Relief renders"),
            std::string::npos)
      << r.err;
  // Lit, or only constant surfaces: nothing to say.
  for (const auto& [name, world] : {std::pair<std::string, std::string>{"lit", "LightSource \"ambientlight\" 1\n"},
                                    {"constant", "Surface \"constant\"\n"}}) {
    const fs::path quiet = writeFile(dir / (name + ".rib"), "Format 16 12 1\nWorldBegin\n" + world +
                                                                "Translate 0 0 5\nSphere 1 -1 1 360\nWorldEnd\n");
    r = run(kRelief + " " + quiet.string() + " -o " + (dir / (name + ".png")).string());
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(r.err.find("LightSource"), std::string::npos) << name << ": " << r.err;
  }
}

// The default edge length is in world units: a scene modelled in large units asks for hundreds of
// millions of micro-triangles without saying so. relief warns at the Displacement, naming the
// setting (the sphere is behind the camera, so nothing is subdivided here).
TEST(Relief, ManyMicroTrianglesAreAWarningNamingTheEdgeLength) {
  const fs::path dir = scratchDir();
  const fs::path scene = writeFile(dir / "big.rib",
                                   "Format 8 6 1\nProjection \"perspective\" \"fov\" [40]\nWorldBegin\n"
                                   "LightSource \"distantlight\" 1\n"
                                   "Attribute \"displacementbound\" \"float sphere\" [5]\n"
                                   "Displacement \"bumps\" \"float Km\" [5]\n"
                                   "Translate 0 0 -400\nSphere 100 -100 100 360\nWorldEnd\n");
  const std::string base = kRelief + " " + scene.string() + " -I " + kSource + "/examples/shaders -o " +
                           (dir / "big.png").string();
  RunResult r = run(base);
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find(scene.string() + ":6: warning: displacement shader 'bumps': an edge length of 0.05 "
                                         "(world units) asks for about"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("Attribute \"relief\" \"float edgelength\" sets it"), std::string::npos) << r.err;
  r = run(base + " --edge-length 2");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err.find("micro-triangles"), std::string::npos) << r.err;
}

// A scene smaller than the warning's absolute threshold still warns when it asks for far more
// micro-triangles than its image has pixels; and running out of memory in the fills is an error at
// the scene naming the Displacement that asks for the most, on any thread (it terminated the
// process from a second thread, and was an unlocated 'std::bad_alloc' from the first).
TEST(Relief, RunningOutOfMemoryNamesTheDisplacement) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizers reserve more address space than the limit this test sets";
#else
  const fs::path dir = scratchDir();
  const fs::path scene = writeFile(dir / "plane.rib",
                                   "Format 16 12 1\nProjection \"perspective\" \"fov\" [40]\n"
                                   "Translate 0 0 240\nRotate -30 1 0 0\nWorldBegin\n"
                                   "LightSource \"distantlight\" 1 \"from\" [0 1 0] \"to\" [0 0 0]\n"
                                   "Attribute \"displacementbound\" \"sphere\" [5]\n"
                                   "Displacement \"bumps\" \"Km\" 5 \"freq\" 10\n"
                                   "Patch \"bilinear\" \"P\" [-200 0 -200  200 0 -200  -200 0 200  200 0 200]\n"
                                   "WorldEnd\n");
  // Asked for in so many words: an unlimited cache and a side cache big enough to keep the
  // plane's two whole subdivisions (16.8M micro-triangles each), so the fills run out of memory.
  RunResult r = run("ulimit -v 1000000; " + kRelief + " " + scene.string() + " -I " + kSource +
                    "/examples/shaders --threads 2 --cache-triangles unlimited --side-cache 1000000000 -o " +
                    (dir / "plane.png").string());
  EXPECT_EQ(r.exitCode, 1) << r.err;
  EXPECT_NE(r.err.find(scene.string() + ":8: warning: displacement shader 'bumps': an edge length of 0.05 "
                                         "(world units) asks for about 3.4e+07"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find(scene.string() + ": error: out of memory while rendering\n" + scene.string() +
                       ":8: note: displacement shader 'bumps' asks for about 3.4e+07 micro-triangles"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "plane.png"));
  // With no budget given, a scene asking for more than half the memory holds (here the address
  // space, 1,000,000 KiB: 10.7M triangles at 48 bytes) gets that budget and renders (a few pixels,
  // so fast).
  r = run("ulimit -v 1000000; " + kRelief + " " + scene.string() + " -I " + kSource +
          "/examples/shaders --threads 2 --resolution 4x3 -o " + (dir / "small.png").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find(scene.string() + ": warning: the displacements ask for about 3.4e+07 micro-triangles, "
                                         "more than half the memory holds; the cache keeps at most 1.1e+07"),
            std::string::npos)
      << r.err;
  EXPECT_TRUE(fs::exists(dir / "small.png"));
#endif
}

TEST(Relief, MissingSceneIsAnErrorNamingTheFile) {
  const fs::path image = scratchDir() / "none.png";
  RunResult r = run(kRelief + " /nonexistent/scene.rib --quiet -o " + image.string());
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.err.find("/nonexistent/scene.rib"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(image));
}

TEST(Relief, BrokenShaderStopsTheRenderWithoutAnImage) {
  const fs::path dir = scratchDir();
  writeFile(dir / "oops.disp", "displacement oops(float Km = 0.1)\n{\n    P += N * Kn;\n}\n");
  writeFile(dir / "scene.rib",
            "Format 32 24 1\n"
            "Projection \"perspective\" \"fov\" [40]\n"
            "Translate 0 0 5\n"
            "WorldBegin\n"
            "LightSource \"distantlight\" 1\n"
            "Attribute \"displacementbound\" \"float sphere\" [0.1]\n"
            "Displacement \"oops\"\n"
            "Sphere 1 -1 1 360\n"
            "WorldEnd\n");
  const fs::path image = dir / "oops.png";
  RunResult r = run(kRelief + " " + (dir / "scene.rib").string() + " --quiet -I " + dir.string() +
                    " -o " + image.string());
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.err.find("oops.disp:3:14: error: use of undeclared identifier 'Kn'"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("scene.rib:7"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(image));
}

// relief compiles shaders with a reliefc child process (tools/shader_process.h): one it cannot
// run, or one that returns something else than a shader bundle, is an error at the Displacement.
TEST(Relief, AShaderCompilerThatCannotRunIsAnErrorAtTheDisplacement) {
  const fs::path dir = scratchDir();
  const std::string scene = kSource + "/examples/scenes/sphere.rib";
  RunResult r = run("RELIEF_COMPILER=/nonexistent/reliefc " + kRelief + " " + scene + " --quiet -o " +
                    (dir / "a.png").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("sphere.rib:19: error: cannot load displacement shader 'bumps': cannot run the shader "
                       "compiler '/nonexistent/reliefc': No such file or directory"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "a.png"));
  r = run("RELIEF_COMPILER=/bin/echo " + kRelief + " " + scene + " --quiet -o " + (dir / "b.png").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("sphere.rib:19: error: cannot load displacement shader 'bumps': cannot load the code "
                       "reliefc compiled from"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "b.png"));
}

// RI Exposure: colour becomes (colour * gain)^(1/gamma), and a gamma other than 1 replaces the
// sRGB encoding of 8-bit outputs; a PGM holds the luminance, not the red channel.
TEST(Relief, ExposureAndGreyPgm) {
  const fs::path dir = scratchDir();
  auto scene = [&](const std::string& name, const std::string& exposure) {
    return writeFile(dir / name, "Format 4 4 1\n" + exposure +
                                     "Projection \"orthographic\"\nWorldBegin\nSurface \"constant\"\n"
                                     "Color [1 0 0]\nPolygon \"P\" [-5 -5 2  5 -5 2  5 5 2  -5 5 2]\nWorldEnd\n");
  };
  auto firstPixel = [&](const fs::path& rib, const std::string& out, std::string* header) {
    const RunResult r = run(kRelief + " " + rib.string() + " --quiet -o " + (dir / out).string());
    EXPECT_EQ(r.exitCode, 0) << r.err;
    std::ifstream in(dir / out, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    *header = bytes.substr(0, 11);
    return bytes.size() > 11 ? int(static_cast<unsigned char>(bytes[11])) : -1;
  };
  std::string header;
  // Luminance of linear red, 0.2126, sRGB-encoded: 127.
  EXPECT_EQ(firstPixel(scene("plain.rib", ""), "plain.pgm", &header), 127);
  EXPECT_EQ(header, "P5\n4 4\n255\n");
  // Red 1 * 2 = 2, to the power 1/2.2 = 1.370, then luminance 0.291 without sRGB: 74.
  EXPECT_EQ(firstPixel(scene("exposed.rib", "Exposure 2 2.2\n"), "exposed.pgm", &header), 74);
  EXPECT_EQ(firstPixel(scene("exposed.rib", "Exposure 2 2.2\n"), "exposed.ppm", &header), 255);
  EXPECT_EQ(header, "P6\n4 4\n255\n");
  // A PNG says how its values were encoded: gAMA 1/2.2 (45455), no sRGB chunk (it had said gamma
  // 1, and colour-managed viewers brightened the image a second time).
  auto pngChunks = [&](const std::string& out) {
    EXPECT_EQ(run(kRelief + " " + scene("exposed.rib", "Exposure 2 2.2\n").string() + " --quiet -o " + (dir / out).string()).exitCode, 0);
    std::ifstream in(dir / out, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string png = pngChunks("exposed.png");
  const size_t gama = png.find("gAMA");
  ASSERT_NE(gama, std::string::npos);
  EXPECT_EQ(png.substr(gama + 4, 4), std::string("\x00\x00\xb1\x8f", 4));  // 45455
  EXPECT_EQ(png.find("sRGB"), std::string::npos);
  const RunResult bad = run(kRelief + " " + scene("bad.rib", "Exposure 1 0\n").string() + " --quiet -o " +
                            (dir / "bad.png").string());
  EXPECT_EQ(bad.exitCode, 1);
  EXPECT_NE(bad.err.find("bad.rib:2: error: 'Exposure' expects a gain of 0 or more and a gamma above 0"),
            std::string::npos)
      << bad.err;
}

TEST(Relief, MalformedSceneReportsFileAndLine) {
  const fs::path dir = scratchDir();
  writeFile(dir / "bad.rib", "Format 32 24 1\nWorldBegin\nSphere 1 -1 \"x\" 360\nWorldEnd\n");
  const fs::path image = dir / "bad.png";
  RunResult r = run(kRelief + " " + (dir / "bad.rib").string() + " --quiet -o " + image.string());
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.err.find("bad.rib:3:"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(image));
}

// The issue's bad inputs through the command line: each is `file:line: error:` naming what is
// missing, a non-zero exit, and no image (the reader tests check the messages in detail).
TEST(Relief, BadInputsAreFileAndLineErrorsWithoutAnImage) {
  const fs::path dir = scratchDir();
  const std::string head =
      "Format 32 24 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\nWorldBegin\n"
      "LightSource \"distantlight\" 1\n";
  struct Case {
    const char* name;
    std::string text;
    const char* where;  // expected "file:line" suffix
    const char* what;   // expected part of the message
  };
  const Case cases[] = {
      {"noshader", head + "Attribute \"displacementbound\" \"float sphere\" [0.1]\n"
                          "Displacement \"nosuchshader\"\nSphere 1 -1 1 360\nWorldEnd\n",
       ".rib:7: error:", "nosuchshader"},
      {"nomesh", head + "Geometry \"objmesh\" \"string filename\" [\"nosuchmesh.obj\"]\nWorldEnd\n",
       ".rib:6: error:", "nosuchmesh.obj"},
      {"truncated", head + "Sphere 1 -1 1 360\nAttributeBegin\n", ".rib:", "error:"},
      {"wrongtype", head + "Surface \"plastic\" \"float Ks\" [\"shiny\"]\nSphere 1 -1 1 360\nWorldEnd\n",
       ".rib:6: error:", "'Ks'"},
  };
  for (const Case& c : cases) {
    const fs::path scene = writeFile(dir / (std::string(c.name) + ".rib"), c.text);
    const fs::path image = dir / (std::string(c.name) + ".png");
    RunResult r = run(kRelief + " " + scene.string() + " --quiet -o " + image.string());
    EXPECT_NE(r.exitCode, 0) << c.name;
    EXPECT_NE(r.err.find(std::string(c.name) + c.where), std::string::npos) << c.name << ": " << r.err;
    EXPECT_NE(r.err.find(c.what), std::string::npos) << c.name << ": " << r.err;
    EXPECT_FALSE(fs::exists(image)) << c.name;
  }
}

TEST(Relief, HelpListsEveryOptionAndTheEnvironment) {
  RunResult r = run(kRelief + " --help");
  EXPECT_EQ(r.exitCode, 0);
  for (const char* option :
       {"-I", "-o ", "--resolution", "--spp", "--threads", "--order", "--max-depth", "--filter",
        "blackman-harris", "--cache-triangles", "--no-displacement", "--stats", "--stats-json",
        "--quiet", "--help", "--version", "RELIEF_SHADER_PATH", "cachemiss", "exit status",
        "--frame", "out.0001.png", "--print-limit", "RELIEF_COMPILER"})
    EXPECT_NE(r.out.find(option), std::string::npos) << option;
}

TEST(Relief, VersionIsPrinted) {
  RunResult r = run(kRelief + " --version");
  EXPECT_EQ(r.exitCode, 0);
  EXPECT_EQ(r.out.rfind("relief ", 0), 0u) << r.out;
}

TEST(Relief, BadFlagValuesAreUsageErrors) {
  for (const char* flags : {"--filter mitchell", "--max-depth -1", "--max-depth x", "--order zigzag",
                            "--spp 0", "--frobnicate", "--print-limit -1", "--print-limit x"}) {
    RunResult r = run(kRelief + " " + kSphereScene + " " + flags);
    EXPECT_EQ(r.exitCode, 2) << flags;
    EXPECT_NE(r.err.find("relief: error:"), std::string::npos) << flags << ": " << r.err;
  }
  // A shader given where the scene goes is said to be one, not lexed as RIB.
  {
    RunResult r = run(kRelief + " " + kShaders + "/bumps.disp");
    EXPECT_EQ(r.exitCode, 2);
    EXPECT_NE(r.err.find("bumps.disp' is a shader: relief renders a RIB scene that names it (Displacement \"bumps\")"),
              std::string::npos)
        << r.err;
  }
  // Options that cannot take effect warn, and --quiet silences that like any warning.
  const fs::path dir = scratchDir();
  const std::string base = kRelief + " " + kSphereScene + " --resolution 8x6 -o " + (dir / "w.png").string();
  RunResult r = run(base + " -I " + (dir / "nowhere").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("relief: warning: shader directory '" + (dir / "nowhere").string() + "' does not exist"),
            std::string::npos)
      << r.err;
  r = run(base + " -q -I " + (dir / "nowhere").string());
  EXPECT_EQ(r.err, "");
}

// RIB piped in as "-" (as PRMan and 3Delight read it), named <stdin> in messages, with relative
// paths from the working directory; options also take GNU-style "--name=value".
TEST(Relief, ReadsTheSceneFromStandardInputAndNameEqualsValueOptions) {
  const fs::path dir = scratchDir();
  writeFile(dir / "piped.rib",
            "Format 16 12 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\nWorldBegin\n"
            "LightSource \"distantlight\" 1\nAttribute \"displacementbound\" \"float sphere\" [0.1]\n"
            "Displacement \"bumps\"\nSphere 1 -1 1 360\nWorldEnd\n");
  const std::string image = (dir / "piped.png").string();
  // In a subshell: run() gives the command line's own standard input /dev/null.
  RunResult r = run("(cat " + (dir / "piped.rib").string() + " | " + kRelief + " - --quiet --shader-path=" + kShaders +
                    " --resolution=8x6 -o " + image + ")");
  EXPECT_EQ(r.exitCode, 0) << r.err;
  {
    auto in = OIIO::ImageInput::open(image);  // --resolution=8x6 took its value
    ASSERT_TRUE(in) << r.err;
    EXPECT_EQ(in->spec().width, 8);
    EXPECT_EQ(in->spec().height, 6);
  }
  // Its directory is the working directory's: the shader is not found without the flag, and the
  // error is located in <stdin>.
  r = run("(cd " + dir.string() + " && cat piped.rib | env -u RELIEF_SHADER_PATH " + kRelief + " - --quiet -o " +
          image + ")");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("<stdin>:7: error: cannot load displacement shader 'bumps'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("in the search path ('.')"), std::string::npos) << r.err;
  // A flag that takes no value refuses one.
  r = run(kRelief + " " + kSphereScene + " --stats=yes");
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("'--stats' takes no value (given '--stats=yes')"), std::string::npos) << r.err;
}

// gzip-compressed scenes and archives (.rib.gz) are read as PRMan and 3Delight read them; a
// damaged one is an error naming the file, not "binary RIB".
TEST(Relief, ReadsGzipCompressedScenesAndArchives) {
  const fs::path dir = scratchDir();
  writeFile(dir / "part.rib", "Sphere 1 -1 1 360\n");
  writeFile(dir / "plain.rib",
            "Format 16 12 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\nWorldBegin\n"
            "LightSource \"distantlight\" 1\nReadArchive \"part.rib.gz\"\nWorldEnd\n");
  ASSERT_EQ(run("gzip -kf " + (dir / "part.rib").string() + " " + (dir / "plain.rib").string()).exitCode, 0);
  RunResult r = run(kRelief + " " + (dir / "plain.rib.gz").string() + " --quiet -o " + (dir / "gz.png").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  r = run(kRelief + " " + (dir / "plain.rib").string() + " --quiet -o " + (dir / "plain.png").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  // The same pixels (the files differ only in the scene name they record).
  const relief::test::ImageDiff diff =
      relief::test::compareImages((dir / "gz.png").string(), (dir / "plain.png").string(), 0.0f);
  ASSERT_TRUE(diff.loaded) << diff.error;
  EXPECT_EQ(diff.maxDifference, 0.0);
  // And the archive's sphere is in them.
  writeFile(dir / "empty.rib",
            "Format 16 12 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\nWorldBegin\n"
            "LightSource \"distantlight\" 1\nWorldEnd\n");
  r = run(kRelief + " " + (dir / "empty.rib").string() + " --quiet -o " + (dir / "empty.png").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_GT(relief::test::compareImages((dir / "gz.png").string(), (dir / "empty.png").string(), 0.0f).maxDifference,
            0.1);
  const std::string whole = readFile(dir / "plain.rib.gz");
  // Members one after another are one file, as zcat reads them.
  const std::string plainText = readFile(dir / "plain.rib");
  const size_t split = plainText.find("WorldBegin");
  writeFile(dir / "head.rib", plainText.substr(0, split));
  writeFile(dir / "tail.rib", plainText.substr(split));
  ASSERT_EQ(run("gzip -kf " + (dir / "head.rib").string() + " " + (dir / "tail.rib").string()).exitCode, 0);
  writeFile(dir / "two.rib.gz", readFile(dir / "head.rib.gz") + readFile(dir / "tail.rib.gz"));
  r = run(kRelief + " " + (dir / "two.rib.gz").string() + " --quiet -o " + (dir / "two.png").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(relief::test::compareImages((dir / "two.png").string(), (dir / "plain.png").string(), 0.0f).maxDifference,
            0.0);
  // Anything else after the stream is damage, not dropped without a word.
  writeFile(dir / "junk.rib.gz", whole + "garbage");
  r = run(kRelief + " " + (dir / "junk.rib.gz").string() + " --quiet -o " + (dir / "junk.png").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("has 7 bytes of trailing data after its stream"), std::string::npos) << r.err;
  writeFile(dir / "cut.rib.gz", whole.substr(0, whole.size() / 2));
  r = run(kRelief + " " + (dir / "cut.rib.gz").string() + " --quiet -o " + (dir / "cut.png").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("cut.rib.gz: error: the gzip-compressed scene is damaged or truncated"), std::string::npos)
      << r.err;
}

// A tiny scene with one distant light and a plane; `extra` goes inside the world.
fs::path smallScene(const fs::path& dir, const std::string& displays, const std::string& extra = "") {
  return writeFile(dir / "small.rib",
                   "Format 16 12 1\n" + displays +
                       "Projection \"perspective\" \"fov\" [40]\n"
                       "Translate 0 0 5\n"
                       "WorldBegin\n"
                       "LightSource \"distantlight\" 1 \"from\" [0 0 -1] \"to\" [0 0 0]\n" +
                       extra +
                       "Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]\n"
                       "WorldEnd\n");
}

// smallScene with its square displaced by `call` (a Displacement line), under a displacement bound
// of `bound` world units and a coarse edge length. The Displacement call is line 8.
fs::path displacedScene(const fs::path& dir, const std::string& bound, const std::string& call) {
  return smallScene(dir, "",
                    "Attribute \"displacementbound\" \"float sphere\" [" + bound + "]\n"
                    "Attribute \"relief\" \"float edgelength\" [0.5]\n" + call + "\n");
}

// Where the warning starting with `prefix` is in `err` (npos if absent), after checking that it is
// the only one: relief warns once per Displacement, however many points went wrong.
size_t onlyWarning(const std::string& err, const std::string& prefix) {
  const size_t at = err.find(prefix);
  if (at != std::string::npos) {
    EXPECT_EQ(err.find(prefix, at + 1), std::string::npos) << err;  // once
  }
  return at;
}

TEST(Relief, PlainProgressLinesWhenNotATerminalAndNoneWhenQuiet) {
  const fs::path dir = scratchDir();
  const fs::path scene = smallScene(dir, "");
  RunResult r = run(kRelief + " " + scene.string() + " -o " + (dir / "a.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("rendering 100%"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find('\r'), std::string::npos);  // no terminal redraws in a log
  EXPECT_NE(r.err.find("ETA"), std::string::npos) << r.err;
  r = run(kRelief + " " + scene.string() + " --quiet -o " + (dir / "b.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(r.out, (dir / "b.png").string() + "\n");
}

TEST(Relief, FiltersAndDepthFlagsRender) {
  const fs::path dir = scratchDir();
  const fs::path scene = smallScene(dir, "PixelSamples 2 2\n");
  for (const char* flags : {"--filter box", "--filter blackman-harris", "--max-depth 0"}) {
    const fs::path image = dir / "f.exr";
    RunResult r = run(kRelief + " " + scene.string() + " --quiet " + flags + " -o " + image.string());
    EXPECT_EQ(r.exitCode, 0) << flags << ": " << r.err;
    EXPECT_TRUE(fs::exists(image)) << flags;
    fs::remove(image);
  }
}

// PNG output is Relief's own: a scene without textures renders to PNG even when OpenImageIO's
// plugin cannot be loaded (so it is never loaded), and a format that needs it fails with the reason.
TEST(Relief, PngNeedsNoImageLibraryOtherFormatsSayWhyTheyFail) {
  const fs::path dir = scratchDir();
  const fs::path scene = smallScene(dir, "");
  const std::string noLibrary = "RELIEF_IMAGE_LIBRARY=" + (dir / "missing.so").string() + " ";
  RunResult png = run(noLibrary + kRelief + " " + scene.string() + " --quiet -o " + (dir / "a.png").string());
  EXPECT_EQ(png.exitCode, 0) << png.err;
  EXPECT_TRUE(fs::exists(dir / "a.png"));
  RunResult exr = run(noLibrary + kRelief + " " + scene.string() + " --quiet -o " + (dir / "a.exr").string());
  EXPECT_NE(exr.exitCode, 0);
  EXPECT_NE(exr.err.find("cannot write '" + (dir / "a.exr").string() + "': cannot load the image library"),
            std::string::npos)
      << exr.err;
  EXPECT_NE(exr.err.find("missing.so"), std::string::npos) << exr.err;
  EXPECT_FALSE(fs::exists(dir / "a.exr"));
}

TEST(Relief, ExrHasRenderMetadata) {
  const fs::path dir = scratchDir();
  const fs::path scene = smallScene(dir, "");
  const fs::path image = dir / "m.exr";
  RunResult r = run(kRelief + " " + scene.string() + " --quiet -o " + image.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  auto in = OIIO::ImageInput::open(image.string());
  ASSERT_TRUE(in);
  const OIIO::ImageSpec& spec = in->spec();
  EXPECT_EQ(spec.get_string_attribute("relief:scene"), scene.string());
  EXPECT_FALSE(spec.get_string_attribute("relief:version").empty());
  EXPECT_FALSE(spec.get_string_attribute("relief:renderSeconds").empty());
  EXPECT_FALSE(spec.get_string_attribute("relief:cacheAccesses").empty());
  EXPECT_EQ(spec.format, OIIO::TypeDesc::FLOAT);
  EXPECT_FLOAT_EQ(spec.get_float_attribute("PixelAspectRatio", 1.0f), 1.0f);
  // Format's pixel aspect ratio is recorded as the format's own (it was always 1).
  writeFile(scene, "Format 16 12 2\n" + readFile(scene).substr(std::string("Format 16 12 1\n").size()));
  r = run(kRelief + " " + scene.string() + " --quiet -o " + image.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  in = OIIO::ImageInput::open(image.string());
  ASSERT_TRUE(in);
  EXPECT_FLOAT_EQ(in->spec().get_float_attribute("PixelAspectRatio", 1.0f), 2.0f);
}

// RenderMan's "rgbaz" and "az" modes add a Z channel (camera depth, as the "z" AOV), "a" writes
// coverage alone; a depth channel in an 8-bit format is refused before the render.
TEST(Relief, DisplayModesWithDepthAndAlphaAlone) {
  const fs::path dir = scratchDir();
  const fs::path scene =
      smallScene(dir, "Display \"" + (dir / "c.exr").string() + "\" \"file\" \"rgbaz\"\n" +
                          "Display \"+" + (dir / "z.exr").string() + "\" \"file\" \"z\"\n" +
                          "Display \"+" + (dir / "az.exr").string() + "\" \"file\" \"az\"\n" +
                          "Display \"+" + (dir / "a.png").string() + "\" \"file\" \"a\"\n");
  RunResult r = run(kRelief + " " + scene.string() + " --quiet");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  auto read = [](const fs::path& path, std::vector<float>* pixels) {
    auto in = OIIO::ImageInput::open(path.string());
    if (!in) return OIIO::ImageSpec();
    OIIO::ImageSpec spec = in->spec();
    pixels->resize(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels));
    in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels->data());
    return spec;
  };
  std::vector<float> c, z, az, a;
  const OIIO::ImageSpec cs = read(dir / "c.exr", &c), zs = read(dir / "z.exr", &z);
  const OIIO::ImageSpec azs = read(dir / "az.exr", &az), as = read(dir / "a.png", &a);
  ASSERT_EQ(cs.nchannels, 5);
  EXPECT_EQ(cs.channelnames, (std::vector<std::string>{"R", "G", "B", "A", "Z"}));
  ASSERT_EQ(zs.nchannels, 1);
  ASSERT_EQ(azs.nchannels, 2);
  ASSERT_EQ(as.nchannels, 1);
  const size_t pixels = size_t(cs.width) * size_t(cs.height);
  int covered = 0;
  for (size_t i = 0; i < pixels; ++i) {
    EXPECT_EQ(c[5 * i + 4], z[i]);
    EXPECT_EQ(az[2 * i + 1], z[i]);
    EXPECT_EQ(az[2 * i], c[5 * i + 3]);
    EXPECT_NEAR(a[i], c[5 * i + 3], 0.5f / 255.0f);
    covered += c[5 * i + 3] > 0.0f;
  }
  EXPECT_GT(covered, 0);
  EXPECT_LT(covered, int(pixels));
  r = run(kRelief + " " + smallScene(dir, "Display \"" + (dir / "d.png").string() + "\" \"file\" \"rgbz\"\n").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("display mode 'rgbz' has a depth channel, which needs a float format"), std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "d.png"));
}

// RI CropWindow: the image written is the crop, and EXR records where it lies in the whole image
// (its data window); a window that covers no pixel or is reversed is an error.
TEST(Relief, CropWindowWritesTheCropWithItsDataWindow) {
  const fs::path dir = scratchDir();
  const fs::path scene = smallScene(dir, "CropWindow 0.25 0.75 0.5 1\n");
  const fs::path image = dir / "c.exr";
  RunResult r = run(kRelief + " " + scene.string() + " --quiet -o " + image.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  auto in = OIIO::ImageInput::open(image.string());
  ASSERT_TRUE(in);
  const OIIO::ImageSpec& spec = in->spec();
  EXPECT_EQ(spec.width, 8);
  EXPECT_EQ(spec.height, 6);
  EXPECT_EQ(spec.x, 4);
  EXPECT_EQ(spec.y, 6);
  EXPECT_EQ(spec.full_width, 16);
  EXPECT_EQ(spec.full_height, 12);
  r = run(kRelief + " " + smallScene(dir, "CropWindow 0.5 0.5 0 1\n").string() + " --quiet -o " + image.string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("small.rib:2: error: 'CropWindow' expects xmin < xmax"), std::string::npos) << r.err;
  r = run(kRelief + " " + smallScene(dir, "CropWindow 0.01 0.02 0 1\n").string() + " --quiet -o " + image.string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("small.rib:2: error: the 'CropWindow' covers no pixel of the 16x12 image"), std::string::npos)
      << r.err;
}

// -I directories come before RELIEF_SHADER_PATH, which comes before the scene's directory: a
// broken shader of the same name later in the path is never seen.
TEST(Relief, ShaderPathPrecedence) {
  const fs::path dir = scratchDir();
  fs::create_directories(dir / "good");
  fs::create_directories(dir / "bad");
  writeFile(dir / "good" / "bump.disp",
            "displacement bump(float Km = 0.01)\n{\n    P += Km * normalize(N);\n}\n");
  writeFile(dir / "bad" / "bump.disp", "displacement bump(float Km = 0.01)\n{\n    P += N * Kn;\n}\n");
  const fs::path scene = smallScene(
      dir, "", "Attribute \"displacementbound\" \"float sphere\" [0.01]\nDisplacement \"bump\"\n");
  const std::string image = " --quiet -o " + (dir / "p.png").string();
  const std::string good = (dir / "good").string(), bad = (dir / "bad").string();
  RunResult r = run("RELIEF_SHADER_PATH=" + good + " " + kRelief + " " + scene.string() + image);
  EXPECT_EQ(r.exitCode, 0) << r.err;  // found through the environment alone
  r = run("RELIEF_SHADER_PATH=" + bad + " " + kRelief + " " + scene.string() + " -I " + good + image);
  EXPECT_EQ(r.exitCode, 0) << r.err;  // -I wins
  r = run("RELIEF_SHADER_PATH=" + good + " " + kRelief + " " + scene.string() + " -I " + bad + image);
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("bad/bump.disp"), std::string::npos) << r.err;
  r = run("RELIEF_SHADER_PATH=/nonexistent:" + good + " " + kRelief + " " + scene.string() + image);
  EXPECT_EQ(r.exitCode, 0) << r.err;  // ':'-separated, missing directories skipped
  r = run("env -u RELIEF_SHADER_PATH " + kRelief + " " + scene.string() + image);
  EXPECT_EQ(r.exitCode, 1);  // nowhere to be found
}

// Display modes "z", "N" and "cachemiss" add AOV images next to the main one.
TEST(Relief, AovDisplaysAreWritten) {
  const fs::path dir = scratchDir();
  const std::string main = (dir / "main.png").string(), z = (dir / "z.exr").string(),
                    n = (dir / "n.exr").string(), heat = (dir / "heat.png").string();
  const fs::path scene = smallScene(dir, "Display \"" + main + "\" \"file\" \"rgb\"\n"
                                    "Display \"+" + z + "\" \"file\" \"z\"\n"
                                    "Display \"+" + n + "\" \"file\" \"N\"\n"
                                    "Display \"+" + heat + "\" \"file\" \"cachemiss\"\n");
  RunResult r = run(kRelief + " " + scene.string() + " --quiet");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  for (const std::string& f : {main, z, n, heat}) EXPECT_TRUE(fs::exists(f)) << f;
  auto in = OIIO::ImageInput::open(z);
  ASSERT_TRUE(in);
  ASSERT_EQ(in->spec().nchannels, 1);
  std::vector<float> depth(16 * 12);
  ASSERT_TRUE(in->read_image(0, 0, 0, 1, OIIO::TypeDesc::FLOAT, depth.data()));
  EXPECT_NEAR(depth[6 * 16 + 8], 5.0f, 1e-4f);  // the plane is 5 units in front of the camera
  EXPECT_EQ(depth[0], 0.0f);                    // a corner misses it
}

// With -o, relative AOV names follow the image into its directory.
TEST(Relief, RelativeAovsFollowTheOutputDirectory) {
  const fs::path dir = scratchDir();
  const fs::path scene = smallScene(dir, "Display \"main.png\" \"file\" \"rgb\"\n"
                                         "Display \"+depth.exr\" \"file\" \"z\"\n");
  fs::create_directories(dir / "out");
  RunResult r = run(kRelief + " " + scene.string() + " --quiet -o " + (dir / "out" / "x.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir / "out" / "x.png"));
  EXPECT_TRUE(fs::exists(dir / "out" / "depth.exr"));
  EXPECT_NE(r.out.find((dir / "out" / "depth.exr").string()), std::string::npos) << r.out;
}

// Texture names resolve along Option "searchpath" "texture" (relative to the scene); an unreadable
// texture is one runtime error naming the file, and the render goes on with the fill value.
TEST(Relief, TexturesFollowTheSearchPathAndAMissingOneIsOneError) {
  const fs::path dir = scratchDir();
  fs::create_directories(dir / "maps");
  {
    std::vector<float> white(8 * 8, 1.0f);
    auto out = OIIO::ImageOutput::create("bump.tif");
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open((dir / "maps" / "bump.tif").string(), OIIO::ImageSpec(8, 8, 1, OIIO::TypeDesc::FLOAT)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, white.data()));
    out->close();
  }
  writeFile(dir / "lift.disp",
            "displacement lift(string texname = \"\") {\n"
            "  P += 0.25 * float texture(texname, s, t, \"wrap\", \"periodic\") * normalize(N);\n"
            "  N = normalize(calculatenormal(P));\n}\n");
  auto sceneWith = [&](const std::string& name, const std::string& file) {
    return smallScene(dir, "Option \"searchpath\" \"string texture\" [\"maps\"]\n"
                           "Display \"" + name + ".png\" \"file\" \"rgb\"\n"
                           "Display \"+" + name + ".exr\" \"file\" \"z\"\n",
                      "Attribute \"displacementbound\" \"float sphere\" [0.25]\n"
                      "Attribute \"relief\" \"float edgelength\" [0.2]\n"
                      "Displacement \"lift\" \"string texname\" [\"" + file + "\"]\n");
  };
  auto centreDepth = [&](const fs::path& exr) {
    auto in = OIIO::ImageInput::open(exr.string());
    std::vector<float> depth(16 * 12, -1.0f);
    if (in) in->read_image(0, 0, 0, 1, OIIO::TypeDesc::FLOAT, depth.data());
    return depth[6 * 16 + 8];
  };
  RunResult r = run(kRelief + " " + sceneWith("found", "bump.tif").string() + " --quiet -o " +
                    (dir / "found.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err.find("texture"), std::string::npos) << r.err;
  EXPECT_NEAR(std::abs(centreDepth(dir / "found.exr") - 5.0f), 0.25f, 0.01f);  // lifted by 0.25

  r = run(kRelief + " " + sceneWith("missing", "nothere.tif").string() + " --quiet -o " +
          (dir / "missing.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir / "missing.png"));
  // Said where the scene bound the shader, and why, whichever thread failed first (OpenImageIO
  // gave its reason to one thread only, so the reason was sometimes missing).
  const std::string message = "small.rib:11: error: displacement shader 'lift': cannot read texture 'nothere.tif': no such file";
  const size_t first = r.err.find(message);
  EXPECT_NE(first, std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(message, first + 1), std::string::npos) << r.err;  // once per file
  EXPECT_NEAR(centreDepth(dir / "missing.exr"), 5.0f, 1e-3f);  // fill value 0: not lifted

  // An empty name is an unreadable file like any other: said once, and why.
  r = run(kRelief + " " + sceneWith("empty", "").string() + " --quiet -o " + (dir / "empty.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const std::string empty = "small.rib:11: error: displacement shader 'lift': cannot read texture '': the file name is empty";
  const size_t at = r.err.find(empty);
  EXPECT_NE(at, std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(empty, at + 1), std::string::npos) << r.err;
}

// A shader overflowing to infinity: the points stay undisplaced, the render finishes, and one warning names
// the shader and the RIB line of its Displacement call.
TEST(Relief, NanFromAShaderIsAWarningNamingIt) {
  const fs::path dir = scratchDir();
  writeFile(dir / "broken.disp",
            "displacement broken(float Km = 1) {\n"
            "  float big = 1e30 + u;\n"
            "  P += Km * big * big * normalize(N);\n"
            "}\n");
  const fs::path scene = displacedScene(dir, "0.1", "Displacement \"broken\"");
  RunResult r = run(kRelief + " " + scene.string() + " -o " + (dir / "nan.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir / "nan.png"));
  const std::string expected = scene.string() + ":8: warning: displacement shader 'broken': ";
  const size_t at = onlyWarning(r.err, expected);
  ASSERT_NE(at, std::string::npos) << r.err;
  EXPECT_NE(r.err.find("points produced a NaN or infinite P (left undisplaced)", at), std::string::npos) << r.err;
  // --quiet says nothing, but the statistics still count them.
  r = run(kRelief + " " + scene.string() + " --quiet -o " + (dir / "nan2.png").string() + " --stats-json " +
          (dir / "nan.json").string());
  EXPECT_EQ(r.err, "");
  std::ifstream json(dir / "nan.json");
  const std::string stats((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_EQ(stats.find("\"shader.nonfinite_points\": 0,"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"shader.nonfinite_points\": "), std::string::npos) << stats;

  // A NaN normal with a finite P: displaced, and a warning of its own.
  writeFile(dir / "badn.disp",
            "displacement badn(float Km = 0.05) {\n"
            "  P += Km * normalize(N);\n"
            "  float big = 1e30 * (1 + u);\n"
            "  N = normal(big * big - big * big);\n"
            "}\n");
  const fs::path badn = displacedScene(dir, "0.1", "Displacement \"badn\"");
  r = run(kRelief + " " + badn.string() + " -o " + (dir / "badn.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("points produced a NaN, infinite or zero N (the displaced surface's own normal is used)"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("left undisplaced"), std::string::npos) << r.err;
}

// A shader loop that never ends costs each point the whole loop-iteration limit (language.md §7):
// at every point of a 64x48 sphere that took minutes. The render now stops with an error at the
// Displacement once 1024 invocations have hit the limit, with no image.
TEST(Relief, EndlessShaderLoopsStopTheRender) {
  const fs::path dir = scratchDir();
  writeFile(dir / "loopy.disp",
            "displacement loopy(float Km = 0.05)\n{\n    float i = 0;\n    while (i < 1) { i = i * 1; }\n"
            "    P += Km * normalize(N);\n}\n");
  const fs::path scene = writeFile(dir / "loopy.rib",
                                   "Format 64 48 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\n"
                                   "WorldBegin\nAttribute \"displacementbound\" \"float sphere\" [0.1]\n"
                                   "Displacement \"loopy\"\nSphere 1 -1 1 360\nWorldEnd\n");
  const RunResult r = run(kRelief + " " + scene.string() + " --threads 2 -o " + (dir / "loopy.png").string());
  EXPECT_EQ(r.exitCode, 1) << r.err;
  EXPECT_NE(r.err.find(scene.string() + ":6: error: displacement shader 'loopy': "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("invocations hit the loop-iteration limit"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "loopy.png"));
}

// subdivide.h, work guard: a scene whose undisplaced surface alone asks for more micro-triangles
// than any render could make is an error at its Displacement line before rendering, and a shader
// whose edges never get short (here: points moved a thousand times beyond the bound, rippling
// fast) stops the render within seconds with an error naming the line, the cause and the remedy.
// Neither writes an image.
TEST(Relief, RunawaySubdivisionIsAnErrorNotAHang) {
  const fs::path dir = scratchDir();
  writeFile(dir / "push.disp",
            "displacement push(float amount = 0.2) { P += amount * normalize(N); }\n");
  auto sphereScene = [&](const std::string& name, const std::string& call) {
    return writeFile(dir / name,
                     "Format 16 12 1\nProjection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\n"
                     "WorldBegin\nAttribute \"displacementbound\" \"float sphere\" [0.1]\n" +
                         call + "\nSphere 1 -1 1 360\nWorldEnd\n");
  };
  const fs::path sphere = sphereScene("sphere.rib", "Displacement \"push\"");
  RunResult r = run(kRelief + " " + sphere.string() + " --edge-length 1e-9 -o " +
                    (dir / "tiny.png").string());
  EXPECT_EQ(r.exitCode, 1) << r.err;
  EXPECT_NE(r.err.find(sphere.string() + ":6: error: displacement shader 'push': an edge length of 1e-09 asks for about "),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("raise --edge-length"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "tiny.png"));
  // Far below that guard but far beyond what the image can show (1.5e10 micro-triangles for 192
  // pixels): an error too, where it filled memory for minutes before.
  r = run(kRelief + " " + sphere.string() + " --edge-length 1e-4 -o " + (dir / "fine.png").string());
  EXPECT_EQ(r.exitCode, 1) << r.err;
  EXPECT_NE(r.err.find(":6: error: displacement shader 'push': an edge length of 0.0001 asks for about 1.5e+10 "
                       "micro-triangles on the undisplaced surface alone, more than 1e+09 (100000 per pixel of "
                       "a 16x12 image, at least 1e+09)"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "fine.png"));
  // The same sphere at a sane edge length renders.
  r = run(kRelief + " " + sphere.string() + " --edge-length 0.05 -o " + (dir / "sane.png").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;

  writeFile(dir / "ripple.disp",
            "displacement ripple(float Km = 1) { P += Km * sin(40 * xcomp(P)) * normalize(N); }\n");
  const fs::path scene = sphereScene("ripple.rib", "Displacement \"ripple\" \"float Km\" [100]");
  r = run(kRelief + " " + scene.string() + " -o " + (dir / "ripple.png").string());
  EXPECT_EQ(r.exitCode, 1) << r.err;
  EXPECT_NE(r.err.find(scene.string() + ":6: error: displacement shader 'ripple': subdivision ran away"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("beyond its displacement bound of 0.1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("rendering stopped"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "ripple.png"));
}

// Geometry so far from the camera that float intersection overflows is said to be, once; the
// scene near it is not.
TEST(Relief, GeometryBeyondFloatIntersectionRangeWarns) {
  const fs::path dir = scratchDir();
  const fs::path far = smallScene(dir, "", "Polygon \"P\" [0 0 1e15  1e13 0 1e15  0 1e13 1e15]\n");
  RunResult r = run(kRelief + " " + far.string() + " -o " + (dir / "far.png").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(onlyWarning(r.err, "small.rib: warning: the scene reaches about 1.0001e+15 units from the camera; beyond about 2e+14"),
            std::string::npos)
      << r.err;
  r = run(kRelief + " " + smallScene(dir, "").string() + " -o " + (dir / "near.png").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err.find("units from the camera"), std::string::npos) << r.err;
}

// language.md §7: a shader that moves points farther than the declared bound is not clamped, and the
// host warns once per Displacement with the largest excess; one within its bound gets no warning.
TEST(Relief, DisplacementBeyondTheBoundIsOneWarningWithTheLargestExcess) {
  const fs::path dir = scratchDir();
  writeFile(dir / "push.disp",
            "displacement push(float amount = 0.2) { P += amount * normalize(N); }\n");
  const std::string push = "Displacement \"push\" \"float amount\" [0.2]";
  const fs::path scene = displacedScene(dir, "0.05", push);
  RunResult r = run(kRelief + " " + scene.string() + " -o " + (dir / "far.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const std::string expected = scene.string() + ":8: warning: displacement shader 'push' moved ";
  const size_t at = onlyWarning(r.err, expected);
  ASSERT_NE(at, std::string::npos) << r.err;
  EXPECT_NE(r.err.find("beyond the displacement bound 0.05 (world units), by up to 0.15", at),
            std::string::npos)
      << r.err;

  const fs::path within = displacedScene(dir, "0.25", push);
  r = run(kRelief + " " + within.string() + " -o " + (dir / "near.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err.find("beyond the displacement bound"), std::string::npos) << r.err;

  // A move whose square overflows a float is still measured (it was reported as "inf").
  const fs::path huge = displacedScene(dir, "0.05", "Displacement \"push\" \"float amount\" [1e20]");
  r = run(kRelief + " " + huge.string() + " -o " + (dir / "huge.png").string());
  EXPECT_NE(r.err.find("up to 1e+20"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("inf"), std::string::npos) << r.err;

  // A bound far beyond what the shader does, large against the scene, slows the render for
  // nothing: said once, with what the shader did. A bound within 16 times of it is not.
  // Renders `scene` and expects the one warning at its Displacement call (line 8) that `text` starts.
  auto renderWarnsOnce = [&](const fs::path& scene, const std::string& text) {
    const RunResult render = run(kRelief + " " + scene.string() + " -o " + (dir / "bound.png").string());
    ASSERT_EQ(render.exitCode, 0) << render.err;
    EXPECT_NE(onlyWarning(render.err, scene.string() + ":8: warning: displacement shader 'push' " + text),
              std::string::npos)
        << render.err;
  };
  const fs::path loose = displacedScene(dir, "4", push);
  renderWarnsOnce(loose, "moved no point farther than 0.2 (world units), against a displacement bound of 4;");
  r = run(kRelief + " " + displacedScene(dir, "3", push).string() + " -o " + (dir / "near.png").string());
  EXPECT_EQ(r.err.find("moved no point farther"), std::string::npos) << r.err;
  // Primitives of one Displacement call under different transforms: still one warning.
  const fs::path two = smallScene(dir, "",
                                  "Attribute \"displacementbound\" \"float sphere\" [4]\n"
                                  "Attribute \"relief\" \"float edgelength\" [0.5]\n" + push + "\n"
                                  "TransformBegin\nTranslate 0 0 0.5\nPolygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]\n"
                                  "TransformEnd\n");
  renderWarnsOnce(two, "moved no point farther than");
  // A shader that moves nothing needs no bound at all.
  const fs::path still = displacedScene(dir, "1", "Displacement \"push\" \"float amount\" [0]");
  renderWarnsOnce(still, "moved no point at all, under a displacement bound of 1;");
  // Near float's limit the grown boxes would overflow and every ray miss: an error, not a black
  // image.
  const fs::path overflowing = displacedScene(dir, "2e38", push);
  r = run(kRelief + " " + overflowing.string() + " -o " + (dir / "overflow.png").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("the displacement bound is 2e+38 world units, beyond any scene"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "overflow.png"));
}

// A spline basis named at run time that the library does not know falls back to catmull-rom and
// is counted (language.md §6.6); the render warns once, naming the shader and its RIB line.
TEST(Relief, UnknownRuntimeSplineBasisIsOneWarningNamingTheShader) {
  const fs::path dir = scratchDir();
  writeFile(dir / "sb.disp",
            "displacement sb(string basis = \"nosuch\") {\n"
            "  float k = spline(basis, u, 0, 0.1, 0.2, 0.3);\n"
            "  P += 0.01 * k * normalize(N);\n"
            "}\n");
  const fs::path scene = displacedScene(dir, "0.01", "Displacement \"sb\"");
  RunResult r = run(kRelief + " " + scene.string() + " -o " + (dir / "sb.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const std::string expected = scene.string() + ":8: warning: displacement shader 'sb': ";
  const size_t at = onlyWarning(r.err, expected);
  ASSERT_NE(at, std::string::npos) << r.err;
  EXPECT_NE(r.err.find("unknown basis or one unfit for their knots", at), std::string::npos) << r.err;
}

// A shader's printf goes to standard output, whole messages, up to --print-limit of them (a shader
// prints at every point it displaces); how many more there were is said once, unless quiet.
TEST(Relief, ShaderPrintfReachesStandardOutputUpToTheLimit) {
  const fs::path dir = scratchDir();
  writeFile(dir / "talk.disp",
            "displacement talk(float Km = 0.01) {\n"
            "  printf(\"point at u=%f\\n\", u);\n"
            "  P += Km * normalize(N);\n"
            "}\n");
  const fs::path scene = displacedScene(dir, "0.02", "Displacement \"talk\"");
  const std::string base = kRelief + " " + scene.string() + " --threads 2 -I " + dir.string() + " -o " +
                           (dir / "talk.png").string();
  auto count = [](const std::string& text, const std::string& what) {
    size_t n = 0;
    for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
    return n;
  };
  RunResult r = run(base + " --print-limit 7");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(count(r.out, "point at u="), 7u) << r.out;
  EXPECT_EQ(count(r.out, "\n"), 8u) << r.out;  // 7 whole lines, then the image path
  EXPECT_NE(r.out.find((dir / "talk.png").string() + "\n"), std::string::npos) << r.out;
  EXPECT_EQ(count(r.err, "more printf messages from shaders not shown (--print-limit 7)"), 1u) << r.err;
  r = run(base + " --print-limit 0 -q");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.out, (dir / "talk.png").string() + "\n");
  EXPECT_EQ(r.err, "");
  r = run(base + " --edge-length 0.05");  // thousands of points
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(count(r.out, "point at u="), 100u);  // the default limit
}

TEST(Relief, FailedOutputLeavesNoImage) {
  const fs::path dir = scratchDir();
  const fs::path scene = smallScene(dir, "");
  // A file where a directory should be: the image cannot be created.
  writeFile(dir / "blocker", "x");
  RunResult r = run(kRelief + " " + scene.string() + " --quiet -o " + (dir / "blocker" / "a.png").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("a.png"), std::string::npos) << r.err;
  r = run(kRelief + " " + scene.string() + " --quiet -o " + (dir / "a.unknownformat").string());
  EXPECT_EQ(r.exitCode, 1);
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    EXPECT_TRUE(name == "small.rib" || name == "blocker" || name == "stdout.txt" || name == "stderr.txt")
        << name;
  }
}

// A format nothing can write is an error before the render starts (no progress is printed), and
// the message names the file the user asked for, not the temporary it would have been staged in.
TEST(Relief, AnUnwritableFormatFailsBeforeTheRender) {
  const fs::path dir = scratchDir();
  const fs::path scene = smallScene(dir, "");
  const fs::path image = dir / "a.unknownformat";
  RunResult r = run(kRelief + " " + scene.string() + " -o " + image.string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("relief: error: cannot write '" + image.string() + "'"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(".tmp"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("rendering"), std::string::npos) << r.err;
  r = run(kRelief + " " + scene.string() + " -o " + (dir / "noextension").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("no file extension"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("rendering"), std::string::npos) << r.err;
  // PNM has no alpha: an "rgba" display in it is refused before the render too.
  const fs::path rgba = smallScene(dir, "Display \"" + (dir / "a.ppm").string() + "\" \"file\" \"rgba\"\n");
  r = run(kRelief + " " + rgba.string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("PNM has no alpha channel"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(rgba.string() + ":2: error: cannot write"), std::string::npos) << r.err;  // the Display line
  EXPECT_EQ(r.err.find("rendering"), std::string::npos) << r.err;
  // With -o naming the file, the mode is still the Display's: the error says where it came from.
  r = run(kRelief + " " + rgba.string() + " -o " + (dir / "b.ppm").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("(display mode 'rgba' from the Display at " + rgba.string() + ":2)"), std::string::npos) << r.err;
  // An error the mode did not cause (an unknown format) does not blame it.
  r = run(kRelief + " " + rgba.string() + " -o " + (dir / "b.xyz").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("cannot write"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("display mode"), std::string::npos) << r.err;
  // Nor has JPEG: rgba to a .jpg is refused, not written as rgb in silence.
  const fs::path jpeg = smallScene(dir, "Display \"" + (dir / "a.jpg").string() + "\" \"file\" \"rgba\"\n");
  r = run(kRelief + " " + jpeg.string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("has no alpha channel"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "a.jpg"));
  // So is a place nothing can be written to, image or statistics; a missing directory is made
  // for either, and an empty name is a usage error.
  writeFile(dir / "plainfile", "x");
  r = run(kRelief + " " + scene.string() + " -o " + (dir / "plainfile" / "a.png").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("relief: error: cannot write '" + (dir / "plainfile" / "a.png").string() + "': '" +
                       (dir / "plainfile").string() + "' is not a directory"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("rendering"), std::string::npos) << r.err;
  r = run(kRelief + " " + scene.string() + " -o " + (dir / "ok.png").string() + " --stats-json " +
          (dir / "plainfile" / "s.json").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("relief: error: cannot write statistics: "), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("rendering"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "ok.png"));
  r = run(kRelief + " " + scene.string() + " --quiet -o " + (dir / "ok.png").string() + " --stats-json " +
          (dir / "new" / "dir" / "s.json").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir / "new" / "dir" / "s.json"));
  // A write that fails only when flushed (a full disk) is an error too; it passed silently.
  if (fs::exists("/dev/full")) {
    r = run(kRelief + " " + scene.string() + " --quiet -o " + (dir / "ok.png").string() + " --stats-json /dev/full");
    EXPECT_EQ(r.exitCode, 1);
    EXPECT_NE(r.err.find("relief: error: cannot write statistics to '/dev/full'"), std::string::npos) << r.err;
  }
  EXPECT_EQ(run(kRelief + " " + scene.string() + " -o ''").exitCode, 2);
  EXPECT_EQ(run(kRelief + " " + scene.string() + " --stats-json ''").exitCode, 2);
}

// Two outputs of one frame on one file would keep only the last written (the depth image over
// the colour one, the statistics over the image): an error before rendering, naming both.
// The statistics give the pixel order the render used, here the scene's.
TEST(Relief, OutputsOfOneFrameMayNotShareAFile) {
  const fs::path dir = scratchDir();
  const std::string same = (dir / "same.png").string();
  const fs::path scene = smallScene(dir, "Display \"" + same + "\" \"file\" \"rgb\"\nDisplay \"+" + same +
                                             "\" \"file\" \"z\"\n");
  RunResult r = run(kRelief + " " + scene.string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find(scene.string() + ":3: error: the image and the \"z\" display would both write '" + same + "'"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(same));
  const fs::path plain = smallScene(dir, "", "");
  const std::string image = (dir / "x.png").string();
  r = run(kRelief + " " + plain.string() + " -o " + image + " --stats-json " + image);
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("relief: error: the image and --stats-json would both write '" + image + "'"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(image));
  const fs::path ordered = smallScene(dir, "Option \"relief\" \"string order\" [\"scanline\"]\n");
  r = run(kRelief + " " + ordered.string() + " --quiet -o " + image + " --stats-json " + (dir / "s.json").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(readFile(dir / "s.json").find("\"render.order\": \"scanline\""), std::string::npos);
}

// Displays are all-or-nothing: when a later one cannot be written, the earlier ones (complete by
// then) are not left behind either, nor any temporary file; the exit status says the render failed.
TEST(Relief, FailedDisplayLeavesNoneOfTheOthers) {
  const fs::path dir = scratchDir();
  writeFile(dir / "blocker", "x");  // a file where a directory should be
  const fs::path scene = smallScene(dir, "Display \"" + (dir / "main.png").string() + "\" \"file\" \"rgb\"\n"
                                    "Display \"+" + (dir / "z.exr").string() + "\" \"file\" \"z\"\n"
                                    "Display \"+" + (dir / "blocker" / "n.png").string() + "\" \"file\" \"N\"\n");
  RunResult r = run(kRelief + " " + scene.string() + " --quiet");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("n.png"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "");
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    EXPECT_TRUE(name == "small.rib" || name == "blocker" || name == "stdout.txt" || name == "stderr.txt")
        << name;
  }
}

// An exporter's animation: the camera before the first FrameBegin is shared; each frame has its
// own Display and Format, and only frame 2 has a sphere. `frame2` replaces frame 2's world body.
fs::path twoFrameScene(const fs::path& dir, const std::string& displayDir,
                       const std::string& frame2 = "Sphere 0.5 -0.5 0.5 360\n") {
  auto display = [&](const std::string& name) {
    return displayDir.empty() ? std::string()
                              : "Display \"" + (fs::path(displayDir) / name).string() +
                                    "\" \"file\" \"rgb\"\n";
  };
  const std::string light = "LightSource \"distantlight\" 1 \"from\" [0 0 -1] \"to\" [0 0 0]\n";
  return writeFile(dir / "anim.rib",
                   "Option \"othercat\" \"int x\" [1]\n"
                   "Projection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\n"
                   "FrameBegin 1\n" + display("anim.0001.png") + "Format 16 12 1\n"
                   "WorldBegin\n" + light + "Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]\n"
                   "WorldEnd\nFrameEnd\n"
                   "FrameBegin 2\n" + display("anim.0002.png") + "Format 24 18 1\n"
                   "WorldBegin\n" + light + frame2 + "WorldEnd\nFrameEnd\n");
}

// Width x height of an image file, or "missing".
std::string imageSize(const fs::path& file) {
  auto in = OIIO::ImageInput::open(file.string());
  if (!in) return "missing";
  return std::to_string(in->spec().width) + "x" + std::to_string(in->spec().height);
}

size_t count(const std::string& text, const std::string& part) {
  size_t n = 0;
  for (size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
  return n;
}

TEST(Relief, EveryFrameIsRenderedToItsOwnDisplay) {
  const fs::path dir = scratchDir();
  const fs::path scene = twoFrameScene(dir, dir.string());
  RunResult r = run(kRelief + " " + scene.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const fs::path first = dir / "anim.0001.png", second = dir / "anim.0002.png";
  EXPECT_EQ(r.out, first.string() + "\n" + second.string() + "\n");
  EXPECT_EQ(imageSize(first), "16x12");
  EXPECT_EQ(imageSize(second), "24x18");
  // Progress per frame; the shared part's warning once, not once per frame.
  EXPECT_NE(r.err.find("relief: frame 1 (1 of 2)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("relief: frame 2 (2 of 2)"), std::string::npos) << r.err;
  EXPECT_EQ(count(r.err, "unsupported option 'othercat'"), 1u) << r.err;
  EXPECT_EQ(count(r.err, "rendering 100%"), 2u) << r.err;
  // The sphere is in frame 2 only: rendered alone, frame 2 without it differs.
  const fs::path plain = dir / "plain.png";
  twoFrameScene(dir, "", "");
  r = run(kRelief + " " + scene.string() + " --quiet --frame 2 -o " + plain.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  twoFrameScene(dir, "");
  const fs::path sphere = dir / "sphere.png";
  r = run(kRelief + " " + scene.string() + " --quiet --frame 2 -o " + sphere.string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  relief::test::ImageDiff d = relief::test::compareImages(sphere.string(), plain.string(), 0.1f);
  ASSERT_TRUE(d.loaded) << d.error;
  EXPECT_GT(d.failingPixels, 10);
}

TEST(Relief, FrameFlagRendersOneFrameByItsNumber) {
  const fs::path dir = scratchDir();
  const fs::path scene = twoFrameScene(dir, dir.string());
  RunResult r = run(kRelief + " " + scene.string() + " --frame 2");
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.out, (dir / "anim.0002.png").string() + "\n");
  EXPECT_FALSE(fs::exists(dir / "anim.0001.png"));
  EXPECT_EQ(r.err.find("relief: frame"), std::string::npos) << r.err;
  // One frame with -o: the name is used as given.
  r = run(kRelief + " " + scene.string() + " --quiet --frame 1 -o " + (dir / "one.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(imageSize(dir / "one.png"), "16x12");
}

TEST(Relief, OutputAndStatsNamesGetTheFrameNumber) {
  const fs::path dir = scratchDir();
  const fs::path scene = twoFrameScene(dir, "");
  RunResult r = run(kRelief + " " + scene.string() + " --quiet -o " + (dir / "out.png").string() +
                    " --stats-json " + (dir / "stats.json").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.out, (dir / "out.0001.png").string() + "\n" + (dir / "out.0002.png").string() + "\n");
  EXPECT_EQ(imageSize(dir / "out.0001.png"), "16x12");
  EXPECT_EQ(imageSize(dir / "out.0002.png"), "24x18");
  EXPECT_FALSE(fs::exists(dir / "out.png"));
  EXPECT_FALSE(fs::exists(dir / "stats.json"));
  EXPECT_NE(readFile(dir / "stats.0001.json").find("\"scene.frame\": 1,"), std::string::npos);
  EXPECT_NE(readFile(dir / "stats.0002.json").find("\"scene.frame\": 2,"), std::string::npos);
  // A negative frame number keeps four digits after its sign.
  std::string text = readFile(scene);
  text.replace(text.find("FrameBegin 2"), 12, "FrameBegin -3");
  writeFile(scene, text);
  r = run(kRelief + " " + scene.string() + " --quiet -o " + (dir / "neg.png").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.out, (dir / "neg.0001.png").string() + "\n" + (dir / "neg.-0003.png").string() + "\n");
}

TEST(Relief, FramesWritingOneFileWarnOnce) {
  const fs::path dir = scratchDir();
  // The Display before the first frame is every frame's.
  writeFile(dir / "same.rib", "Display \"" + (dir / "same.png").string() +
                                  "\" \"file\" \"rgb\"\nFormat 8 6 1\nFrameBegin 1\nWorldBegin\n"
                                  "WorldEnd\nFrameEnd\nFrameBegin 2\nWorldBegin\nWorldEnd\n"
                                  "FrameEnd\nFrameBegin 3\nWorldBegin\nWorldEnd\nFrameEnd\n");
  RunResult r = run(kRelief + " " + (dir / "same.rib").string());
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(count(r.err, "over an earlier frame's image"), 1u) << r.err;
  EXPECT_NE(r.err.find("warning: frame 2 writes '" + (dir / "same.png").string() + "' again"),
            std::string::npos)
      << r.err;
}

TEST(Relief, MissingFrameIsAUsageError) {
  const fs::path dir = scratchDir();
  const fs::path scene = twoFrameScene(dir, dir.string());
  RunResult r = run(kRelief + " " + scene.string() + " --frame 3");
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("relief: error: no 'FrameBegin 3' in '" + scene.string() +
                       "' (its frames: 1, 2)"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "anim.0001.png"));
  r = run(kRelief + " " + smallScene(dir, "").string() + " --frame 1");
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("has no FrameBegin blocks"), std::string::npos) << r.err;
  for (const char* bad : {"--frame", "--frame x", "--frame 1.5"}) {
    r = run(kRelief + " " + scene.string() + " " + bad);
    EXPECT_EQ(r.exitCode, 2) << bad;
    EXPECT_NE(r.err.find("'--frame' needs a frame number"), std::string::npos) << r.err;
  }
}

// A frame that fails stops the run at its file:line; the frames before it are complete and stay.
TEST(Relief, FailedFrameKeepsTheEarlierFrames) {
  const fs::path dir = scratchDir();
  const fs::path scene = twoFrameScene(dir, "", "Sphere 1 -1 \"x\" 360\n");
  RunResult r = run(kRelief + " " + scene.string() + " --quiet -o " + (dir / "out.png").string());
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find(scene.string() + ":15: error:"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, (dir / "out.0001.png").string() + "\n");
  EXPECT_EQ(imageSize(dir / "out.0001.png"), "16x12");
  EXPECT_FALSE(fs::exists(dir / "out.0002.png"));
  // Frame 1 alone does not read frame 2's calls.
  r = run(kRelief + " " + scene.string() + " --quiet --frame 1 -o " + (dir / "one.png").string());
  EXPECT_EQ(r.exitCode, 0) << r.err;
}

}  // namespace
