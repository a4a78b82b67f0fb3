// Tests of runtime/shader.*: parameter-block layout from reflection, defaults, binding scene values
// with the language's promotions, and rejection of values that do not fit.
#include "runtime/shader.h"

#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

namespace relief::runtime {
namespace {

// A stand-in entry: P += Km * N, reading Km from offset 0 of the block.
void addAlongNormal(const RlfShadingBatch* b, const void* params, RlfStatus*) {
  float km;
  std::memcpy(&km, params, 4);
  for (uint32_t i = 0; i < b->count; ++i) {
    b->Pout.x[i] = b->P.x[i] + km * b->N.x[i];
    b->Pout.y[i] = b->P.y[i] + km * b->N.y[i];
    b->Pout.z[i] = b->P.z[i] + km * b->N.z[i];
    b->Nout.x[i] = b->N.x[i];
    b->Nout.y[i] = b->N.y[i];
    b->Nout.z[i] = b->N.z[i];
  }
}

std::shared_ptr<CompiledShader> makeShader() {
  std::vector<ParamInfo> params;
  params.push_back({"Km", ParamType::Float, 0, false, 0, {0.5f}, {}});
  params.push_back({"n", ParamType::Int, 0, false, 4, {3}, {}});
  params.push_back({"c", ParamType::Color, 0, false, 8, {1, 2, 3}, {}});
  params.push_back({"dir", ParamType::Vector, 0, false, 20, {0, 0, 1}, {}});
  params.push_back({"arr", ParamType::Float, 2, false, 32, {7, 8}, {}});
  params.push_back({"name", ParamType::String, 0, false, 40, {}, {"rock.tx"}});
  return std::make_shared<CompiledShader>("stub", &addAlongNormal, std::move(params), 48, nullptr);
}

template <typename T>
T read(const ShaderInstance& inst, size_t offset) {
  T v;
  std::memcpy(&v, inst.block().data() + offset, sizeof v);
  return v;
}

TEST(ShaderInstance, DefaultsAreLaidOutByReflection) {
  ShaderInstance inst(makeShader());
  EXPECT_FLOAT_EQ(read<float>(inst, 0), 0.5f);
  EXPECT_EQ(read<int32_t>(inst, 4), 3);
  EXPECT_FLOAT_EQ(read<float>(inst, 16), 3.0f);
  EXPECT_FLOAT_EQ(read<float>(inst, 36), 8.0f);
  EXPECT_STREQ(read<const char*>(inst, 40), "rock.tx");
}

TEST(ShaderInstance, BindPromotesLikeTheLanguage) {
  ShaderInstance inst(makeShader());
  std::string error;
  EXPECT_TRUE(inst.bind({"n", ParamType::Float, {4.75f}, {}}, &error)) << error;
  EXPECT_EQ(read<int32_t>(inst, 4), 4);  // float -> int truncates
  EXPECT_TRUE(inst.bind({"c", ParamType::Float, {0.25f}, {}}, &error)) << error;
  EXPECT_FLOAT_EQ(read<float>(inst, 12), 0.25f);  // splat
  EXPECT_TRUE(inst.bind({"dir", ParamType::Point, {1, 0, 0}, {}}, &error)) << error;
  EXPECT_FLOAT_EQ(read<float>(inst, 20), 1.0f);  // point -> vector copies components
  EXPECT_TRUE(inst.bind({"name", ParamType::String, {}, {"other.tx"}}, &error)) << error;
  EXPECT_STREQ(read<const char*>(inst, 40), "other.tx");
}

TEST(ShaderInstance, BindRejectsWhatDoesNotFit) {
  ShaderInstance inst(makeShader());
  std::string error;
  EXPECT_FALSE(inst.bind({"Kn", ParamType::Float, {1}, {}}, &error));
  EXPECT_NE(error.find("no parameter 'Kn'"), std::string::npos) << error;
  EXPECT_FALSE(inst.bind({"c", ParamType::Vector, {1, 2, 3}, {}}, &error));  // color <- spatial
  EXPECT_NE(error.find("declared 'color'"), std::string::npos) << error;
  EXPECT_FALSE(inst.bind({"Km", ParamType::String, {}, {"x"}}, &error));
  EXPECT_FALSE(inst.bind({"arr", ParamType::Float, {1, 2, 3}, {}}, &error));  // too many
  // Too few: RenderMan binds whole arrays (a short list kept the rest at their defaults).
  EXPECT_FALSE(inst.bind({"arr", ParamType::Float, {1}, {}}, &error));
  EXPECT_NE(error.find("declared 'float[2]' (2 numbers) but was given 1"), std::string::npos) << error;
  EXPECT_FALSE(inst.bind({"Km", ParamType::Float, {}, {}}, &error));          // no value
  // The right type with the wrong count says the count, not "declared 'color', given 'color'".
  EXPECT_FALSE(inst.bind({"c", ParamType::Color, {0.1f}, {}}, &error));
  EXPECT_NE(error.find("declared 'color' (3 numbers) but was given 1"), std::string::npos) << error;
  // A value contradicting the call's own "int" declaration is refused, not bound as 2.5 or 2.
  EXPECT_FALSE(inst.bind({"Km", ParamType::Int, {2.5}, {}}, &error));
  EXPECT_NE(error.find("'Km' is declared 'int' but was given 2.5"), std::string::npos) << error;
  // A rejected bind leaves the previous value.
  EXPECT_FLOAT_EQ(read<float>(inst, 0), 0.5f);
  EXPECT_TRUE(inst.bind({"Km", ParamType::Int, {2}, {}}, &error)) << error;
  EXPECT_FLOAT_EQ(read<float>(inst, 0), 2.0f);
}

TEST(ShaderInstance, EvaluateRunsTheEntryOnABatch) {
  ShaderInstance inst(makeShader());
  std::string error;
  ASSERT_TRUE(inst.bind({"Km", ParamType::Float, {2}, {}}, &error));
  float px[2] = {1, 2}, py[2] = {0, 0}, pz[2] = {0, 0};
  float nx[2] = {0, 0}, ny[2] = {1, 1}, nz[2] = {0, 0};
  float ox[2], oy[2], oz[2], qx[2], qy[2], qz[2];
  RlfSpaces spaces{};
  RlfShadingBatch b{};
  b.count = 2;
  b.P = {px, py, pz};
  b.N = {nx, ny, nz};
  b.spaces = &spaces;
  b.Pout = {ox, oy, oz};
  b.Nout = {qx, qy, qz};
  RlfStatus status{};
  inst.evaluate(b, status);
  EXPECT_FLOAT_EQ(oy[0], 2.0f);
  EXPECT_FLOAT_EQ(ox[1], 2.0f);
}

// A file may define several shaders: "file:shader" selects one, and a bare name with no file of
// its own is found among the declarations in the search path (ambiguity is an error, not a pick).
TEST(LocateShaderFile, SelectsAmongSeveralShadersOfAFile) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("relief_locate_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir / "a");
  std::filesystem::create_directories(dir / "b");
  auto write = [](const std::filesystem::path& p, const char* text) { std::ofstream(p) << text; };
  write(dir / "a" / "lib.disp",
        "float h(float x) { return x; }\ndisplacement lib(float k = 1) {}\ndisplacement\n  other (float k = 1) {}\n");
  write(dir / "a" / "notes.disp",
        "// displacement others( in a comment\n/* displacement others() */\n"
        "string s = \"displacement others()\";\n");
  write(dir / "b" / "one.disp", "displacement twice() {}\n");
  write(dir / "b" / "two.disp", "displacement twice() {}\n");
  const std::vector<std::string> path = {(dir / "a").string(), (dir / "b").string()};
  std::string file, shader, error;

  ASSERT_TRUE(locateShaderFile("lib:other", path, &file, &shader, &error)) << error;
  EXPECT_EQ(file, (dir / "a" / "lib.disp").string());
  EXPECT_EQ(shader, "other");
  ASSERT_TRUE(locateShaderFile("lib.disp:lib", path, &file, &shader, &error)) << error;
  EXPECT_EQ(shader, "lib");
  ASSERT_TRUE(locateShaderFile("other", path, &file, &shader, &error)) << error;
  EXPECT_EQ(file, (dir / "a" / "lib.disp").string());
  EXPECT_EQ(shader, "other");
  ASSERT_TRUE(locateShaderFile("lib", path, &file, &shader, &error)) << error;  // the file's own
  EXPECT_EQ(shader, "lib");

  EXPECT_FALSE(locateShaderFile("twice", path, &file, &shader, &error));
  EXPECT_NE(error.find("defined by both '" + (dir / "b" / "one.disp").string() + "' and"), std::string::npos) << error;
  EXPECT_NE(error.find("'one:twice'"), std::string::npos) << error;
  ASSERT_TRUE(locateShaderFile("two:twice", path, &file, &shader, &error)) << error;
  EXPECT_EQ(file, (dir / "b" / "two.disp").string());

  EXPECT_FALSE(locateShaderFile("others", path, &file, &shader, &error));
  EXPECT_NE(error.find("no 'others.disp' in the search path"), std::string::npos) << error;
  EXPECT_FALSE(locateShaderFile("nofile:other", path, &file, &shader, &error));
  EXPECT_NE(error.find("no 'nofile.disp'"), std::string::npos) << error;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace relief::runtime
