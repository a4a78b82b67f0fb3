// reliefc as a program (language.md §8): every golden diagnostics case through the executable
// (stderr byte for byte, exit code 1 with errors, 0 with warnings only), JSON diagnostics, usage
// and I/O exit codes, and --eval printing the displaced P and N.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "compiler/diagnostics.h"

namespace {

namespace fs = std::filesystem;

std::string readFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

struct CliRun {
  int exitCode = -1;
  std::string out, err;
};

// Runs reliefc with `args` (already quoted) in `dir`.
CliRun reliefc(const std::string& args, const fs::path& dir = fs::current_path()) {
  static int counter = 0;
  // ctest runs each test in its own process, several at once: the pid keeps their files apart.
  const fs::path tmp = fs::path(::testing::TempDir()) /
                       ("reliefc_cli_" + std::to_string(getpid()) + "_" + std::to_string(counter++));
  const std::string command = "cd " + quote(dir.string()) + " && " + quote(RELIEF_RELIEFC_PATH) + " " + args +
                              " >" + quote(tmp.string() + ".out") + " 2>" + quote(tmp.string() + ".err");
  const int status = std::system(command.c_str());
  CliRun r;
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = readFile(tmp.string() + ".out");
  r.err = readFile(tmp.string() + ".err");
  return r;
}

fs::path writeTemp(const std::string& name, const std::string& text) {
  const fs::path p = fs::path(::testing::TempDir()) / name;
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

TEST(CliTest, GoldenCasesPrintTheirDiagnosticsAndExitCodes) {
  const fs::path dir = fs::path(RELIEF_TEST_DATA_DIR) / "diagnostics";
  std::vector<fs::path> cases;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.path().extension() == ".disp") cases.push_back(entry.path());
  std::sort(cases.begin(), cases.end());
  ASSERT_GE(cases.size(), 40u);
  size_t withErrors = 0;
  for (const fs::path& path : cases) {
    SCOPED_TRACE(path.filename().string());
    fs::path expectedPath = path;
    expectedPath.replace_extension(".expected");
    const std::string expected = readFile(expectedPath);
    ASSERT_FALSE(expected.empty());
    const CliRun r = reliefc("--color=never " + quote(path.filename().string()), dir);
    EXPECT_EQ(r.err, expected);
    EXPECT_EQ(r.out, "");
    // Errors (including fatal ones) exit with 1; warnings alone with 0.
    const bool errors = expected.find(": error: ") != std::string::npos ||
                        expected.find(": fatal error: ") != std::string::npos;
    withErrors += errors;
    EXPECT_EQ(r.exitCode, errors ? 1 : 0);
  }
  EXPECT_GE(withErrors, 40u);
}

TEST(CliTest, WerrorTurnsWarningsIntoExitCodeOne) {
  const fs::path dir = fs::path(RELIEF_TEST_DATA_DIR) / "diagnostics";
  const CliRun r = reliefc("--color=never -Werror unused_variable.disp", dir);
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find("error: unused variable 'tmp' [-Werror,-Wunused-variable]"), std::string::npos) << r.err;
  const CliRun quiet = reliefc("--color=never -Wno-unused-variable unused_variable.disp", dir);
  EXPECT_EQ(quiet.exitCode, 0);
  EXPECT_EQ(quiet.err.find("unused variable"), std::string::npos) << quiet.err;

