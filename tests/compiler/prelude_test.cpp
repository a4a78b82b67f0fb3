// The stdlib/ prelude (compiler/prelude.h): library functions written in the language are compiled
// with every shader, loaded once per process, hidden by user functions of their name, never the
// source of a diagnostic about user code; a missing or broken stdlib is a clear error.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "compiler/compiler.h"
#include "compiler/prelude.h"

namespace relief::compiler {
namespace {

namespace fs = std::filesystem;

const fs::path kStdlib = fs::path(RELIEF_SOURCE_DIR) / "stdlib";

CompileResult check(const std::string& source, const std::string& stdlibDir = "") {
  CompileOptions options;
  options.stdlibDir = stdlibDir;
  CompileFlags flags;
  flags.jit = false;
  return compileSource("p.disp", source, options, flags);
}

// A copy of the real stdlib in a fresh directory, plus `extra` as extra.disp.
fs::path stdlibCopy(const std::string& name, const std::string& extra = "") {
  const fs::path dir = fs::path(::testing::TempDir()) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const auto& entry : fs::directory_iterator(kStdlib)) fs::copy_file(entry.path(), dir / entry.path().filename());
  if (!extra.empty()) std::ofstream(dir / "extra.disp") << extra;
  return dir;
}

TEST(PreludeTest, LoadedOncePerProcessAndSharedByCompilations) {
  CompileResult a = check("displacement a() { P += fBm(P, 3) * N; }");
  CompileResult b = check("displacement b() { P += distance(P, point(0)) * N; }");
  ASSERT_TRUE(a.success()) << renderDiagnostics(a) << a.internalError;
  ASSERT_TRUE(b.success()) << renderDiagnostics(b) << b.internalError;
  EXPECT_EQ(a.prelude.get(), b.prelude.get());
  EXPECT_EQ(fs::path(a.prelude->dir), kStdlib);  // the build tree's binaries use the source tree's
}

TEST(PreludeTest, UserFunctionsHideLibraryFunctions) {
  // §3: a user function hides every library overload of its name, with -Wshadow at its name.
  CompileResult r = check(
      "float fBm(point p) { return xcomp(p); }\n"
      "displacement d() { P += fBm(P) * N; }\n");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r);
  EXPECT_EQ(renderDiagnostics(r),
            "p.disp:1:7: warning: function 'fBm' hides the built-in function of the same name [-Wshadow]\n"
            "float fBm(point p) { return xcomp(p); }\n"
            "      ^~~\n"
            "1 warning generated.\n");
  // The library's 2-argument form is hidden too.
  CompileResult hidden = check("float fBm(point p) { return xcomp(p); }\ndisplacement d() { P += fBm(P, 4) * N; }\n");
  EXPECT_NE(renderDiagnostics(hidden).find("p.disp:2:25: error: no matching function for call to 'fBm' with arguments "
                                           "(point, int)"),
            std::string::npos)
      << renderDiagnostics(hidden);
}

// The stdlib's files are the prelude, always compiled in: including one (as RSL shaders include
// their noise headers) adds nothing. Its text included again redefined every function in it
// (errors when included twice, a -Wshadow warning per function once).
TEST(PreludeTest, IncludingAStdlibFileChangesNothing) {
  CompileResult r = check(
      "#include <noise.disp>\n#include <noise.disp>\n#include \"geometry.disp\"\n"
      "displacement d(float Km = 0.05) { P += Km * fBm(P, 4) * area(P) * normalize(N); }\n");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r);
  EXPECT_EQ(renderDiagnostics(r), "") << renderDiagnostics(r);
}

