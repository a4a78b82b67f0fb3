// Preprocessor unit tests (language.md §1.1): macros, conditionals, includes, and their errors.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "compiler/preprocessor.h"

namespace relief::compiler {
namespace {

struct Run {
  SourceManager sm;
  DiagnosticsEngine diags;
  std::string text;     // token spellings joined by spaces
  std::string errors;   // "line:col: message" per diagnostic
};

std::unique_ptr<Run> preprocess(const std::string& source, PreprocessorOptions options = {},
                                const std::string& name = "pp.disp") {
  auto r = std::make_unique<Run>();
  const auto id = r->sm.addBuffer(name, source);
  std::vector<Token> toks = Preprocessor(r->sm, r->diags, options).run(id);
  for (const Token& t : toks) {
    if (t.is(Tok::Eof)) break;
    if (!r->text.empty()) r->text += ' ';
    r->text += t.text;
  }
  for (const Diagnostic& d : r->diags.sorted(r->sm)) {
    const PresumedLoc p = r->sm.presumed(d.loc);
    r->errors += std::to_string(p.line) + ":" + std::to_string(p.column) + ": " + d.message + "\n";
  }
  return r;
}

TEST(PreprocessorTest, ObjectAndFunctionLikeMacros) {
  auto r = preprocess("#define A 1 + 2\n#define F(x, y) (x * y)\n#define G F\nA F(A, 3) G(1,2) F\n");
  EXPECT_EQ(r->errors, "");
  EXPECT_EQ(r->text, "1 + 2 ( 1 + 2 * 3 ) ( 1 * 2 ) F");
}

TEST(PreprocessorTest, ExpansionIsNotRecursiveAndSitsAtTheUse) {
  auto r = preprocess("#define X X + 1\nfloat a = X;\n");
  EXPECT_EQ(r->text, "float a = X + 1 ;");
  // A name left unexpanded inside its own expansion stays so when an argument carries it on.
  auto arg = preprocess("#define w w + 1\n#define ID(x) x\n#define ID2(x) ID(x)\nw ID(w) ID2(w)\n");
  EXPECT_EQ(arg->text, "w + 1 w + 1 w + 1");
  auto fn = preprocess("#define f(x) g(x) + f(x)\n#define g(x) f(x)\n#define ID(x) x\nID(f(1))\n");
  EXPECT_EQ(fn->text, "f ( 1 ) + f ( 1 )");
  auto loc = preprocess("#define K 42\n  K\n");
  EXPECT_EQ(loc->text, "42");
}

TEST(PreprocessorTest, LineAndFileAreTheUsesOwn) {
  auto r = preprocess("#define WHERE __FILE__ __LINE__\nfloat a;\n__LINE__ WHERE\n", {}, "dir/my \"pp\".disp");
  EXPECT_EQ(r->errors, "");
  EXPECT_EQ(r->text, "float a ; 3 \"dir/my \\\"pp\\\".disp\" 3");
}

TEST(PreprocessorTest, Conditionals) {
  auto r = preprocess(
      "#define TWO 2\n#if TWO * 2 == 4 && defined(TWO) && !defined NONE\na\n#elif 1\nb\n#else\nc\n#endif\n"
      "#ifdef NONE\nd\n#elif TWO > 1\ne\n#endif\n#ifndef NONE\nf\n#endif\n#if 0\n#error skipped\n\"bad\n#endif\n");
  EXPECT_EQ(r->errors, "");
  EXPECT_EQ(r->text, "a e f");
}

TEST(PreprocessorTest, DirectiveErrors) {
  auto r = preprocess("#bogus\n#if\n#endif\n#else\n#define 3\n#error stop here\n#if 1\n");
  EXPECT_EQ(r->errors,
            "1:2: invalid preprocessing directive 'bogus'\n"
            "2:2: invalid integer expression in #if\n"
            "4:2: #else without #if\n"
            "5:9: macro name must be an identifier\n"
            "6:1: stop here\n"
            "7:1: unterminated conditional directive\n");
}

// Division by zero in an evaluated operand is an error, as in C; operands the value does not
// depend on are not evaluated; overflow wraps instead of being undefined.
TEST(PreprocessorTest, ConditionArithmetic) {
  auto r = preprocess("#if 1 / 0\na\n#endif\n#if 2 % (1 - 1)\nb\n#endif\n");
  EXPECT_EQ(r->errors,
            "1:2: division by zero in #if\n"
            "4:2: division by zero in #if\n");
  EXPECT_EQ(r->text, "");
  r = preprocess("#if 0 && 1 / 0\na\n#elif 1 || 1 % 0\nb\n#endif\n#if 1 ? 2 : 3 / 0\nc\n#endif\n#if 0 ? 1 / 0 : 4\nd\n#endif\n");
  EXPECT_EQ(r->errors, "");
  EXPECT_EQ(r->text, "b c d");
  r = preprocess("#define MIN (65536 * 65536 * 65536 * 32768)\n#if MIN < 0 && -MIN < 0 && MIN / -1 < 0 && MIN % -1 == 0\n"
                 "wraps\n#endif\n");
  EXPECT_EQ(r->errors, "");
  EXPECT_EQ(r->text, "wraps");
}

TEST(PreprocessorTest, MacroArgumentCountIsChecked) {
  auto r = preprocess("#define F(a, b) a\nF(1)\n");
  EXPECT_EQ(r->errors, "2:1: macro 'F' expects 2 arguments, but was given 1\n");
  r = preprocess("#define G(a) a\nG(1, 2)\n");
  EXPECT_EQ(r->errors, "2:1: macro 'G' expects 1 argument, but was given 2\n");
}

TEST(PreprocessorTest, IncludesSearchPathsAndPragmaOnce) {
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) / "relief_pp";
  std::filesystem::create_directories(dir / "sys");
  std::ofstream(dir / "local.h") << "#pragma once\nlocal\n";
  std::ofstream(dir / "sys" / "lib.h") << "lib\n";
  PreprocessorOptions options;
  options.includeDirs = {(dir / "sys").string()};
  auto r = preprocess("#include \"local.h\"\n#include \"local.h\"\n#include <lib.h>\n#include \"lib.h\"\n", options,
                      (dir / "main.disp").string());
  EXPECT_EQ(r->errors, "");
  EXPECT_EQ(r->text, "local lib lib");