  // A warning made an error leaves the program whole: every other warning is still reported, in
  // the same run. -Werror=<name> promotes one; -Wno-error=<name> exempts one from -Werror.
  const fs::path three = writeTemp("relief_three_warnings.disp",
                                   "displacement d(float Km = 1)\n{\n    float h;\n    int i = 2.5;\n"
                                   "    float unused = 1;\n    if (u > 0.5) h = 1;\n    P += N * Km * h * i;\n}\n");
  auto count = [](const std::string& text, const std::string& what) {
    size_t n = 0;
    for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
    return n;
  };
  const CliRun all = reliefc("--color=never -Werror " + quote(three.string()));
  EXPECT_EQ(all.exitCode, 1);
  EXPECT_EQ(count(all.err, ": error: "), 3u) << all.err;
  // A variable whose initializer had a promoted warning is still a variable: unused is reported.
  const fs::path narrowUnused = writeTemp("relief_narrow_unused.disp", "displacement t() { int i = 1.5; }\n");
  const CliRun both = reliefc("--color=never -Werror " + quote(narrowUnused.string()));
  EXPECT_NE(both.err.find("unused variable 'i'"), std::string::npos) << both.err;
  EXPECT_NE(both.err.find("truncates"), std::string::npos) << both.err;
  // -Wno-error cancels an earlier -Werror, as in clang.
  EXPECT_EQ(reliefc("--color=never -Werror -Wno-error " + quote(three.string())).exitCode, 0);
  // Past the error limit the summary counts what was shown: the warnings after the cut are not.
  const fs::path cut = writeTemp("relief_cut.disp",
                                 "displacement d()\n{\n    P += Kn;\n    P += Km;\n    float w1 = 1, w2 = 2;\n}\n");
  const CliRun limited = reliefc("--color=never -ferror-limit=1 " + quote(cut.string()));
  EXPECT_EQ(count(limited.err, ": warning: "), 0u) << limited.err;
  EXPECT_NE(limited.err.find("\n1 error generated.\n"), std::string::npos) << limited.err;
  const CliRun one = reliefc("--color=never -Werror=narrowing " + quote(three.string()));
  EXPECT_EQ(one.exitCode, 1);
  EXPECT_EQ(count(one.err, ": error: "), 1u) << one.err;
  EXPECT_EQ(count(one.err, ": warning: "), 2u) << one.err;
  const CliRun exempt = reliefc("--color=never -Werror -Wno-error=narrowing -Wno-error=unused-variable -Wno-error=uninitialized " +
                                quote(three.string()));
  EXPECT_EQ(exempt.exitCode, 0) << exempt.err;
  EXPECT_EQ(count(exempt.err, ": warning: "), 3u) << exempt.err;
  // The last flag naming a warning wins, as in clang (both had kept the first's effect).
  const CliRun reenabled = reliefc("--color=never -Wno-unused-variable -Wunused-variable " + quote(three.string()));
  EXPECT_EQ(count(reenabled.err, "unused variable 'unused'"), 1u) << reenabled.err;
  const CliRun lastError = reliefc("--color=never -Wno-error=narrowing -Werror=narrowing " + quote(three.string()));
  EXPECT_EQ(lastError.exitCode, 1) << lastError.err;
  const CliRun lastWarning = reliefc("--color=never -Werror=narrowing -Wno-error=narrowing " + quote(three.string()));
  EXPECT_EQ(lastWarning.exitCode, 0) << lastWarning.err;
  EXPECT_EQ(count(lastWarning.err, ": warning: "), 3u) << lastWarning.err;
  const CliRun errorEnables = reliefc("--color=never -Wno-narrowing -Werror=narrowing " + quote(three.string()));
  EXPECT_EQ(count(errorEnables.err, ": error: "), 1u) << errorEnables.err;
}

