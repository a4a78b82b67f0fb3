// Tests of the RIB reader: tokenizer, each supported request's effect on the Scene, and located
// errors for malformed or truncated input.
#include "renderer/rib_reader.h"

#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "render_test_util.h"
#include "renderer/camera.h"

namespace relief {
namespace {

struct ReadResult {
  std::optional<Scene> scene;
  SceneError error;
  std::string warnings;
};

ReadResult read(const std::string& text, runtime::ShaderProvider* shaders = nullptr,
                std::vector<std::string> defaultPath = {}) {
  std::ostringstream warnings;
  RibReadOptions options;
  options.shaders = shaders;
  options.defaultShaderPath = std::move(defaultPath);
  options.warnings = &warnings;
  ReadResult r;
  r.scene = readRibString(text, "/scenes/test.rib", options, &r.error);
  r.warnings = warnings.str();
  return r;
}

// Wraps world-block text in a minimal frame.
std::string world(const std::string& body) { return "WorldBegin\n" + body + "\nWorldEnd\n"; }

glm::vec3 apply(const glm::mat4& m, glm::vec3 p) { return glm::vec3(m * glm::vec4(p, 1.0f)); }

void expectNear(glm::vec3 a, glm::vec3 b, float eps = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

TEST(RibTokenizer, SplitsRequestsNumbersStringsAndArrays) {
  std::vector<RibToken> tokens;
  SceneError error;
  ASSERT_TRUE(tokenizeRib("Format 64 -2.5e1 .5 # comment \"not a string\"\r\n"
                          "Display \"a\\\"b\\n\" [1 2]\r\n",
                          "t.rib", &tokens, &error))
      << error.format();
  ASSERT_EQ(tokens.size(), 11u);
  EXPECT_EQ(tokens[0].kind, RibToken::Kind::Request);
  EXPECT_EQ(tokens[0].text, "Format");
  EXPECT_EQ(tokens[1].number, 64.0);
  EXPECT_EQ(tokens[2].number, -25.0);
  EXPECT_EQ(tokens[3].number, 0.5);
  EXPECT_EQ(tokens[4].text, "Display");
  EXPECT_EQ(tokens[4].line, 2);
  EXPECT_EQ(tokens[5].kind, RibToken::Kind::String);
  EXPECT_EQ(tokens[5].text, "a\"b\n");
  EXPECT_EQ(tokens[6].kind, RibToken::Kind::OpenBracket);
  EXPECT_EQ(tokens[8].number, 2.0);
  EXPECT_EQ(tokens[9].kind, RibToken::Kind::CloseBracket);
  EXPECT_EQ(tokens[10].kind, RibToken::Kind::End);
  EXPECT_EQ(tokens[10].line, 3);
}

TEST(RibTokenizer, ReportsUnterminatedStringAtItsStart) {
  std::vector<RibToken> tokens;
  SceneError error;
  EXPECT_FALSE(tokenizeRib("Format 1 1 1\nDisplay \"abc\n\n", "t.rib", &tokens, &error));
  EXPECT_EQ(error.format(), "t.rib:2: error: unterminated string");
}

TEST(RibTokenizer, RejectsMalformedNumbersAndBinaryBytes) {
  std::vector<RibToken> tokens;
  SceneError error;
  EXPECT_FALSE(tokenizeRib("Translate 1.2.3 0 0", "t.rib", &tokens, &error));
  EXPECT_EQ(error.message, "malformed number '1.2.3'");
  tokens.clear();
  EXPECT_FALSE(tokenizeRib("\n\x81\x02", "t.rib", &tokens, &error));
  EXPECT_EQ(error.line, 2);
  tokens.clear();
  EXPECT_FALSE(tokenizeRib("Scale 1e99 1 1", "t.rib", &tokens, &error));
  // A UTF-8 byte-order mark opens the file without being a byte of the stream; later it is one.
  tokens.clear();
  EXPECT_TRUE(tokenizeRib("\xEF\xBB\xBF" "WorldBegin", "t.rib", &tokens, &error)) << error.message;
  std::vector<RibToken> plain;
  EXPECT_TRUE(tokenizeRib("WorldBegin", "t.rib", &plain, &error));
  ASSERT_EQ(tokens.size(), plain.size());
  EXPECT_EQ(tokens[0].text, plain[0].text);
  tokens.clear();
  EXPECT_FALSE(tokenizeRib("WorldBegin \xEF\xBB\xBF", "t.rib", &tokens, &error));
}

TEST(RibReader, ReadsImageAndCameraOptions) {
  ReadResult r = read("Format 320 200 1\nPixelSamples 2 3\nClipping 0.5 100\n"
                      "Projection \"perspective\" \"fov\" [35]\nScreenWindow -2 2 -1 1\n" +
                      world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->width, 320);
  EXPECT_EQ(r.scene->height, 200);
  EXPECT_EQ(r.scene->pixelSamples, 6);
  EXPECT_TRUE(r.scene->camera.perspective);
  EXPECT_FLOAT_EQ(r.scene->camera.fovDegrees, 35.0f);
  EXPECT_FLOAT_EQ(r.scene->camera.nearClip, 0.5f);
  EXPECT_FLOAT_EQ(r.scene->camera.farClip, 100.0f);
  EXPECT_TRUE(r.scene->camera.screenWindowSet);
  EXPECT_FLOAT_EQ(r.scene->camera.screenWindow[0], -2.0f);
  EXPECT_FLOAT_EQ(r.scene->camera.screenWindow[3], 1.0f);
  EXPECT_EQ(r.warnings, "");
}

// A Projection replaces the one before it whole: without "fov", the RI default of 90 degrees.
TEST(RibReader, ProjectionWithoutFovIsNinetyDegrees) {
  ReadResult r = read("Projection \"perspective\" \"fov\" [35]\nProjection \"perspective\"\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_FLOAT_EQ(r.scene->camera.fovDegrees, 90.0f);
  r = read("Projection \"perspective\" \"fov\" [35]\nProjection \"orthographic\"\nProjection \"perspective\"\n" +
           world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_TRUE(r.scene->camera.perspective);
  EXPECT_FLOAT_EQ(r.scene->camera.fovDegrees, 90.0f);
}

// RI spec: the transforms before Projection act on screen space and the current transform starts
// again from the identity, so a z flip there does not turn the camera round (it only reorders
// depth), and a rotation about z turns the picture, not the view.
TEST(RibReader, TransformsBeforeProjectionActOnScreenSpace) {
  ReadResult r = read("Format 64 48 1\nScale 1 1 -1\nProjection \"perspective\" \"fov\" [60]\n"
                      "Translate 0 0 5\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.warnings, "");
  CameraRays rays(r.scene->camera, 64, 48);
  Ray centre = rays.generate(32, 24);
  EXPECT_EQ(centre.origin, glm::vec3(0.0f, 0.0f, -5.0f));
  EXPECT_GT(centre.direction.z, 0.0f);  // still looking down +z, at the world's origin
  r = read("Format 64 48 1\nRotate 90 0 0 1\nProjection \"perspective\" \"fov\" [60]\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  CameraRays turned(r.scene->camera, 64, 48);
  centre = turned.generate(32, 24);
  EXPECT_NEAR(centre.direction.x, 0.0f, 1e-6f);
  EXPECT_NEAR(centre.direction.y, 0.0f, 1e-6f);
  // The right edge's ray of the turned screen is a vertical one of the plain screen.
  const Ray right = turned.generate(64, 24);
  EXPECT_NEAR(right.direction.x, 0.0f, 1e-5f);
  EXPECT_GT(std::fabs(right.direction.y), 0.5f);
  r = read("ConcatTransform [1 0 0 0  0 1 0 0  0.5 0 1 0  0 0 0 1]\nProjection \"perspective\"\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_NE(r.warnings.find("act on screen space"), std::string::npos) << r.warnings;
  // A camera's Translate written before Projection instead of after it is dropped, and said.
  r = read("Translate 0 0 5\nProjection \"perspective\"\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_NE(r.warnings.find(":2: warning: 'Projection': the transforms before it act on screen space"),
            std::string::npos)
      << r.warnings;
  EXPECT_NE(r.warnings.find("goes between Projection and WorldBegin"), std::string::npos) << r.warnings;
}

// RI matrices are homogeneous: a uniform w divides out; projective ones and cameras that overflow
// are errors at their line, not silently wrong or black pictures.
TEST(RibReader, HomogeneousMatricesAndNonFiniteCameras) {
  ReadResult a = read(world("ConcatTransform [2 0 0 0  0 2 0 0  0 0 2 0  0 0 0 2]\nPolygon \"P\" [0 0 0 1 0 0 1 1 0]"));
  ReadResult b = read(world("Polygon \"P\" [0 0 0 1 0 0 1 1 0]"));
  ASSERT_TRUE(a.scene && b.scene) << a.error.format();
  EXPECT_EQ(a.scene->meshes.at(0).P, b.scene->meshes.at(0).P);
  ReadResult c = read(world("Transform [1 0 0 0  0 1 0 0  0 0 1 0  0 0 0 0.5]\nPolygon \"P\" [0 0 0 1 0 0 1 1 0]"));
  ASSERT_TRUE(c.scene) << c.error.format();
  EXPECT_EQ(c.scene->meshes.at(0).P.at(1), glm::vec3(2.0f, 0.0f, 0.0f));
  ReadResult d = read(world("ConcatTransform [1 0 0 0.5  0 1 0 0  0 0 1 0  0 0 0 1]\nPolygon \"P\" [0 0 0 1 0 0 1 1 0]"));
  EXPECT_FALSE(d.scene);
  EXPECT_NE(d.error.message.find("projective"), std::string::npos) << d.error.message;
  ReadResult e = read("Translate 0 0 5\nScale 1e30 1e30 1e30\nTranslate 1e30 0 0\n" + world(""));
  EXPECT_FALSE(e.scene);
  EXPECT_NE(e.error.message.find("non-finite"), std::string::npos) << e.error.message;
}

// A world block after the last FrameEnd is a further image: an error at its line, not skipped with
// every error inside it.
TEST(RibReader, WorldAfterTheLastFrameIsAnError) {
  ReadResult r = read("FrameBegin 1\n" + world("") + "FrameEnd\nWorldBegin\nReadArchive \"missing.rib\"\nWorldEnd\n");
  EXPECT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 6);  // the second WorldBegin
  EXPECT_NE(r.error.message.find("frame block"), std::string::npos) << r.error.message;
}

// RI spec: options are frozen at WorldBegin. One inside the world block is a warning naming its
// line and the WorldBegin, and changes nothing.
TEST(RibReader, OptionsInsideTheWorldBlockAreIgnoredWithAWarning) {
  ReadResult r = read("Format 320 200 1\nPixelSamples 2 2\nWorldBegin\nFormat 64 48 1\n"
                      "Projection \"perspective\"\nPixelSamples 4 4\nDisplay \"x.png\" \"file\" \"rgb\"\n"
                      "Option \"relief\" \"int cachebudget\" [10]\nWorldEnd\n");
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->width, 320);
  EXPECT_EQ(r.scene->pixelSamples, 4);
  EXPECT_FALSE(r.scene->camera.perspective);  // the default projection, orthographic
  EXPECT_TRUE(r.scene->displays.empty());
  EXPECT_EQ(r.scene->cacheBudgetTriangles, 0u);
  EXPECT_NE(r.warnings.find(":4: warning: 'Format' inside the world block (WorldBegin at line 3) is ignored: "
                            "options must come before WorldBegin"),
            std::string::npos)
      << r.warnings;
  for (const char* name : {"Projection", "PixelSamples", "Display", "Option"})
    EXPECT_NE(r.warnings.find(std::string("'") + name + "' inside the world block"), std::string::npos)
        << name << "\n" << r.warnings;
}

TEST(RibReader, FrameAspectRatioSetsTheScreenWindow) {
  ReadResult r = read("FrameAspectRatio 0.5\nProjection \"orthographic\"\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_FALSE(r.scene->camera.perspective);
  EXPECT_TRUE(r.scene->camera.screenWindowSet);
  EXPECT_FLOAT_EQ(r.scene->camera.screenWindow[1], 1.0f);
  EXPECT_FLOAT_EQ(r.scene->camera.screenWindow[3], 2.0f);
}

// Format's third number: the frame aspect is xres * pixelaspect / yres (RI spec), so 160x120
// pixels twice as wide as tall make a 8:3 frame, and the same pixels rendered at 120x120 (a
// command-line resolution) a 2:1 frame; FrameAspectRatio, when given, wins.
TEST(RibReader, PixelAspectRatioShapesTheDefaultFrame) {
  // The frame's half extents, right over top, as the camera rays span them.
  auto frameAspect = [](const Camera& camera, int width, int height) {
    const CameraRays rays(camera, width, height);
    const Ray right = rays.generate(float(width), 0.5f * float(height));
    const Ray top = rays.generate(0.5f * float(width), 0.0f);
    return (right.direction.x / right.direction.z) / (top.direction.y / top.direction.z);
  };
  ReadResult r = read("Format 160 120 2\nProjection \"perspective\"\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_FALSE(r.scene->camera.screenWindowSet);
  EXPECT_NEAR(frameAspect(r.scene->camera, 160, 120), 160.0f * 2 / 120, 1e-5f);
  EXPECT_NEAR(frameAspect(r.scene->camera, 120, 120), 2.0f, 1e-5f);
  ReadResult square = read("Format 160 120 1\nProjection \"perspective\"\n" + world(""));
  ASSERT_TRUE(square.scene);
  EXPECT_NEAR(frameAspect(square.scene->camera, 160, 120), 160.0f / 120, 1e-5f);
  ReadResult given = read("Format 160 120 2\nFrameAspectRatio 0.5\n" + world(""));
  ASSERT_TRUE(given.scene);
  EXPECT_FLOAT_EQ(given.scene->camera.screenWindow[3], 2.0f);
  // Not positive: the default 1, with a warning unless it is RenderMan's "default" -1.
  ReadResult zero = read("Format 160 120 0\n" + world(""));
  ASSERT_TRUE(zero.scene);
  EXPECT_EQ(zero.scene->camera.pixelAspect, 1.0f);
  EXPECT_NE(zero.warnings.find("pixel aspect ratio must be positive"), std::string::npos) << zero.warnings;
  ReadResult byDefault = read("Format 160 120 -1\n" + world(""));
  ASSERT_TRUE(byDefault.scene);
  EXPECT_EQ(byDefault.warnings, "");
}

TEST(RibReader, TransformAtWorldBeginIsCameraFromWorld) {
  ReadResult r = read("Translate 0 0 5\nRotate 90 0 1 0\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  const glm::mat4 cameraFromWorld = glm::inverse(r.scene->camera.worldFromCamera);
  // Rotate applies first: world +x turns to camera -z (about +y), then the translation.
  expectNear(apply(cameraFromWorld, glm::vec3(0, 0, 0)), glm::vec3(0, 0, 5));
  expectNear(apply(cameraFromWorld, glm::vec3(1, 0, 0)), glm::vec3(0, 0, 4));
  // The eye sits 5 units back along the rotated view axis.
  expectNear(apply(r.scene->camera.worldFromCamera, glm::vec3(0, 0, 0)), glm::vec3(5, 0, 0));
}

TEST(RibReader, ConcatTransformTakesRowMajorRowVectorMatrices) {
  // RIB matrices carry the translation in elements 12..14.
  ReadResult r = read("ConcatTransform [1 0 0 0  0 1 0 0  0 0 1 0  1 2 3 1]\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  expectNear(apply(r.scene->camera.worldFromCamera, glm::vec3(0)), glm::vec3(-1, -2, -3));
}

TEST(RibReader, SphereBecomesWorldSpaceTriangles) {
  ReadResult r = read(world("Translate 3 0 0\nScale 2 2 2\nColor [0.5 0.25 1]\nSphere 1 -1 1 360"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 1u);
  const Mesh& mesh = r.scene->meshes[0];
  EXPECT_GT(mesh.numTriangles(), 100u);
  EXPECT_EQ(mesh.displacementIndex, UINT32_MAX);
  for (const glm::vec3& p : mesh.P) EXPECT_NEAR(glm::length(p - glm::vec3(3, 0, 0)), 2.0f, 1e-4f);
  ASSERT_LT(mesh.materialIndex, r.scene->materials.size());
  const Material& m = r.scene->materials[mesh.materialIndex];
  expectNear(m.color, glm::vec3(0.5f, 0.25f, 1.0f));
  EXPECT_EQ(m.Ka, 1.0f);
  EXPECT_EQ(m.Kd, 1.0f);
}

TEST(RibReader, AttributeAndTransformBlocksRestoreState) {
  ReadResult r = read(world("Color [1 0 0]\n"
                            "AttributeBegin\n Color [0 1 0]\n Translate 10 0 0\nAttributeEnd\n"
                            "TransformBegin\n Translate 0 10 0\n Color [0 0 1]\nTransformEnd\n"
                            "Polygon \"P\" [0 0 0  1 0 0  0 1 0]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 1u);
  const Mesh& mesh = r.scene->meshes[0];
  expectNear(mesh.P[1], glm::vec3(1, 0, 0));  // both translations undone
  // TransformEnd restores only the transform: the colour set inside stays.
  expectNear(r.scene->materials[mesh.materialIndex].color, glm::vec3(0, 0, 1));
}

TEST(RibReader, SurfaceMatteReadsKaKdAndUnknownSurfacesWarnOnce) {
  ReadResult r = read(world("Surface \"matte\" \"Ka\" [0.2] \"float Kd\" 0.7\n"
                            "Polygon \"P\" [0 0 0  1 0 0  0 1 0]\n"
                            "Surface \"velvet\"\nSurface \"velvet\"\n"
                            "Polygon \"P\" [0 0 0  1 0 0  0 1 0]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  const Material& m = r.scene->materials[r.scene->meshes[0].materialIndex];
  EXPECT_FLOAT_EQ(m.Ka, 0.2f);
  EXPECT_FLOAT_EQ(m.Kd, 0.7f);
  EXPECT_EQ(r.warnings,
            "/scenes/test.rib:4: warning: surface 'velvet' is not supported; using 'matte'\n");
}

TEST(RibReader, DistantLightDefaultsAndFromTo) {
  ReadResult r = read(world("LightSource \"distantlight\" 1\n"
                            "LightSource \"distantlight\" 2 \"intensity\" [2] \"lightcolor\" [1 0.5 0]"
                            " \"from\" [0 10 0] \"to\" [0 0 0]\n"
                            "Rotate 90 1 0 0\nLightSource \"distantlight\" \"key\"\n"
                            "LightSource \"ambientlight\" 4 \"intensity\" [0.25]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->distantLights.size(), 3u);
  // Default: light travels from the origin along +z, so the surface sees it towards -z.
  expectNear(r.scene->distantLights[0].directionToLight, glm::vec3(0, 0, -1));
  expectNear(r.scene->distantLights[0].color, glm::vec3(1));
  expectNear(r.scene->distantLights[1].directionToLight, glm::vec3(0, 1, 0));
  expectNear(r.scene->distantLights[1].color, glm::vec3(2, 1, 0));
  // from/to are in the current space at the call: Rotate 90 about x turns +z into -y, so the
  // light travels along -y and the surface sees it towards +y.
  expectNear(r.scene->distantLights[2].directionToLight, glm::vec3(0, 1, 0));
  EXPECT_FLOAT_EQ(r.scene->ambient, 0.25f);
  expectNear(r.scene->ambientColor, glm::vec3(0.25f));
  r = read(world("LightSource \"ambientlight\" 1 \"lightcolor\" [1 0 0]\n"
                 "LightSource \"ambientlight\" 2 \"intensity\" [0.5] \"lightcolor\" [0 1 0]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  expectNear(r.scene->ambientColor, glm::vec3(1, 0.5f, 0));
}

TEST(RibReader, DisplacementBindsTypedAndUntypedParameters) {
  test::TestShaderProvider shaders;
  ReadResult r = read(world("Attribute \"displacementbound\" \"float sphere\" [0.1]\n"
                            "Attribute \"relief\" \"float edgelength\" [0.02] \"float flatness\" [0.001]\n"
                            "Displacement \"push\" \"float Km\" [0.25] \"tint\" [1 0 0]"
                            " \"string map\" [\"bricks.tx\"]\n"
                            "Scale 3 1 1\nSphere 1 -1 1 360"),
                      &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->displacements.size(), 1u);
  ASSERT_EQ(r.scene->meshes[0].displacementIndex, 0u);
  const Displacement& d = r.scene->displacements[0];
  ASSERT_TRUE(d.shader);
  EXPECT_EQ(d.shader->name(), "push");
  float km;
  std::memcpy(&km, d.shader->block().data(), 4);
  EXPECT_FLOAT_EQ(km, 0.25f);
  float tint[3];
  std::memcpy(tint, d.shader->block().data() + 4, 12);
  EXPECT_FLOAT_EQ(tint[1], 0.0f);
  const char* map;
  std::memcpy(&map, d.shader->block().data() + 16, sizeof map);
  EXPECT_STREQ(map, "bricks.tx");
  // The bound is in object space and the object is scaled by up to 3.
  EXPECT_FLOAT_EQ(d.boundWorld, 0.3f);
  EXPECT_FLOAT_EQ(d.edgeLength, 0.02f);
  EXPECT_FLOAT_EQ(d.flatness, 0.001f);
  EXPECT_EQ(d.sourceLine, 4);
  // Object space is scaled after the call; shader space is object space at the call.
  EXPECT_FLOAT_EQ(d.spaces.currentFromObject[0], 3.0f);
  EXPECT_FLOAT_EQ(d.spaces.currentFromShader[0], 1.0f);
  EXPECT_FLOAT_EQ(d.spaces.objectFromCurrent[0], 1.0f / 3.0f);
}

// RenderMan binds a primitive variable named like a shader parameter over the Displacement
// call's value, for that primitive: one value (constant, or the same on every face) does; the
// other bound values stay; primitives with equal values share an instance; a value varying over
// the primitive and a name the shader lacks warn.
TEST(RibReader, PrimitiveVariablesBindShaderParameters) {
  test::TestShaderProvider shaders;
  ReadResult r = read(world("Attribute \"displacementbound\" \"float sphere\" [0.1]\n"
                            "Displacement \"push\" \"float Km\" [0.25] \"string map\" [\"bricks.tx\"]\n"
                            "Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"float Km\" [0.5]\n"
                            "Polygon \"P\" [0 0 0  1 0 0  0 1 0]\n"
                            "Sphere 1 -1 1 360 \"constant float Km\" [0.5]\n"
                            "PointsPolygons [3 3] [0 1 2 0 2 3] \"P\" [0 0 0  1 0 0  1 1 0  0 1 0]"
                            " \"uniform float Km\" [0.75 0.75] \"tint\" [0 1 0]\n"
                            "Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"varying float Km\" [1 2 3]\n"
                            "Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"float Kq\" [1]\n"
                            "Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"vertex float Km\" [0.125 0.125 0.125]\n"),
                      &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 7u);
  auto block = [&](size_t mesh) { return r.scene->displacements[r.scene->meshes[mesh].displacementIndex].shader->block().data(); };
  auto km = [&](size_t mesh) {
    float v;
    std::memcpy(&v, block(mesh), 4);
    return v;
  };
  EXPECT_FLOAT_EQ(km(0), 0.5f);
  EXPECT_FLOAT_EQ(km(1), 0.25f);
  EXPECT_FLOAT_EQ(km(2), 0.5f);
  EXPECT_EQ(r.scene->displacements[r.scene->meshes[0].displacementIndex].shader,
            r.scene->displacements[r.scene->meshes[2].displacementIndex].shader);
  EXPECT_FLOAT_EQ(km(3), 0.75f);
  float tint[3];
  std::memcpy(tint, block(3) + 4, 12);
  EXPECT_FLOAT_EQ(tint[1], 1.0f);
  const char* map;
  std::memcpy(&map, block(3) + 16, sizeof map);
  EXPECT_STREQ(map, "bricks.tx");  // the Displacement call's, kept
  EXPECT_FLOAT_EQ(km(4), 0.25f);
  EXPECT_FLOAT_EQ(km(5), 0.25f);
  EXPECT_FLOAT_EQ(km(6), 0.125f);  // per vertex, but the same at every vertex: one value
  EXPECT_NE(r.warnings.find(":8: warning: 'Polygon': primitive variable 'Km' varies over the primitive"),
            std::string::npos)
      << r.warnings;
  EXPECT_NE(r.warnings.find(":9: warning: 'Polygon': primitive variable 'Kq' is not supported"), std::string::npos)
      << r.warnings;
}

// A shader-parameter primitive variable whose count fits no storage class of the primitive (or
// not the class declared) is an error at its line, as for st or Cs: it used to pass as "varies".
TEST(RibReader, PrimitiveVariableCountsThatFitNoClassAreErrors) {
  test::TestShaderProvider shaders;
  const std::pair<const char*, const char*> cases[] = {
      {"Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"float Km\" [1 2]", "'Km' has 2 values; expected 1 (one in all)"},
      {"Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"uniform float Km\" [3 4]", "uniform 'Km' needs 1 value, got 2"},
      {"Sphere 1 -1 1 360 \"point centre\" [1 2]", "'centre' has 2 values; expected 3 (one in all)"}};
  for (const auto& [call, message] : cases) {
    ReadResult r = read(world("Attribute \"displacementbound\" \"float sphere\" [0.1]\n"
                              "Displacement \"push\" \"float Km\" [0.25]\n" + std::string(call) + "\n"),
                        &shaders);
    ASSERT_FALSE(r.scene) << call;
    EXPECT_NE(r.error.format().find(":4: error: "), std::string::npos) << r.error.format();
    EXPECT_NE(r.error.format().find(message), std::string::npos) << r.error.format();
  }
}

// RenderMan gives point, vector and normal parameters in the space current at the call; the
// shader reads them in its current space (world). Before, they were bound as given.
TEST(RibReader, SpatialShaderParametersAreInTheSpaceOfTheCall) {
  test::TestShaderProvider shaders;
  ReadResult r = read(world("Attribute \"displacementbound\" \"float sphere\" [0.1]\n"
                            "Translate 1 0 0\nScale 2 1 1\n"
                            "Displacement \"push\" \"centre\" [0 0 -1] \"vector direction\" [1 1 0]"
                            " \"normal facing\" [1 1 0]\n"
                            "Sphere 1 -1 1 360"),
                      &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->displacements.size(), 1u);
  const std::byte* block = r.scene->displacements[0].shader->block().data();
  glm::vec3 centre, direction, facing;
  std::memcpy(&centre, block + 24, 12);
  std::memcpy(&direction, block + 36, 12);
  std::memcpy(&facing, block + 48, 12);
  expectNear(centre, glm::vec3(1, 0, -1));    // translated
  expectNear(direction, glm::vec3(2, 1, 0));  // scaled, not translated
  expectNear(facing, glm::vec3(0.5f, 1, 0));  // inverse transpose
  // An hpoint is (x y z w), the point (x/w, y/w, z/w), then moved as a point.
  ReadResult h = read(world("Attribute \"displacementbound\" \"float sphere\" [0.1]\n"
                            "Translate 1 0 0\nDisplacement \"push\" \"hpoint centre\" [2 4 6 2]\nSphere 1 -1 1 360"),
                      &shaders);
  ASSERT_TRUE(h.scene) << h.error.format();
  std::memcpy(&centre, h.scene->displacements[0].shader->block().data() + 24, 12);
  expectNear(centre, glm::vec3(2, 2, 3));
  EXPECT_FALSE(read(world("Displacement \"push\" \"hpoint centre\" [2 4 6 0]\nSphere 1 -1 1 360"), &shaders).scene);
  // A triple moves as the shader declares its parameter, whatever spatial kind the call names:
  // a "point" given to the normal 'facing' is a normal (it had picked up the translation).
  ReadResult k = read(world("Attribute \"displacementbound\" \"float sphere\" [0.1]\n"
                            "Translate 1 0 0\nScale 2 1 1\nDisplacement \"push\" \"point facing\" [1 2 3]\nSphere 1 -1 1 360"),
                      &shaders);
  ASSERT_TRUE(k.scene) << k.error.format();
  std::memcpy(&facing, k.scene->displacements[0].shader->block().data() + 48, 12);
  expectNear(facing, glm::vec3(0.5f, 2, 3));
}

// Before WorldBegin the transform is the camera's being built, so a Displacement there is given
// in camera space, as lights are: its shader space and its points move to world at WorldBegin
// (they had been taken as world).
TEST(RibReader, DisplacementBeforeWorldBeginIsInCameraSpace) {
  test::TestShaderProvider shaders;
  ReadResult r = read("Attribute \"displacementbound\" \"float sphere\" [0.1]\n"
                      "Displacement \"push\" \"point centre\" [0 0 0] \"vector direction\" [0 0 1]\n"
                      "Translate 0 0 5\nRotate 90 0 1 0\n" +
                          world("Sphere 1 -1 1 360"),
                      &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  // The camera sits at world (5, 0, 0), looking down world -x.
  const glm::vec3 eye(r.scene->camera.worldFromCamera * glm::vec4(0, 0, 0, 1));
  expectNear(eye, glm::vec3(5, 0, 0));
  const std::byte* block = r.scene->displacements[0].shader->block().data();
  glm::vec3 centre, direction;
  std::memcpy(&centre, block + 24, 12);
  std::memcpy(&direction, block + 36, 12);
  expectNear(centre, eye);
  expectNear(direction, glm::vec3(-1, 0, 0));
  const RlfSpaces& spaces = r.scene->displacements[0].spaces;
  EXPECT_NEAR(spaces.currentFromShader[12], 5.0f, 1e-5f);  // shader space's origin: the eye
}

// Primitives binding equal primitive-variable values under different Displacement calls get
// their own calls' values: the cache of bound instances was keyed by the call instance's address,
// which the next attribute block's call reused once AttributeEnd had freed the first.
TEST(RibReader, BoundInstancesKeepTheirOwnCallsValues) {
  test::TestShaderProvider shaders;
  std::string body;
  for (const char* km : {"0.25", "0.5", "0.75"})
    body += std::string("AttributeBegin\nAttribute \"displacementbound\" \"float sphere\" [1]\n") +
            "Displacement \"push\" \"float Km\" [" + km + "]\n"
            "Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"color tint\" [0 1 0]\nAttributeEnd\n";
  ReadResult r = read(world(body), &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 3u);
  for (size_t m = 0; m < 3; ++m) {
    float km;
    std::memcpy(&km, r.scene->displacements[r.scene->meshes[m].displacementIndex].shader->block().data(), 4);
    EXPECT_FLOAT_EQ(km, 0.25f * float(m + 1)) << m;
  }
}

TEST(RibReader, WorldBoundIsNotScaled) {
  test::TestShaderProvider shaders;
  ReadResult r = read(world("Attribute \"displacementbound\" \"float sphere\" [0.1]"
                            " \"string coordinatesystem\" [\"world\"]\n"
                            "Displacement \"push\"\nScale 3 3 3\nSphere 1 -1 1 360"),
                      &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_FLOAT_EQ(r.scene->displacements[0].boundWorld, 0.1f);
}

TEST(RibReader, SpacesAreRowMajorRowVector) {
  test::TestShaderProvider shaders;
  ReadResult r = read("Translate 0 0 7\n" +
                          world("Translate 1 2 3\nDisplacement \"push\"\nSphere 1 -1 1 360"),
                      &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  const RlfSpaces& s = r.scene->displacements[0].spaces;
  EXPECT_FLOAT_EQ(s.currentFromObject[12], 1.0f);
  EXPECT_FLOAT_EQ(s.currentFromObject[13], 2.0f);
  EXPECT_FLOAT_EQ(s.currentFromObject[14], 3.0f);
  EXPECT_FLOAT_EQ(s.currentFromObject[3], 0.0f);
  EXPECT_FLOAT_EQ(s.currentFromCamera[14], -7.0f);
  EXPECT_FLOAT_EQ(s.cameraFromCurrent[14], 7.0f);
}

TEST(RibReader, DisplacementErrorsAreLocatedAtTheCall) {
  test::TestShaderProvider shaders;
  ReadResult r = read(world("\nDisplacement \"nosuch\" \"float Km\" [1]"), &shaders);
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 3);
  EXPECT_NE(r.error.format().find("/scenes/test.rib:3: error: cannot load displacement shader "
                                  "'nosuch': no shader named 'nosuch'"),
            std::string::npos)
      << r.error.format();

  r = read(world("Displacement \"push\" \"string Km\" [\"x\"]"), &shaders);
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 2);
  EXPECT_NE(r.error.message.find("'Km'"), std::string::npos) << r.error.message;

  r = read(world("Displacement \"push\"\n  \"Km\" [0.1]\n  \"tint\" [\"red\"]"), &shaders);
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 2);  // the call, not the parameter's line

  // A name the shader lacks warns at the call and is skipped, as in RenderMan (exporters write
  // extras such as "__instanceid"); the parameters it has are still bound.
  r = read(world("Displacement \"push\" \"Kx\" [1] \"string __instanceid\" [\"a_1\"] \"Km\" [0.5]\n"
                 "Sphere 1 -1 1 360"),
           &shaders);
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_NE(r.warnings.find(":2: warning: shader 'push' has no parameter 'Kx'; ignored"), std::string::npos) << r.warnings;
  EXPECT_NE(r.warnings.find(":2: warning: shader 'push' has no parameter '__instanceid'; ignored"), std::string::npos)
      << r.warnings;
  float km;
  std::memcpy(&km, r.scene->displacements[0].shader->block().data(), 4);
  EXPECT_FLOAT_EQ(km, 0.5f);

  r = read(world("Displacement \"push\" \"Km\" [\"text\"]"), &shaders);
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 2);

  r = read(world("Displacement \"push\""));  // no provider
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 2);
}

TEST(RibReader, SearchPathExpandsAmpersandAtAndRelativeDirectories) {
  test::TestShaderProvider shaders;
  ReadResult r = read("Option \"searchpath\" \"string shader\" [\"a:&\"]\n"
                      "Option \"searchpath\" \"shader\" [\"/abs:&:@\"]\n" +
                          world("Displacement \"push\""),
                      &shaders, {"/default"});
  ASSERT_TRUE(r.scene) << r.error.format();
  // "/default" came by "&" and again by "@": searched once, at its first place.
  const std::vector<std::string> expected = {"/abs", "/scenes/a", "/default"};
  EXPECT_EQ(shaders.lastSearchPath, expected);
  // "&:&" thirty times over would double the path thirty times; it stays one entry per directory.
  std::string doubling;
  for (int i = 0; i < 30; ++i) doubling += "Option \"searchpath\" \"string shader\" [\"&:&\"]\n";
  ReadResult d = read(doubling + world("Displacement \"push\""), &shaders, {"/default"});
  ASSERT_TRUE(d.scene) << d.error.format();
  EXPECT_EQ(shaders.lastSearchPath, std::vector<std::string>{"/default"});
}

TEST(RibReader, PointsPolygonsTriangulatesAndReadsPrimvars) {
  ReadResult r = read(world("Translate 0 0 1\n"
                            "PointsPolygons [4 3] [0 1 2 3  0 3 4]"
                            " \"P\" [0 0 0  1 0 0  1 1 0  0 1 0  -1 0 0]"
                            " \"N\" [0 0 -1  0 0 -1  0 0 -1  0 0 -1  0 0 -1]"
                            " \"st\" [0 0  1 0  1 1  0 1  0.5 0.5]"
                            " \"Cq\" [1 2 3 4 5]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 1u);
  const Mesh& m = r.scene->meshes[0];
  EXPECT_EQ(m.numTriangles(), 3u);
  const std::vector<uint32_t> indices = {0, 1, 2, 0, 2, 3, 0, 3, 4};
  EXPECT_EQ(m.indices, indices);
  expectNear(m.P[2], glm::vec3(1, 1, 1));
  ASSERT_EQ(m.N.size(), 5u);
  expectNear(m.N[0], glm::vec3(0, 0, -1));
  ASSERT_EQ(m.st.size(), 5u);
  EXPECT_FLOAT_EQ(m.st[4].x, 0.5f);
  EXPECT_NE(r.warnings.find("'Cq' is not supported"), std::string::npos) << r.warnings;
}

TEST(RibReader, VertexColours) {
  ReadResult r = read(world("Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"Cs\" [1 0 0  0 1 0  0 0 1]\n"
                            "Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"constant color Cs\" [0.5 0.5 0]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes[0].Cs.size(), 3u);
  expectNear(r.scene->meshes[0].Cs[1], glm::vec3(0, 1, 0));
  ASSERT_EQ(r.scene->meshes[1].Cs.size(), 3u);
  expectNear(r.scene->meshes[1].Cs[2], glm::vec3(0.5f, 0.5f, 0));
  r = read(world("Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"Cs\" [1 0 0  0 1 0]"));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("one color per vertex"), std::string::npos) << r.error.message;
}

TEST(RibReader, SeparateSAndTBecomeSt) {
  ReadResult r = read(world("Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"s\" [0 1 0] \"t\" [0 0 1]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes[0].st.size(), 3u);
  EXPECT_FLOAT_EQ(r.scene->meshes[0].st[2].y, 1.0f);
}

// RI spec, "Polygons": the surface parameters are the object-space (x, y), and st equals them
// unless given; so a point shared by two faces has one (u, v), also when uniform primvars split
// the mesh per corner, and the transform does not enter.
TEST(RibReader, PolygonSurfaceParametersAreObjectXY) {
  ReadResult r = read(world("Translate 5 6 7\nRotate 90 0 0 1\n"
                            "PointsPolygons [4 3] [0 1 2 3  0 3 4] \"P\" [0 0 0  2 0 0  2 3 0  0 3 0  -1 0 0]\n"
                            "PointsPolygons [3 3] [0 1 2  0 2 3] \"P\" [0 0 0  1 0 0  1 1 0  0 1 0]"
                            " \"uniform color Cs\" [1 0 0  0 1 0]\n"
                            "Polygon \"P\" [0 0 0  1 0 0  0 1 0] \"st\" [0.5 0.5  0.75 0.5  0.5 0.75]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 3u);
  const Mesh& m = r.scene->meshes[0];
  const std::vector<glm::vec2> xy = {{0, 0}, {2, 0}, {2, 3}, {0, 3}, {-1, 0}};
  EXPECT_EQ(m.uv, xy);
  EXPECT_TRUE(m.st.empty());  // st defaults to uv
  const Mesh& split = r.scene->meshes[1];  // per-corner vertices: shared points agree
  ASSERT_EQ(split.uv.size(), split.P.size());
  for (size_t i = 0; i < split.P.size(); ++i)
    for (size_t j = 0; j < split.P.size(); ++j)
      if (split.P[i] == split.P[j]) {
        EXPECT_EQ(split.uv[i], split.uv[j]);
      }
  const Mesh& given = r.scene->meshes[2];
  ASSERT_EQ(given.st.size(), 3u);
  EXPECT_EQ(given.st[1], glm::vec2(0.75f, 0.5f));
  EXPECT_EQ(given.uv[1], glm::vec2(1, 0));
}

TEST(RibReader, PolygonErrorsNameTheProblem) {
  ReadResult r = read(world("PointsPolygons [3] [0 1 5] \"P\" [0 0 0  1 0 0  0 1 0]"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.format(), "/scenes/test.rib:2: error: 'PointsPolygons': vertex index 5 out "
                              "of range (\"P\" has 3 points)");
  r = read(world("Polygon \"P\" [0 0 0  1 0 0  0 1]"));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("multiple of 3"), std::string::npos);
  r = read(world("Polygon \"P\" [\"a\" \"b\" \"c\"]"));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("expects point values, got a string array"), std::string::npos)
      << r.error.message;
  r = read(world("Polygon \"N\" [0 0 1]"));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("needs a \"P\""), std::string::npos);
}

TEST(RibReader, WrongArgumentTypesAreErrors) {
  ReadResult r = read("Format 32 24 1\nWorldBegin\nSphere 1 -1 \"x\" 360\nWorldEnd\n");
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.format(), "/scenes/test.rib:3: error: 'Sphere' expects 4 numbers, got 2 (then 'x', a string)");
  // A bare word ends a request's arguments (it is the next request): named when on the same line.
  r = read(world("Sphere nan 1 -1 360"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "'Sphere' expects 4 numbers, got 0 ('nan' is not a number)");
  r = read(world("Sphere 1 -1\nTranslate 0 0 1"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "'Sphere' expects 4 numbers, got 2");
  r = read("Projection \"perspective\" \"fov\" \"wide\"\n" + world(""));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 1);
  r = read("Projection \"perspective\" \"string fov\" [\"x\"]\n" + world(""));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("should be 'float'"), std::string::npos);
  r = read(world("Surface \"matte\" \"Kd\""));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("has no value"), std::string::npos);
  r = read("Format 65536 65536 1\n" + world(""));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("pixels"), std::string::npos);
  r = read(world("Color 1 2"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "'Color' expects 3 numbers, got 2");
  // Array sizes in declarations are whole numbers (they were read with atoi, so junk passed), and
  // a declared array holds that many values.
  for (const char* junk : {"float[0x10] Ks", "float[-1] Ks", "float[4000000000] Ks", "float[2]x Ks", "float[] Ks"}) {
    r = read(world(std::string("Surface \"plastic\" \"") + junk + "\" [0.5]"));
    ASSERT_FALSE(r.scene) << junk;
    EXPECT_EQ(r.error.message, std::string("malformed parameter declaration '") + junk +
                                   "': the array size must be a whole number from 1 to 1000000");
  }
  r = read(world("Surface \"plastic\" \"float[2] Ks\" [0.5]"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "'Surface': parameter 'float[2] Ks' expects 2 values, got 1");
  r = read(world("Declare \"w\" \"color[2]\"\nSurface \"plastic\" \"w\" [1 2 3]"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "'Surface': parameter 'w' expects 6 values, got 3");
  // Counts and indices are whole numbers: an index of 1.5 was truncated, a count of 3e9 clamped.
  r = read(world("PointsPolygons [3] [0 1 1.5] \"P\" [0 0 0 1 0 0 0 1 0]"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "'PointsPolygons': vertex indices must be whole numbers up to 1e9, got 1.5");
  r = read(world("PointsGeneralPolygons [1] [3000000000] [0 1 2] \"P\" [0 0 0 1 0 0 0 1 0]"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "'PointsGeneralPolygons': vertex counts must be whole numbers up to 1e9, got 3000000000");
  r = read("Format 64.5 48 1\n" + world(""));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "'Format' resolution must be whole numbers between 1 and 65536");
}

TEST(RibReader, TruncatedFilesAreErrors) {
  ReadResult r = read("WorldBegin\nSphere 1 -1 1 360\n");
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.format(),
            "/scenes/test.rib:3: error: unexpected end of file: 'WorldBegin' at line 1 has no "
            "'WorldEnd'");
  r = read("WorldBegin\nAttributeBegin\nWorldEnd\n");
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 3);
  r = read("WorldBegin\nAttributeBegin\n");
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("'AttributeBegin' at line 2 has no 'AttributeEnd'"),
            std::string::npos);
  r = read("WorldBegin\nPolygon \"P\" [0 0 0 1 0 0\n");
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 2);
  EXPECT_NE(r.error.message.find("missing ']'"), std::string::npos);
  r = read("Format 10 10 1\n");
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("no 'WorldBegin'"), std::string::npos);
}

// Objects instancing the one before twice, 26 deep, expand to 2^26 requests: an error naming the
// line where the budget ran out, within seconds, not hours.
TEST(RibReader, ExponentialInstancingIsAnError) {
  std::string text = "ObjectBegin 0\nColor 1 1 1\nObjectEnd\n";
  for (int i = 1; i <= 26; ++i)
    text += "ObjectBegin " + std::to_string(i) + "\nObjectInstance " + std::to_string(i - 1) +
            "\nObjectInstance " + std::to_string(i - 1) + "\nObjectEnd\n";
  ReadResult r = read(world(text + "ObjectInstance 26"));
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("the scene expands to more than 16777216 requests"), std::string::npos)
      << r.error.format();
}

TEST(RibReader, MismatchedBlocksAreErrors) {
  ReadResult r = read(world("TransformBegin\nAttributeEnd"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "'AttributeEnd' closes 'TransformBegin' at line 2");
  r = read(world("AttributeEnd"));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "'AttributeEnd' without 'AttributeBegin'");
  r = read("Sphere 1 -1 1 360\n" + world(""));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.line, 1);
  r = read("42\n" + world(""));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "expected a request name, found number '42'");
}

TEST(RibReader, UnknownRequestsWarnOnceAndAreSkipped) {
  ReadResult r = read("ShadingRate 1\nShadingRate 2\nversion 3.04\n" +
                      world("Blobby 0 [] [] []\nPolygon \"P\" [0 0 0  1 0 0  0 1 0]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->meshes.size(), 1u);
  EXPECT_EQ(r.warnings,
            "/scenes/test.rib:1: warning: unsupported request 'ShadingRate' ignored (Relief dices "
            "displacement by world-space edge length: Attribute \"relief\" \"float edgelength\", or "
            "--edge-length)\n"
            "/scenes/test.rib:5: warning: unsupported request 'Blobby' ignored\n");
  // A name RenderMan does not have is a slip: said so, with the request it likely meant.
  r = read(world("Spehre 1 -1 1 360\nattributebegin\nFrobnicate 1\nAttributeBegin\nAttributeEnd"));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.warnings,
            "/scenes/test.rib:2: warning: unknown request 'Spehre' ignored (did you mean 'Sphere'?)\n"
            "/scenes/test.rib:3: warning: unknown request 'attributebegin' ignored (did you mean "
            "'AttributeBegin'?)\n"
            "/scenes/test.rib:4: warning: unknown request 'Frobnicate' ignored\n");
}

TEST(RibReader, DisplayNamesTheOutputs) {
  ReadResult r = read("Display \"a.png\" \"file\" \"rgb\"\nDisplay \"+b.exr\" \"file\" \"rgba\"\n" +
                      world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  const std::vector<std::string> expected = {"a.png", "b.exr"};
  EXPECT_EQ(r.scene->displays, expected);
  EXPECT_EQ(r.scene->displayModes, (std::vector<std::string>{"rgb", "rgba"}));
  r = read("Display \"a.png\" \"file\" \"rgb\"\nDisplay \"c.tif\" \"framebuffer\" \"rgb\"\n" +
           world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->displays, std::vector<std::string>{"c.tif"});
  r = read("Display \"sphere\" \"framebuffer\" \"rgb\"\n" + world(""));
  ASSERT_TRUE(r.scene) << r.error.format();
  EXPECT_EQ(r.scene->displays, std::vector<std::string>{"sphere.png"});
  EXPECT_NE(r.warnings.find("writing 'sphere.png'"), std::string::npos);
}

TEST(RibReader, DeclareTypesLaterParameters) {
  test::TestShaderProvider shaders;
  ReadResult r = read(world("Declare \"Km\" \"uniform string\"\nDisplacement \"push\" \"Km\" [\"x\"]"),
                      &shaders);
  ASSERT_FALSE(r.scene);  // declared a string, but the shader's Km is a float
  EXPECT_EQ(r.error.line, 3);
  // The message names the Declare, not only a type the call never wrote.
  r = read(world("Declare \"Km\" \"color\"\nDisplacement \"push\" \"Km\" [3 3 3]"), &shaders);
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("declared 'float' but was given 'color' (typed by the 'Declare' at line 2)"),
            std::string::npos)
      << r.error.message;
  // So does a primitive variable that binds the parameter.
  r = read(world("Declare \"Km\" \"color\"\nDisplacement \"push\"\nSphere 1 -1 1 360 \"Km\" [3 3 3]"), &shaders);
  ASSERT_FALSE(r.scene);
  EXPECT_NE(r.error.message.find("(typed by the 'Declare' at line 2)"), std::string::npos) << r.error.message;
}

TEST(RibReader, BilinearPatch) {
  ReadResult r = read(world("Patch \"bilinear\" \"P\" [0 0 0  2 0 0  0 1 0  2 1 0]"
                            " \"st\" [0 0  1 0  0 0.5  1 0.5]\n"
                            "Patch \"bilinear\" \"P\" [0 0 0  1 0 0  0 1 0  1 1 1]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 2u);
  const Mesh& flat = r.scene->meshes[0];
  EXPECT_EQ(flat.numTriangles(), 2u);
  ASSERT_EQ(flat.uv.size(), 4u);
  expectNear(flat.P[3], glm::vec3(2, 1, 0));
  EXPECT_EQ(flat.uv[3], glm::vec2(1, 1));
  EXPECT_EQ(flat.st[2], glm::vec2(0, 0.5f));
  // Triangles wind like dPdu x dPdv.
  const glm::vec3 n = glm::cross(flat.P[flat.indices[1]] - flat.P[flat.indices[0]],
                                 flat.P[flat.indices[2]] - flat.P[flat.indices[0]]);
  EXPECT_GT(n.z, 0.0f);
  const Mesh& warped = r.scene->meshes[1];
  EXPECT_GT(warped.numTriangles(), 2u);
  for (size_t i = 0; i < warped.P.size(); ++i)  // the bilinear surface z = u v
    EXPECT_NEAR(warped.P[i].z, warped.uv[i].x * warped.uv[i].y, 1e-5f);
}

TEST(RibReader, QuadricsFollowTheirParametricDefinitions) {
  ReadResult r = read(world("Cylinder 2 -1 3 360\nCone 2 1 180\nDisk 0.5 3 360\n"
                            "Torus 3 1 0 360 360\nCylinder 0 0 1 360"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 4u);  // the zero-radius cylinder is skipped
  EXPECT_NE(r.warnings.find("degenerate 'Cylinder' skipped"), std::string::npos);
  const Mesh& cylinder = r.scene->meshes[0];
  for (size_t i = 0; i < cylinder.P.size(); ++i) {
    const glm::vec3 p = cylinder.P[i];
    EXPECT_NEAR(std::hypot(p.x, p.y), 2.0f, 1e-4f);
    EXPECT_NEAR(p.z, -1.0f + 4.0f * cylinder.uv[i].y, 1e-4f);
    EXPECT_GT(glm::dot(cylinder.N[i], glm::vec3(p.x, p.y, 0)), 0.0f);  // outward
  }
  const Mesh& cone = r.scene->meshes[1];
  for (size_t i = 0; i < cone.P.size(); ++i) {
    const glm::vec3 p = cone.P[i];
    EXPECT_NEAR(std::hypot(p.x, p.y), 1.0f - p.z / 2.0f, 1e-4f);
    EXPECT_GE(p.y, -1e-4f);  // a half cone: theta in [0, 180]
  }
  const Mesh& disk = r.scene->meshes[2];
  for (size_t i = 0; i < disk.P.size(); ++i) {
    EXPECT_NEAR(disk.P[i].z, 0.5f, 1e-6f);
    EXPECT_LE(std::hypot(disk.P[i].x, disk.P[i].y), 3.0f + 1e-4f);
    EXPECT_NEAR(std::fabs(disk.N[i].z), 1.0f, 1e-4f);
  }
  const Mesh& torus = r.scene->meshes[3];
  for (size_t i = 0; i < torus.P.size(); ++i) {
    const glm::vec3 p = torus.P[i];
    const float ring = std::hypot(p.x, p.y) - 3.0f;
    EXPECT_NEAR(ring * ring + p.z * p.z, 1.0f, 1e-3f);
    const glm::vec3 centre = glm::vec3(p.x, p.y, 0) * (3.0f / std::hypot(p.x, p.y));
    EXPECT_GT(glm::dot(torus.N[i], p - centre), 0.0f);  // away from the tube's core
  }
}

TEST(RibReader, ParaboloidHyperboloidAndGeneralPolygon) {
  ReadResult r = read(world("Paraboloid 2 0 4 360\nHyperboloid 1 0 0  0 1 1  360\n"
                            "GeneralPolygon [4] \"P\" [0 0 0  1 0 0  1 1 0  0 1 0]\n"
                            "GeneralPolygon [4 3] \"P\" [0 0 0  1 0 0  1 1 0  0 1 0  0 0 0  1 0 0  1 1 0]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 4u);
  for (const glm::vec3& p : r.scene->meshes[0].P)  // r = rmax sqrt(z / zmax)
    EXPECT_NEAR(std::hypot(p.x, p.y), 2.0f * std::sqrt(p.z / 4.0f), 1e-4f);
  const Mesh& hyper = r.scene->meshes[1];
  for (size_t i = 0; i < hyper.P.size(); ++i) {  // the line (1,0,0)-(0,1,1) swept about z
    const float t = hyper.uv[i].y;
    EXPECT_NEAR(std::hypot(hyper.P[i].x, hyper.P[i].y), std::hypot(1.0f - t, t), 1e-4f);
    EXPECT_NEAR(hyper.P[i].z, t, 1e-5f);
  }
  EXPECT_EQ(r.scene->meshes[2].numTriangles(), 2u);
  // The second loop is a hole (here it covers half of the square): 4 + 3 corners, 2 bridges.
  EXPECT_EQ(r.scene->meshes[3].numTriangles(), 7u);
  // A hole outside the boundary was bridged to, drawing a spike out to it: now it is left out,
  // with a warning.
  r = read(world("GeneralPolygon [4 3] \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0  5 5 0  6 5 0  5 6 0]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  ASSERT_EQ(r.scene->meshes.size(), 1u);
  EXPECT_EQ(r.scene->meshes[0].numTriangles(), 2u);
  for (const uint32_t i : r.scene->meshes[0].indices) EXPECT_LE(r.scene->meshes[0].P[i].x, 1.0f);
  EXPECT_NE(r.warnings.find("a hole reaches outside its polygon's boundary; the hole is ignored"), std::string::npos)
      << r.warnings;
}

TEST(RibReader, NamedCoordinateSystems) {
  ReadResult r = read(world("TransformBegin\nTranslate 5 0 0\nScale 2 2 2\n"
                            "CoordinateSystem \"lamp\"\nTransformEnd\n"
                            "CoordSysTransform \"lamp\"\nPolygon \"P\" [0 0 0  1 0 0  0 1 0]\n"
                            "CoordSysTransform \"world\"\nPolygon \"P\" [0 0 0  1 0 0  0 1 0]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  expectNear(r.scene->meshes[0].P[1], glm::vec3(7, 0, 0));
  expectNear(r.scene->meshes[1].P[1], glm::vec3(1, 0, 0));
  r = read(world("CoordSysTransform \"nowhere\""));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "unknown coordinate system 'nowhere'");

  // Named before WorldBegin, a space is relative to the camera (the world is not placed yet): the
  // camera sits at world z = -5, so the space 5 units in front of it is the world's origin.
  r = read("CoordinateSystem \"front\"\nTranslate 0 0 5\nCoordinateSystem \"atOrigin\"\n" +
           world("CoordSysTransform \"front\"\nTranslate 1 0 5\nPolygon \"P\" [0 0 0  1 0 0  0 1 0]\n"
                 "CoordSysTransform \"atOrigin\"\nPolygon \"P\" [0 0 0  1 0 0  0 1 0]"));
  ASSERT_TRUE(r.scene) << r.error.format();
  expectNear(r.scene->meshes[0].P[0], glm::vec3(1, 0, 0));
  expectNear(r.scene->meshes[1].P[1], glm::vec3(1, 0, 0));

  // ScopedCoordinateSystem lasts until the end of its attribute block, then the name means what
  // it meant before (or nothing).
  r = read(world("AttributeBegin\nTranslate -1 0 0\nCoordinateSystem \"a\"\nAttributeEnd\n"
                 "AttributeBegin\nTranslate 1 0 0\nScopedCoordinateSystem \"a\"\n"
                 "ScopedCoordinateSystem \"b\"\nCoordSysTransform \"a\"\n"
                 "Polygon \"P\" [0 0 0  1 0 0  0 1 0]\nAttributeEnd\n"
                 "CoordSysTransform \"a\"\nPolygon \"P\" [0 0 0  1 0 0  0 1 0]\n"));
  ASSERT_TRUE(r.scene) << r.error.format();
  expectNear(r.scene->meshes[0].P[0], glm::vec3(1, 0, 0));
  expectNear(r.scene->meshes[1].P[0], glm::vec3(-1, 0, 0));
  r = read(world("AttributeBegin\nScopedCoordinateSystem \"b\"\nAttributeEnd\nCoordSysTransform \"b\""));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "unknown coordinate system 'b'");
  // The same before WorldBegin: the scope ends there too, and the name is not left behind.
  r = read("AttributeBegin\nScopedCoordinateSystem \"b\"\nAttributeEnd\n" + world("CoordSysTransform \"b\""));
  ASSERT_FALSE(r.scene);
  EXPECT_EQ(r.error.message, "unknown coordinate system 'b'");
}

// A mirroring transform flips the orientation with the coordinate system (RI spec), so every kind
// of primitive keeps its side: its winding's normal agrees with its (outward) normals either way.
// One-sided culling and displacement shaders' Ng follow the winding.
TEST(RibReader, EveryPrimitiveKeepsItsSideUnderAMirror) {
  for (const char* primitive :
       {"Sphere 1 -1 1 360", "Cylinder 1 -1 1 360", "Cone 1 1 360", "Disk 0 1 360", "Torus 1 0.3 0 360 360",
        "Paraboloid 1 0 1 360", "Hyperboloid 1 0 0 0 1 1 360", "Polygon \"P\" [0 0 0  1 0 0  1 1 0  0 1 0]",
        "Patch \"bilinear\" \"P\" [0 0 0  1 0 0  0 1 0  1 1 1]"}) {
    for (const char* mirror : {"", "Scale -1 1 1\n", "Scale 1 -2 1\n"}) {
      SCOPED_TRACE(std::string(primitive) + " / " + mirror);
      ReadResult r = read(world(std::string(mirror) + primitive));
      ASSERT_TRUE(r.scene) << r.error.format();
      const Mesh& m = r.scene->meshes.at(0);
      int agree = 0, disagree = 0;
      for (uint32_t t = 0; t < m.numTriangles(); ++t) {
        const uint32_t* i = &m.indices[3 * size_t(t)];
        const glm::vec3 n = glm::cross(m.P[i[1]] - m.P[i[0]], m.P[i[2]] - m.P[i[0]]);
        if (glm::length(n) < 1e-9f) continue;
        glm::vec3 shading = m.N.empty() ? glm::vec3(0, 0, 1) : m.N[i[0]] + m.N[i[1]] + m.N[i[2]];
        if (m.N.empty()) continue;
        (glm::dot(n, shading) > 0 ? agree : disagree)++;
      }
      if (!m.N.empty()) {
        EXPECT_GT(agree, 0);
        EXPECT_EQ(disagree, 0);
      }
    }
  }
}

TEST(RibReader, ReadArchiveIncludesFilesRelativeToTheReader) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("relief-archive-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir / "parts");
  std::ofstream(dir / "parts" / "tri.rib") << "Color [0 1 0]\nReadArchive \"more.rib\"\n";
  std::ofstream(dir / "parts" / "more.rib") << "Polygon \"P\" [0 0 0  1 0 0  0 1 0]\n";
  std::ofstream(dir / "parts" / "bad.rib") << "\n\nSphere 1\n";
  std::ofstream(dir / "parts" / "loop.rib") << "ReadArchive \"loop.rib\"\n";
  std::ofstream(dir / "main.rib") << "WorldBegin\nReadArchive \"parts/tri.rib\"\nWorldEnd\n";
  std::ofstream(dir / "bad.rib") << "WorldBegin\nReadArchive \"parts/bad.rib\"\nWorldEnd\n";
  std::ofstream(dir / "loop.rib") << "WorldBegin\nReadArchive \"parts/loop.rib\"\nWorldEnd\n";
  SceneError error;
  std::optional<Scene> scene = readRibFile((dir / "main.rib").string(), RibReadOptions{}, &error);
  ASSERT_TRUE(scene) << error.format();
  ASSERT_EQ(scene->meshes.size(), 1u);
  expectNear(scene->materials[scene->meshes[0].materialIndex].color, glm::vec3(0, 1, 0));
  EXPECT_FALSE(readRibFile((dir / "bad.rib").string(), RibReadOptions{}, &error));
  EXPECT_EQ(error.file, (dir / "parts" / "bad.rib").string());
  EXPECT_EQ(error.line, 3);
  EXPECT_FALSE(readRibFile((dir / "loop.rib").string(), RibReadOptions{}, &error));
  EXPECT_NE(error.message.find("nested more than"), std::string::npos) << error.message;
  std::filesystem::remove_all(dir);
}

// A displacement's messages (texture errors, the bound warning) point at its Displacement call,
// file and line, also when the geometry comes from another file: they had the geometry's file
// with the call's line.
TEST(RibReader, DisplacementSourceIsTheCallsFileAndLine) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("relief-dispsource-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "grid.rib") << "Polygon \"P\" [0 0 0  1 0 0  0 1 0]\n";
  std::ofstream(dir / "disp.rib") << "Attribute \"displacementbound\" \"float sphere\" [0.1]\nDisplacement \"push\"\n";
  std::ofstream(dir / "main.rib") << "WorldBegin\nAttributeBegin\n\nDisplacement \"push\"\nReadArchive \"grid.rib\"\n"
                                     "AttributeEnd\nReadArchive \"disp.rib\"\nSphere 1 -1 1 360\nWorldEnd\n";
  test::TestShaderProvider shaders;
  RibReadOptions options;
  options.shaders = &shaders;
  std::ostringstream warnings;
  options.warnings = &warnings;
  SceneError error;
  std::optional<Scene> scene = readRibFile((dir / "main.rib").string(), options, &error);
  ASSERT_TRUE(scene) << error.format();
  ASSERT_EQ(scene->meshes.size(), 2u);
  const Displacement& first = scene->displacements[scene->meshes[0].displacementIndex];
  EXPECT_EQ(first.sourceFile, (dir / "main.rib").string());
  EXPECT_EQ(first.sourceLine, 4);
  const Displacement& second = scene->displacements[scene->meshes[1].displacementIndex];
  EXPECT_EQ(second.sourceFile, (dir / "disp.rib").string());
  EXPECT_EQ(second.sourceLine, 2);
  std::filesystem::remove_all(dir);
}

// An inline archive read while a file it reads defines the same name again runs its own calls to
// the end (from a copy); a block opened in an archive file must close in it.
TEST(RibReader, InlineArchivesSurviveRedefinitionAndCloseInTheirFile) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("relief-inline-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::string redefine = "ArchiveBegin \"a\"\n";
  for (int i = 0; i < 200; ++i) redefine += "Polygon \"P\" [0 0 0  1 0 0  0 1 0]\n";
  std::ofstream(dir / "redefine.rib") << redefine << "ArchiveEnd\n";
  std::ofstream(dir / "main.rib") << "ArchiveBegin \"a\"\nReadArchive \"redefine.rib\"\n"
                                     "Translate 1 0 0\nPolygon \"P\" [0 0 0  1 0 0  0 1 0]\nArchiveEnd\n"
                                     "WorldBegin\nReadArchive \"a\"\nReadArchive \"a\"\nWorldEnd\n";
  std::ofstream(dir / "open.rib") << "ArchiveBegin \"x\"\n";
  std::ofstream(dir / "swallow.rib") << "WorldBegin\nReadArchive \"open.rib\"\nSphere 1 -1 1 360\nArchiveEnd\nWorldEnd\n";
  SceneError error;
  std::optional<Scene> scene = readRibFile((dir / "main.rib").string(), RibReadOptions{}, &error);
  ASSERT_TRUE(scene) << error.format();
  ASSERT_EQ(scene->meshes.size(), 201u);  // the first read's own polygon, then the new archive
  expectNear(scene->meshes[0].P[0], glm::vec3(1, 0, 0));
  EXPECT_FALSE(readRibFile((dir / "swallow.rib").string(), RibReadOptions{}, &error));
  EXPECT_EQ(error.file, (dir / "open.rib").string());
  EXPECT_EQ(error.line, 1);
  EXPECT_NE(error.message.find("'ArchiveBegin' at line 1 has no 'ArchiveEnd'"), std::string::npos) << error.message;
  std::filesystem::remove_all(dir);
}

// A block an archive opens and leaves open is reported at the end of the main file, naming the
// archive and its line: the archive's line number alone would point into the wrong file.
TEST(RibReader, BlocksLeftOpenByAnArchiveNameTheArchive) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("relief-open-blocks-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "opens.rib") << "# an archive\n\nAttributeBegin\n";
  std::ofstream(dir / "main.rib") << "WorldBegin\nReadArchive \"opens.rib\"\nWorldEnd\n";
  SceneError error;
  EXPECT_FALSE(readRibFile((dir / "main.rib").string(), RibReadOptions{}, &error));
  EXPECT_EQ(error.file, (dir / "main.rib").string());
  EXPECT_EQ(error.line, 3);
  EXPECT_NE(error.message.find("'AttributeBegin' (line 3 of '" + (dir / "opens.rib").string() + "')"),
            std::string::npos)
      << error.message;
  std::ofstream(dir / "main.rib") << "WorldBegin\nAttributeBegin\nReadArchive \"opens.rib\"\n";
  EXPECT_FALSE(readRibFile((dir / "main.rib").string(), RibReadOptions{}, &error));
  EXPECT_NE(error.message.find("'AttributeBegin' at line 3 of '" + (dir / "opens.rib").string() + "' has no"),
            std::string::npos)
      << error.message;
  std::filesystem::remove_all(dir);
}

TEST(RibReader, MissingFileIsAnErrorNamingIt) {
  SceneError error;
  EXPECT_FALSE(readRibFile("/nonexistent/scene.rib", RibReadOptions{}, &error));
  EXPECT_EQ(error.file, "/nonexistent/scene.rib");
  EXPECT_NE(error.format().find("/nonexistent/scene.rib: error: cannot open"), std::string::npos);
}

TEST(RibReader, ExampleSceneLoads) {
  test::TestShaderProvider shaders;
  // The example's "bumps" shader is served by a renamed stand-in: only the reader is under test.
  class Renaming : public runtime::ShaderProvider {
   public:
    std::shared_ptr<const runtime::CompiledShader> find(std::string_view,
                                                        std::span<const std::string>,
                                                        std::string*) override {
      std::vector<runtime::ParamInfo> params(2);
      params[0].name = "Km";
      params[1].name = "freq";
      params[1].offset = 4;
      return std::make_shared<runtime::CompiledShader>("bumps", &test::pushEntry, params, 8,
                                                       nullptr);
    }
  } provider;
  RibReadOptions options;
  options.shaders = &provider;
  SceneError error;
  std::optional<Scene> scene =
      readRibFile(std::string(RELIEF_SOURCE_DIR) + "/examples/scenes/sphere.rib", options, &error);
  ASSERT_TRUE(scene) << error.format();
  EXPECT_EQ(scene->width, 480);
  EXPECT_EQ(scene->meshes.size(), 2u);
  EXPECT_EQ(scene->distantLights.size(), 1u);
  EXPECT_EQ(scene->displays, std::vector<std::string>{"sphere.png"});
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// Robustness: byte-level mutations of a realistic scene must give a scene or a located error,
// never a crash or a hang (run under ASan/UBSan in CI). Fixed seed, so failures reproduce.
TEST(RibReader, SurvivesMutatedInput) {
  const std::string base =
      "Option \"searchpath\" \"string shader\" [\"../shaders:&\"]\n"
      "Format 48 36 1\nPixelSamples 2 2\nDisplay \"x.png\" \"file\" \"rgb\"\n"
      "Projection \"perspective\" \"fov\" [30]\nTranslate 0 0 6.5\nRotate -25 1 0 0\n"
      "WorldBegin\n"
      "LightSource \"distantlight\" 1 \"intensity\" [1.1] \"from\" [-2 3 -1.5] \"to\" [0 0 0]\n"
      "AttributeBegin\nColor [0.9 0.55 0.35]\nSurface \"matte\" \"Kd\" [0.8]\n"
      "Attribute \"displacementbound\" \"float sphere\" [0.06]\n"
      "Displacement \"push\" \"float Km\" [0.05] \"tint\" [1 1 0]\n"
      "Sphere 1 -1 1 360\nAttributeEnd\nCone 1 0.5 90\n"
      "Patch \"bilinear\" \"P\" [0 0 0  1 0 0  0 1 0  1 1 1]\n"
      "PointsPolygons [4] [0 1 2 3] \"P\" [-5 -1 -5  -5 -1 5  5 -1 5  5 -1 -5] \"st\" [0 0 1 0 1 1 0 1]\n"
      "WorldEnd\n";
  const std::string alphabet = "[]\"#\\ \n\r0123456789.-+eE AttributeEnd WorldBegin xyz";
  test::TestShaderProvider shaders;
  const auto [parsed, rejected] = test::mutationFuzz(base, alphabet, 12345, 1500, [&](const std::string& text) {
    ReadResult r = read(text, &shaders);
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
