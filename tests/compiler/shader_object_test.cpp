// Shader bundles (runtime/shader_object.h): the code relief loads from reliefc --emit-bundle must
// be the JIT's, bit for bit, with the same parameter layouts and defaults; a malformed bundle or
// an object calling what shader code may not call is an error, never a crash.
#include <elf.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "compiler/compiler.h"
#include "runtime/shader.h"
#include "runtime/shader_object.h"
#include "runtime/symbols.h"
#include "test_batch.h"

namespace relief::compiler {
namespace {

using testing::TestBatch;

CompileResult compileWithObject(const std::string& path) {
  CompileFlags flags;
  flags.emitObject = true;
  flags.jit = true;  // the reference: the same file through the in-process JIT
  return compileFile(path, {}, flags);
}

// Points spread over a bumpy sphere, with every input the ABI has.
void fillBatch(TestBatch& b) {
  for (size_t i = 0; i < b.count; ++i) {
    const float u = float(i) / float(b.count), v = 0.05f + 0.9f * float((i * 37) % b.count) / float(b.count);
    const float phi = 6.2831853f * u, theta = 3.14159265f * v;
    const float p[3] = {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
    for (int k = 0; k < 3; ++k) {
      b.P[k][i] = 2.0f * p[k], b.N[k][i] = b.Ng[k][i] = p[k];
      b.dPdu[k][i] = k == 0 ? 1.0f : 0.0f, b.dPdv[k][i] = k == 1 ? 1.0f : 0.0f;
    }
    b.u[i] = b.s[i] = u, b.v[i] = b.t[i] = v;
    b.du[i] = b.dv[i] = 0.01f, b.dsdu[i] = b.dtdv[i] = 1.0f;
  }
}

TEST(ShaderBundle, LoadedCodeIsTheJitsBitForBit) {
  const std::filesystem::path dir = std::filesystem::path(RELIEF_SOURCE_DIR) / "examples" / "shaders";
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() != ".disp") continue;
    ++files;
    SCOPED_TRACE(entry.path().string());
    const CompileResult r = compileWithObject(entry.path().string());
    ASSERT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
    ASSERT_FALSE(r.object.empty());
    ASSERT_EQ(r.layouts.size(), r.shaders.size());
    const std::string bundle = runtime::encodeShaderBundle(r.layouts, r.object);
    std::vector<std::shared_ptr<const runtime::CompiledShader>> loaded;
    std::string error;
    ASSERT_TRUE(runtime::loadShaderBundle(bundle, &loaded, &error)) << error;
    ASSERT_EQ(loaded.size(), r.shaders.size());
    for (size_t s = 0; s < loaded.size(); ++s) {
      const runtime::CompiledShader& jit = *r.shaders[s];
      const runtime::CompiledShader& obj = *loaded[s];
      EXPECT_EQ(obj.name(), jit.name());
      EXPECT_EQ(obj.blockSize(), jit.blockSize());
      EXPECT_EQ(obj.ownNormal(), jit.ownNormal());
      ASSERT_EQ(obj.params().size(), jit.params().size());
      for (size_t p = 0; p < jit.params().size(); ++p) {
        const runtime::ParamInfo &a = jit.params()[p], &b = obj.params()[p];
        EXPECT_EQ(a.name, b.name);
        EXPECT_EQ(a.type, b.type);
        EXPECT_EQ(a.arrayLength, b.arrayLength);
        EXPECT_EQ(a.offset, b.offset);
        EXPECT_EQ(a.boundFlagOffset, b.boundFlagOffset);
        EXPECT_EQ(a.defaultNumbers, b.defaultNumbers) << a.name;
        EXPECT_EQ(a.defaultStrings, b.defaultStrings) << a.name;
      }
      TestBatch one(512), two(512);
      fillBatch(one), fillBatch(two);
      runtime::ShaderInstance a(r.shaders[s]), b(loaded[s]);
      RlfStatus sa{}, sb{};
      a.evaluate(one.view(0, one.count), sa);
      b.evaluate(two.view(0, two.count), sb);
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(std::memcmp(one.Pout[k].data(), two.Pout[k].data(), one.count * sizeof(float)), 0) << "P " << k;
        EXPECT_EQ(std::memcmp(one.Nout[k].data(), two.Nout[k].data(), one.count * sizeof(float)), 0) << "N " << k;
      }
      EXPECT_EQ(sa.nonFinite, sb.nonFinite);
      EXPECT_EQ(sa.textureErrors, sb.textureErrors);
    }
  }
  EXPECT_GE(files, 7);
}