TEST(CliTest, JsonDiagnosticsAreOneObjectPerLine) {
  const fs::path dir = fs::path(RELIEF_TEST_DATA_DIR) / "diagnostics";
  const CliRun r = reliefc("--diagnostics-format=json matrix_operands.disp", dir);
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_EQ(r.err,
            "{\"severity\":\"error\",\"file\":\"matrix_operands.disp\",\"line\":5,\"column\":18,"
            "\"message\":\"invalid operands to binary expression ('matrix' and 'matrix')\","
            "\"ranges\":[{\"begin\":[5,16],\"end\":[5,17]},{\"begin\":[5,20],\"end\":[5,21]}]}\n"
            "{\"severity\":\"error\",\"file\":\"matrix_operands.disp\",\"line\":6,\"column\":17,"
            "\"message\":\"invalid operands to binary expression ('point' and 'matrix')\","
            "\"ranges\":[{\"begin\":[6,15],\"end\":[6,16]},{\"begin\":[6,19],\"end\":[6,20]}]}\n");
  const CliRun warn = reliefc("--diagnostics-format=json macro_redefined.disp", dir);
  EXPECT_EQ(warn.exitCode, 0);
  EXPECT_NE(warn.err.find("\"flag\":\"-Wmacro-redefined\""), std::string::npos) << warn.err;
  EXPECT_NE(warn.err.find("\"notes\":[{\"severity\":\"note\""), std::string::npos) << warn.err;
  // A bad option is a JSON line too, and a file name that is not UTF-8 stays valid JSON.
  const CliRun option = reliefc("--diagnostics-format=json -Wbogus macro_redefined.disp", dir);
  EXPECT_EQ(option.err.rfind("{\"severity\":\"warning\",\"message\":\"unknown warning option '-Wbogus'\"}\n", 0), 0u)
      << option.err;
  EXPECT_EQ(relief::compiler::jsonQuoted("a\xe9" "b\"\n\xc3\xa9"), "\"a\\ufffd" "b\\\"\\n\xc3\xa9\"");
  // A diagnostic inside an included file carries the include stack, outermost first, as the text
  // output's "In file included from" lines.
  const CliRun nested = reliefc("--diagnostics-format=json nested_include.disp", dir);
  EXPECT_NE(nested.err.find("\"included_from\":[{\"file\":\"nested_include.disp\",\"line\":"), std::string::npos)
      << nested.err;
  // -p and --at without --eval change nothing: a warning says so (in the format asked for).
  const CliRun unused = reliefc("--diagnostics-format=json -p Km=1 macro_redefined.disp", dir);
  EXPECT_EQ(unused.err.rfind("{\"severity\":\"warning\",\"message\":\"-p only applies with --eval; ignored\"}\n", 0), 0u)
      << unused.err;
}

TEST(CliTest, UsageAndInputErrorsExitWithTwo) {
  EXPECT_EQ(reliefc("").exitCode, 2);
  EXPECT_EQ(reliefc("--no-such-option x.disp").exitCode, 2);
  EXPECT_EQ(reliefc("--diagnostics-format=xml x.disp").exitCode, 2);
  EXPECT_EQ(reliefc("-D= x.disp").exitCode, 2);
  // A parameter value out of float's range is no value (it would be infinity).
  EXPECT_EQ(reliefc("--eval -p Km=1e39 " + quote(RELIEF_SOURCE_DIR "/examples/shaders/bumps.disp")).exitCode, 2);
  EXPECT_EQ(reliefc("-D1X=2 x.disp").exitCode, 2);
  const CliRun missing = reliefc(quote(::testing::TempDir() + "/relief_no_such_shader.disp"));
  EXPECT_EQ(missing.exitCode, 2);
  // Clang-style, with the file as the location (§8: "No position: <file>: error: …").
  EXPECT_EQ(missing.err, ::testing::TempDir() + "/relief_no_such_shader.disp: error: cannot open file: No such file or "
                                                "directory\n1 error generated.\n");
  EXPECT_EQ(reliefc("--help").exitCode, 0);
  // Numeric options take digits only: a sign, a suffix or nothing is a usage error, said as such
  // (the shader exists, so nothing else could make the run fail).
  const fs::path ok = writeTemp("relief_limits.disp", "displacement d() { P += N; }\n");
  EXPECT_EQ(reliefc("-ferror-limit=5 -floop-limit=100 " + quote(ok.string())).exitCode, 0);
  for (const char* bad : {"abc", "-3", "", "2x", "+4"}) {
    for (const char* option : {"-ferror-limit=", "-floop-limit="}) {
      const CliRun r = reliefc(std::string(option) + bad + " " + quote(ok.string()));
      EXPECT_EQ(r.exitCode, 2) << option << bad;
      EXPECT_NE(r.err.find("bad value for " + std::string(option).substr(0, std::string(option).size() - 1)),
                std::string::npos) << r.err;
    }
  }
}

