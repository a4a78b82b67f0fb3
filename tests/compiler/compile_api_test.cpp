// The compile facade (compiler.h) as hosts see it: nothing thrown inside the compiler escapes it,
// whatever the cause; it becomes CompileResult::internalError (reliefc exits with 3, language.md §8).
// Its reflection of whether a shader sets its own shading normal.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <utility>

#include "compiler/compiler.h"

namespace relief::compiler {
namespace {

TEST(CompileApiTest, ExceptionsBecomeInternalErrors) {
  CompileFlags flags;
  flags.jit = false;
  flags.onChecked = [](const TranslationUnit&) { throw std::runtime_error("boom"); };
  CompileResult r;
  EXPECT_NO_THROW(r = compileSource("x.disp", "displacement d() { P += 0.1 * N; }", {}, flags));
  EXPECT_FALSE(r.success());
  EXPECT_EQ(r.internalError, "unexpected exception: boom");
  flags.onChecked = [](const TranslationUnit&) { throw 42; };
  EXPECT_NO_THROW(r = compileSource("x.disp", "displacement d() { P += 0.1 * N; }", {}, flags));
  EXPECT_EQ(r.internalError, "unexpected exception");
}

TEST(CompileApiTest, PragmaOnceInAFileTheFileSystemCannotResolve) {
  // A path component longer than NAME_MAX makes std::filesystem throw; #pragma once must cope.
  const std::string name = std::string(300, 'n') + ".disp";
  CompileFlags flags;
  flags.jit = false;
  CompileResult r = compileSource(name, "#pragma once\ndisplacement d() { P += 0.1 * N; }", {}, flags);
  EXPECT_TRUE(r.success()) << r.internalError << renderDiagnostics(r);
}

// Reflection tells the renderer whether the output N is the shader's own shading normal (a bump,
// language.md §5) or the displaced surface's normal, which its micro-triangles already have.
TEST(CompileApiTest, OwnNormalIsReflectedForBumpsOnly) {
  const std::pair<const char*, bool> cases[] = {
      {"displacement d() { P += 0.1 * N; }", false},
      {"displacement d() { P += 0.1 * N; N = calculatenormal(P); }", false},
      {"displacement d() { P += 0.1 * N; N = normalize(calculatenormal(P)); }", false},
      {"displacement d() { displace(0.1); }", false},
      {"void up(float k) { P += k * N; N = normalize(calculatenormal(P)); }\n"
       "displacement d() { up(0.1); }",
       false},
      {"displacement d() { N = normalize(calculatenormal(P + 0.1 * noise(P) * N)); }", true},
      {"displacement d() { N += 0.1 * Ng; }", true},
      {"displacement d() { N = Ng; }", true},
      {"displacement d() { setxcomp(N, 0); }", true},
      {"void tilt(output normal n) { n = normalize(n + 0.2 * Ng); }\ndisplacement d() { tilt(N); }", true},
      {"void bump() { N = normalize(N + 0.1 * Ng); }\ndisplacement d() { bump(); }", true},
  };
  for (const auto& [source, own] : cases) {
    CompileResult r = compileSource("x.disp", source, {}, {});
    ASSERT_TRUE(r.success()) << source << "\n" << renderDiagnostics(r);
    ASSERT_EQ(r.shaders.size(), 1u);
    EXPECT_EQ(r.shaders[0]->ownNormal(), own) << source;
  }
}

}  // namespace
}  // namespace relief::compiler
