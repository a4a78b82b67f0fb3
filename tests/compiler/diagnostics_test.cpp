// Diagnostics: the engine and text rendering, and the golden suite tests/compiler/diagnostics/
// (<case>.disp compared exactly with <case>.expected, i.e. what `reliefc <case>.disp` prints).
// Regenerate with RELIEF_UPDATE_GOLDEN=1 and review the diff.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "compiler/compiler.h"
#include "compiler/diagnostics.h"
#include "compiler/source_manager.h"

namespace relief::compiler {
namespace {

std::string readFile(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(DiagnosticsTest, RendersClangStyleWithCaretAndRange) {
  SourceManager sm;
  const auto id = sm.addBuffer("a.disp", "x\n\tfloat tmp = 2;\n");
  DiagnosticsEngine diags;
  const SourceLoc tmp = sm.startOf(id).advanced(2 + 7);  // 't' of tmp
  diags.report(DiagId::WarnUnusedVariable, tmp).arg("tmp").range({tmp, tmp.advanced(3)});
  std::ostringstream out;
  renderAllText(out, sm, diags);
  EXPECT_EQ(out.str(),
            "a.disp:2:8: warning: unused variable 'tmp' [-Wunused-variable]\n"
            "        float tmp = 2;\n"  // tabs expanded to stops of 8, as clang shows them
            "              ^~~\n");
  EXPECT_EQ(summaryLine(1, 2), "1 warning and 2 errors generated.");
  EXPECT_EQ(summaryLine(0, 1), "1 error generated.");
  EXPECT_EQ(summaryLine(3, 0), "3 warnings generated.");
  EXPECT_EQ(summaryLine(0, 0), "");
}

TEST(DiagnosticsTest, SortsByLocationAndPromotesWarnings) {
  SourceManager sm;
  const auto id = sm.addBuffer("b.disp", "abc def\n");
  DiagnosticOptions options;
  options.warningsAsErrors = true;
  DiagnosticsEngine diags(options);
  diags.report(DiagId::ErrUndeclared, sm.startOf(id).advanced(4)).arg("def");
  diags.report(DiagId::WarnUnusedVariable, sm.startOf(id)).arg("abc");
  const auto sorted = diags.sorted();
  ASSERT_EQ(sorted.size(), 2u);
  EXPECT_EQ(sorted[0].severity, Severity::Error);  // promoted by -Werror
  EXPECT_EQ(sorted[0].message, "unused variable 'abc'");
  EXPECT_EQ(sorted[1].message, "use of undeclared identifier 'def'");
  EXPECT_EQ(diags.numErrors(), 2u);
  std::ostringstream out;
  renderText(out, sm, sorted[0]);
  EXPECT_NE(out.str().find("[-Werror,-Wunused-variable]"), std::string::npos);
}

TEST(DiagnosticsTest, ErrorLimitStopsWithFatalError) {
  SourceManager sm;
  const auto id = sm.addBuffer("c.disp", "0123456789\n");
  DiagnosticOptions options;
  options.errorLimit = 3;
  DiagnosticsEngine diags(options);
  diags.setFileName("c.disp");
  // Reported out of source order (as parse errors come before earlier type errors): the limit
  // keeps the first three by location, and the notice names the file.
  for (int i : {5, 4, 3, 2, 1, 0}) diags.report(DiagId::ErrUndeclared, sm.startOf(id).advanced(uint32_t(i))).arg("x");
  const auto sorted = diags.sorted();
  ASSERT_EQ(sorted.size(), 4u);
  for (uint32_t i = 0; i < 3; ++i) EXPECT_EQ(sorted[i].loc.offset, sm.startOf(id).advanced(i).offset);
  EXPECT_EQ(sorted.back().severity, Severity::Fatal);
  EXPECT_EQ(sorted.back().message, "too many errors emitted, stopping now [-ferror-limit=]");
  EXPECT_EQ(sorted.back().file, "c.disp");
  EXPECT_EQ(diags.numShownErrors(), 3u);
  EXPECT_EQ(diags.numErrors(), 6u);
  EXPECT_TRUE(diags.hasErrors());
}

TEST(DiagnosticsTest, JsonIsOneObjectPerLine) {
  SourceManager sm;
  const auto id = sm.addBuffer("d.disp", "P += \"q\";\n");
  DiagnosticsEngine diags;
  diags.report(DiagId::ErrIncompatibleAssign, sm.startOf(id).advanced(5)).arg("point").arg("string");
  std::ostringstream out;
  renderJson(out, sm, diags.sorted()[0]);
  EXPECT_EQ(out.str(),
            "{\"severity\":\"error\",\"file\":\"d.disp\",\"line\":1,\"column\":6,"
            "\"message\":\"assigning to 'point' from incompatible type 'string'\"}\n");
}

TEST(DiagnosticsTest, SourceManagerHandlesAllLineEndings) {
  SourceManager sm;
  const auto id = sm.addBuffer("e.disp", "a\r\nb\rc\nd");
  const SourceLoc start = sm.startOf(id);
  EXPECT_EQ(sm.presumed(start.advanced(3)).line, 2u);
  EXPECT_EQ(sm.presumed(start.advanced(5)).line, 3u);
  EXPECT_EQ(sm.presumed(start.advanced(7)).line, 4u);
  EXPECT_EQ(sm.presumed(start.advanced(7)).column, 1u);
  EXPECT_EQ(sm.lineText(start.advanced(3)), "b");
}

TEST(GoldenDiagnosticsTest, AllCasesMatch) {
  const std::filesystem::path dir = std::filesystem::path(RELIEF_TEST_DATA_DIR) / "diagnostics";
  const bool update = [] {
    const char* e = std::getenv("RELIEF_UPDATE_GOLDEN");
    return e && std::string(e) == "1";
  }();
  std::vector<std::filesystem::path> cases;
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    if (entry.path().extension() == ".disp") cases.push_back(entry.path());
  std::sort(cases.begin(), cases.end());
  ASSERT_GE(cases.size(), 15u);
  // Run from the cases' directory, as `cd diagnostics && reliefc <case>.disp` would, so that
  // #include paths and file names print the same.
  const std::filesystem::path savedCwd = std::filesystem::current_path();
  std::filesystem::current_path(dir);
  for (const auto& path : cases) {
    SCOPED_TRACE(path.filename().string());
    CompileFlags flags;
    flags.jit = false;
    CompileResult result = compileSource(path.filename().string(), readFile(path), {}, flags);
    EXPECT_TRUE(result.internalError.empty()) << result.internalError;
    const std::string actual = renderDiagnostics(result);
    std::filesystem::path expectedPath = path;
    expectedPath.replace_extension(".expected");
    if (update) {
      std::ofstream(expectedPath, std::ios::binary) << actual;
      continue;
    }
    ASSERT_TRUE(std::filesystem::exists(expectedPath)) << "missing " << expectedPath
                                                       << " (run with RELIEF_UPDATE_GOLDEN=1)";
    EXPECT_EQ(actual, readFile(expectedPath));
  }
  std::filesystem::current_path(savedCwd);
}

}  // namespace
}  // namespace relief::compiler