TEST(CliTest, FindsTheStdlibNextToAnInstalledBinaryOrWhereTheEnvironmentSays) {
  const fs::path source = fs::path(RELIEF_TEST_DATA_DIR) / "spec" / "examples.disp";
  // $RELIEF_STDLIB_DIR first: a missing directory is an I/O error (exit 2) naming it.
  setenv("RELIEF_STDLIB_DIR", "/nonexistent/stdlib", 1);
  const CliRun missing = reliefc(quote(source.string()));
  unsetenv("RELIEF_STDLIB_DIR");
  EXPECT_EQ(missing.exitCode, 2);
  EXPECT_NE(missing.err.find("error: cannot load the standard library: no directory '/nonexistent/stdlib'"),
            std::string::npos)
      << missing.err;

  // An installed layout, <prefix>/bin/reliefc and <prefix>/<bin>/RELIEF_STDLIB_FROM_BIN, wins over
  // the source tree: an incomplete stdlib there is what this copy of reliefc reports.
  const fs::path prefix = fs::path(::testing::TempDir()) / "relief_install";
  fs::remove_all(prefix);
  fs::create_directories(prefix / "bin");
  const fs::path stdlib = (prefix / "bin" / RELIEF_STDLIB_FROM_BIN).lexically_normal();
  fs::create_directories(stdlib);
  fs::copy_file(RELIEF_RELIEFC_PATH, prefix / "bin" / "reliefc");
  fs::copy_file(fs::path(RELIEF_SOURCE_DIR) / "stdlib" / "noise.disp", stdlib / "noise.disp");
  const std::string installed = quote((prefix / "bin" / "reliefc").string());
  const std::string evalCraggy = " --eval " + quote(source.string()) + " --shader craggy";
  const int incomplete = std::system((installed + evalCraggy + " >/dev/null 2>" +
                                      quote((prefix / "err.txt").string())).c_str());
  EXPECT_EQ(WEXITSTATUS(incomplete), 2);
  EXPECT_NE(readFile(prefix / "err.txt").find("'" + stdlib.string() + "' does not define 'linearstep'"),
            std::string::npos)
      << readFile(prefix / "err.txt");
  for (const auto& entry : fs::directory_iterator(fs::path(RELIEF_SOURCE_DIR) / "stdlib"))
    fs::copy_file(entry.path(), stdlib / entry.path().filename(), fs::copy_options::overwrite_existing);
  const int complete = std::system((installed + evalCraggy + " >" + quote((prefix / "out.txt").string())).c_str());
  EXPECT_EQ(WEXITSTATUS(complete), 0);
  EXPECT_EQ(readFile(prefix / "out.txt"), reliefc(evalCraggy.substr(1)).out);
}

TEST(CliTest, EvalPrintsTheDisplacedPointAndNormal) {
  const fs::path lift = writeTemp("relief_lift.disp", "displacement lift(float Km = 0.05)\n{\n    P += Km * normalize(N);\n}\n");
  const CliRun r = reliefc("--eval " + quote(lift.string()) + " -p Km=0.2 --at " +
                        quote("P=(0,0,1) N=(0,0,1) u=0.5 v=0.5"));
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.out, "P = (0, 0, 1.20000005)\nN = (0, 0, 1)\n");

  // The spec's sinebumps on the plane P = (u, v, 0): P' = (u, v, h), N' ∝ (-h_u, -h_v, 1).
  const std::string examples = std::string(RELIEF_TEST_DATA_DIR) + "/spec/examples.disp";
  const CliRun s = reliefc("--eval " + quote(examples) + " --shader sinebumps -p Km=0.1 --at " +
                        quote("P=(0.3,0.7,0) N=(0,0,1) u=0.3 v=0.7 dPdu=(1,0,0) dPdv=(0,1,0)"));
  ASSERT_EQ(s.exitCode, 0) << s.err;
  double p[3], n[3];
  ASSERT_EQ(std::sscanf(s.out.c_str(), "P = (%lf, %lf, %lf)\nN = (%lf, %lf, %lf)", &p[0], &p[1], &p[2], &n[0], &n[1],
                        &n[2]),
            6)
      << s.out;
  const double pi = 3.14159265358979323846, Km = 0.1, f = 12, u = 0.3, v = 0.7;
  const double h = Km * std::sin(f * 2 * pi * u) * std::sin(f * pi * v);
  const double hu = Km * f * 2 * pi * std::cos(f * 2 * pi * u) * std::sin(f * pi * v);
  const double hv = Km * f * pi * std::sin(f * 2 * pi * u) * std::cos(f * pi * v);
  const double len = std::sqrt(hu * hu + hv * hv + 1);
  EXPECT_NEAR(p[0], 0.3, 1e-6);
  EXPECT_NEAR(p[1], 0.7, 1e-6);
  EXPECT_NEAR(p[2], h, 1e-5);
  EXPECT_NEAR(n[0], -hu / len, 1e-4);
  EXPECT_NEAR(n[1], -hv / len, 1e-4);
  EXPECT_NEAR(n[2], 1 / len, 1e-4);

  // A matrix parameter takes 16 numbers, row-major (translation in the last row).
  const fs::path mv = writeTemp("relief_mv.disp", "displacement mv(matrix M = 1)\n{\n    P = transform(M, P);\n}\n");
  const CliRun m = reliefc("--eval " + quote(mv.string()) + " -p " + quote("M=(1,0,0,0, 0,1,0,0, 0,0,1,0, 1,2,3,1)"));
  EXPECT_EQ(m.exitCode, 0) << m.err;
  EXPECT_EQ(m.out, "P = (1, 2, 4)\nN = (0, 0, 1)\n");

  // Bad parameter bindings are usage errors; a triple given two numbers says what it takes.
  EXPECT_EQ(reliefc("--eval " + quote(lift.string()) + " -p nosuch=1").exitCode, 2);
  const fs::path tinted = writeTemp("relief_tinted.disp", "displacement tinted(color c = 1)\n{\n    P += comp(c, 0) * N;\n}\n");
  const CliRun pair = reliefc("--eval " + quote(tinted.string()) + " -p " + quote("c=(0,1)"));
  EXPECT_EQ(pair.exitCode, 2);
  EXPECT_NE(pair.err.find("parameter 'c' is a color: give 3 numbers, not 2"), std::string::npos) << pair.err;
}

