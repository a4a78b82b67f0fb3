// Parser unit tests: precedence and associativity (language.md §4.1), statements, formals, and
// syntax errors with their locations and recovery.
#include <algorithm>
#include <gtest/gtest.h>

#include <sstream>

#include "compiler/compiler.h"
#include "compiler/parser.h"

namespace relief::compiler {
namespace {

std::string dumpExpr(const std::string& text, std::string* errors = nullptr) {
  SourceManager sm;
  DiagnosticsEngine diags;
  const auto id = sm.addBuffer("e.disp", text);
  Parser parser(sm, id, diags);
  ExprPtr e = parser.parseStandaloneExpression();
  if (errors) {
    for (const Diagnostic& d : diags.sorted()) {
      const PresumedLoc p = sm.presumed(d.loc);
      *errors += std::to_string(p.line) + ":" + std::to_string(p.column) + ": " + d.message + "\n";
    }
  }
  if (!e) return "<null>";
  std::ostringstream out;
  dump(out, *e);
  return out.str();
}

// Diagnostics of a whole file as "line:col: severity: message" lines.
std::string errorsOf(const std::string& source) {
  CompileFlags flags;
  flags.jit = false;
  CompileResult r = compileSource("p.disp", source, {}, flags);
  std::string out;
  for (const Diagnostic& d : r.diagnostics->sorted()) {
    const PresumedLoc p = r.sources->presumed(d.loc);
    out += std::to_string(p.line) + ":" + std::to_string(p.column) + ": " + d.message + "\n";
  }
  return out;
}

TEST(ParserTest, MultiplicationBindsTighterThanAddition) {
  EXPECT_EQ(dumpExpr("a + b * c"),
            "Binary +\n  Identifier a\n  Binary *\n    Identifier b\n    Identifier c\n");
}

TEST(ParserTest, DotBindsTighterThanMultiplicationAndCrossLooserThanIt) {
  EXPECT_EQ(dumpExpr("a * b . c"),
            "Binary *\n  Identifier a\n  Binary .\n    Identifier b\n    Identifier c\n");
  EXPECT_EQ(dumpExpr("a ^ b * c"),
            "Binary ^\n  Identifier a\n  Binary *\n    Identifier b\n    Identifier c\n");
  EXPECT_EQ(dumpExpr("a + b ^ c"),
            "Binary +\n  Identifier a\n  Binary ^\n    Identifier b\n    Identifier c\n");
}

TEST(ParserTest, BinaryOperatorsAreLeftAssociative) {
  EXPECT_EQ(dumpExpr("a - b - c"),
            "Binary -\n  Binary -\n    Identifier a\n    Identifier b\n  Identifier c\n");
}

TEST(ParserTest, AssignmentAndConditionalAreRightAssociative) {
  EXPECT_EQ(dumpExpr("a = b += c"),
            "Assign =\n  Identifier a\n  Assign +=\n    Identifier b\n    Identifier c\n");
  EXPECT_EQ(dumpExpr("a ? b : c ? d : e"),
            "Conditional\n  Identifier a\n  Identifier b\n  Conditional\n    Identifier c\n"
            "    Identifier d\n    Identifier e\n");
}

TEST(ParserTest, LogicalAndComparisonPrecedence) {
  EXPECT_EQ(dumpExpr("a < b == c && d || e"),
            "Binary ||\n  Binary &&\n    Binary ==\n      Binary <\n        Identifier a\n"
            "        Identifier b\n      Identifier c\n    Identifier d\n  Identifier e\n");
}

TEST(ParserTest, UnaryPostfixCastsAndConstructors) {
  EXPECT_EQ(dumpExpr("-a . b"), "Binary .\n  Unary -\n    Identifier a\n  Identifier b\n");
  EXPECT_EQ(dumpExpr("!x++"), "Unary !\n  PostIncDec ++\n    Identifier x\n");
  EXPECT_EQ(dumpExpr("(float) i"), "Cast float\n  Identifier i\n");
  EXPECT_EQ(dumpExpr("float noise(P)"), "Cast float\n  Call noise\n    Identifier P\n");
  EXPECT_EQ(dumpExpr("point \"object\" (1, 2, 3)"),
            "Construct point\n  StringLiteral \"object\"\n  IntLiteral 1\n  IntLiteral 2\n  IntLiteral 3\n");
  EXPECT_EQ(dumpExpr("v[1]"), "Index\n  Identifier v\n  IntLiteral 1\n");
  EXPECT_EQ(dumpExpr("(1, 2, 3)"), "Tuple\n  IntLiteral 1\n  IntLiteral 2\n  IntLiteral 3\n");
}

TEST(ParserTest, ExpectedExpressionPointsAtTheToken) {
  std::string errors;
  EXPECT_EQ(dumpExpr("a + * b", &errors), "<null>");
  EXPECT_EQ(errors, "1:5: expected expression\n");
}

TEST(ParserTest, RslAndOslParameterGroups) {
  CompileFlags flags;
  flags.jit = false;
  flags.keepAst = true;
  CompileResult r = compileSource(
      "g.disp", "displacement g(float a = 1, b = 2; point c = 0, float d = 3; output vector e = 0;) { P += a*b*c*d*e; }",
      {}, flags);
  ASSERT_TRUE(r.success()) << renderDiagnostics(r);
  const auto& params = r.ast->shaders[0]->params;
  ASSERT_EQ(params.size(), 5u);
  EXPECT_EQ(params[1]->name, "b");
  EXPECT_EQ(params[1]->type.kind, TypeKind::Float);
  EXPECT_EQ(params[2]->type.kind, TypeKind::Point);
  EXPECT_EQ(params[3]->type.kind, TypeKind::Float);
  EXPECT_TRUE(params[4]->isOutput);
}

// A stray ';' between definitions (`float f() { ... };`) is an empty declaration, as C++ and RSL
// compilers take it; it was "expected a shader or function definition".
TEST(ParserTest, StraySemicolonsBetweenDefinitionsAreEmptyDeclarations) {
  EXPECT_EQ(errorsOf("float f(float x) { return x; };\n;\ndisplacement d(float Km = 0.1) { P += f(Km) * N; };\n"), "");
}

TEST(ParserTest, MissingSemicolonIsReportedPastThePreviousToken) {
  EXPECT_EQ(errorsOf("displacement d()\n{\n    P += N\n    P += N;\n}\n"),
            "3:11: expected ';' after expression\n");
  // A declaration or a statement keyword after the missing ';' on the same line is kept: its
  // names stay declared (`b` was reported as undeclared).
  EXPECT_EQ(errorsOf("displacement d()\n{\n    float a = 1 float b = 2;\n    P += a * b * N return;\n}\n"),
            "3:16: expected ';' after declaration\n4:19: expected ';' after expression\n");
}

TEST(ParserTest, MissingClosersGetANoteAtTheOpener) {
  CompileFlags flags;
  flags.jit = false;
  CompileResult r = compileSource("c.disp", "displacement d() {\n  if (u > 0 { P += N; }\n}\n", {}, flags);
  const auto sorted = r.diagnostics->sorted();
  ASSERT_EQ(sorted.size(), 1u);
  EXPECT_EQ(sorted[0].message, "expected ')'");
  ASSERT_EQ(sorted[0].notes.size(), 1u);
  EXPECT_EQ(sorted[0].notes[0].message, "to match this '('");
  EXPECT_EQ(r.sources->presumed(sorted[0].notes[0].loc).column, 6u);

  EXPECT_EQ(errorsOf("displacement d() {\n  P += N;\n"), "2:10: expected '}'\n");
}

TEST(ParserTest, SeveralErrorsAreReportedInOneRun) {
  EXPECT_EQ(errorsOf("displacement d()\n{\n  float a = 1 +;\n  P += ) N;\n  P += a * N;\n}\n"
                     "displacement e( { }\n"
                     "displacement f() { P += N }\n"),
            "3:16: expected expression\n"
            "4:8: expected expression\n"
            "7:17: expected a type\n"
            "8:26: expected ';' after expression\n");
}

// A for header in error gives one error: its remains are not read as statements (the comma,
// which the language does not have, once gave three), and a syntax error in the body still shows.
TEST(ParserTest, ForHeaderErrorsAreReportedOnce) {
  EXPECT_EQ(errorsOf("displacement d()\n{\n  float a, b;\n  for (a = 0, b = 10; a < 3; a += 1) ;\n"
                     "  for (a = 0; a < 3 a += 1) { b += 1; }\n  for (a = 0; (a < 3; a += ) { b = ; }\n"
                     "  P += b * N;\n}\n"),
            "4:13: expected ';'\n"
            "5:20: expected ';'\n"
            "6:21: expected ')'\n"
            "6:28: expected expression\n"
            "6:36: expected expression\n");
}

// `a.5` is `a` `.5` (language.md §1), a syntax error, and only that: what the parser made of
// the statement before the missing ';' is not type-checked into more errors or warnings, and
// the variable it declares is not reported again where it is used.
TEST(ParserTest, StatementCutShortMidLineGivesOnlyTheSyntaxError) {
  EXPECT_EQ(errorsOf("displacement d()\n{\n  vector w = N;\n  float g = w.5;\n  float h;\n  h = w.5;\n"
                     "  w .5;\n  P += (g + h) * N;\n}\n"),
            "4:14: expected ';' after declaration\n"
            "6:8: expected ';' after expression\n"
            "7:4: expected ';' after expression\n");
}

TEST(ParserTest, OnlyDisplacementShadersAndNoReservedIdentifiers) {
  EXPECT_EQ(errorsOf("light l() {}\ndisplacement d() { float solar = 1; P += N; }\n"),
            "1:1: only displacement shaders are supported, not 'light' shaders\n"
            "2:26: 'solar' is a reserved word\n");
}

// As in C, 2147483648 fits an int only under a unary minus (INT_MIN); hex literals keep their bits.
TEST(ParserTest, TwoToTheThirtyFirstOnlyUnderUnaryMinus) {
  EXPECT_EQ(errorsOf("displacement d() { int a = -2147483648; int b = - 2147483648; int h = 0xFFFFFFFF;\n"
                     "  int x = 2147483648; int y = 1 - 2147483648; P += (a + b + h + x + y) * N; }\n"),
            "2:11: integer literal is too large to be represented in 32 bits\n"
            "2:35: integer literal is too large to be represented in 32 bits\n");
}

TEST(ParserTest, HostileNestingGivesOneErrorNotACrash) {
  const std::string parens = "displacement d() { P += " + std::string(50000, '(') + "1" + std::string(50000, ')') + " * N; }";
  EXPECT_EQ(errorsOf(parens), "1:280: expressions nested too deeply (the limit is 256 levels)\n");
  const std::string blocks = "displacement d() " + std::string(50000, '{') + std::string(50000, '}');
  EXPECT_EQ(errorsOf(blocks), "1:275: statements nested too deeply (the limit is 256 levels)\n");
  std::string chain = "displacement d() { float a = 1";
  for (int i = 0; i < 20000; ++i) chain += " + 1";
  chain += "; P += a * N; }";
  const std::string errors = errorsOf(chain);
  EXPECT_EQ(std::count(errors.begin(), errors.end(), '\n'), 1) << errors;
  EXPECT_NE(errors.find(": expression too long or nested too deeply (the limit is 16384 levels of operators)\n"),
            std::string::npos)
      << errors;
}

// `else if` chains are not nesting (a shader may list thousands of cases); only their length
// is bounded, with its own message.
TEST(ParserTest, ElseIfChainsAreBoundedByLengthNotNesting) {
  auto chainOf = [](int links) {
    std::string s = "displacement d(float k = 1) {\n  float h = 0;\n  if (k == 0) h = 0;\n";
    for (int i = 1; i < links; ++i) s += "  else if (k == " + std::to_string(i) + ") h = " + std::to_string(i) + ";\n";
    return s + "  P += h * N;\n}\n";
  };
  EXPECT_EQ(errorsOf(chainOf(4000)), "");
  EXPECT_EQ(errorsOf(chainOf(5000)), "4100:8: 'else if' chain too long (the limit is 4096 links)\n");
}

TEST(ParserTest, LongButAllowedChainsCompileAndRun) {
  std::string chain = "displacement d() { float a = 0";
  for (int i = 0; i < 5000; ++i) chain += " + u";
  chain += "; P += a * N; }";
  CompileResult r = compileSource("chain.disp", chain);
  ASSERT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
  EXPECT_EQ(r.shaders.size(), 1u);
}

}  // namespace
}  // namespace relief::compiler
