// Tests of the RIB calls added for the full scene format (docs/scene-format.md): options, displays,
// frames, surfaces, lights and Illuminate, orientation, object instancing, procedurals, OBJ
// meshes, patches and patch meshes, general polygons and primitive variable classes, the errors
// bad input gets, and the warnings (not errors) for input written for other renderers. Each test
// checks the call's effect on the Scene.
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include <gtest/gtest.h>

#include "render_test_util.h"
#include "renderer/rib_geometry.h"
#include "renderer/rib_reader.h"

namespace relief {
namespace {

struct ReadResult {
  std::optional<Scene> scene;
  SceneError error;
  std::string warnings;
};

ReadResult read(const std::string& text, runtime::ShaderProvider* shaders = nullptr,
                const std::string& fileName = "/scenes/test.rib") {
  std::ostringstream warnings;
  RibReadOptions options;
  options.shaders = shaders;
  options.defaultShaderPath = {"/default"};
  options.defaultTexturePath = {"/textures"};
  options.warnings = &warnings;
  ReadResult r;
  r.scene = readRibString(text, fileName, options, &r.error);
  r.warnings = warnings.str();
  return r;
}

std::string world(const std::string& body) { return "WorldBegin\n" + body + "\nWorldEnd\n"; }
const char* kTriangle = "Polygon \"P\" [0 0 0  1 0 0  0 1 0]\n";

void expectNear(glm::vec3 a, glm::vec3 b, float eps = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

const Material& materialOf(const Scene& scene, size_t mesh) {
  return scene.materials[scene.meshes.at(mesh).materialIndex];
}

// A scratch directory for tests that read files.
struct TempDir {
  std::filesystem::path path;
  explicit TempDir(const std::string& tag)
      : path(std::filesystem::temp_directory_path() /
             ("relief-" + tag + "-" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string write(const std::string& name, const std::string& text) const {
    std::filesystem::create_directories((path / name).parent_path());
    std::ofstream(path / name, std::ios::binary) << text;
    return (path / name).string();
  }
};

// --- Options ---

TEST(RibOptions, ProjectionDefaultsToOrthographic) {
  ReadResult r = read(world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_FALSE(r.scene->camera.perspective);
  r = read("Projection \"perspective\"\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_TRUE(r.scene->camera.perspective);
  EXPECT_FLOAT_EQ(r.scene->camera.fovDegrees, 90.0f);
  EXPECT_FALSE(read("Projection \"perspective\" \"fov\" [\"wide\"]\n" + world("")).scene);
  // Other projections are outside the subset: a warning and the default.
  r = read("Projection \"perspective\"\nProjection \"fisheye\" \"fov\" [180]\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_FALSE(r.scene->camera.perspective);
  EXPECT_NE(r.warnings.find(":2: warning: unsupported projection 'fisheye'; using orthographic"),
            std::string::npos)
      << r.warnings;
}

TEST(RibOptions, DisplayModesNameTheAovs) {
  ReadResult r = read("Display \"a.exr\" \"file\" \"rgba\"\nDisplay \"+depth.exr\" \"file\" \"z\"\n"
                      "Display \"+normal.exr\" \"file\" \"N\"\n"
                      "Display \"+miss.png\" \"file\" \"cachemiss\"\n"
                      "Display \"+d2.exr\" \"file\" \"Z\"\nDisplay \"+o.exr\" \"file\" \"rgbaz\"\n"
                      "Display \"+p.png\" \"file\" \"a\"\nDisplay \"+q.png\" \"file\" \"rgbaq\"\n" +
                      world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->displays,
            (std::vector<std::string>{"a.exr", "depth.exr", "normal.exr", "miss.png", "d2.exr",
                                      "o.exr", "p.png", "q.png"}));
  EXPECT_EQ(r.scene->displayModes,
            (std::vector<std::string>{"rgba", "z", "N", "cachemiss", "z", "rgbaz", "a", "rgb"}));
  EXPECT_NE(r.warnings.find("display mode 'rgbaq' written as 'rgb'"), std::string::npos);
}

TEST(RibOptions, ReliefOptionSetsRenderSettings) {
  ReadResult r = read("Option \"relief\" \"int cachebudget\" [200000] \"string order\" "
                      "[\"bucket\"] \"int maxdepth\" [6]\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->cacheBudgetTriangles, 200000u);
  EXPECT_EQ(r.scene->order, "bucket");
  EXPECT_EQ(r.scene->maxDepth, 6);
  EXPECT_EQ(r.warnings, "");
  r = read(world(""));
  EXPECT_EQ(r.scene->cacheBudgetTriangles, 0u);
  EXPECT_EQ(r.scene->order, "");
  EXPECT_EQ(r.scene->maxDepth, -1);  // not set
  // 0 (no secondary rays) to 100, as --max-depth.
  r = read("Option \"relief\" \"int maxdepth\" [0]\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->maxDepth, 0);
  EXPECT_FALSE(read("Option \"relief\" \"int maxdepth\" [101]\n" + world("")).scene);
  EXPECT_FALSE(read("Option \"relief\" \"int maxdepth\" [2.5]\n" + world("")).scene);
  r = read("Option \"relief\" \"string order\" [\"spiral\"]\n" + world(""));
  EXPECT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 1);
  EXPECT_FALSE(read("Option \"relief\" \"int maxdepth\" [\"deep\"]\n" + world("")).scene);
  EXPECT_FALSE(read("Option \"relief\" \"int cachebudget\" [-5]\n" + world("")).scene);
  // -1 and "" are values like any other (they had passed as "not given").
  EXPECT_FALSE(read("Option \"relief\" \"int maxdepth\" [-1]\n" + world("")).scene);
  EXPECT_FALSE(read("Option \"relief\" \"int cachebudget\" [-1]\n" + world("")).scene);
  EXPECT_FALSE(read("Option \"relief\" \"string order\" [\"\"]\n" + world("")).scene);
}

TEST(RibOptions, PixelFilterChoosesTheReconstructionFilter) {
  ReadResult r = read("PixelFilter \"blackman-harris\" 3 3\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->pixelFilter, "blackman-harris");
  EXPECT_EQ(r.warnings, "");
  r = read("PixelFilter \"box\" 2 2\n" + world(""));
  EXPECT_EQ(r.scene->pixelFilter, "box");
  EXPECT_NE(r.warnings.find("widths ignored, 'box' uses 1 x 1"), std::string::npos) << r.warnings;
  r = read("PixelFilter \"catmull-rom\" 4 4\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->pixelFilter, "");
  EXPECT_NE(r.warnings.find("unsupported pixel filter 'catmull-rom'"), std::string::npos);
  EXPECT_EQ(read(world("")).scene->pixelFilter, "");
}

TEST(RibOptions, FractionalOrNonPositivePixelSamplesAreRoundedWithAWarning) {
  ReadResult r = read("PixelSamples 2.5 -2\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->pixelSamples, 3);
  EXPECT_NE(r.warnings.find("'PixelSamples 2.5 -2' takes 3 x 1 samples per pixel"), std::string::npos) << r.warnings;
  r = read("PixelSamples 3 2\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->pixelSamples, 6);
  EXPECT_EQ(r.warnings, "");
}

TEST(RibOptions, AbsurdCountsAndHandlesAreErrorsNotOverflows) {
  EXPECT_FALSE(read("PixelSamples 1e30 1e30\n" + world("")).scene);
  ReadResult r = read(world("LightSource \"pointlight\" 1e30\nIlluminate 1e30 0\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_FALSE(r.scene->lights[0].handle.empty());
}

TEST(RibOptions, TextureSearchPath) {
  ReadResult r = read(world(""));
  EXPECT_EQ(r.scene->texturePath, std::vector<std::string>{"/textures"});
  r = read("Option \"searchpath\" \"string texture\" [\"maps:/abs\"]\n"
           "Option \"searchpath\" \"string texture\" [\"&:@\"]\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->texturePath,
            (std::vector<std::string>{"/scenes/maps", "/abs", "/textures"}));
  EXPECT_FALSE(read("Option \"searchpath\" \"texture\" [1]\n" + world("")).scene);
}

TEST(RibOptions, UnsupportedCallsWarnOnceEach) {
  ReadResult r = read("PixelFilter \"sinc\" 4 4\nPixelFilter \"sinc\" 6 6\nHider \"hidden\"\n"
                      "Shutter 0 1\nOption \"limits\" \"bucketsize\" [16 16]\n" +
                      world("ShadingRate 1\nAttribute \"identifier\" \"name\" [\"x\"]\n"
                            "Attribute \"identifier\" \"name\" [\"y\"]\n") );
  ASSERT_TRUE(r.scene) << r.error.format();
  std::istringstream lines(r.warnings);
  int count = 0;
  for (std::string line; std::getline(lines, line);) ++count;
  EXPECT_EQ(count, 6) << r.warnings;  // sinc Hider Shutter limits ShadingRate identifier
}

TEST(RibOptions, CrlfAndCommentsKeepLineNumbers) {
  ReadResult r = read("# a comment\r\nWorldBegin\r\n  # another\r\n  Sphere 1 -1 1\r\nWorldEnd\r\n");
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 4);
  EXPECT_EQ(r.error.format().rfind("/scenes/test.rib:4: error: ", 0), 0u) << r.error.format();
}

TEST(RibTransforms, IdentityAndTransformReplaceTheCurrentTransform) {
  ReadResult r = read(world("Translate 5 5 5\nIdentity\n" + std::string(kTriangle) +
                            "Translate 5 5 5\nTransform [2 0 0 0  0 2 0 0  0 0 2 0  0 0 1 1]\n" +
                            kTriangle));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 2u);
  expectNear(r.scene->meshes[0].P[1], glm::vec3(1, 0, 0));
  expectNear(r.scene->meshes[1].P[1], glm::vec3(2, 0, 1));
  EXPECT_FALSE(read(world("Transform [1 0 0]")).scene);
}

// Exporters hide objects with Scale 0 0 0; any transform without an inverse skips the geometry
// under it with one warning instead of stopping the load.
TEST(RibTransforms, SingularTransformsSkipTheirGeometry) {
  ReadResult r = read(world("AttributeBegin\nScale 0 0 0\n" + std::string(kTriangle) +
                            "Sphere 1 -1 1 360\nAttributeEnd\n" +
                            "AttributeBegin\nTransform [0 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1]\n" +
                            kTriangle + "AttributeEnd\n" + kTriangle));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->meshes.size(), 1u);
  EXPECT_NE(r.warnings.find(":4: warning: 'Polygon' under a singular transform"), std::string::npos)
      << r.warnings;
  EXPECT_NE(r.warnings.find(":5: warning: 'Sphere' under a singular transform"), std::string::npos)
      << r.warnings;
  EXPECT_FALSE(read("Scale 0 1 1\n" + world("")).scene);  // but the camera needs an inverse
}

// --- Frames and archives ---

ReadResult readFrame(const std::string& text, int frame) {
  std::ostringstream warnings;
  RibReadOptions options;
  options.warnings = &warnings;
  options.frame = frame;
  ReadResult r;
  r.scene = readRibString(text, "/scenes/anim.rib", options, &r.error);
  r.warnings = warnings.str();
  return r;
}

// An exporter's animation: shared options first, then per frame a Display, a camera and a world.
const std::string kTwoFrames =
    "Format 10 10 1\nPixelSamples 2 2\nOption \"relief\" \"int maxdepth\" [3]\n"
    "FrameBegin 7\nDisplay \"anim.0007.png\" \"file\" \"rgba\"\n"
    "Projection \"perspective\" \"fov\" [40]\nTranslate 0 0 5\n" +
    world(kTriangle) +
    "FrameEnd\nPixelSamples 3 3\n"
    "FrameBegin 8\nDisplay \"anim.0008.png\" \"file\" \"rgb\"\nFormat 20 20 1\n" +
    world(std::string(kTriangle) + "Sphere 1 -1 1 360") + "FrameEnd\n";

TEST(RibFrames, EachFrameHasItsOwnDisplayCameraAndWorld) {
  ReadResult first = readFrame(kTwoFrames, 0);
  ASSERT_TRUE(first.scene) << first.error.format();
  EXPECT_EQ(first.scene->frameNumbers, (std::vector<int>{7, 8}));
  EXPECT_EQ(first.scene->numFrames(), 2);
  EXPECT_EQ(first.scene->frameIndex, 0);
  EXPECT_EQ(first.scene->displays, (std::vector<std::string>{"anim.0007.png"}));
  EXPECT_EQ(first.scene->displayModes, (std::vector<std::string>{"rgba"}));
  EXPECT_TRUE(first.scene->camera.perspective);
  EXPECT_FLOAT_EQ(first.scene->camera.fovDegrees, 40.0f);
  expectNear(glm::vec3(first.scene->camera.worldFromCamera[3]), glm::vec3(0, 0, -5));
  EXPECT_EQ(first.scene->meshes.size(), 1u);
  EXPECT_EQ(first.scene->width, 10);
  EXPECT_EQ(first.scene->pixelSamples, 4);  // the PixelSamples after its FrameEnd comes too late
  EXPECT_EQ(first.warnings, "");

  ReadResult second = readFrame(kTwoFrames, 1);
  ASSERT_TRUE(second.scene) << second.error.format();
  EXPECT_EQ(second.scene->frameNumbers, (std::vector<int>{7, 8}));
  EXPECT_EQ(second.scene->frameIndex, 1);
  EXPECT_EQ(second.scene->displays, (std::vector<std::string>{"anim.0008.png"}));
  // Frame 7's camera ended with it; the options before the first frame are shared.
  EXPECT_FALSE(second.scene->camera.perspective);
  expectNear(glm::vec3(second.scene->camera.worldFromCamera[3]), glm::vec3(0));
  EXPECT_EQ(second.scene->meshes.size(), 2u);
  EXPECT_EQ(second.scene->width, 20);
  EXPECT_EQ(second.scene->pixelSamples, 9);
  EXPECT_EQ(second.scene->maxDepth, 3);
  EXPECT_EQ(first.scene->maxDepth, 3);

  ReadResult missing = readFrame(kTwoFrames, 2);
  ASSERT_FALSE(missing.scene);
  EXPECT_EQ(missing.error.format(),
            "/scenes/anim.rib: error: no frame with index 2: the file has 2 frames");
}

TEST(RibFrames, AFileWithoutFramesIsOneFrame) {
  ReadResult r = read(world(kTriangle));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_TRUE(r.scene->frameNumbers.empty());
  EXPECT_EQ(r.scene->numFrames(), 1);
  EXPECT_FALSE(readFrame(world(kTriangle), 1).scene);
  ReadResult one = read("FrameBegin 3\n" + world(kTriangle) + "FrameEnd\n");
  ASSERT_TRUE(one.scene) << one.error.format();
  EXPECT_EQ(one.scene->frameNumbers, (std::vector<int>{3}));
  EXPECT_EQ(one.warnings, "");
}

TEST(RibFrames, SkippedFramesAreStillChecked) {
  // Frame 2 is skipped when frame 1 is read, but an unclosed or nested block in it is an error
  // at its line; a stray character anywhere is a tokenizer error.
  const std::string good = "FrameBegin 1\n" + world(kTriangle) + "FrameEnd\n";  // lines 1-6
  ReadResult unclosed = readFrame(good + "FrameBegin 2\n" + world(kTriangle), 0);
  ASSERT_FALSE(unclosed.scene);
  EXPECT_GT(unclosed.error.line, 7);
  EXPECT_NE(unclosed.error.message.find("'FrameBegin' at line 7 has no 'FrameEnd'"),
            std::string::npos)
      << unclosed.error.message;
  ReadResult nested = readFrame(good + "FrameBegin 2\nFrameBegin 3\nFrameEnd\nFrameEnd\n", 0);
  ASSERT_FALSE(nested.scene);
  EXPECT_EQ(nested.error.format(), "/scenes/anim.rib:8: error: nested 'FrameBegin'");
  ReadResult stray = readFrame(good + "FrameEnd\n", 0);
  ASSERT_FALSE(stray.scene);
  EXPECT_EQ(stray.error.format(), "/scenes/anim.rib:7: error: 'FrameEnd' without 'FrameBegin'");
  ReadResult token = readFrame(good + "FrameBegin 2\nSphere 1 -1 1 \"360\nFrameEnd\n", 0);
  ASSERT_FALSE(token.scene);
  EXPECT_EQ(token.error.line, 8);
  // A skipped frame's calls are not run: a bad one only fails when that frame is read.
  const std::string badSecond = good + "FrameBegin 2\nSides 3\n" + world(kTriangle) + "FrameEnd\n";
  EXPECT_TRUE(readFrame(badSecond, 0).scene);
  ReadResult bad = readFrame(badSecond, 1);
  ASSERT_FALSE(bad.scene);
  EXPECT_EQ(bad.error.line, 8);
  // A frame without a world has nothing to render; the error names the frame.
  ReadResult empty = readFrame(good + "FrameBegin 2\nFrameEnd\n", 1);
  ASSERT_FALSE(empty.scene);
  EXPECT_EQ(empty.error.format(),
            "/scenes/anim.rib:7: error: frame 2 has no 'WorldBegin'/'WorldEnd' block: nothing to "
            "render");
  EXPECT_FALSE(read("FrameBegin 1\n" + world("")).scene);  // unclosed frame
  EXPECT_FALSE(read("FrameEnd\n" + world("")).scene);
  EXPECT_FALSE(read("FrameBegin 1\n" + world("") + world("") + "FrameEnd\n").scene);
}

TEST(RibFrames, FramesWithoutANumberAreNumberedByPosition) {
  ReadResult r = readFrame("FrameBegin\n" + world(kTriangle) + "FrameEnd\nFrameBegin 1.5\n" +
                               world(kTriangle) + "FrameEnd\n",
                           1);
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->frameNumbers, (std::vector<int>{1, 2}));
  EXPECT_NE(r.warnings.find(":7: warning: 'FrameBegin' expects an integer frame number; numbering "
                            "this frame 2"),
            std::string::npos)
      << r.warnings;
}

TEST(RibFrames, FrameNumbersAreListedWithoutReadingTheFrames) {
  TempDir dir("frames");
  // The frames' calls would fail (no shader provider), but listing runs none of them.
  const std::string path = dir.write(
      "anim.rib", "Format 8 8 1\nFrameBegin 10\nDisplacement \"bumps\"\n" + world(kTriangle) +
                      "FrameEnd\nFrameBegin 20\n" + world(kTriangle) + "FrameEnd\n");
  SceneError error;
  std::optional<std::vector<int>> numbers = readRibFrameNumbers(path, RibReadOptions(), &error);
  ASSERT_TRUE(numbers) << error.format();
  EXPECT_EQ(*numbers, (std::vector<int>{10, 20}));
  const std::string single = dir.write("single.rib", world(kTriangle));
  numbers = readRibFrameNumbers(single, RibReadOptions(), &error);
  ASSERT_TRUE(numbers) << error.format();
  EXPECT_TRUE(numbers->empty());
  const std::string broken = dir.write("broken.rib", "FrameBegin 1\n" + world(kTriangle));
  EXPECT_FALSE(readRibFrameNumbers(broken, RibReadOptions(), &error));
  EXPECT_GT(error.line, 1);
  EXPECT_NE(error.message.find("'FrameBegin' at line 1 has no 'FrameEnd'"), std::string::npos);
  EXPECT_FALSE(readRibFrameNumbers((dir.path / "none.rib").string(), RibReadOptions(), &error));
}

TEST(RibFrames, DelayedReadArchiveReadsTheArchive) {
  TempDir dir("procedural");
  dir.write("parts/tri.rib", kTriangle);
  const std::string main =
      dir.write("main.rib", world("Procedural \"DelayedReadArchive\" [\"parts/tri.rib\"] "
                                  "[-1 1 -1 1 -1 1]\nProcedural \"RunProgram\" [\"x\" \"\"] "
                                  "[-1 1 -1 1 -1 1]"));
  SceneError error;
  std::ostringstream warnings;
  RibReadOptions options;
  options.warnings = &warnings;
  std::optional<Scene> scene = readRibFile(main, options, &error);
  ASSERT_TRUE(scene) << error.format();
  EXPECT_EQ(scene->meshes.size(), 1u);
  EXPECT_NE(warnings.str().find("'Procedural \"RunProgram\"' is not supported"), std::string::npos);
  const std::string missing =
      dir.write("missing.rib", world("\nReadArchive \"nowhere.rib\""));
  EXPECT_FALSE(readRibFile(missing, options, &error));
  EXPECT_EQ(error.line, 3);
  EXPECT_NE(error.message.find("cannot open archive"), std::string::npos);
  // A device is not a missing file: it says what it is.
  const std::string device = dir.write("device.rib", world("ReadArchive \"/dev/null\""));
  EXPECT_FALSE(readRibFile(device, options, &error));
  EXPECT_NE(error.message.find("'/dev/null': not a regular file"), std::string::npos) << error.message;
  // A bound with a minimum above its maximum warns (it is not needed, but it is a slip).
  const std::string inverted = dir.write("inverted.rib", world("Procedural \"DelayedReadArchive\" [\"parts/tri.rib\"] [1 -1 -1 1 -1 1]"));
  ASSERT_TRUE(readRibFile(inverted, options, &error)) << error.format();
  EXPECT_NE(warnings.str().find("has a minimum above its maximum"), std::string::npos) << warnings.str();
}

// --- Surfaces and attributes ---

TEST(RibSurfaces, StandardSurfacesAndTheirParameters) {
  ReadResult r = read(world(
      "Color [0.5 0.5 0.5]\nOpacity [1 0.5 0.25]\n"
      "Surface \"plastic\" \"Ks\" [0.7] \"roughness\" [0.2] \"color specularcolor\" [1 0 0]\n" +
      std::string(kTriangle) + "Surface \"metal\"\n" + kTriangle +
      "Surface \"shinymetal\" \"Kr\" [0.6]\n" + kTriangle + "Surface \"mirror\"\n" + kTriangle +
      "Surface \"glass\" \"eta\" [1.33] \"transmitcolor\" [0.9 1 0.9]\n" + kTriangle +
      "Surface \"constant\"\n" + kTriangle + "Surface \"matte\" \"Kd\" [0.3]\n" + kTriangle));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 7u);
  const Material& plastic = materialOf(*r.scene, 0);
  EXPECT_EQ(plastic.type, SurfaceType::Plastic);
  EXPECT_FLOAT_EQ(plastic.Ks, 0.7f);
  EXPECT_FLOAT_EQ(plastic.Kd, 0.5f);
  EXPECT_FLOAT_EQ(plastic.roughness, 0.2f);
  expectNear(plastic.specularColor, glm::vec3(1, 0, 0));
  expectNear(plastic.opacity, glm::vec3(1, 0.5f, 0.25f));
  expectNear(plastic.color, glm::vec3(0.5f));
  EXPECT_EQ(materialOf(*r.scene, 1).type, SurfaceType::Metal);
  EXPECT_FLOAT_EQ(materialOf(*r.scene, 1).Ks, 1.0f);
  EXPECT_EQ(materialOf(*r.scene, 2).type, SurfaceType::Mirror);
  EXPECT_FLOAT_EQ(materialOf(*r.scene, 2).Kr, 0.6f);
  EXPECT_EQ(materialOf(*r.scene, 3).type, SurfaceType::Mirror);
  EXPECT_FLOAT_EQ(materialOf(*r.scene, 3).Kr, 1.0f);
  const Material& glass = materialOf(*r.scene, 4);
  EXPECT_EQ(glass.type, SurfaceType::Glass);
  EXPECT_FLOAT_EQ(glass.eta, 1.33f);
  expectNear(glass.transmitColor, glm::vec3(0.9f, 1, 0.9f));
  EXPECT_EQ(materialOf(*r.scene, 5).type, SurfaceType::Constant);
  const Material& matte = materialOf(*r.scene, 6);
  EXPECT_EQ(matte.type, SurfaceType::Matte);
  EXPECT_FLOAT_EQ(matte.Ka, 1.0f);
  EXPECT_FLOAT_EQ(matte.Kd, 0.3f);
  EXPECT_EQ(r.warnings, "");
  EXPECT_FALSE(read(world("Surface \"plastic\" \"roughness\" [\"rough\"]")).scene);
  EXPECT_FALSE(read(world("Surface \"glass\" \"eta\" [0]")).scene);
  ReadResult unknown = read(world("Surface \"plastic\" \"Kt\" [1]"));
  EXPECT_NE(unknown.warnings.find("parameter 'Kt' is not supported"), std::string::npos);
}

TEST(RibSurfaces, SidesAndOrientation) {
  ReadResult r = read(world(std::string(kTriangle) + "Sides 1\n" + kTriangle +
                            "Orientation \"inside\"\n" + kTriangle + "ReverseOrientation\n" +
                            kTriangle + "AttributeBegin\nOrientation \"rh\"\n" + kTriangle +
                            "AttributeEnd\n" + kTriangle));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_TRUE(materialOf(*r.scene, 0).twoSided);
  EXPECT_FALSE(materialOf(*r.scene, 0).reverseOrientation);
  EXPECT_FALSE(materialOf(*r.scene, 1).twoSided);
  EXPECT_TRUE(materialOf(*r.scene, 2).reverseOrientation);
  EXPECT_FALSE(materialOf(*r.scene, 3).reverseOrientation);  // inside, then reversed
  EXPECT_TRUE(materialOf(*r.scene, 4).reverseOrientation);
  EXPECT_FALSE(materialOf(*r.scene, 5).reverseOrientation);  // restored by AttributeEnd
  EXPECT_FALSE(read(world("Sides 3")).scene);
  EXPECT_FALSE(read(world("Orientation \"up\"")).scene);
}

// RI spec, "Orientation": the current orientation flips whenever the current coordinate system's
// handedness does, and a primitive is inside out when the two differ. So a mirroring transform
// keeps a polygon facing the way it faced (its winding is reversed back), and "lh"/"rh" are
// judged against the handedness in force (camera space is left-handed; `Scale 1 1 -1` before
// WorldBegin, as Maya exporters write, makes the world right-handed).
TEST(RibSurfaces, OrientationFollowsTheHandednessOfTheCoordinateSystem) {
  auto normalZ = [](const Mesh& m) {
    const glm::vec3 a = m.P[m.indices[0]], b = m.P[m.indices[1]], c = m.P[m.indices[2]];
    return glm::cross(b - a, c - a).z;
  };
  for (const char* prim : {"Polygon \"P\" [0 0 0  1 0 0  0 1 0]",
                           "PointsPolygons [3] [0 1 2] \"P\" [0 0 0  1 0 0  0 1 0]",
                           "GeneralPolygon [3] \"P\" [0 0 0  1 0 0  0 1 0]"}) {
    SCOPED_TRACE(prim);
    ReadResult plain = read(world(prim));
    ASSERT_TRUE(plain.scene) << plain.error.format();
    // The triangle lies in z = 0: its normal is the mirror image of the unmirrored one, so it
    // keeps its z unless the mirror is in z.
    for (const auto& [mirror, zSign] : {std::pair<const char*, float>{"Scale -1 1 1", 1.0f},
                                        {"Scale 1 -1 1", 1.0f}, {"Scale -2 3 1", 1.0f},
                                        {"Scale 2 3 -1", -1.0f}, {"Scale -2 -3 -1", -1.0f}}) {
      SCOPED_TRACE(mirror);
      ReadResult mirrored = read(world(std::string(mirror) + "\n" + prim));
      ASSERT_TRUE(mirrored.scene) << mirrored.error.format();
      EXPECT_GT(zSign * normalZ(mirrored.scene->meshes[0]) * normalZ(plain.scene->meshes[0]), 0.0f);
      EXPECT_FALSE(materialOf(*mirrored.scene, 0).reverseOrientation);
    }
  }
  const std::string maya = "Scale 1 1 -1\n";
  ReadResult r = read(maya + world(std::string("Orientation \"rh\"\n") + kTriangle + "Orientation \"lh\"\n" +
                                   kTriangle + "Orientation \"outside\"\n" + kTriangle));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_FALSE(materialOf(*r.scene, 0).reverseOrientation);  // rh in a right-handed world
  EXPECT_TRUE(materialOf(*r.scene, 1).reverseOrientation);
  EXPECT_FALSE(materialOf(*r.scene, 2).reverseOrientation);
  // Set before the camera's mirror, "lh" is judged in camera space: it stays outside.
  ReadResult before = read("Orientation \"lh\"\n" + maya + world(kTriangle));
  ASSERT_TRUE(before.scene) << before.error.format();
  EXPECT_FALSE(materialOf(*before.scene, 0).reverseOrientation);
  // In a mirrored object space, "lh" is the other handedness: inside out.
  ReadResult inner = read(world(std::string("Scale -1 1 1\nOrientation \"lh\"\n") + kTriangle +
                                "Orientation \"rh\"\n" + kTriangle));
  ASSERT_TRUE(inner.scene) << inner.error.format();
  EXPECT_TRUE(materialOf(*inner.scene, 0).reverseOrientation);
  EXPECT_FALSE(materialOf(*inner.scene, 1).reverseOrientation);
}

TEST(RibSurfaces, VisibilityTransmissionControlsShadowCasting) {
  ReadResult r = read(world(std::string(kTriangle) + "AttributeBegin\n" +
                            "Attribute \"visibility\" \"int transmission\" [0]\n" + kTriangle +
                            "Attribute \"visibility\" \"string transmission\" [\"opaque\"]\n" +
                            kTriangle + "Attribute \"visibility\" \"transmission\" [\"transparent\"]\n" +
                            kTriangle + "AttributeEnd\n" + kTriangle +
                            "Attribute \"visibility\" \"int camera\" [1]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_TRUE(materialOf(*r.scene, 0).castsShadows);
  EXPECT_FALSE(materialOf(*r.scene, 1).castsShadows);
  EXPECT_TRUE(materialOf(*r.scene, 2).castsShadows);
  EXPECT_TRUE(materialOf(*r.scene, 2).opaqueShadows);  // "opaque": a full shadow whatever Os
  EXPECT_FALSE(materialOf(*r.scene, 0).opaqueShadows);
  EXPECT_FALSE(materialOf(*r.scene, 3).castsShadows);
  EXPECT_TRUE(materialOf(*r.scene, 4).castsShadows);  // restored by AttributeEnd
  // A Surface after the attribute keeps it (it made a new material that cast shadows again).
  ReadResult after = read(world("Attribute \"visibility\" \"int transmission\" [0]\nSurface \"plastic\"\n" +
                                std::string(kTriangle)));
  ASSERT_TRUE(after.scene) << after.error.format();
  EXPECT_FALSE(materialOf(*after.scene, 0).castsShadows);
  EXPECT_NE(r.warnings.find("'visibility' 'camera' ignored"), std::string::npos) << r.warnings;
  ReadResult bad = read(world("Attribute \"visibility\" \"string transmission\" [\"glassy\"]"));
  EXPECT_FALSE(bad.scene);
  EXPECT_NE(bad.error.format().find("unknown transmission 'glassy'"), std::string::npos)
      << bad.error.format();
}

TEST(RibSurfaces, OlderDisplacementBoundSpelling) {
  test::TestShaderProvider shaders;
  ReadResult r = read(world("Scale 2 2 2\nAttribute \"bound\" \"displacement\" [0.25]\n"
                            "Displacement \"push\"\nSphere 1 -1 1 360"),
                      &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->displacements.size(), 1u);
  EXPECT_FLOAT_EQ(r.scene->displacements[0].boundWorld, 0.5f);
  // A missing bound warns; a bound of 0 given is the scene's word (it warned as missing).
  r = read(world("Displacement \"push\"\nSphere 1 -1 1 360"), &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_NE(r.warnings.find("has no 'displacementbound'"), std::string::npos) << r.warnings;
  r = read(world("Attribute \"displacementbound\" \"sphere\" [0]\nDisplacement \"push\"\nSphere 1 -1 1 360"),
           &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.warnings.find("displacementbound"), std::string::npos) << r.warnings;
}

TEST(RibSurfaces, DisplacementKnowsTheOrientation) {
  test::TestShaderProvider shaders;
  ReadResult r = read(world("Attribute \"displacementbound\" \"sphere\" [0.1]\nDisplacement \"push\"\n" +
                            std::string(kTriangle) + "Orientation \"inside\"\n" + kTriangle +
                            "ReverseOrientation\n" + kTriangle),
                      &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 3u);
  const auto reversed = [&](size_t m) {
    return r.scene->displacements[r.scene->meshes[m].displacementIndex].reverseOrientation;
  };
  EXPECT_FALSE(reversed(0));
  EXPECT_TRUE(reversed(1));
  EXPECT_FALSE(reversed(2));  // inside, then reversed
}

TEST(RibSurfaces, DisplacementParametersTypedInlineOrByDeclare) {
  test::TestShaderProvider shaders;
  ReadResult r = read(world("Declare \"tint\" \"color\"\n"
                            "Displacement \"push\" \"float Km\" [0.2] \"tint\" [1 0 0]\n" +
                            std::string(kTriangle)),
                      &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->displacements.size(), 1u);
  ReadResult missing = read(world("\nDisplacement \"nosuch\" \"float Km\" [1]"), &shaders);
  ASSERT_FALSE(missing.scene);
  EXPECT_EQ(missing.error.line, 3);
  EXPECT_NE(missing.error.message.find("cannot load displacement shader 'nosuch'"),
            std::string::npos);
  ReadResult wrongType = read(world("Displacement \"push\" \"float Km\" [\"x\"]"), &shaders);
  EXPECT_FALSE(wrongType.scene);
}

// --- Lights ---

TEST(RibLights, StandardLightsInWorldSpace) {
  ReadResult r = read(world(
      "Translate 0 0 1\n"
      "LightSource \"pointlight\" 1 \"intensity\" [4] \"from\" [1 2 3]\n"
      "LightSource \"spotlight\" 2 \"from\" [0 0 0] \"to\" [0 -1 0] \"coneangle\" [0.4] "
      "\"conedeltaangle\" [0.1] \"beamdistribution\" [3] \"lightcolor\" [1 0.5 0.25]\n"
      "LightSource \"distantlight\" \"sun\" \"from\" [0 1 0] \"to\" [0 0 0]\n"
      "LightSource \"ambientlight\" 4 \"intensity\" [0.1]\n"
      "LightSource \"ambientlight\" 5 \"intensity\" [0.2] \"lightcolor\" [1 0 0]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->lights.size(), 5u);
  const Light& point = r.scene->lights[0];
  EXPECT_EQ(point.type, LightType::Point);
  expectNear(point.position, glm::vec3(1, 2, 4));
  expectNear(point.color, glm::vec3(4));
  EXPECT_EQ(point.handle, "1");
  EXPECT_EQ(point.sourceLine, 3);
  const Light& spot = r.scene->lights[1];
  EXPECT_EQ(spot.type, LightType::Spot);
  expectNear(spot.position, glm::vec3(0, 0, 1));
  expectNear(spot.direction, glm::vec3(0, -1, 0));
  EXPECT_FLOAT_EQ(spot.coneAngle, 0.4f);
  EXPECT_FLOAT_EQ(spot.coneDeltaAngle, 0.1f);
  EXPECT_FLOAT_EQ(spot.beamDistribution, 3.0f);
  expectNear(spot.color, glm::vec3(1, 0.5f, 0.25f));
  EXPECT_EQ(r.scene->lights[2].handle, "sun");
  expectNear(r.scene->lights[2].direction, glm::vec3(0, -1, 0));
  // The older view is kept in step.
  ASSERT_EQ(r.scene->distantLights.size(), 1u);
  expectNear(r.scene->distantLights[0].directionToLight, glm::vec3(0, 1, 0));
  expectNear(r.scene->ambientColor, glm::vec3(0.3f, 0.1f, 0.1f));
  EXPECT_NEAR(r.scene->ambient, 0.5f / 3.0f, 1e-6f);
  EXPECT_FALSE(read(world("LightSource \"spotlight\" 1 \"coneangle\" [4]")).scene);
  EXPECT_FALSE(read(world("LightSource \"pointlight\" 1 \"from\" [1 2]")).scene);
  // Coincident from and to: a light that lights nothing (RenderMan renders the frame), warned.
  ReadResult same = read(world("LightSource \"distantlight\" 1 \"from\" [1 1 1] \"to\" [1 1 1]"));
  ASSERT_TRUE(same.scene);
  ASSERT_EQ(same.scene->lights.size(), 1u);
  EXPECT_EQ(same.scene->lights[0].color, glm::vec3(0.0f));
}

TEST(RibLights, AreaLightsRectangleAndDisk) {
  ReadResult r = read(world(
      "Translate 0 3 0\nRotate 90 1 0 0\n"
      "LightSource \"arealight\" 1 \"float width\" [2] \"float height\" [1] \"int samples\" [9]\n"
      "LightSource \"arealight\" 2 \"string shape\" [\"disk\"] \"radius\" [0.5]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->lights.size(), 2u);
  const Light& rect = r.scene->lights[0];
  EXPECT_EQ(rect.type, LightType::Area);
  EXPECT_EQ(rect.shape, AreaShape::Rectangle);
  EXPECT_EQ(rect.samples, 9);
  expectNear(rect.position, glm::vec3(0, 3, 0));
  // Rotate 90 about x takes light-space +z to world -y: the light faces down.
  expectNear(rect.direction, glm::vec3(0, -1, 0));
  EXPECT_NEAR(glm::length(rect.edgeU), 2.0f, 1e-5f);
  EXPECT_NEAR(glm::length(rect.edgeV), 1.0f, 1e-5f);
  expectNear(rect.corner + 0.5f * (rect.edgeU + rect.edgeV), rect.position);
  EXPECT_GT(glm::dot(glm::cross(rect.edgeU, rect.edgeV), rect.direction), 0.0f);
  const Light& disk = r.scene->lights[1];
  EXPECT_EQ(disk.shape, AreaShape::Disk);
  EXPECT_FLOAT_EQ(disk.radius, 0.5f);
  EXPECT_FALSE(read(world("LightSource \"arealight\" 1 \"string shape\" [\"star\"]")).scene);
  EXPECT_FALSE(read(world("LightSource \"arealight\" 1 \"samples\" [0]")).scene);
}

TEST(RibLights, LightsBeforeWorldBeginAreInCameraSpace) {
  // The camera sits at world (0, 0, -5) looking down +z; a light at the eye in camera space.
  ReadResult r = read("LightSource \"pointlight\" 1 \"from\" [0 0 0]\n"
                      "LightSource \"distantlight\" 2\nTranslate 0 0 5\n"
                      "LightSource \"pointlight\" 3\n" + world(kTriangle));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->lights.size(), 3u);
  expectNear(r.scene->lights[0].position, glm::vec3(0, 0, -5));
  expectNear(r.scene->lights[1].direction, glm::vec3(0, 0, 1));
  expectNear(r.scene->lights[2].position, glm::vec3(0, 0, 0));  // placed like the world
  EXPECT_EQ(r.scene->meshes[0].lights, (std::vector<uint32_t>{0, 1, 2}));
}

TEST(RibLights, IlluminateSelectsTheLightsOfEachMesh) {
  ReadResult r = read(world("LightSource \"pointlight\" 1\nLightSource \"ambientlight\" \"amb\"\n" +
                            std::string(kTriangle) +
                            "AttributeBegin\nIlluminate 1 0\n" + kTriangle +
                            "LightSource \"distantlight\" 3\n" + kTriangle +
                            "AttributeEnd\n" + kTriangle + "Illuminate \"amb\" 0\n" + kTriangle +
                            "Illuminate 3 1\n" + kTriangle));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 6u);
  using L = std::vector<uint32_t>;
  EXPECT_EQ(r.scene->meshes[0].lights, (L{0, 1}));
  EXPECT_EQ(r.scene->meshes[1].lights, (L{1}));
  EXPECT_EQ(r.scene->meshes[2].lights, (L{1, 2}));
  EXPECT_EQ(r.scene->meshes[3].lights, (L{0, 1}));  // the block's changes end at AttributeEnd
  EXPECT_EQ(r.scene->meshes[4].lights, (L{0}));
  EXPECT_EQ(r.scene->meshes[5].lights, (L{0, 2}));
  ReadResult bad = read(world("\nIlluminate 7 1"));
  ASSERT_FALSE(bad.scene);
  EXPECT_EQ(bad.error.format(), "/scenes/test.rib:3: error: 'Illuminate': no light with handle '7'");
}

// --- Instancing ---

TEST(RibObjects, InstancesReplayTheObjectUnderTheCurrentTransform) {
  ReadResult r = read(world("ObjectBegin \"tri\"\nColor [1 0 0]\n" + std::string(kTriangle) +
                            "ObjectEnd\nObjectBegin 2\nTranslate 0 0 1\nObjectInstance \"tri\"\n"
                            "ObjectEnd\n"
                            "Translate 5 0 0\nObjectInstance \"tri\"\nTranslate 5 0 0\n"
                            "ObjectInstance 2\n" + kTriangle));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 3u);
  expectNear(r.scene->meshes[0].P[1], glm::vec3(6, 0, 0));
  expectNear(r.scene->meshes[1].P[1], glm::vec3(11, 0, 1));
  expectNear(materialOf(*r.scene, 1).color, glm::vec3(1, 0, 0));
  // The instance's attributes do not leak out.
  expectNear(materialOf(*r.scene, 2).color, glm::vec3(1, 1, 1));
  expectNear(r.scene->meshes[2].P[1], glm::vec3(11, 0, 0));
  EXPECT_FALSE(read(world("ObjectInstance \"none\"")).scene);
  EXPECT_FALSE(read(world("ObjectBegin 1\n" + std::string(kTriangle))).scene);  // no ObjectEnd
  EXPECT_FALSE(read(world("ObjectEnd")).scene);
  ReadResult self = read(world("ObjectBegin 1\nObjectInstance 1\nObjectEnd\nObjectInstance 1"));
  EXPECT_FALSE(self.scene);
  EXPECT_NE(self.error.message.find("nested more than"), std::string::npos);
}

// --- Polygons ---

TEST(RibPolygons, GeneralPolygonsWithHolesAndConcaveFaces) {
  ReadResult r = read(world(
      "PointsGeneralPolygons [2 1] [4 4 3]"
      " [0 1 2 3  4 5 6 7  0 1 8]"
      " \"P\" [0 0 0  4 0 0  4 4 0  0 4 0  1 1 0  2 1 0  2 2 0  1 2 0  2 -2 0]\n"
      "Polygon \"P\" [0 0 0  2 0 0  2 1 0  1 1 0  1 2 0  0 2 0]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 2u);
  auto area = [](const Mesh& m) {
    float a = 0;
    for (size_t i = 0; i < m.indices.size(); i += 3)
      a += 0.5f * glm::cross(m.P[m.indices[i + 1]] - m.P[m.indices[i]],
                             m.P[m.indices[i + 2]] - m.P[m.indices[i]]).z;
    return a;
  };
  EXPECT_NEAR(area(r.scene->meshes[0]), 16.0f - 1.0f - 4.0f, 1e-4f);  // square - hole - triangle
  EXPECT_NEAR(area(r.scene->meshes[1]), 3.0f, 1e-5f);                 // the concave L
  EXPECT_FALSE(read(world("PointsGeneralPolygons [2] [4] [0 1 2 3] \"P\" [0 0 0 1 0 0 1 1 0 0 1 0]"))
                   .scene);
}

TEST(RibPolygons, PrimvarClasses) {
  ReadResult r = read(world(
      "PointsPolygons [3 3] [0 1 2  0 2 3] \"P\" [0 0 0  1 0 0  1 1 0  0 1 0]"
      " \"uniform color Cs\" [1 0 0  0 0 1]"
      " \"facevarying float[2] st\" [0 0  1 0  1 1  0 0  1 1  0 1]"
      " \"constant normal N\" [0 0 1]\n"
      "PointsPolygons [3 3] [0 1 2  0 2 3] \"P\" [0 0 0  1 0 0  1 1 0  0 1 0]"
      " \"varying float s\" [0 1 1 0] \"t\" [0 0 1 1]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  const Mesh& split = r.scene->meshes[0];
  ASSERT_EQ(split.P.size(), 6u);  // per face corner
  ASSERT_EQ(split.Cs.size(), 6u);
  expectNear(split.Cs[2], glm::vec3(1, 0, 0));
  expectNear(split.Cs[3], glm::vec3(0, 0, 1));
  EXPECT_EQ(split.st[5], glm::vec2(0, 1));
  expectNear(split.N[4], glm::vec3(0, 0, 1));
  const Mesh& shared = r.scene->meshes[1];
  ASSERT_EQ(shared.P.size(), 4u);
  EXPECT_EQ(shared.st[2], glm::vec2(1, 1));
  ReadResult bad = read(world("PointsPolygons [3] [0 1 2] \"P\" [0 0 0  1 0 0  1 1 0]"
                              " \"vertex color Cs\" [1 0 0]"));
  ASSERT_FALSE(bad.scene);
  EXPECT_NE(bad.error.message.find("vertex 'Cs' needs 9 numbers"), std::string::npos)
      << bad.error.message;
  EXPECT_FALSE(read(world("PointsPolygons [3] [0 1 2] \"P\" [0 0 0  1 0 0  1 1 0]"
                          " \"Cs\" [1 0 0 1]")).scene);
}

// s and t are separate primitive variables: the one not given keeps its default, (u, v), the
// object-space (x, y) on polygons (it was 0).
TEST(RibPolygons, SOrTAloneLeavesTheOtherAtItsDefault) {
  ReadResult r = read(world("Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] \"s\" [0 1 1 0]\n"
                            "PointsPolygons [4] [0 1 2 3] \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]"
                            " \"uniform float t\" [7]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 2u);
  for (int m = 0; m < 2; ++m) {
    const Mesh& mesh = r.scene->meshes[size_t(m)];
    ASSERT_EQ(mesh.st.size(), mesh.P.size());
    for (size_t i = 0; i < mesh.P.size(); ++i) {
      const float expectedS[4] = {0, 1, 1, 0};
      if (m == 0) EXPECT_EQ(mesh.st[i], glm::vec2(expectedS[i % 4], mesh.uv[i].y)) << i;
      else EXPECT_EQ(mesh.st[i], glm::vec2(mesh.uv[i].x, 7.0f)) << i;
    }
  }
}

TEST(RibPolygons, QuadricPrimvarsAreConstantOrCornerValues) {
  ReadResult r = read(world("Sphere 1 -1 1 360 \"constant color Cs\" [1 0 0]\n"
                            "Cylinder 1 0 1 360 \"st\" [0 0  2 0  0 3  2 3]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 2u);
  const Mesh& sphere = r.scene->meshes[0];
  ASSERT_EQ(sphere.Cs.size(), sphere.P.size());
  expectNear(sphere.Cs[7], glm::vec3(1, 0, 0));
  const Mesh& cylinder = r.scene->meshes[1];
  ASSERT_EQ(cylinder.st.size(), cylinder.P.size());
  for (size_t i = 0; i < cylinder.P.size(); ++i) {
    EXPECT_NEAR(cylinder.st[i].x, 2.0f * cylinder.uv[i].x, 1e-5f);
    EXPECT_NEAR(cylinder.st[i].y, 3.0f * cylinder.uv[i].y, 1e-5f);
  }
  EXPECT_FALSE(read(world("Sphere 1 -1 1 360 \"Cs\" [1 0]")).scene);
  EXPECT_FALSE(read(world("Disk 0 1 360 \"N\" [0 0 1]")).scene);
}

// --- Patches ---

TEST(RibPatches, BicubicBezierPatchInterpolatesItsCorners) {
  std::string P;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i)
      P += std::to_string(i) + " " + std::to_string(j) + " " +
           ((i == 1 || i == 2) && (j == 1 || j == 2) ? "1" : "0") + "  ";
  ReadResult r = read(world("Patch \"bicubic\" \"P\" [" + P + "]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  const Mesh& m = r.scene->meshes.at(0);
  EXPECT_GT(m.numTriangles(), 2u);
  ASSERT_EQ(m.N.size(), m.P.size());
  float maxZ = 0;
  for (size_t i = 0; i < m.P.size(); ++i) {
    maxZ = std::max(maxZ, m.P[i].z);
    if (m.uv[i] == glm::vec2(1, 1)) {
      expectNear(m.P[i], glm::vec3(3, 3, 0));
    }
    if (m.uv[i] == glm::vec2(0.5f, 0.5f)) {
      EXPECT_NEAR(m.P[i].z, 0.5625f, 1e-5f);  // (3/4)^2
    }
  }
  EXPECT_NEAR(maxZ, 0.5625f, 1e-5f);
  expectNear(m.N[0], glm::vec3(0, 0, 1));  // dPdu x dPdv at a flat corner
}

// The copies of one point of a surface (a cone's apex, a patch row collapsed to a pole) share one
// normal, so that displacing along N moves them alike. A patch's pole had cleared the normals of
// the whole primitive (displaced along facet normals, every edge opened) and a cone's apex copies
// each had their own column's normal (the apex opened into a hole).
TEST(RibPatches, CoincidentPointsOfASurfaceShareOneNormal) {
  const std::string lid =
      "Patch \"bicubic\" \"P\" [0 0 -0.8 0 0 -0.8 0 0 -0.8 0 0 -0.8  -0.9 -0.3 -0.5 -0.3 -0.9 -0.5 0.3 -0.9 -0.5 "
      "0.9 -0.3 -0.5  -1 0.2 0.2 -0.4 -0.5 0.3 0.4 -0.5 0.3 1 0.2 0.2  -1 0.9 0.5 -0.3 0.9 0.6 0.3 0.9 0.6 1 0.9 0.5]\n";
  for (const std::string& shape : {lid, std::string("Cone 1.2 0.8 360\n"), std::string("Paraboloid 0.8 0 1 360\n"),
                                   std::string("Hyperboloid 0.5 0 -0.5  -0.5 0 0.5 360\n")}) {
    SCOPED_TRACE(shape);
    const ReadResult r = read(world(shape));
    ASSERT_TRUE(r.scene) << r.error.format();
    const Mesh& mesh = r.scene->meshes.at(0);
    ASSERT_EQ(mesh.N.size(), mesh.P.size());
    std::map<std::tuple<float, float, float>, std::set<std::tuple<float, float, float>>> normals;
    for (size_t i = 0; i < mesh.P.size(); ++i)
      normals[{mesh.P[i].x, mesh.P[i].y, mesh.P[i].z}].insert({mesh.N[i].x, mesh.N[i].y, mesh.N[i].z});
    for (const auto& [point, ns] : normals)
      EXPECT_EQ(ns.size(), 1u) << std::get<0>(point) << " " << std::get<1>(point) << " " << std::get<2>(point);
    EXPECT_LT(normals.size(), mesh.P.size());  // there were copies to share
    for (const glm::vec3& n : mesh.N) EXPECT_NEAR(glm::length(n), 1.0f, 1e-4f);
  }
}

// dPdu and dPdv on quadrics, patches and NURBS are the surface's own derivatives (RI: N is their
// cross product), shared by a point's copies. They were the mean of the facets' around each
// vertex: 24-51% off on a hyperboloid (one row of facets in v) and not tangent to N.
TEST(RibPatches, DerivativesAreTheSurfacesOwn) {
  const float thetamax = glm::radians(300.0f);
  const ReadResult r = read(world("Hyperboloid 1 0 -0.5  0.5 0.5 0.7  300\nSphere 1 -0.5 0.8 270\n"
                                  "NuPatch 5 3 [0 0 0 0.3 1.7 2 2 2] 0 2 4 3 [1 1 1 1.2 3 3 3] 1 3 \"Pw\" [" +
                                  [] {
                                    std::string pw;  // a rational, bumpy sheet
                                    for (int j = 0; j < 4; ++j)
                                      for (int i = 0; i < 5; ++i) {
                                        const float w = (i + j) % 3 == 0 ? 1.5f : 1.0f;
                                        pw += std::to_string(w * float(i)) + " " + std::to_string(w * float(j)) + " " +
                                              std::to_string(w * 0.3f * std::sin(float(i * 3 + j))) + " " + std::to_string(w) + "  ";
                                      }
                                    return pw;
                                  }() + "]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 3u);
  for (size_t m = 0; m < 3; ++m) {
    SCOPED_TRACE(m);
    const Mesh& mesh = r.scene->meshes[m];
    ASSERT_EQ(mesh.dPdu.size(), mesh.P.size());
    ASSERT_EQ(mesh.dPdv.size(), mesh.P.size());
    for (size_t i = 0; i < mesh.P.size(); ++i) {
      if (glm::length(mesh.dPdu[i]) < 1e-3f || glm::length(mesh.dPdv[i]) < 1e-3f) continue;  // a pole
      // Tangent: N is their cross product.
      EXPECT_NEAR(glm::dot(glm::normalize(mesh.dPdu[i]), mesh.N[i]), 0.0f, 2e-3f) << i;
      EXPECT_NEAR(glm::dot(glm::normalize(mesh.dPdv[i]), mesh.N[i]), 0.0f, 2e-3f) << i;
      if (m == 2) continue;
      // Quadrics turn about z with u: dP/du = thetamax (-y, x, 0).
      const float sweep = m == 0 ? thetamax : glm::radians(270.0f);
      const glm::vec3 expected = sweep * glm::vec3(-mesh.P[i].y, mesh.P[i].x, 0.0f);
      EXPECT_LT(glm::length(mesh.dPdu[i] - expected), 1e-3f * glm::length(expected)) << i;
      if (m == 0) {
        // dP/dv: the generating segment (p2 - p1) turned with the point.
        const float angle = mesh.uv[i].x * thetamax;
        const glm::vec3 d(-0.5f * std::cos(angle) - 0.5f * std::sin(angle), -0.5f * std::sin(angle) + 0.5f * std::cos(angle), 1.2f);
        EXPECT_LT(glm::length(mesh.dPdv[i] - d), 1e-3f) << i;
      }
    }
  }
}

// A negative sphere radius follows the RI formula x = r cos(phi) cos(theta), as the other quadrics'
// radii do: half a turn about z (u starts at -x), the same z range, still facing out. It was taken
// as |radius|, so a partial sweep covered the other half.
TEST(RibPatches, NegativeSphereRadiusTurnsItHalfATurn) {
  const ReadResult r = read(world("Sphere -1 -0.5 0.5 180\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  const Mesh& mesh = r.scene->meshes.at(0);
  bool sawStart = false;
  for (size_t i = 0; i < mesh.P.size(); ++i) {
    EXPECT_LE(mesh.P[i].y, 1e-5f) << i;  // theta in [pi, 2 pi]: y <= 0
    EXPECT_GT(glm::dot(mesh.N[i], mesh.P[i]), 0.0f) << i;  // outward
    if (mesh.uv[i] == glm::vec2(0.0f, 0.0f)) {
      sawStart = true;
      expectNear(mesh.P[i], glm::vec3(-std::sqrt(0.75f), 0.0f, -0.5f));
    }
  }
  EXPECT_TRUE(sawStart);
}

// "Pz" (RI 3.2): a height field whose x and y are the surface parameters; it was refused as
// lacking "P".
TEST(RibPatches, PzIsAHeightFieldOverTheParameters) {
  const ReadResult r = read(world("Patch \"bilinear\" \"Pz\" [0 0.5 0.5 1]\n"
                                  "PatchMesh \"bicubic\" 4 \"nonperiodic\" 4 \"nonperiodic\" \"Pz\" [0 0 0 0  0 1 1 0  0 1 1 0  0 0 0 0]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 2u);
  for (const Mesh& mesh : r.scene->meshes)
    for (size_t i = 0; i < mesh.P.size(); ++i) {
      EXPECT_NEAR(mesh.P[i].x, mesh.uv[i].x, 1e-6f) << i;
      EXPECT_NEAR(mesh.P[i].y, mesh.uv[i].y, 1e-6f) << i;
    }
  const Mesh& bilinear = r.scene->meshes[0];
  for (size_t i = 0; i < bilinear.P.size(); ++i)
    EXPECT_NEAR(bilinear.P[i].z, 0.5f * (bilinear.uv[i].x + bilinear.uv[i].y), 1e-6f) << i;
  const Mesh& bump = r.scene->meshes[1];
  for (size_t i = 0; i < bump.P.size(); ++i) {
    if (bump.uv[i] == glm::vec2(0.5f, 0.5f)) {
      EXPECT_NEAR(bump.P[i].z, 0.5625f, 1e-5f);  // (3/4)^2
    }
  }
  EXPECT_TRUE(r.warnings.empty()) << r.warnings;
}

// Where patches meet at a crease, a point's normal is the mean of both sides', not one side's: a
// square tube's corner took the next face's normal, and displacement pushed the crease sideways.
TEST(RibPatches, CreasesBetweenPatchesTakeBothSidesNormals) {
  const ReadResult r = read(world("PatchMesh \"bilinear\" 4 \"periodic\" 2 \"nonperiodic\" \"P\" [1 0 0  0 1 0  -1 0 0  0 -1 0   "
                                  "1 0 1  0 1 1  -1 0 1  0 -1 1]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  const Mesh& mesh = r.scene->meshes.at(0);
  bool sawCorner = false;
  for (size_t i = 0; i < mesh.P.size(); ++i) {
    for (const glm::vec3 corner : {glm::vec3(1, 0, 0), glm::vec3(0, 1, 0), glm::vec3(-1, 0, 0), glm::vec3(0, -1, 0)}) {
      if (glm::length(glm::vec3(mesh.P[i].x, mesh.P[i].y, 0) - corner) > 1e-5f) continue;
      sawCorner = true;
      EXPECT_GT(std::fabs(glm::dot(mesh.N[i], corner)), 0.9999f) << i;  // outward or inward, along the bisector
    }
  }
  EXPECT_TRUE(sawCorner);
}

TEST(RibPatches, PatchMeshBasesAndWrapping) {
  // A periodic b-spline tube: 8 control points around, 4 along; no seam crack.
  std::string P;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 8; ++i) {
      const float a = float(i) * 2.0f * float(M_PI) / 8.0f;
      P += std::to_string(std::cos(a)) + " " + std::to_string(std::sin(a)) + " " +
           std::to_string(j) + "  ";
    }
  ReadResult r = read(world("Basis \"b-spline\" 1 \"b-spline\" 1\n"
                            "PatchMesh \"bicubic\" 8 \"periodic\" 4 \"nonperiodic\" \"P\" [" + P +
                            "]\n"
                            "Basis \"catmull-rom\" 1 [-1 3 -3 1  3 -6 3 0  -3 3 0 0  1 0 0 0] 3\n"
                            "PatchMesh \"bilinear\" 3 \"nonperiodic\" 2 \"nonperiodic\" "
                            "\"P\" [0 0 0  1 0 0  2 0 0  0 1 0  1 1 0  2 1 0]"
                            " \"Cs\" [1 0 0  0 1 0  0 0 1  1 1 1  1 1 1  1 1 1]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 2u);
  const Mesh& tube = r.scene->meshes[0];
  for (size_t i = 0; i < tube.P.size(); ++i) {
    const float radius = std::hypot(tube.P[i].x, tube.P[i].y);
    EXPECT_GT(radius, 0.8f);
    EXPECT_LT(radius, 1.0f);
    EXPECT_GE(tube.P[i].z, 1.0f - 1e-5f);  // the nonperiodic b-spline spans z in [1, 2]
    EXPECT_LE(tube.P[i].z, 2.0f + 1e-5f);
  }
  // The u = 1 column repeats the u = 0 column exactly.
  int seamPairs = 0;
  for (size_t i = 0; i < tube.P.size(); ++i) {
    if (tube.uv[i].x != 1.0f) continue;
    for (size_t k = 0; k < tube.P.size(); ++k) {
      if (tube.uv[k].x == 0.0f && tube.uv[k].y == tube.uv[i].y) {
        EXPECT_EQ(tube.P[k], tube.P[i]);
        ++seamPairs;
      }
    }
  }
  EXPECT_GT(seamPairs, 2);
  // Flat patches, but Cs is not affine over them (c00 + c11 != c10 + c01): two triangles each
  // would interpolate it along a diagonal, so they are sampled, and the centre of the first patch
  // has the bilinear average of its corners.
  const Mesh& flat = r.scene->meshes[1];
  EXPECT_GT(flat.numTriangles(), 4u);
  ASSERT_EQ(flat.Cs.size(), flat.P.size());
  int centres = 0;
  for (size_t i = 0; i < flat.P.size(); ++i) {
    if (flat.uv[i] == glm::vec2(0.5f, 0.0f)) expectNear(flat.Cs[i], glm::vec3(0, 1, 0));
    if (flat.uv[i] == glm::vec2(0.25f, 0.5f)) {
      expectNear(flat.Cs[i], glm::vec3(0.75f, 0.75f, 0.5f));
      expectNear(flat.P[i], glm::vec3(0.5f, 0.5f, 0));
      ++centres;
    }
  }
  EXPECT_EQ(centres, 1);
  EXPECT_FALSE(read(world("PatchMesh \"bicubic\" 5 \"nonperiodic\" 4 \"nonperiodic\" \"P\" [" +
                          std::string(60 * 2, ' ') + "]")).scene);
  EXPECT_FALSE(read(world("Basis \"nurbs\" 1 \"bezier\" 3")).scene);
  EXPECT_FALSE(read(world("PatchMesh \"bicubic\" 4 \"sideways\" 4 \"nonperiodic\" \"P\" [0 0 0]"))
                   .scene);
  EXPECT_FALSE(read(world("Patch \"bicubic\" \"P\" [0 0 0]")).scene);
}

// SubdivisionMesh "catmull-clark": a cube's control mesh becomes a closed rounded surface inside
// the cube with outward normals; a flat open grid stays flat, reaches its boundary and keeps its
// corners; uniform colours follow their faces; bad indices and counts are errors at the call.
TEST(RibSubdivision, CatmullClarkCubeAndOpenGrid) {
  const std::string cube =
      "SubdivisionMesh \"catmull-clark\" [4 4 4 4 4 4]\n"
      "  [0 1 3 2  2 3 5 4  4 5 7 6  6 7 1 0  1 7 5 3  6 0 2 4]\n"
      "  [\"interpolateboundary\"] [0 0] [] []\n"
      "  \"P\" [-1 -1 1  1 -1 1  -1 1 1  1 1 1  -1 1 -1  1 1 -1  -1 -1 -1  1 -1 -1]\n"
      "  \"uniform color Cs\" [1 0 0  0 1 0  0 0 1  1 1 0  1 0 1  0 1 1]\n";
  ReadResult r = read(world(cube));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 1u);
  const Mesh& m = r.scene->meshes[0];
  EXPECT_GE(m.numTriangles(), 6u * 16u * 2u);  // at least 2 levels of quads
  ASSERT_EQ(m.N.size(), m.P.size());
  float nearest = 10.0f;
  for (size_t i = 0; i < m.P.size(); ++i) {
    EXPECT_LE(std::max({std::fabs(m.P[i].x), std::fabs(m.P[i].y), std::fabs(m.P[i].z)}), 1.0f + 1e-5f);
    nearest = std::min(nearest, glm::length(m.P[i]));
    EXPECT_GT(glm::dot(m.N[i], m.P[i]), 0.0f) << i;  // outward
  }
  EXPECT_GT(nearest, 0.5f);
  ASSERT_EQ(m.Cs.size(), m.P.size());
  int red = 0;
  for (const glm::vec3& c : m.Cs) red += c == glm::vec3(1, 0, 0);
  EXPECT_GT(red, 0);
  // Triangles keep the control faces' winding: their normals agree with the point normals.
  for (uint32_t t = 0; t < m.numTriangles(); ++t) {
    const glm::vec3 a = m.P[m.indices[3 * t]], b = m.P[m.indices[3 * t + 1]], c = m.P[m.indices[3 * t + 2]];
    EXPECT_GT(glm::dot(glm::cross(b - a, c - a), m.N[m.indices[3 * t]]), 0.0f) << t;
  }

  r = read(world("SubdivisionMesh \"catmull-clark\" [4 4 4 4] [0 1 4 3  1 2 5 4  3 4 7 6  4 5 8 7]\n"
                 "  [\"interpolateboundary\"] [0 0] [] []\n"
                 "  \"P\" [0 0 0  1 0 0  2 0 0  0 1 0  1 1 0  2 1 0  0 2 0  1 2 0  2 2 0]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  const Mesh& grid = r.scene->meshes[0];
  bool corner = false;
  glm::vec3 lo(10.0f), hi(-10.0f);
  for (const glm::vec3& p : grid.P) {
    EXPECT_EQ(p.z, 0.0f);
    lo = glm::min(lo, p), hi = glm::max(hi, p);
    corner = corner || p == glm::vec3(2, 2, 0);
  }
  EXPECT_EQ(lo, glm::vec3(0, 0, 0));
  EXPECT_EQ(hi, glm::vec3(2, 2, 0));
  EXPECT_TRUE(corner);

  EXPECT_FALSE(read(world("SubdivisionMesh \"catmull-clark\" [4] [0 1 2 9] \"P\" [0 0 0  1 0 0  1 1 0  0 1 0]\n")).scene);
  EXPECT_FALSE(read(world("SubdivisionMesh \"catmull-clark\" [4 4] [0 1 2 3] \"P\" [0 0 0  1 0 0  1 1 0  0 1 0]\n")).scene);
  ReadResult tagged = read(world("SubdivisionMesh \"catmull-clark\" [4] [0 1 2 3] [\"stitch\" \"crease\"] [1 0 2 1] [7 0 1] [5]"
                                 " \"P\" [0 0 0  1 0 0  1 1 0  0 1 0]\n"));
  ASSERT_TRUE(tagged.scene) << tagged.error.format();
  EXPECT_NE(tagged.warnings.find("tag 'stitch' is not supported"), std::string::npos) << tagged.warnings;
  EXPECT_EQ(tagged.warnings.find("crease"), std::string::npos) << tagged.warnings;
}

// Tags as RenderMan exporters write them: creases and corners keep the cube's edges and corners,
// a hole takes its face's share of the triangles out, facevarying st follows each face; tag
// arguments that do not add up, or name missing points or faces, are errors at the call.
// A card of two back-to-back faces folds onto itself: its points' normals cancel. It is read
// with face normals and a warning (it had failed with "zero-length normal", a message about
// normals the scene never gave).
TEST(RibSubdivision, AMeshFoldedOntoItselfReadsWithFaceNormals) {
  const ReadResult r = read(world("SubdivisionMesh \"catmull-clark\" [4 4] [0 1 2 3 0 3 2 1] [] [] [] [] "
                                  "\"P\" [0 0 0 1 0 0 1 1 0 0 1 0]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_GT(r.scene->meshes.at(0).numTriangles(), 0u);
  EXPECT_TRUE(r.scene->meshes.at(0).N.empty());
  EXPECT_NE(r.warnings.find(":2: warning: 'SubdivisionMesh': the surface folds back onto itself"), std::string::npos)
      << r.warnings;
}

TEST(RibSubdivision, CreasesCornersHolesFacevaryingAndTagErrors) {
  const std::string cube =
      "SubdivisionMesh \"catmull-clark\" [4 4 4 4 4 4]\n"
      "  [0 1 3 2  2 3 5 4  4 5 7 6  6 7 1 0  1 7 5 3  6 0 2 4]\n"
      "  [\"interpolateboundary\" TAGS] [0 0 NARGS] [INTS] [FLOATS]\n"
      "  \"P\" [-1 -1 1  1 -1 1  -1 1 1  1 1 1  -1 1 -1  1 1 -1  -1 -1 -1  1 -1 -1]\n"
      "  \"facevarying float[2] st\" [0 0 1 0 1 1 0 1  0 0 1 0 1 1 0 1  0 0 1 0 1 1 0 1"
      "  0 0 1 0 1 1 0 1  0 0 1 0 1 1 0 1  0 0 1 0 1 1 0 1]\n";
  auto with = [&](const std::string& tags, const std::string& nargs, const std::string& ints, const std::string& floats) {
    std::string text = cube;
    for (const auto& [key, value] : {std::pair<std::string, std::string>{"TAGS", tags}, {"NARGS", nargs}, {"INTS", ints}, {"FLOATS", floats}})
      text.replace(text.find(key), key.size(), value);
    return read(world(text));
  };
  auto reach = [](const Mesh& m) {
    float r = 0.0f;
    for (const glm::vec3& p : m.P) r = std::max(r, glm::length(p));
    return r;
  };
  ReadResult smooth = with("", "", "", "");
  ASSERT_TRUE(smooth.scene) << smooth.error.format();
  EXPECT_EQ(smooth.warnings, "");
  const Mesh& round = smooth.scene->meshes[0];
  ASSERT_EQ(round.st.size(), round.P.size());
  for (const glm::vec2& st : round.st) EXPECT_TRUE(st.x >= 0 && st.x <= 1 && st.y >= 0 && st.y <= 1) << st.x << " " << st.y;
  EXPECT_LT(reach(round), 1.2f);

  // All twelve edges as three chains (RI_INFINITY sharpness) and one corner: a sharp cube.
  ReadResult sharp = with("\"crease\" \"crease\" \"crease\"", "5 1 5 1 6 1",
                          "0 1 3 2 0  4 5 7 6 4  0 6 1 7 3 5", "1e38 1e38 1e38");
  ASSERT_TRUE(sharp.scene) << sharp.error.format();
  // The third chain's 6-1 and 7-3 are no edges (ignored) and edge 2-4 is in no chain: points 2
  // and 4 have two sharp edges (crease rule), the other six corners three (they stay).
  auto has = [](const Mesh& m, glm::vec3 q) { return std::find(m.P.begin(), m.P.end(), q) != m.P.end(); };
  for (const glm::vec3 q : {glm::vec3(-1, -1, 1), glm::vec3(1, -1, 1), glm::vec3(1, 1, 1), glm::vec3(1, 1, -1),
                            glm::vec3(-1, -1, -1), glm::vec3(1, -1, -1)})
    EXPECT_TRUE(has(sharp.scene->meshes[0], q)) << q.x << " " << q.y << " " << q.z;
  EXPECT_FALSE(has(sharp.scene->meshes[0], glm::vec3(-1, 1, 1)));
  EXPECT_FALSE(has(round, glm::vec3(1, 1, 1)));
  ReadResult cornered = with("\"corner\"", "1 1", "3", "10");
  ASSERT_TRUE(cornered.scene) << cornered.error.format();
  EXPECT_TRUE(has(cornered.scene->meshes[0], glm::vec3(1, 1, 1)));

  ReadResult holed = with("\"hole\"", "2 0", "0 5", "");
  ASSERT_TRUE(holed.scene) << holed.error.format();
  EXPECT_EQ(3 * holed.scene->meshes[0].numTriangles(), 2 * round.numTriangles());

  for (const auto& [tags, nargs, ints, floats, message] :
       {std::tuple<const char*, const char*, const char*, const char*, const char*>{
            "\"crease\"", "2 1", "0 9", "2", "crease point 9 is out of range"},
        {"\"crease\"", "2 1", "0 1", "", "do not match"},
        {"\"crease\"", "2", "0 1", "1", "nargs"},
        {"\"hole\"", "1 0", "6", "", "hole face 6 is out of range"},
        {"\"corner\"", "1 0", "1", "", "a corner tag takes"},
        {"\"hole\"", "1 0", "1 2", "", "account for 1 intargs"}}) {
    ReadResult bad = with(tags, nargs, ints, floats);
    ASSERT_FALSE(bad.scene) << tags << " " << ints;
    EXPECT_NE(bad.error.format().find(message), std::string::npos) << bad.error.format();
    EXPECT_NE(bad.error.format().find(":4:"), std::string::npos) << bad.error.format();
  }
}

// NuPatch: the classic rational sphere (9 x 5 Pw points, degree 2) lies on the unit sphere with
// outward normals; its seam and poles are bit-identical points with one normal, so displacement
// cannot crack them; a non-rational bilinear NuPatch is the plane through its corners; malformed
// knots, orders and ranges are errors at the call.
TEST(RibPatches, NuPatchRationalSphereSeamsPolesAndErrors) {
  const std::string sphere =
      "NuPatch 9 3 [0 0 0 .25 .25 .5 .5 .75 .75 1 1 1] 0 1 5 3 [0 0 0 .5 .5 1 1 1] 0 1 \"Pw\" [PW]\n";
  std::string text = sphere;
  text.replace(text.find("PW"), 2, "0 0 -1 1 0 0 -0.707106781 0.707106781 0 0 -1 1 0 0 -0.707106781 0.707106781 0 0 -1 1 0 0 -0.707106781 0.707106781 0 0 -1 1 0 0 -0.707106781 0.707106781 0 0 -1 1 0.707106781 0 -0.707106781 0.707106781 0.5 0.5 -0.5 0.5 0 0.707106781 -0.707106781 0.707106781 -0.5 0.5 -0.5 0.5 -0.707106781 0 -0.707106781 0.707106781 -0.5 -0.5 -0.5 0.5 0 -0.707106781 -0.707106781 0.707106781 0.5 -0.5 -0.5 0.5 0.707106781 0 -0.707106781 0.707106781 1 0 0 1 0.707106781 0.707106781 0 0.707106781 0 1 0 1 -0.707106781 0.707106781 0 0.707106781 -1 0 0 1 -0.707106781 -0.707106781 0 0.707106781 0 -1 0 1 0.707106781 -0.707106781 0 0.707106781 1 0 0 1 0.707106781 0 0.707106781 0.707106781 0.5 0.5 0.5 0.5 0 0.707106781 0.707106781 0.707106781 -0.5 0.5 0.5 0.5 -0.707106781 0 0.707106781 0.707106781 -0.5 -0.5 0.5 0.5 0 -0.707106781 0.707106781 0.707106781 0.5 -0.5 0.5 0.5 0.707106781 0 0.707106781 0.707106781 0 0 1 1 0 0 0.707106781 0.707106781 0 0 1 1 0 0 0.707106781 0.707106781 0 0 1 1 0 0 0.707106781 0.707106781 0 0 1 1 0 0 0.707106781 0.707106781 0 0 1 1");
  ReadResult r = read(world(text));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.warnings, "");
  ASSERT_EQ(r.scene->meshes.size(), 1u);
  const Mesh& m = r.scene->meshes[0];
  ASSERT_EQ(m.N.size(), m.P.size());
  EXPECT_GE(m.numTriangles(), 2u * 32u * 16u);
  std::map<std::tuple<float, float, float>, glm::vec3> normalAt;
  for (size_t i = 0; i < m.P.size(); ++i) {
    EXPECT_NEAR(glm::length(m.P[i]), 1.0f, 1e-5f) << i;
    EXPECT_GT(glm::dot(m.N[i], m.P[i]), 0.99f) << i;
    // Points that coincide share their bits and their normal.
    const auto key = std::make_tuple(m.P[i].x, m.P[i].y, m.P[i].z);
    const auto [it, fresh] = normalAt.emplace(key, m.N[i]);
    if (!fresh) {
      EXPECT_EQ(it->second, m.N[i]) << i;
    }
    EXPECT_GE(m.uv[i].x, 0.0f);
    EXPECT_LE(m.uv[i].x, 1.0f);
  }
  // The seam column and the pole rows each collapse onto points shared with another column.
  EXPECT_LT(normalAt.size(), m.P.size() - 16);
  for (uint32_t t = 0; t < m.numTriangles(); ++t) {
    const glm::vec3 a = m.P[m.indices[3 * t]], b = m.P[m.indices[3 * t + 1]], c = m.P[m.indices[3 * t + 2]];
    const glm::vec3 n = glm::cross(b - a, c - a);
    if (glm::length(n) > 1e-7f) {
      EXPECT_GT(glm::dot(n, a + b + c), 0.0f) << t;  // wound outwards
    }
  }

  r = read(world("NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 2 2] 0 2 \"P\" [0 0 0  1 0 0  0 1 1  1 1 1] \"Cs\" [1 0 0  0 1 0  0 0 1  1 1 1]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  const Mesh& flat = r.scene->meshes[0];
  EXPECT_EQ(flat.numTriangles(), 2u);
  ASSERT_EQ(flat.Cs.size(), flat.P.size());
  for (size_t i = 0; i < flat.P.size(); ++i) {
    EXPECT_EQ(flat.P[i].y, flat.P[i].z);
    EXPECT_EQ(flat.uv[i].y, 2.0f * flat.P[i].y);  // v runs over the knot range [0, 2]
  }

  // A rational bilinear NuPatch is projective in (u, v): sampled, every vertex on the surface at
  // its own (u, v) (two triangles put u = 0.25 at x = -0.5, not 0.538).
  r = read(world("NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"Pw\" [-1 -1 0 1  10 -10 0 10  -1 1 0 1  1 1 0 1]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  const Mesh& rational = r.scene->meshes[0];
  EXPECT_GT(rational.numTriangles(), 2u);
  for (size_t i = 0; i < rational.P.size(); ++i) {
    const float u = rational.uv[i].x, v = rational.uv[i].y;
    const float w = (1 - v) * ((1 - u) + 10 * u) + v;
    const float x = ((1 - v) * (-(1 - u) + 10 * u) + v * (-(1 - u) + u)) / w;
    const float y = ((1 - v) * (-(1 - u) - 10 * u) + v) / w;
    EXPECT_NEAR(rational.P[i].x, x, 1e-5f) << u << " " << v;
    EXPECT_NEAR(rational.P[i].y, y, 1e-5f) << u << " " << v;
  }

  const std::pair<const char*, const char*> bad[] = {
      {"NuPatch 2 2 [0 0 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]", "uknot needs nu + uorder = 4 values, got 3"},
      {"NuPatch 2 3 [0 0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]", "at most the count"},
      {"NuPatch 2 2 [0 1 0 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]", "non-decreasing"},
      {"NuPatch 2 2 [0 0 1 1] 2 3 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]", "holds none of the knot range"},
      {"NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0]", "'P' expects 12 values"},
      {"NuPatch 2 2 [0 0 1 1] 0 1 2 2 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]", "expects nu uorder"}};
  for (const auto& [call, message] : bad) {
    ReadResult e = read(world(call));
    ASSERT_FALSE(e.scene) << call;
    EXPECT_NE(e.error.format().find(message), std::string::npos) << e.error.format();
    EXPECT_NE(e.error.format().find(":2:"), std::string::npos) << e.error.format();
  }
}

// Smooth surfaces (quadrics, patches, NURBS, subdivision meshes) are marked so that the shader's
// Ng follows their normals (Mesh::smoothSurface); polygons keep their facets' Ng, and so do patches
// whose normals the scene gave.
TEST(RibSurfaces, SmoothSurfacesAreMarkedPolygonsAreNot) {
  ReadResult r = read(world(
      "Sphere 1 -1 1 360\n"
      "Torus 1 0.25 0 360 360\n"
      "Patch \"bicubic\" \"P\" [0 0 0 1 0 0 2 0 0 3 0 0  0 1 0 1 1 1 2 1 1 3 1 0  0 2 0 1 2 1 2 2 1 3 2 0  0 3 0 1 3 0 2 3 0 3 3 0]\n"
      "NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]\n"
      "SubdivisionMesh \"catmull-clark\" [4] [0 1 2 3] \"P\" [0 0 0 1 0 0 1 1 0 0 1 0]\n"
      "Polygon \"P\" [0 0 0 1 0 0 1 1 0]\n"
      "Patch \"bilinear\" \"P\" [0 0 0 1 0 0 0 1 1 1 1 1] \"N\" [0 0 1 0 0 1 0 0 1 0 0 1]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 7u);
  for (size_t m = 0; m < 5; ++m) EXPECT_TRUE(r.scene->meshes[m].smoothSurface) << m;
  EXPECT_FALSE(r.scene->meshes[4].givenNormals);  // the subdivision surface's normals are its own
  EXPECT_FALSE(r.scene->meshes[5].smoothSurface);
  EXPECT_FALSE(r.scene->meshes[6].smoothSurface);
  // A full sweep's seam: the last column repeats the first bit for bit (cos 2 pi is not exactly
  // 1 in float), so both copies get one dPdu and displacement cannot open it (review finding).
  for (size_t m : {size_t(1)}) {  // the torus: its u and its v go all the way round
    const Mesh& torus = r.scene->meshes[m];
    ASSERT_EQ(torus.dPdu.size(), torus.P.size());
    size_t seams = 0;
    for (size_t i = 0; i < torus.P.size(); ++i)
      for (size_t j = i + 1; j < torus.P.size(); ++j)
        if (torus.P[i] == torus.P[j] && torus.N[i] == torus.N[j]) {
          EXPECT_EQ(torus.dPdu[i], torus.dPdu[j]) << i << " " << j;
          ++seams;
        }
    EXPECT_GT(seams, 20u);
  }
}

TEST(RibPatches, FlatBilinearPatchesAreTwoTrianglesOnlyWhereTheMapIsAffine) {
  // A rectangle with affine Cs: two triangles are exact. A flat trapezoid is not affine: its
  // v = 0.5 isoline runs through the midpoints of the slanted sides, and st there must be 0.5.
  ReadResult r = read(world("Patch \"bilinear\" \"P\" [0 0 0  2 0 0  0 1 0  2 1 0]"
                            " \"Cs\" [0 0 0  1 0 0  0 1 0  1 1 0]\n"
                            "Patch \"bilinear\" \"P\" [0 0 0  4 0 0  1 1 0  3 1 0]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 2u);
  EXPECT_EQ(r.scene->meshes[0].numTriangles(), 2u);
  const Mesh& trapezoid = r.scene->meshes[1];
  EXPECT_GT(trapezoid.numTriangles(), 2u);
  int found = 0;
  for (size_t i = 0; i < trapezoid.P.size(); ++i)
    if (trapezoid.st[i] == glm::vec2(0.0f, 0.5f)) {
      expectNear(trapezoid.P[i], glm::vec3(0.5f, 0.5f, 0));
      ++found;
    }
  EXPECT_EQ(found, 1);
}

TEST(RibPatches, UniformAndFaceVaryingValuesStayInTheirPatch) {
  // Two flat bilinear patches side by side (x in [0, 1] and [1, 2]), and the same as a curved
  // bicubic mesh: a uniform Cs colours each patch whole, facevarying s gives each patch its own
  // corners, and every triangle lies in one patch, whose value all its corners carry.
  const std::string flatP = "\"P\" [0 0 0  1 0 0  2 0 0  0 1 0  1 1 0  2 1 0]";
  for (const std::string& request :
       {"PatchMesh \"bilinear\" 3 \"nonperiodic\" 2 \"nonperiodic\" " + flatP +
            " \"uniform color Cs\" [1 0 0  0 0 1] \"facevarying float s\" [0 0 0 0  5 5 5 5]",
        std::string("Basis \"b-spline\" 1 \"b-spline\" 1\n"
                    "PatchMesh \"bicubic\" 5 \"nonperiodic\" 4 \"nonperiodic\" \"P\" [") +
            [] {
              std::string P;
              for (int j = 0; j < 4; ++j)
                for (int i = 0; i < 5; ++i)
                  P += std::to_string(i - 1) + " " + std::to_string(j) + " " + (i == 2 ? "0.5" : "0") + "  ";
              return P;
            }() +
            "] \"uniform color Cs\" [1 0 0  0 0 1] \"facevarying float s\" [0 0 0 0  5 5 5 5]"}) {
    SCOPED_TRACE(request);
    ReadResult r = read(world(request));
    ASSERT_TRUE(r.scene) << r.error.format();
    const Mesh& m = r.scene->meshes.at(0);
    ASSERT_EQ(m.Cs.size(), m.P.size());
    ASSERT_EQ(m.st.size(), m.P.size());
    int red = 0, blue = 0;
    for (uint32_t tri = 0; tri < m.numTriangles(); ++tri) {
      const uint32_t* corner = &m.indices[3 * size_t(tri)];
      const bool left = m.Cs[corner[0]] == glm::vec3(1, 0, 0);
      (left ? red : blue)++;
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(m.Cs[corner[c]], left ? glm::vec3(1, 0, 0) : glm::vec3(0, 0, 1));
        EXPECT_EQ(m.st[corner[c]].x, left ? 0.0f : 5.0f);
        EXPECT_LE(m.uv[corner[c]].x, left ? 0.5f : 1.0f);
        EXPECT_GE(m.uv[corner[c]].x, left ? 0.0f : 0.5f);
      }
    }
    EXPECT_EQ(red, blue);
    EXPECT_GT(red, 0);
    // Where the patches meet, both copies of a border vertex have the same position bits.
    for (size_t i = 0; i < m.P.size(); ++i)
      for (size_t k = i + 1; k < m.P.size(); ++k)
        if (m.uv[i] == m.uv[k]) {
          EXPECT_EQ(m.P[i], m.P[k]);
        }
  }
}

// --- OBJ meshes ---

TEST(RibObjMesh, LoadsAnObjFileRelativeToTheScene) {
  TempDir dir("objmesh");
  dir.write("meshes/quad.obj",
            "# a quad and an L\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
            "f 1/1/1 2/2/1 3/3/1 4/4/1\n");
  dir.write("meshes/broken.obj", "v 0 0 0\nf 1 2 3\n");
  const std::string scene = dir.write(
      "scene.rib", world("Translate 0 0 2\nGeometry \"objmesh\" \"string filename\" "
                         "[\"meshes/quad.obj\"]\n"));
  SceneError error;
  std::optional<Scene> s = readRibFile(scene, RibReadOptions{}, &error);
  ASSERT_TRUE(s) << error.format();
  ASSERT_EQ(s->meshes.size(), 1u);
  const Mesh& m = s->meshes[0];
  EXPECT_EQ(m.numTriangles(), 2u);
  ASSERT_EQ(m.P.size(), 4u);
  expectNear(m.P[2], glm::vec3(1, 1, 2));
  ASSERT_EQ(m.N.size(), 4u);
  expectNear(m.N[0], glm::vec3(0, 0, 1));
  ASSERT_EQ(m.st.size(), 4u);
  EXPECT_EQ(m.st[3], glm::vec2(0, 0));  // OBJ v = 1 is t = 0
  const std::string missing = dir.write(
      "missing.rib", world("\nGeometry \"objmesh\" \"string filename\" [\"meshes/none.obj\"]"));
  EXPECT_FALSE(readRibFile(missing, RibReadOptions{}, &error));
  EXPECT_EQ(error.line, 3);
  EXPECT_NE(error.message.find("cannot open mesh"), std::string::npos) << error.message;
  const std::string broken = dir.write(
      "broken.rib", world("Geometry \"objmesh\" \"string filename\" [\"meshes/broken.obj\"]"));
  EXPECT_FALSE(readRibFile(broken, RibReadOptions{}, &error));
  EXPECT_EQ(error.line, 2);
  const std::string wrongType =
      dir.write("wrong.rib", world("Geometry \"objmesh\" \"float filename\" [1]"));
  EXPECT_FALSE(readRibFile(wrongType, RibReadOptions{}, &error));
  // tinyobjloader reads nan, inf and a missing coordinate as 0: such files are errors naming the
  // line, not a plausible mesh. A material library is not followed (materials are unused), so a
  // missing one costs nothing.
  for (const auto& [text, message] : std::vector<std::pair<std::string, std::string>>{
           {"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "line 1: 'nan' is not a finite number"},
           {"v 0 0 0\nv 1 0 0\nv inf 1 0\nf 1 2 3\n", "line 3: 'inf' is not a finite number"},
           {"v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", "line 2: 'v' needs at least 3 numbers, got 2"},
           {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nf 1//1 2//1 3//1\n", "line 4: zero-length normal"}}) {
    dir.write("meshes/bad.obj", text);
    const std::string bad = dir.write("bad.rib", world("Geometry \"objmesh\" \"string filename\" [\"meshes/bad.obj\"]"));
    EXPECT_FALSE(readRibFile(bad, RibReadOptions{}, &error)) << text;
    EXPECT_NE(error.message.find(message), std::string::npos) << error.message;
  }
  dir.write("meshes/withmtl.obj", "mtllib nowhere.mtl\nv 0 0 0 # origin\nv 1 0 0\nv 0 1 0\nusemtl stone\nf 1 2 3\n");
  const std::string withMtl =
      dir.write("withmtl.rib", world("Geometry \"objmesh\" \"string filename\" [\"meshes/withmtl.obj\"]"));
  EXPECT_TRUE(readRibFile(withMtl, RibReadOptions{}, &error)) << error.format();
}

// Transforms that overflow float (two Scale 1e38) make geometry an error at its line, not
// "singular" geometry quietly skipped.
TEST(RibErrors, OverflowedTransformsAreErrors) {
  ReadResult r = read(world("Scale 1e38 1e38 1e38\nScale 1e38 1e38 1e38\nSphere 1 -1 1 360\n"));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.format().find(":4: error: 'Sphere': the current transform is not finite"), std::string::npos)
      << r.error.format();
}

// --- Input written for other renderers ---

// Lights Relief does not have (another renderer's shaders, area light sources) are skipped with one
// warning each, and their handles stay known: Illuminate of them changes nothing. A handle never
// declared is still an error.
TEST(RibForeign, IlluminateOfASkippedLightIsANoOp) {
  ReadResult r = read(world(
      "LightSource \"distantlight\" \"key\"\n"
      "LightSource \"shadowspot\" \"shadow\" \"float intensity\" [3] \"string shadowname\" [\"a.shd\"]\n"
      "LightSource \"PxrDomeLight\" 7 \"bool enableTemperature\" [1]\n"
      "AreaLightSource \"arealight\" \"panel\" \"float intensity\" [2]\n"
      "Illuminate \"shadow\" 0\nIlluminate 7 1\nIlluminate \"panel\" 0\nIlluminate \"shadow\" 1\n" +
      std::string(kTriangle)));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->lights.size(), 1u);
  EXPECT_EQ(r.scene->meshes.at(0).lights, std::vector<uint32_t>{0});
  EXPECT_NE(r.warnings.find(":3: warning: light source 'shadowspot' is not supported"),
            std::string::npos)
      << r.warnings;
  EXPECT_NE(r.warnings.find(":5: warning: 'AreaLightSource' is not supported"), std::string::npos)
      << r.warnings;
  const std::string skipped = "'Illuminate': light 'shadow' was skipped";
  EXPECT_EQ(r.warnings.find(skipped, r.warnings.find(skipped) + 1), std::string::npos)
      << r.warnings;  // once
  ReadResult bad = read(world("LightSource \"shadowspot\" 1\nIlluminate 2 1"));
  ASSERT_FALSE(bad.scene);
  EXPECT_EQ(bad.error.message, "'Illuminate': no light with handle '2'");
  // A handle reused by a supported light is that light again.
  r = read(world("LightSource \"shadowspot\" 1\nLightSource \"pointlight\" 1\nIlluminate 1 0\n" +
                 std::string(kTriangle)));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_TRUE(r.scene->meshes.at(0).lights.empty());
  EXPECT_TRUE(r.scene->meshes.at(0).lightsSet);
}

// Options and attributes of other renderers are skipped before their parameters are read, so
// type words Relief does not know cannot stop the load; hpoint and bool are known types.
TEST(RibForeign, UnknownCategoriesAndTypesWarn) {
  ReadResult r = read("Option \"user\" \"bool foo\" [1]\nOption \"ri\" \"weird bar\" [\"x\"]\n"
                      "Declare \"pw\" \"hpoint\"\nDeclare \"flag\" \"uniform bool\"\n"
                      "Declare \"odd\" \"quaternion\"\n" +
                      world("Attribute \"user\" \"struct s\" [1 2]\n"
                            "Attribute \"visibility\" \"bool transmission\" [0]\n"
                            "Sphere 1 -1 1 360 \"uniform mystery q\" [1] \"flag\" [1]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_FALSE(r.scene->materials.at(r.scene->meshes.at(0).materialIndex).castsShadows);
  for (const char* expected : {":1: warning: unsupported option 'user' ignored",
                               ":2: warning: unsupported option 'ri' ignored",
                               ":5: warning: 'Declare': unknown type 'quaternion'",
                               ":7: warning: unsupported attribute 'user' ignored",
                               ":9: warning: 'Sphere': unknown type 'mystery'"})
    EXPECT_NE(r.warnings.find(expected), std::string::npos) << expected << "\n" << r.warnings;
}

// A surface Relief does not have is matte; its parameters are another shader's, so a Kd or Ka of
// another type is ignored instead of being an error, and one that is a single float is kept.
TEST(RibForeign, UnknownSurfaceIsMatteWithoutTypeChecks) {
  ReadResult r = read(world("Surface \"foo\" \"color Kd\" [1 0 0] \"float Ka\" [0.25] "
                            "\"string map\" [\"x.tx\"] \"strange s\" [1]\n" + std::string(kTriangle) +
                            "Surface \"bar\" \"Kd\" [0.5] \"Ka\" [\"no\"]\n" + kTriangle));
  ASSERT_TRUE(r.scene) << r.error.format();
  const Material& foo = materialOf(*r.scene, 0);
  EXPECT_EQ(foo.type, SurfaceType::Matte);
  EXPECT_FLOAT_EQ(foo.Kd, 1.0f);
  EXPECT_FLOAT_EQ(foo.Ka, 0.25f);
  const Material& bar = materialOf(*r.scene, 1);
  EXPECT_FLOAT_EQ(bar.Kd, 0.5f);
  EXPECT_FLOAT_EQ(bar.Ka, 1.0f);
  EXPECT_NE(r.warnings.find("surface 'foo' is not supported; using 'matte'"), std::string::npos);
  EXPECT_EQ(r.warnings.find("strange"), std::string::npos) << r.warnings;
}

// "Pw" (homogeneous points) stands in for "P": RenderMan's point is (x/w, y/w, z/w).
TEST(RibForeign, PwIsDividedByW) {
  ReadResult r = read("Declare \"Pw\" \"vertex hpoint\"\n" +
                      world("Polygon \"vertex hpoint Pw\" [0 0 0 1  2 0 0 2  0 3 0 3]\n"
                            "PointsPolygons [3] [0 1 2] \"Pw\" [0 0 1 0.5  1 0 1 1  0 1 1 1]\n"
                            "Patch \"bilinear\" \"Pw\" [0 0 0 1  2 0 0 2  0 2 0 2  4 4 0 4]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 3u);
  expectNear(r.scene->meshes[0].P[1], glm::vec3(1, 0, 0));
  expectNear(r.scene->meshes[0].P[2], glm::vec3(0, 1, 0));
  expectNear(r.scene->meshes[1].P[0], glm::vec3(0, 0, 2));
  expectNear(r.scene->meshes[2].P.back(), glm::vec3(1, 1, 0));
  EXPECT_EQ(r.warnings.find("Pw"), std::string::npos) << r.warnings;
  r = read(world("\nPolygon \"Pw\" [0 0 0 1  1 0 0 0  0 1 0 1]"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.format(), "/scenes/test.rib:3: error: 'Polygon': \"Pw\" point 1 has w = 0");
  r = read(world("\nPolygon \"Pw\" [0 0 0  1 0 0  0 1 0]"));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("\"Pw\" needs 4 numbers (x y z w) per point"), std::string::npos);
}

// Without motion blur a motion block is its first sample: two Translates do not add up and two
// Spheres are one sphere.
TEST(RibForeign, MotionBlocksUseTheirFirstSample) {
  ReadResult r = read(world("MotionBegin [0 1]\nTranslate 1 0 0\nTranslate 2 0 0\nMotionEnd\n" +
                            std::string(kTriangle) +
                            "MotionBegin [0 0.5 1]\nSphere 1 -1 1 360\nSphere 2 -2 2 360\n"
                            "Sphere 3 -3 3 360\nMotionEnd\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 2u);
  expectNear(r.scene->meshes[0].P[0], glm::vec3(1, 0, 0));
  float radius = 0.0f;
  for (const glm::vec3& p : r.scene->meshes[1].P) radius = std::max(radius, glm::length(p - glm::vec3(1, 0, 0)));
  EXPECT_NEAR(radius, 1.0f, 1e-4f);
  EXPECT_NE(r.warnings.find(":2: warning: motion blur is not supported"), std::string::npos);
  EXPECT_EQ(r.warnings.find("motion blur", r.warnings.find("motion blur") + 1), std::string::npos);
  // An instance as a motion sample plays all its calls.
  r = read(world("ObjectBegin 1\n" + std::string(kTriangle) + kTriangle + "ObjectEnd\n"
                 "MotionBegin [0 1]\nObjectInstance 1\nObjectInstance 1\nMotionEnd\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->meshes.size(), 2u);
  r = read(world("MotionBegin [0 1]\nTranslate 1 0 0\n"));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("'MotionBegin' at line 2 has no 'MotionEnd'"), std::string::npos)
      << r.error.message;
  EXPECT_FALSE(read(world("MotionEnd")).scene);
  EXPECT_FALSE(read(world("MotionBegin [0 1]\nMotionBegin [0 1]\nMotionEnd\nMotionEnd")).scene);
}

// Archives and OBJ meshes: beside the file that names them, then along Option "searchpath"
// "archive", then from the working directory.
TEST(RibForeign, ArchivesFollowTheSearchPathAndTheWorkingDirectory) {
  TempDir dir("archivepath");
  dir.write("lib/tri.rib", kTriangle);
  dir.write("lib/quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  dir.write("cwd/fromcwd.rib", kTriangle);
  const std::string scene =
      dir.write("scenes/main.rib", "Option \"searchpath\" \"string archive\" [\"../lib:&\"]\n" +
                                       world("ReadArchive \"tri.rib\"\n"
                                             "Geometry \"objmesh\" \"string filename\" [\"quad.obj\"]\n"
                                             "ReadArchive \"fromcwd.rib\"\n"));
  const std::filesystem::path previous = std::filesystem::current_path();
  std::filesystem::current_path(dir.path / "cwd");
  SceneError error;
  std::optional<Scene> s = readRibFile(scene, RibReadOptions{}, &error);
  std::filesystem::current_path(previous);
  ASSERT_TRUE(s) << error.format();
  EXPECT_EQ(s->meshes.size(), 3u);
  // Without the search path the archive is not found, and the message says where it looked.
  const std::string plain = dir.write("scenes/plain.rib", world("\nReadArchive \"tri.rib\""));
  EXPECT_FALSE(readRibFile(plain, RibReadOptions{}, &error));
  EXPECT_EQ(error.line, 3);
  EXPECT_NE(error.message.find("cannot open archive 'tri.rib' (tried '" +
                               (dir.path / "scenes" / "tri.rib").string() + "'"),
            std::string::npos)
      << error.message;
}

// Small slips of exporters warn instead of stopping the load.
TEST(RibForeign, ExtraNumbersAndZeroRoughnessWarn) {
  ReadResult r = read(world("Color 1 0 0 0\nOpacity [1 1 1 1]\nSurface \"plastic\" \"float roughness\" [0]\n" +
                            std::string(kTriangle)));
  ASSERT_TRUE(r.scene) << r.error.format();
  const Material& m = materialOf(*r.scene, 0);
  expectNear(m.color, glm::vec3(1, 0, 0));
  EXPECT_GT(m.roughness, 0.0f);
  EXPECT_NE(r.warnings.find(":2: warning: 'Color' takes 3 numbers; 1 more ignored"), std::string::npos)
      << r.warnings;
  EXPECT_NE(r.warnings.find(":3: warning: 'Opacity' takes 3 numbers; 1 more ignored"), std::string::npos)
      << r.warnings;
  EXPECT_NE(r.warnings.find(":4: warning: 'plastic': 'roughness' 0 is not positive; using 0.001"),
            std::string::npos)
      << r.warnings;
  // A tiny positive roughness is not "not positive" (a fuzzing probe's 1e-38).
  ReadResult tiny = read(world("Surface \"plastic\" \"float roughness\" [1e-38]\nSphere 1 -1 1 360\n"));
  ASSERT_TRUE(tiny.scene) << tiny.error.format();
  EXPECT_NE(tiny.warnings.find("'roughness' 1e-38 is below 0.001; using 0.001"), std::string::npos) << tiny.warnings;
}

// --- The feature scene ---

TEST(RibFeatureScene, LoadsWithOneOfEverything) {
  // Stand-ins for the example shaders (only the reader is under test): float parameters by name.
  class StandIns : public runtime::ShaderProvider {
   public:
    std::shared_ptr<const runtime::CompiledShader> find(std::string_view name,
                                                        std::span<const std::string>,
                                                        std::string* error) override {
      std::vector<std::string> names;
      if (name == "bumps") names = {"Km", "freq"};
      if (name == "grooves") names = {"depth", "count"};
      if (name == "bricks") names = {"Km", "texname"};
      if (names.empty()) {
        *error = "unexpected shader";
        return nullptr;
      }
      std::vector<runtime::ParamInfo> params(names.size());
      for (size_t i = 0; i < names.size(); ++i) {
        params[i].name = names[i];
        params[i].offset = uint32_t(4 * i);
        if (names[i] == "texname") params[i].type = runtime::ParamType::String;
      }
      return std::make_shared<runtime::CompiledShader>(std::string(name), &test::pushEntry,
                                                       params, 4 * names.size(), nullptr);
    }
  } shaders;
  RibReadOptions options;
  options.shaders = &shaders;
  std::ostringstream warnings;
  options.warnings = &warnings;
  SceneError error;
  std::optional<Scene> scene = readRibFile(
      std::string(RELIEF_SOURCE_DIR) + "/examples/scenes/features.rib", options, &error);
  ASSERT_TRUE(scene) << error.format();
  EXPECT_EQ(warnings.str(), "");
  EXPECT_EQ(scene->displayModes, (std::vector<std::string>{"rgb", "z", "N", "cachemiss"}));
  EXPECT_EQ(scene->maxDepth, 5);
  EXPECT_EQ(scene->cacheBudgetTriangles, 1000000u);
  EXPECT_EQ(scene->order, "hilbert");
  ASSERT_FALSE(scene->texturePath.empty());
  EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(scene->texturePath[0]) / "bricks.png"));
  std::set<LightType> lightTypes;
  std::set<AreaShape> areaShapes;
  for (const Light& l : scene->lights) {
    lightTypes.insert(l.type);
    if (l.type == LightType::Area) areaShapes.insert(l.shape);
  }
  EXPECT_EQ(lightTypes.size(), 5u);
  EXPECT_EQ(areaShapes.size(), 2u);
  std::set<SurfaceType> surfaces;
  for (const Mesh& m : scene->meshes) surfaces.insert(scene->materials[m.materialIndex].type);
  EXPECT_EQ(surfaces.size(), 6u);  // matte plastic metal mirror glass constant
  EXPECT_EQ(scene->displacements.size(), 3u);
  EXPECT_EQ(scene->meshes.size(), 15u + 4u * 2u);  // 15 shapes and 4 two-part instanced posts
  // The brick wall from the archive: its own normals (towards the camera) and texture coordinates.
  size_t withNormalsAndSt = 0;
  for (const Mesh& m : scene->meshes)
    if (m.displacementIndex != UINT32_MAX && !m.N.empty() && !m.st.empty() &&
        scene->displacements[m.displacementIndex].shader->name() == "bricks") {
      ++withNormalsAndSt;
      EXPECT_TRUE(scene->materials[m.materialIndex].reverseOrientation);
      expectNear(m.N[0], glm::vec3(0, 0, -1));
    }
  EXPECT_EQ(withNormalsAndSt, 1u);
}

// --- Bad input ---

TEST(RibErrors, TruncatedAndMalformedInputIsLocated) {
  const std::string full = "Format 10 10 1\nWorldBegin\nAttributeBegin\nSphere 1 -1 1 360\n"
                           "AttributeEnd\nWorldEnd\n";
  for (size_t cut = 1; cut < full.size(); ++cut) {
    ReadResult r = read(full.substr(0, cut));
    if (!r.scene) {
      EXPECT_GT(r.error.line, 0) << cut;
    }
  }
  EXPECT_FALSE(read(full.substr(0, full.size() - 9)).scene);  // no WorldEnd
  ReadResult wrong = read(world("Sphere \"one\" -1 1 360"));
  ASSERT_FALSE(wrong.scene);
  EXPECT_EQ(wrong.error.line, 2);
  EXPECT_FALSE(read(world("Color [1 0]")).scene);
  EXPECT_FALSE(read(world("LightSource \"pointlight\" 1 \"intensity\" [\"bright\"]")).scene);

  // Each case: the text, the line and the message of its error.
  const std::tuple<std::string, int, std::string> cases[] = {
      // A typo'd number is not a number followed by a request ('36O' once made a 36-degree wedge).
      {world("Sphere 1 -1 1 36O"), 2, "malformed number '36O'"},
      {world("Sphere 1 -1 1 0x168"), 2, "malformed number '0x168'"},
      {world("Sphere 1 -1 1 360 \"Cs\" [1 0\nNaN]"), 3, "'NaN' is not a number: RIB numbers must be finite"},
      // An object's blocks balance inside it, instanced or not, and the error names the lines.
      {world("ObjectBegin \"a\"\nAttributeBegin\nSphere 1 -1 1 360\nObjectEnd"), 5,
       "'ObjectEnd' leaves 'AttributeBegin' (line 3) open in object 'a'"},
      {world("ObjectBegin \"a\"\nTransformEnd\nObjectEnd"), 3,
       "'TransformEnd' without 'TransformBegin' in object 'a' (ObjectBegin at line 2)"},
      {"PixelFilter \"box\"\n" + world(""), 1, "'PixelFilter' expects a filter name and 2 widths, got 0 widths"},
      {world("PatchMesh \"bilinear\" 99999999 \"nonperiodic\" 2 \"nonperiodic\" \"P\" [0 0 0]"), 2,
       "'PatchMesh': nu and nv must be at most 1000000 (got 99999999 x 2)"},
  };
  for (const auto& [text, line, message] : cases) {
    ReadResult r = read(text);
    ASSERT_FALSE(r.scene) << text;
    EXPECT_EQ(r.error.line, line) << text;
    EXPECT_EQ(r.error.message, message) << text;
  }
  ReadResult reversed = read(world("ReverseOrientation 1\n" + std::string(kTriangle)));
  ASSERT_TRUE(reversed.scene) << reversed.error.format();
  EXPECT_NE(reversed.warnings.find("'ReverseOrientation' takes no arguments"), std::string::npos)
      << reversed.warnings;
  // A parameter given twice: the later value, and a warning.
  ReadResult twice = read(world("Color 1 1 1\nLightSource \"pointlight\" 1 \"intensity\" [2] \"intensity\" [5]"));
  ASSERT_TRUE(twice.scene) << twice.error.format();
  EXPECT_NE(twice.warnings.find("parameter 'intensity' is given twice; the later value is used"), std::string::npos)
      << twice.warnings;
  ASSERT_EQ(twice.scene->lights.size(), 1u);
  EXPECT_FLOAT_EQ(twice.scene->lights[0].color.r, 5.0f);
  // A concave polygon past the ear-clipping limit is fanned, and says so.
  std::string star;
  for (size_t i = 0; i <= kMaxEarClippingPoints; ++i) {
    const double a = 2 * M_PI * double(i) / double(kMaxEarClippingPoints + 1);
    const double radius = i % 2 ? 0.5 : 1.0;
    star += std::to_string(radius * std::cos(a)) + " " + std::to_string(radius * std::sin(a)) + " 0 ";
  }
  ReadResult fanned = read(world("Polygon \"P\" [" + star + "]"));
  ASSERT_TRUE(fanned.scene) << fanned.error.format();
  EXPECT_NE(fanned.warnings.find("is split without ear clipping (triangles may cross its concave parts), its holes ignored"), std::string::npos)
      << fanned.warnings;
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// Robustness of the newer calls: byte-level mutations of a scene using them must give a scene or
// a located error, never a crash or a hang (run under ASan/UBSan). Fixed seed: failures reproduce.
TEST(RibErrors, SurvivesMutatedFeatureScene) {
  const std::string base =
      "Option \"relief\" \"int maxdepth\" [3] \"string order\" [\"bucket\"]\n"
      "Display \"x.png\" \"file\" \"rgb\"\nDisplay \"+z.exr\" \"file\" \"z\"\n"
      "LightSource \"pointlight\" 9 \"from\" [0 0 0]\nFrameBegin 1\nWorldBegin\n"
      "LightSource \"spotlight\" \"s\" \"from\" [0 4 0] \"to\" [0 0 0] \"coneangle\" [0.3]\n"
      "LightSource \"arealight\" 2 \"string shape\" [\"disk\"] \"radius\" [0.5]\n"
      "ObjectBegin \"o\"\nSphere 1 -1 1 180 \"constant color Cs\" [1 0 0]\nObjectEnd\n"
      "AttributeBegin\nIlluminate \"s\" 0\nSurface \"glass\" \"eta\" [1.4]\nSides 1\n"
      "ObjectInstance \"o\"\nAttributeEnd\n"
      "Basis \"catmull-rom\" 1 \"bezier\" 3\n"
      "PatchMesh \"bicubic\" 5 \"nonperiodic\" 4 \"nonperiodic\" \"P\" [0 0 0 1 0 0 2 0 0 3 0 0 "
      "4 0 0 0 1 0 1 1 1 2 1 0 3 1 1 4 1 0 0 2 0 1 2 1 2 2 0 3 2 1 4 2 0 0 3 0 1 3 0 2 3 0 3 3 0 "
      "4 3 0]\n"
      "PointsGeneralPolygons [2] [4 3] [0 1 2 3 4 5 6] \"P\" [0 0 0 4 0 0 4 4 0 0 4 0 1 1 0 2 1 0 "
      "1 2 0] \"facevarying float[2] st\" [0 0 1 0 1 1 0 1 0 0 1 0 0 1]\n"
      "Torus 1 0.2 0 360 270\nWorldEnd\nFrameEnd\nFrameBegin 2\nWorldBegin\nWorldEnd\nFrameEnd\n";
  const std::string alphabet = "[]\"#\\ \n\r0123456789.-+eE AttributeEnd ObjectEnd xyz";
  ASSERT_TRUE(read(base).scene) << read(base).error.format();
  const auto [parsed, rejected] = test::mutationFuzz(base, alphabet, 977, 800, [&](const std::string& text) {
    ReadResult r = read(text);
    if (!r.scene) {
      EXPECT_GT(r.error.line, 0) << r.error.format() << "\n" << text;
      EXPECT_FALSE(r.error.message.empty());
    }
    return r.scene.has_value();
  });
  EXPECT_GT(parsed, 0);
  EXPECT_GT(rejected, 0);
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// ArchiveBegin "name" ... ArchiveEnd keeps its calls for ReadArchive "name", which runs them where
// it is read (current transform and attributes), as many times as it is read; the block itself
// draws nothing.
TEST(RibArchives, InlineArchivesRunWhereTheyAreRead) {
  ReadResult r = read("ArchiveBegin \"tri\"\nColor [0 1 0]\nPolygon \"P\" [0 0 0  1 0 0  0 1 0]\nArchiveEnd\n" +
                      world("ReadArchive \"tri\"\nTranslate 5 0 0\nReadArchive \"tri\""));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 2u);
  EXPECT_EQ(r.scene->meshes[1].P[0], glm::vec3(5, 0, 0));
  EXPECT_EQ(r.scene->materials[r.scene->meshes[1].materialIndex].color, glm::vec3(0, 1, 0));
  EXPECT_EQ(r.warnings.find("ArchiveBegin"), std::string::npos) << r.warnings;
  ReadResult unread = read(world("ArchiveBegin \"tri\"\nPolygon \"P\" [0 0 0  1 0 0  0 1 0]\nArchiveEnd"));
  ASSERT_TRUE(unread.scene) << unread.error.format();
  EXPECT_TRUE(unread.scene->meshes.empty());
  // Errors name the line.
  ReadResult open = read(world("ArchiveBegin \"a\"\nSphere 1 -1 1 360"));
  EXPECT_FALSE(open.scene);
  EXPECT_NE(open.error.format().find("'ArchiveBegin' at line 2 has no 'ArchiveEnd'"), std::string::npos)
      << open.error.format();
  ReadResult stray = read(world("ArchiveEnd"));
  EXPECT_FALSE(stray.scene);
  EXPECT_NE(stray.error.format().find("test.rib:2: error: 'ArchiveEnd' without 'ArchiveBegin'"), std::string::npos)
      << stray.error.format();
  ReadResult loop = read(world("ArchiveBegin \"a\"\nReadArchive \"a\"\nArchiveEnd\nReadArchive \"a\""));
  EXPECT_FALSE(loop.scene);
  EXPECT_NE(loop.error.format().find("nested more than 32 deep"), std::string::npos) << loop.error.format();
}

}  // namespace
}  // namespace relief