  auto missing = preprocess("#include \"nope.h\"\nafter\n", options, (dir / "main.disp").string());
  EXPECT_EQ(missing->errors, "1:10: 'nope.h' file not found\n");
  EXPECT_EQ(missing->text, "");  // compilation stops at a missing include
}

TEST(PreprocessorTest, StringizeAndPaste) {
  auto r = preprocess("#define STR(x) #x\n#define CAT(a, b) a ## b\n#define V v ## 2\nSTR(a + \"q\") CAT(my, var) CAT(1, 5) V\n");
  EXPECT_EQ(r->errors, "");
  EXPECT_EQ(r->text, "\"a + \\\"q\\\"\" myvar 15 v2");
  auto bad = preprocess("#define CAT(a, b) a ## b\nCAT(+, /)\nx # y\n");
  EXPECT_EQ(bad->errors,
            "2:1: pasting gives '+/', which is not a valid token\n"
            "3:3: invalid character '#' in source\n");
  // An empty argument beside ## is C's placemarker: the other operand stands alone, and a chain
  // of pastes skips it.
  auto empty = preprocess("#define CAT(a, b) a ## b\n#define CAT3(a, b, c) a ## b ## c\n"
                          "CAT(, x) CAT(y, ) [CAT(, )] CAT3(p, , q) CAT3(, , r) CAT(a b, c d)\n");
  EXPECT_EQ(empty->errors, "");
  EXPECT_EQ(empty->text, "x y [ ] pq r a bc d");
}

TEST(PreprocessorTest, DefinedProducedByAMacroIsEvaluated) {
  // C leaves it undefined; GNU cpp (and RSL headers written for it) evaluate it, its operand
  // unexpanded.
  auto r = preprocess("#define A 1\n#define HAS_A defined(A)\n#define HAS_B defined B\n"
                      "#if HAS_A && !HAS_B\nyes\n#endif\n#if HAS_B\nno\n#endif\n");
  EXPECT_EQ(r->errors, "");
  EXPECT_EQ(r->text, "yes");
}

TEST(PreprocessorTest, CommandLineDefines) {
  PreprocessorOptions options;
  options.defines = {{"LEVEL", "3"}, {"FLAG", "1"}, {"EMPTY", ""}};
  auto r = preprocess("#if LEVEL > 2 && FLAG\nyes M_PI EMPTY\n#endif\n", options);
  EXPECT_EQ(r->errors, "");
  EXPECT_EQ(r->text, "yes 3.14159265358979323846");  // -D EMPTY= defines it empty, as cc does
}

TEST(PreprocessorTest, FunctionLikeMacroArgumentsMayStartOnTheNextLine) {
  // C allows any white space, line breaks included, between the name and its '('.
  auto r = preprocess("#define F(x) (x + 1)\n#define G F\nF\n  (2) F\nz G\n\n(3)\nF\n#define Q 1\nF $\n");
  EXPECT_EQ(r->text, "( 2 + 1 ) F z ( 3 + 1 ) F F $");
  EXPECT_EQ(r->errors, "10:3: invalid character '$' in source\n");
}

TEST(PreprocessorTest, MultiLineDefinesSpliceBackslashNewlines) {
  // RSL headers spread macros over lines (§1.1); what follows keeps its own line numbers.
  auto r = preprocess(
      "#define BUMP(a, f) \\\n    ((a) * \\\r\n     sin(f))\n#error split \\\n message\nBUMP(1, u) $\n");
  EXPECT_EQ(r->text, "( ( 1 ) * sin ( u ) ) $");
  EXPECT_EQ(r->errors,
            "4:1: split  message\n"
            "6:12: invalid character '$' in source\n");
}

}  // namespace
}  // namespace relief::compiler
