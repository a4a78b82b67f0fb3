// The compile facade (compiler.h) as hosts see it: nothing thrown inside the compiler escapes it,
// whatever the cause; it becomes CompileResult::internalError (reliefc exits with 3, language.md §8).
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

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

}  // namespace
}  // namespace relief::compiler
