// Type checker unit tests: the arithmetic table (§4.1), promotions (§2.1), context-typed noise
// (§6.1), poison types (one mistake, one diagnostic) and semantic errors with locations.
#include <gtest/gtest.h>

#include "compiler/compiler.h"

namespace relief::compiler {
namespace {

struct Checked {
  CompileResult result;
  std::string errors;  // "line:col: message" per diagnostic
};

Checked check(const std::string& body, const std::string& params = "") {
  CompileFlags flags;
  flags.jit = false;
  flags.keepAst = true;
  Checked c{compileSource("t.disp", "displacement t(" + params + ")\n{\n" + body + "\n}\n", {}, flags), {}};
  for (const Diagnostic& d : c.result.diagnostics->sorted()) {
    if (d.severity == Severity::Warning) continue;
    const PresumedLoc p = c.result.sources->presumed(d.loc);
    c.errors += std::to_string(p.line) + ":" + std::to_string(p.column) + ": " + d.message + "\n";
  }
  return c;
}

// Type of the initializer of the first declared local in `body`.
std::string typeOfInit(const std::string& decl) {
  Checked c = check(decl + "\nP += 0 * N;");
  if (!c.errors.empty()) return "error: " + c.errors;
  const Stmt& first = *c.result.ast->shaders[0]->body->stmts[0];
  return typeName(first.decls[0]->init->type);
}

TEST(TypeCheckTest, SpatialArithmeticTable) {
  EXPECT_EQ(typeOfInit("vector a = P - P;"), "vector");
  EXPECT_EQ(typeOfInit("point a = P + N;"), "point");
  EXPECT_EQ(typeOfInit("vector a = dPdu + N;"), "vector");
  EXPECT_EQ(typeOfInit("normal a = N - Ng;"), "normal");
  EXPECT_EQ(typeOfInit("vector a = P * N;"), "vector");
  EXPECT_EQ(typeOfInit("normal a = N * N;"), "normal");
  EXPECT_EQ(typeOfInit("point a = 2 * P;"), "point");
  EXPECT_EQ(typeOfInit("float a = P . N;"), "float");
  EXPECT_EQ(typeOfInit("vector a = P ^ N;"), "vector");
  EXPECT_EQ(typeOfInit("int a = 7 / 2;"), "int");
  EXPECT_EQ(typeOfInit("float a = 7 / 2.0;"), "float");
  EXPECT_EQ(typeOfInit("int a = u < v;"), "int");
  EXPECT_EQ(typeOfInit("color a = color(1) * 2;"), "color");
  EXPECT_EQ(typeOfInit("point a = u > 0 ? P : N;"), "point");
}

TEST(TypeCheckTest, ContextTypedNoise) {
  // `P + a*noise(P)` is a point noise; `P += Km*noise(P)*N` a float one (§6.1).
  Checked c = check("float a = 1;\npoint q = P + a * noise(P);\nP += a * noise(P) * N;\nvector w = noise(P);\n"
                    "float f = noise(u, v);\ncolor k = color(noise(P));\nP += q + w + f;\nP += vector(k);");
  ASSERT_EQ(c.errors, "");
  const auto& stmts = c.result.ast->shaders[0]->body->stmts;
  const Expr& q = *stmts[1]->decls[0]->init;                    // P + (a * noise(P))
  EXPECT_EQ(typeName(q.operands[1]->operands[1]->type), "point");
  const Expr& compound = *stmts[2]->expr;                       // P += (a*noise(P))*N
  EXPECT_EQ(typeName(compound.operands[1]->operands[0]->operands[1]->type), "float");
  EXPECT_EQ(typeName(stmts[3]->decls[0]->init->type), "vector");
  EXPECT_EQ(typeName(stmts[4]->decls[0]->init->type), "float");
  EXPECT_EQ(typeName(stmts[5]->decls[0]->init->operands[0]->type), "color");
}

TEST(TypeCheckTest, TextureIsFloatOrColorWhateverTheContext) {
  // §6.7: float|color texture(...), context-typed; a spatial context gets the color.
  EXPECT_EQ(typeOfInit("color c = texture(\"t.tx\");"), "color");
  EXPECT_EQ(typeOfInit("float f = texture(\"t.tx\");"), "float");
  Checked cast = check("vector d = vector(texture(\"t.tx\", s, t));\nP += d;");
  ASSERT_EQ(cast.errors, "");
  EXPECT_EQ(typeName(cast.result.ast->shaders[0]->body->stmts[0]->decls[0]->init->operands[0]->type), "color");
  EXPECT_EQ(check("vector d = texture(\"t.tx\");\nP += d;").errors,
            "3:12: cannot initialize a variable of type 'vector' with a value of type 'color'\n");
  EXPECT_EQ(check("P += texture(\"t.tx\");").errors,
            "3:3: invalid operands to binary expression ('point' and 'color')\n");
  EXPECT_EQ(check("P += texture(\"t.tx\") * N;").errors, "");
}

TEST(TypeCheckTest, Promotions) {
  EXPECT_EQ(check("float f = 1; point p = 2; vector v = P; normal n = v; int i = 0; f = i;\nP += f*p*n;").errors, "");
  EXPECT_EQ(check("color c = P;").errors,
            "3:11: cannot initialize a variable of type 'color' with a value of type 'point'\n");
  EXPECT_EQ(check("float f = N;").errors,
            "3:11: cannot initialize a variable of type 'float' with a value of type 'normal'\n");
  EXPECT_EQ(check("string s = 1;").errors,
            "3:12: cannot initialize a variable of type 'string' with a value of type 'int'\n");
}

TEST(TypeCheckTest, OneMistakeGivesOneDiagnostic) {
  // The undeclared name poisons every expression above it: no follow-on operand errors.
  EXPECT_EQ(check("P += (Kn * N + color(1)) ^ P;\nP += Kn;").errors, "3:7: use of undeclared identifier 'Kn'\n");
  EXPECT_EQ(check("float a = \"s\" * 2;\nP += a * N + 1;").errors,
            "3:15: invalid operands to binary expression ('string' and 'int')\n");
}

TEST(TypeCheckTest, InvalidOperandsPointAtTheOperator) {
  EXPECT_EQ(check("color c = 1;\nP = P + c;").errors,
            "4:7: invalid operands to binary expression ('point' and 'color')\n");
  EXPECT_EQ(check("float x = u % 2;").errors,
            "3:13: invalid operands to binary expression ('float' and 'int')\n");
  EXPECT_EQ(check("P = -\"x\";").errors, "3:5: invalid argument type 'string' to unary expression\n");
}

TEST(TypeCheckTest, ReadOnlyGlobalsAndNonLvalues) {
  EXPECT_EQ(check("Ng = N;\ndPdu += N;\nu++;\nPI = 3;").errors,
            "3:4: cannot assign to read-only variable 'Ng'\n"
            "4:6: cannot assign to read-only variable 'dPdu'\n"
            "5:2: cannot assign to read-only variable 'u'\n"
            "6:4: cannot assign to read-only variable 'PI'\n");
  EXPECT_EQ(check("(P + N) = P;").errors, "3:9: expression is not assignable\n");
  EXPECT_EQ(check("P[0] = 1; N[2] += u; P += N;").errors, "");
}

TEST(TypeCheckTest, OutputArgumentsAreLvaluesOfTheParameterType) {
  const std::string f = "void twice(output float x) { x *= 2; }\n";
  auto errors = [&](const std::string& body) {
    CompileFlags flags;
    flags.jit = false;
    CompileResult r = compileSource("o.disp", f + "displacement o()\n{\n" + body + "\n}\n", {}, flags);
    std::string out;
    for (const Diagnostic& d : r.diagnostics->sorted()) {
      const PresumedLoc p = r.sources->presumed(d.loc);
      out += std::to_string(p.line) + ":" + std::to_string(p.column) + ": " + d.message + "\n";
    }
    return out;
  };
  EXPECT_EQ(errors("float a[2]; vector w = 1; matrix m = 1;\ntwice(a[1]); twice(w[2]); twice(m[0][3]); twice(P[1]);"),
            "");
  EXPECT_EQ(errors("vector w = 1;\ntwice(xcomp(w));"),
            "5:7: argument for output parameter 'x' must be an lvalue of type 'float'\n");
  EXPECT_EQ(errors("int k[2];\ntwice(k[0]);"), "5:7: argument for output parameter 'x' must be an lvalue of type 'float'\n");
  EXPECT_EQ(errors("twice(Ng[0]);"), "4:7: cannot assign to read-only variable 'Ng'\n");
}

TEST(TypeCheckTest, ParameterRules) {
  EXPECT_EQ(check("P += a * N;", "float a").errors, "1:22: shader parameter 'a' has no default value\n");
  EXPECT_EQ(check("P += a * b * N;", "float a = 1; float b = a * 2").errors, "");
  EXPECT_EQ(check("P += a * N;", "float a = v").errors,
            "1:26: default value of a shader parameter must be a constant expression\n");
}

TEST(TypeCheckTest, CallsAreCheckedAgainstBuiltinSignatures) {
  EXPECT_EQ(check("float a = sin(1, 2);").errors,
            "3:11: no matching function for call to 'sin' with arguments (int, int)\n");
  EXPECT_EQ(check("float a = length(u);").errors,
            "3:11: no matching function for call to 'length' with arguments (float)\n");
  EXPECT_EQ(check("float a = frobnicate(u);").errors, "3:11: use of undeclared function 'frobnicate'\n");
  EXPECT_EQ(check("float a1[2] = {1, 2}, a2[2] = {3, 4};\nfloat x = (u > 0 ? a1 : a2)[0];").errors,
            "4:18: a '?:' expression cannot choose between arrays ('float[2]'); use an if statement\n");
  // A macro given the wrong number of arguments is one error, not one more at the parser.
  CompileFlags flags;
  flags.jit = false;
  const CompileResult macro = compileSource(
      "m.disp", "#define G(a, b) (a + b)\ndisplacement t() { float x = G(1) * 2; P += x * N; }\n", {}, flags);
  EXPECT_EQ(macro.diagnostics->numErrors(), 1u) << renderDiagnostics(macro);
  // Once per body, like an undeclared variable; another name is another error.
  EXPECT_EQ(check("float a = frobnicate(u) + frobnicate(v) + twiddle(u);").errors,
            "3:11: use of undeclared function 'frobnicate'\n3:43: use of undeclared function 'twiddle'\n");
  EXPECT_EQ(check("float a = pow(u, 2) + mod(u, 1) + clamp(u, 0, 1) + smoothstep(0, 1, u) + max(u, v, 0.5);\n"
                  "vector d = Du(P); float e = Dv(u); vector n = calculatenormal(P);\n"
                  "P += a * d * e * n * xcomp(P) * dot(P, N) * length(cross(P, N));")
                .errors,
            "");
}

TEST(TypeCheckTest, StatementRules) {
  EXPECT_EQ(check("if (P) P += N;").errors, "3:5: condition of type 'point' is not a number\n");
  EXPECT_EQ(check("u + 1;").errors, "3:1: expression result unused\n");
  EXPECT_EQ(check("return 1;").errors, "3:1: a shader cannot return a value\n");
  EXPECT_EQ(check("continue;").errors, "3:1: 'continue' statement not in loop\n");
  EXPECT_EQ(check("float a = 1;\nfloat a = 2;").errors, "4:7: redefinition of 'a'\n");
  EXPECT_EQ(check("for (int i = 0; i < 3; i++) { if (i == 1) break; P += N; }\nint i = 2;").errors, "");
  EXPECT_EQ(check("float x = P[3];").errors, "3:13: index 3 is out of range for type 'point'\n");
  // A constant negative texture channel, as an index or an option, is an error like a negative
  // index; a run-time one reads the fill value.
  EXPECT_EQ(check("float x = texture(\"t.tx\"[-1], s, t);\nP += x * N;").errors, "3:26: texture channel -1 is negative\n");
  EXPECT_EQ(check("float x = texture(\"t.tx\", s, t, \"firstchannel\", -2.5);\nP += x * N;").errors,
            "3:49: texture channel -2 is negative\n");
  EXPECT_EQ(check("float x = texture(\"t.tx\", s, t, \"firstchannel\", -0.5);\nP += x * N;").errors, "");
}

TEST(TypeCheckTest, Warnings) {
  Checked c = check("float unused = 1;\nint n = 2.5;\nP += n * N;\nreturn;\nP += N;");
  std::vector<std::string> warnings;
  for (const Diagnostic& d : c.result.diagnostics->sorted())
    if (d.severity == Severity::Warning) warnings.push_back(d.flag);
  EXPECT_EQ(warnings, (std::vector<std::string>{"unused-variable", "narrowing", "unreachable-code"}));
}

// Functions are inlined where the shader calls them, so the expansion limit applies to calls the
// shader makes: a library of doubling functions it never calls (or calls only at a small depth)
// compiles; calling the deep one is one error, at the shader's call, with a note at the function
// whose own body passes the limit.
TEST(TypeCheckTest, TheInlineLimitCountsOnlyWhatTheShaderCalls) {
  std::string library = "float f0(float x) { return x * 2 + 1; }\n";
  for (int i = 1; i < 40; ++i)
    library += "float f" + std::to_string(i) + "(float x) { return f" + std::to_string(i - 1) + "(x) + f" +
               std::to_string(i - 1) + "(x + 1); }\n";
  CompileFlags flags;
  flags.jit = false;
  const CompileResult unused =
      compileSource("lib.disp", library + "displacement d() { P += f3(u) * N; }\n", {}, flags);
  EXPECT_TRUE(unused.success()) << renderDiagnostics(unused);
  const CompileResult deep =
      compileSource("lib.disp", library + "displacement d() { P += f39(u) * N; }\n", {}, flags);
  ASSERT_FALSE(deep.success());
  const std::vector<Diagnostic> d = deep.diagnostics->sorted();
  int errors = 0;
  for (const Diagnostic& x : d) errors += x.severity == Severity::Error;
  EXPECT_EQ(errors, 1);
  const std::string text = renderDiagnostics(deep);
  EXPECT_NE(text.find("lib.disp:41:"), std::string::npos) << text;
  EXPECT_NE(text.find("note: 'f15' alone passes the limit here, with its calls of 'f14'"), std::string::npos) << text;
}

// arraylength is the declaration's length, uniform whatever the elements hold (RSL returns a
// uniform float): a varying local array's length was rejected for a uniform variable.
TEST(TypeCheckTest, ArraylengthIsUniform) {
  EXPECT_EQ(check("float loc[4];\nloc[0] = u;\nuniform float m = arraylength(loc);\nP += m * loc[0] * N;").errors, "");
  EXPECT_EQ(check("uniform float m = arraylength(k);\nP += m * N;", "float k[3] = {1, 2, 3}").errors, "");
}

}  // namespace
}  // namespace relief::compiler