// What a clang user passes by habit: warning groups, -fsyntax-only, space-separated values; what
// cannot be meant is a usage error of one line, and IR written to a ".o" is said to be IR.
TEST(CliTest, ClangHabitsAreAcceptedOrAnsweredInOneLine) {
  const fs::path ok = writeTemp("relief_habits.disp", "displacement habits(float Km = 1) { P += Km * N; }\n");
  const std::string file = quote(ok.string());
  CliRun r = reliefc("-Wall -Wextra -Wpedantic -fsyntax-only " + file);
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(r.out, "");
  const fs::path bad = writeTemp("relief_habits_bad.disp", "displacement bad() { P += foo; }\n");
  r = reliefc("--color never --diagnostics-format json -ferror-limit 3 " + quote(bad.string()));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_EQ(r.err.rfind("{\"severity\":\"error\"", 0), 0u) << r.err;
  r = reliefc("--emit-llvm --emit-ast " + file);
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_EQ(r.err, "reliefc: error: --emit-llvm and --emit-ast both print: give one\n"
                   "usage: reliefc [options] file.disp... (see reliefc --help)\n");
  EXPECT_EQ(reliefc("-fsyntax-only --emit-llvm " + file).exitCode, 2);
  const fs::path object = fs::path(::testing::TempDir()) / "relief_habits.o";
  r = reliefc(file + " -o " + quote(object.string()));
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("gets LLVM IR text (.ll), not object code"), std::string::npos) << r.err;
  EXPECT_NE(readFile(object).find("define"), std::string::npos);
}

// --at takes spaces around '=', and a normal given alone comes with tangents perpendicular to it:
// calculatenormal then agrees with it instead of the default frame's +z.
TEST(CliTest, EvalNormalAloneGetsItsOwnTangents) {
  const fs::path bump = writeTemp("relief_tangents.disp",
                                  "displacement tangents() { P += 0.01 * normalize(N); N = calculatenormal(P); }\n");
  const CliRun r = reliefc("--eval " + quote(bump.string()) + " --at " + quote("P = (0,0,1) N = (0,1,0)"));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  double p[3], n[3];
  ASSERT_EQ(std::sscanf(r.out.c_str(), "P = (%lf, %lf, %lf)\nN = (%lf, %lf, %lf)", &p[0], &p[1], &p[2], &n[0], &n[1],
                        &n[2]),
            6)
      << r.out;
  EXPECT_NEAR(p[1], 0.01, 1e-6);
  EXPECT_NEAR(n[0], 0.0, 1e-6);
  EXPECT_NEAR(n[1], 1.0, 1e-6);
  EXPECT_NEAR(n[2], 0.0, 1e-6);
}