TEST(PreludeTest, MisusedLibraryCallsAreReportedAtTheCallLikeBuiltins) {
  // No location inside stdlib/ ever shows: the callee name, as for a built-in (§6).
  CompileResult r = check("displacement d() { P += (fBm(1, 2, 3) + luminance(P) + reflect(N)) * N; }");
  EXPECT_EQ(renderDiagnostics(r),
            "p.disp:1:26: error: no matching function for call to 'fBm' with arguments (int, int, int)\n"
            "displacement d() { P += (fBm(1, 2, 3) + luminance(P) + reflect(N)) * N; }\n"
            "                         ^~~\n"
            "p.disp:1:41: error: no matching function for call to 'luminance' with arguments (point)\n"
            "displacement d() { P += (fBm(1, 2, 3) + luminance(P) + reflect(N)) * N; }\n"
            "                                        ^~~~~~~~~\n"
            "p.disp:1:56: error: no matching function for call to 'reflect' with arguments (normal)\n"
            "displacement d() { P += (fBm(1, 2, 3) + luminance(P) + reflect(N)) * N; }\n"
            "                                                       ^~~~~~~\n"
            "3 errors generated.\n");
}

TEST(PreludeTest, OnlyTheFunctionsTheSpecListsAreVisible) {
  const fs::path dir = stdlibCopy("relief_stdlib_helper", "float rlfHelper(float x) { return 2 * x; }\n"
                                                         "float usesHelper(float x) { return rlfHelper(x); }\n");
  CompileResult r = check("displacement d() { P += rlfHelper(u) * N; }", dir.string());
  EXPECT_EQ(renderDiagnostics(r),
            "p.disp:1:25: error: use of undeclared function 'rlfHelper'\n"
            "displacement d() { P += rlfHelper(u) * N; }\n"
            "                        ^~~~~~~~~\n"
            "1 error generated.\n");
}

TEST(PreludeTest, LibraryCallsArePureConstantsInDefaults) {
  // Pure library functions may compute a parameter's default (§3), loops included.
  CompileFlags flags;
  CompileResult r = compileSource("p.disp", "displacement d(float k = fBm(point(0.3, 0.2, 0.1), 4) + hypot(3, 4))\n"
                                            "{ P += k * N; }\n");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
  ASSERT_EQ(r.shaders.front()->params().size(), 1u);
  EXPECT_GT(r.shaders.front()->params()[0].defaultNumbers[0], 4.0f);
  EXPECT_NE(renderDiagnostics(check("displacement d(float k = area(point(1))) { P += k * N; }"))
                .find("error: default value of a shader parameter must be a constant expression"),
            std::string::npos);
}

TEST(PreludeTest, MissingStdlibIsAClearError) {
  CompileResult r = check("displacement d() { P += 0.1 * N; }", "/nonexistent/relief/stdlib");
  EXPECT_FALSE(r.success());
  EXPECT_TRUE(r.ioError);
  EXPECT_EQ(renderDiagnostics(r),
            "p.disp: error: cannot load the standard library: no directory '/nonexistent/relief/stdlib' (set "
            "RELIEF_STDLIB_DIR to the directory of stdlib/*.disp)\n"
            "1 error generated.\n");
  const fs::path empty = fs::path(::testing::TempDir()) / "relief_stdlib_empty";
  fs::create_directories(empty);
  CompileResult incomplete = check("displacement d() { P += 0.1 * N; }", empty.string());
  EXPECT_NE(renderDiagnostics(incomplete).find("'" + empty.string() + "' does not define 'fBm'"), std::string::npos)
      << renderDiagnostics(incomplete);
}

TEST(PreludeTest, BrokenStdlibIsAnInternalErrorNamingItsOwnLines) {
  const fs::path dir = stdlibCopy("relief_stdlib_broken", "float oops() { return nope; }\n");
  CompileResult r = check("displacement d() { P += 0.1 * N; }", dir.string());
  EXPECT_FALSE(r.success());
  EXPECT_NE(r.internalError.find((dir / "extra.disp").string() + ":1:23: error: use of undeclared identifier 'nope'"),
            std::string::npos)
      << r.internalError;
  EXPECT_EQ(renderDiagnostics(r), "");  // nothing is blamed on the user's file
}

}  // namespace
}  // namespace relief::compiler