TEST(ShaderBundle, MalformedBundlesAndForbiddenCallsAreErrors) {
  const CompileResult r = [] {
    CompileFlags flags;
    flags.emitObject = true;
    flags.jit = false;
    return compileSource("t.disp", "displacement t(float Km = 0.1) { P += Km * sin(u * 7) * N; N = calculatenormal(P); }",
                         {}, flags);
  }();
  ASSERT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
  const std::string bundle = runtime::encodeShaderBundle(r.layouts, r.object);
  std::vector<std::shared_ptr<const runtime::CompiledShader>> loaded;
  std::string error;
  ASSERT_TRUE(runtime::loadShaderBundle(bundle, &loaded, &error)) << error;
  ASSERT_EQ(loaded.size(), 1u);
  EXPECT_EQ(loaded[0]->params()[0].defaultNumbers, std::vector<double>{0.1f});

  // Every truncation is refused, none crashes.
  for (size_t n = 0; n < bundle.size(); n += std::max<size_t>(1, bundle.size() / 97)) {
    loaded.clear();
    EXPECT_FALSE(runtime::loadShaderBundle(std::string_view(bundle).substr(0, n), &loaded, &error)) << n;
    EXPECT_FALSE(error.empty());
  }
  std::string wrongMagic = bundle;
  wrongMagic[0] = 'X';
  EXPECT_FALSE(runtime::loadShaderBundle(wrongMagic, &loaded, &error));
  EXPECT_NE(error.find("not a shader bundle"), std::string::npos) << error;

  // The object may call only the runtime's symbols: rename the one it calls (sin's, through
  // libm) to a name outside them.
  std::string forbidden = bundle, called;
  size_t at = std::string::npos;
  for (const runtime::RuntimeSymbol& symbol : runtime::runtimeSymbols()) {
    at = forbidden.find('\0' + std::string(symbol.name) + '\0');
    if (at != std::string::npos) {
      called = symbol.name;
      break;
    }
  }
  ASSERT_NE(at, std::string::npos);
  forbidden[at + 1] = '_';
  loaded.clear();
  EXPECT_FALSE(runtime::loadShaderBundle(forbidden, &loaded, &error));
  EXPECT_NE(error.find("'_" + called.substr(1) + "', which shader code may not call"), std::string::npos) << error;
  EXPECT_TRUE(loaded.empty());
}

// The loader on corrupt objects: bundles without layouts, so that no loaded code runs and any
// crash (or, under ASan, any stray read or write) is the loader's own.
TEST(ShaderBundle, CorruptObjectsAreRefusedWithoutCrashing) {
  CompileFlags flags;
  flags.emitObject = true;
  flags.jit = false;
  const CompileResult r = compileSource(
      "t.disp", "displacement t(float Km = 0.1; string name = \"x\") { P += Km * noise(P * 3) * N; }", {}, flags);
  ASSERT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
  const std::string& object = r.object;
  std::vector<std::shared_ptr<const runtime::CompiledShader>> loaded;
  std::string error;
  ASSERT_TRUE(runtime::loadShaderBundle(runtime::encodeShaderBundle({}, object), &loaded, &error)) << error;

  // The section headers come last: every truncation cuts them.
  for (size_t n = 0; n < object.size(); n += std::max<size_t>(1, object.size() / 211))
    EXPECT_FALSE(runtime::loadShaderBundle(runtime::encodeShaderBundle({}, object.substr(0, n)), &loaded, &error)) << n;

  // Each section header with one field made absurd: refused or loaded, never a crash.
  Elf64_Ehdr eh;
  std::memcpy(&eh, object.data(), sizeof eh);
  int refused = 0, tried = 0;
  for (size_t i = 0; i < eh.e_shnum; ++i) {
    const size_t at = eh.e_shoff + i * sizeof(Elf64_Shdr);
    auto patched = [&](auto&& edit) {
      std::string copy = object;
      Elf64_Shdr h;
      std::memcpy(&h, copy.data() + at, sizeof h);
      edit(h);
      std::memcpy(copy.data() + at, &h, sizeof h);
      ++tried;
      refused += !runtime::loadShaderBundle(runtime::encodeShaderBundle({}, copy), &loaded, &error);
    };
    patched([](Elf64_Shdr& h) { h.sh_type = SHT_NOBITS; });
    patched([](Elf64_Shdr& h) { h.sh_size = ~uint64_t(0); });
    patched([](Elf64_Shdr& h) { h.sh_offset = ~uint64_t(0); });
    patched([](Elf64_Shdr& h) { h.sh_link = 0xffff; });
    patched([](Elf64_Shdr& h) { h.sh_info = 0xffff; });
    patched([](Elf64_Shdr& h) { h.sh_addralign = 3; });
  }
  EXPECT_GT(refused, tried / 4);

  // A layout whose parameter block is absurd, and a bundle of another ABI, are refused.
  std::vector<runtime::ShaderLayoutInfo> layouts = r.layouts;
  layouts[0].blockSize = 0xFFFFFFFFu;
  EXPECT_FALSE(runtime::loadShaderBundle(runtime::encodeShaderBundle(layouts, object), &loaded, &error));
  std::string otherAbi = runtime::encodeShaderBundle(r.layouts, object);
  otherAbi[8] ^= 0x40;  // the ABI version follows the 8-byte magic
  EXPECT_FALSE(runtime::loadShaderBundle(otherAbi, &loaded, &error));
  EXPECT_NE(error.find("another shader ABI"), std::string::npos) << error;
  EXPECT_TRUE(loaded.empty());
}

}  // namespace
}  // namespace relief::compiler