// '-' compiles standard input (named <stdin> in diagnostics), once; '--' ends the options, so a file
// whose name starts with '-' can be named.
TEST(CliTest, StandardInputAndTheEndOfOptions) {
  const fs::path broken = writeTemp("relief_stdin.disp", "displacement d() { P += N * Kn; }\n");
  const CliRun in = reliefc("- < " + quote(broken.string()));
  EXPECT_EQ(in.exitCode, 1);
  EXPECT_EQ(in.err.rfind("<stdin>:1:29: error: use of undeclared identifier 'Kn'", 0), 0u) << in.err;
  // Standard input can be read once: naming it twice is a usage error, not an empty second file.
  const CliRun twice = reliefc("- - < " + quote(broken.string()));
  EXPECT_EQ(twice.exitCode, 2);
  EXPECT_NE(twice.err.find("standard input ('-') named more than once"), std::string::npos) << twice.err;
  const fs::path dir = fs::path(::testing::TempDir()) / ("reliefc_dash_" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "-odd.disp") << "displacement d() { P += N * u; }\n";
  EXPECT_EQ(reliefc("-- -odd.disp", dir).exitCode, 0);
  EXPECT_EQ(reliefc("-odd.disp", dir).exitCode, 2);  // taken for an option
}

// -o writes what would be printed to a file, only when every input compiled: a failed compile
// leaves an earlier file as it was, and an unwritable path is an I/O error (exit 2) naming it.
TEST(CliTest, OutputFileIsWrittenOnlyWhenEveryInputCompiles) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("reliefc_o_" + std::to_string(getpid()));
  fs::remove_all(dir);  // a process id is reused in time: no earlier run's files
  fs::create_directories(dir);
  std::ofstream(dir / "lift.disp") << "displacement lift(float Km = 0.05)\n{\n    P += Km * normalize(N);\n}\n";
  std::ofstream(dir / "broken.disp") << "displacement d() { P += N * Kn; }\n";
  const CliRun printed = reliefc("--emit-llvm lift.disp", dir);
  ASSERT_EQ(printed.exitCode, 0) << printed.err;
  ASSERT_NE(printed.out.find("define"), std::string::npos) << printed.out;

  // Alone, -o means --emit-llvm; nothing goes to standard output then.
  const CliRun written = reliefc("lift.disp -o lift.ll", dir);
  EXPECT_EQ(written.exitCode, 0) << written.err;
  EXPECT_EQ(written.out, "");
  EXPECT_EQ(readFile(dir / "lift.ll"), printed.out);
  const CliRun ast = reliefc("--emit-ast -olift.ast lift.disp", dir);
  EXPECT_EQ(ast.exitCode, 0) << ast.err;
  EXPECT_EQ(readFile(dir / "lift.ast"), reliefc("--emit-ast lift.disp", dir).out);

  // An error in any input: exit 1, and the earlier file is untouched.
  const CliRun failed = reliefc("lift.disp broken.disp -o lift.ll", dir);
  EXPECT_EQ(failed.exitCode, 1);
  EXPECT_EQ(readFile(dir / "lift.ll"), printed.out);
  EXPECT_EQ(failed.out, "");

  const CliRun unwritable = reliefc("lift.disp -o no/such/dir/lift.ll", dir);
  EXPECT_EQ(unwritable.exitCode, 2);
  EXPECT_NE(unwritable.err.find("cannot write 'no/such/dir/lift.ll'"), std::string::npos) << unwritable.err;
  EXPECT_EQ(reliefc("lift.disp -o", dir).exitCode, 2);
  EXPECT_EQ(reliefc("lift.disp -o a.ll -o b.ll", dir).exitCode, 2);
  // Nothing but the two outputs is left in the directory (no temporary files).
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 4u);

  // A device is written through, not replaced by a renamed regular file (as root, that turned
  // /dev/null into a file).
  const CliRun devnull = reliefc("lift.disp -o /dev/null", dir);
  EXPECT_EQ(devnull.exitCode, 0) << devnull.err;
  struct stat st;
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  fs::remove_all(dir);
}

// Inputs that are no regular files (a device read for ever, a directory) are I/O errors before any
// reading; a chain of calls deeper than code generation can inline is a located error, not a
// crash (16,000 nested calls overflowed the stack).
TEST(CliTest, DevicesAndDeepCallChainsAreErrors) {
  const CliRun zero = reliefc("/dev/zero");
  EXPECT_NE(zero.exitCode, 0);
  EXPECT_NE(zero.err.find("/dev/zero: error: cannot open file: not a regular file"), std::string::npos) << zero.err;
  std::string chain = "float f0(float x) { return x; }\n";
  for (int i = 1; i <= 1200; ++i)
    chain += "float f" + std::to_string(i) + "(float x) { return f" + std::to_string(i - 1) + "(x) + 1; }\n";
  chain += "displacement deep(float Km = 1) { P += Km * f1200(s) * N; }\n";
  const fs::path deep = writeTemp("relief_deep.disp", chain);
  const CliRun r = reliefc(quote(deep.string()));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.err.find(":1001:"), std::string::npos) << r.err.substr(0, 400);  // f1000 calling f999
  EXPECT_NE(r.err.find("starts a chain of function calls nested too deeply (more than 1000 levels)"), std::string::npos)
      << r.err.substr(0, 400);
  // The same chain through an operator whose operands are first checked by a silent probe: the
  // probe's pass must not use up the error and let the real one through (review finding).
  std::string probed = "float g0(float x) { return x; }\n";
  for (int i = 1; i <= 1200; ++i)
    probed += "float g" + std::to_string(i) + "(float x) { return noise(x) * (g" + std::to_string(i - 1) + "(x) + noise(x)); }\n";
  probed += "displacement deeper(float Km = 1) { P += Km * g1200(s) * N; }\n";
  const CliRun p = reliefc(quote(writeTemp("relief_deeper.disp", probed).string()));
  EXPECT_EQ(p.exitCode, 1) << p.err.substr(0, 400);
  EXPECT_NE(p.err.find("nested too deeply (more than 1000 levels)"), std::string::npos) << p.err.substr(0, 400);
}

// §7: the loop limit is a run-time error: said as one, with exit code 1.
// -o takes what --eval prints (the shader's printf output, then P and N), as it does IR; a
// place it cannot write leaves nothing on standard output. -D NAME= defines NAME empty, -D NAME
// as 1 (cc's rule).
TEST(CliTest, EvalOutputGoesToTheOutputFileAndEmptyDefinesStayEmpty) {
  const fs::path shader = writeTemp("relief_evalout.disp",
                                    "displacement e() { float a = 2 X; printf(\"a=%g\\n\", a); }\n");
  const fs::path out = fs::path(::testing::TempDir()) / "relief_evalout.txt";
  fs::remove(out);
  CliRun r = reliefc("--eval -DX= -o " + quote(out.string()) + " " + quote(shader.string()));
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.out, "");
  std::ifstream in(out);
  const std::string written((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(written.substr(0, 4), "a=2\n") << written;
  EXPECT_NE(written.find("P = ("), std::string::npos) << written;
  r = reliefc("--eval -DX=+0 -o /nonexistent/dir/x.txt " + quote(shader.string()));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("cannot write '/nonexistent/dir/x.txt'"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "");
  // A fraction for an int parameter is truncated with a warning.
  const fs::path counted = writeTemp("relief_evalint.disp",
                                     "displacement c(int n = 1) { printf(\"n=%d\\n\", n); }\n");
  r = reliefc("--eval -p n=2.5 " + quote(counted.string()));
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.out.substr(0, 4), "n=2\n") << r.out;
  EXPECT_NE(r.err.find("parameter 'n' is an int; 2.5 is truncated to 2"), std::string::npos) << r.err;
  r = reliefc("--eval -DX=*3 " + quote(shader.string()));
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(r.out.substr(0, 4), "a=6\n") << r.out;
}

// A wrap mode named at run time that is none of the modes warns once (a literal one is a compile
// error); it had been ignored without a word.
TEST(CliTest, EvalWarnsOnceAboutAnUnknownRunTimeWrapMode) {
  const fs::path shader = writeTemp("relief_wrap.disp",
                                    "displacement wrapped(string w = \"repeat\")\n"
                                    "{ P += N * (texture(\"relief_no_such_texture.png\", 0.5, 0.5, \"wrap\", w) +\n"
                                    "            texture(\"relief_no_such_texture.png\", 0.25, 0.5, \"swrap\", w)); }\n");
  CliRun r = reliefc("--eval " + quote(shader.string()));
  const std::string warning = "warning: unknown texture wrap mode 'repeat'";
  const size_t at = r.err.find(warning);
  EXPECT_NE(at, std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(warning, at + 1), std::string::npos) << r.err;  // once
  r = reliefc("--eval -p w=clamp " + quote(shader.string()));
  EXPECT_EQ(r.err.find("wrap mode"), std::string::npos) << r.err;
}

TEST(CliTest, EvalLoopLimitIsAnErrorExitCode) {
  const fs::path loop = writeTemp("relief_loop.disp", "displacement spin() { float x = 0; while (x >= 0) x += 1; P += x * N; }\n");
  const CliRun r = reliefc("--eval -floop-limit=1000 " + quote(loop.string()));
  EXPECT_EQ(r.exitCode, 1) << r.err;
  // At the shader's definition, as compile diagnostics are (it had no file or line).
  EXPECT_NE(r.err.find(loop.string() + ":1:14: error: shader 'spin' exceeded the loop iteration limit"), std::string::npos)
      << r.err;
}

TEST(CliTest, EvalWarnsAboutNonFiniteResultsNamingTheShader) {
  const fs::path inf = writeTemp("relief_inf.disp",
                                 "displacement blowup(float Km = 1e30)\n{\n    P += Km * Km * N;\n}\n");
  const CliRun r = reliefc("--eval " + quote(inf.string()));
  EXPECT_EQ(r.exitCode, 0) << r.err;
  // The undisplaced point and its normal are kept.
  EXPECT_EQ(r.out, "P = (0, 0, 1)\nN = (0, 0, 1)\n");
  EXPECT_NE(r.err.find("shader 'blowup' produced a non-finite P; the undisplaced point"), std::string::npos) << r.err;
  // A non-finite or zero N leaves P displaced; it is its own warning (§7).
  const fs::path zero = writeTemp("relief_zero_n.disp", "displacement flat() { P += 0.1 * N; N = normal(0); }\n");
  const CliRun z = reliefc("--eval " + quote(zero.string()) + " --at \"P=(0,0,1) N=(0,0,1) dPdu=(1,0,0) dPdv=(0,1,0)\"");
  EXPECT_EQ(z.exitCode, 0) << z.err;
  EXPECT_EQ(z.out, "P = (0, 0, 1.10000002)\nN = (0, 0, 1)\n");
  EXPECT_NE(z.err.find("shader 'flat' produced a non-finite or zero N"), std::string::npos) << z.err;
  EXPECT_EQ(z.err.find("non-finite P"), std::string::npos) << z.err;
}

// §6.3 and §2.3: a clamped run-time index and an unknown run-time space name warn once, in
// reliefc --eval as in the renderer.
TEST(CliTest, EvalWarnsAboutClampedIndicesAndUnknownSpaces) {
  const fs::path clamp = writeTemp("relief_clamp.disp",
                                   "displacement clamped(int i = 7; string sp = \"nowhere\")\n{\n"
                                   "    float k[3] = {1, 2, 3};\n    P += k[i] * transform(sp, N);\n}\n");
  const CliRun r = reliefc("--eval " + quote(clamp.string()));
  EXPECT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("shader 'clamped': array or component indices were clamped"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("shader 'clamped': lookups of a coordinate space name other than"), std::string::npos) << r.err;
  const CliRun quiet = reliefc("--eval " + quote(clamp.string()) + " -p i=1 -p sp=object");
  EXPECT_EQ(quiet.err, "") << quiet.err;
}

}  // namespace
