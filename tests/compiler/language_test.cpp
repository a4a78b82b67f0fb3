// Language features evaluated through the JIT against values computed here: the matrix type
// (constructors, m[i][j], arithmetic, transform/determinant/inverse/transpose, coordinate-space
// forms, parameters), format()/concat(), hyperbolic functions, log(x, base), mod and sign of ints
// (floats, §6.2: only abs min max clamp have int forms), the two-argument atan's derivatives,
// compound assignment's single evaluation, defaults in named spaces and vfBm's
// automatically differentiated derivatives.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "compiler/compiler.h"
#include "runtime/builtins_noise.h"
#include "runtime/shader.h"
#include "test_batch.h"

namespace relief::compiler {
namespace {

using testing::TestBatch;
using M4 = std::array<double, 16>;

// Compiles `source`, evaluates its only shader at P = (0.25, 0.5, 0.75) on the plane z = const
// (u = P.x, v = P.y) and returns the printed text; Pout/Nout land in `b`.
std::string evaluate(const std::string& source, TestBatch& b, RlfStatus* statusOut = nullptr) {
  CompileResult r = compileSource("lang.disp", source);
  EXPECT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
  if (!r.success() || r.shaders.empty()) return "";
  runtime::ShaderInstance instance(r.shaders.front());
  b.P[0][0] = 0.25f, b.P[1][0] = 0.5f, b.P[2][0] = 0.75f;
  b.N[2][0] = b.Ng[2][0] = 1;
  b.dPdu[0][0] = b.dPdv[1][0] = 1;
  b.u[0] = b.s[0] = 0.25f;
  b.v[0] = b.t[0] = 0.5f;
  b.dsdu[0] = b.dtdv[0] = 1;
  b.du[0] = b.dv[0] = 0.01f;
  std::string printed;
  RlfHostServices services{};
  services.context = &printed;
  services.print = [](void* context, const char* text) { *static_cast<std::string*>(context) += text; };
  RlfShadingBatch view = b.all();
  view.services = &services;
  RlfStatus status{};
  instance.evaluate(view, status);
  if (statusOut) *statusOut = status;
  return printed;
}

M4 mul(const M4& a, const M4& b) {
  M4 r{};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) r[i * 4 + j] += a[i * 4 + k] * b[k * 4 + j];
  return r;
}

TEST(MatrixTest, ConstructorsIndexingAndArithmetic) {
  TestBatch b(1);
  RlfStatus status{};
  // A is an affine map (scale, shear, translation in row 3, row vectors).
  const std::string printed = evaluate(R"(
displacement m()
{
    matrix A = matrix(2, 1, 0, 0,  0, 3, 0, 0,  0, 0, 4, 0,  1, 2, 3, 1);
    matrix I = 1;
    matrix D = matrix(5);
    matrix T = (1,0,0,0, 0,1,0,0, 0,0,1,0, 7,8,9,1);
    printf("%g %g %g %g\n", A[0][1], A[3][2], I[2][2] + I[2][1], D[1][1]);
    printf("%g\n", determinant(A));
    matrix B = A * inverse(A), C = A / A, R = A * (1 / A), H = (2 / A) * A;  // RSL's 1/m is the inverse
    float err = 0;
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c)
            err += abs(B[r][c] - (r == c)) + abs(C[r][c] - (r == c)) + abs(R[r][c] - (r == c)) +
                   abs(H[r][c] - 2 * (r == c));
    printf("%d\n", err < 1e-5);
    printf("%g\n", transpose(A));
    printf("%g\n", 2 * A / 4);
    printf("%d %d\n", A == A, A != A * 2);
    printf("%g\n", T * A);
    A[1][2] = 6;
    setcomp(A, 2, 0, -1);
    printf("%g %g %g\n", A[1][2], comp(A, 2, 0), comp(A, 1, 1));
    int i = 1, j = 2;
    printf("%g %g\n", A[i][j], A[i + 9][j - 6]);  // run-time indices clamp (and are counted)
    printf("%g\n", inverse(matrix(0)));
})",
                                       b, &status);
  EXPECT_EQ(status.indexClamped, 1u);
  const M4 A = {2, 1, 0, 0, 0, 3, 0, 0, 0, 0, 4, 0, 1, 2, 3, 1};
  const M4 T = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 7, 8, 9, 1};
  std::string expected = "1 3 1 5\n24\n1\n"
                         "2 0 0 1 1 3 0 2 0 0 4 3 0 0 0 1\n1 0.5 0 0 0 1.5 0 0 0 0 2 0 0.5 1 1.5 0.5\n1 1\n";
  const M4 TA = mul(T, A);
  for (int k = 0; k < 16; ++k) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", TA[size_t(k)]);
    expected += std::string(k ? " " : "") + buf;
  }
  expected += "\n6 -1 3\n6 1\n0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\n";
  EXPECT_EQ(printed, expected);
}

TEST(MatrixTest, TransformsPointsVectorsAndNormals) {
  TestBatch b(1);
  // Non-uniform scale (2, 1, 0.5) then translation (1, 2, 3).
  const std::string printed = evaluate(R"(
displacement m(matrix S = matrix(2, 0, 0, 0,  0, 1, 0, 0,  0, 0, 0.5, 0,  1, 2, 3, 1))
{
    point p = transform(S, point(1, 1, 1));
    vector v = transform(S, vector(1, 1, 1));
    normal n = transform(S, normal(1, 1, 1));
    printf("%g; %g; %g\n", p, v, n);
    printf("%g; %g\n", vtransform(S, point(1, 1, 1)), ntransform(S, vector(1, 1, 1)));
    // Projective: w' = 2 divides the point.
    printf("%g\n", transform(matrix(1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 2), point(2, 4, 6)));
    P = transform(S, P);
})",
                                       b);
  EXPECT_EQ(printed, "3 3 3.5; 2 1 0.5; 0.5 1 2\n2 1 0.5; 0.5 1 2\n1 2 3\n");
  EXPECT_FLOAT_EQ(b.Pout[0][0], 0.25f * 2 + 1);
  EXPECT_FLOAT_EQ(b.Pout[1][0], 0.5f + 2);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 0.75f * 0.5f + 3);
  // P' = P·S: the derivatives of P were transformed too, so the host-contract normal is the
  // scaled plane's: dPdu' = (2,0,0), dPdv' = (0,1,0).
  EXPECT_NEAR(b.Nout[2][0], 1.0f, 1e-6);
}

TEST(MatrixTest, CoordinateSpaceForms) {
  TestBatch b(1);
  // object = current scaled by 2 and moved by (10, 0, 0); shader = current moved by (0, 5, 0).
  RlfSpaces& sp = b.spaces;
  const float objectToCurrent[16] = {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 10, 0, 0, 1};
  const float currentToObject[16] = {0.5f, 0, 0, 0, 0, 0.5f, 0, 0, 0, 0, 0.5f, 0, -5, 0, 0, 1};
  const float shaderToCurrent[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 5, 0, 1};
  const float currentToShader[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -5, 0, 1};
  for (int k = 0; k < 16; ++k) {
    sp.currentFromObject[k] = objectToCurrent[k];
    sp.objectFromCurrent[k] = currentToObject[k];
    sp.currentFromShader[k] = shaderToCurrent[k];
    sp.shaderFromCurrent[k] = currentToShader[k];
  }
  const std::string printed = evaluate(R"(
displacement m(string obj = "object")
{
    matrix os = matrix("object", "shader");
    printf("%g\n", transform(os, point(1, 1, 1)));
    printf("%g\n", transform(matrix(obj, "current"), point(1, 1, 1)));
    printf("%g\n", transform(matrix("object", 1), point(1, 1, 1)));
    printf("%g\n", transform(matrix("shader", 1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  1, 1, 1, 1), point(0)));
    printf("%g\n", transform("object", "shader", point(1, 1, 1)));
    // RSL's space-first form means what the RI spec (11.4) says: current -> space, then the
    // matrix, so matrix "object" 1 transforms as transform("object", p) does.
    printf("%g\n", transform(matrix "object" 1, point(12, 2, 2)));
    printf("%g\n", transform(matrix "shader" (1), point(0)));
    printf("%g\n", transform(matrix "object" (1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  1, 1, 1, 1), point(10, 0, 0)));
    printf("%g\n", transform("object", point(12, 2, 2)));
    printf("%g; %g\n", point "object" (1, 1, 1), point "object" P);
})",
                                       b);
  // object (1,1,1) -> current (12, 2, 2) -> shader (12, -3, 2).
  EXPECT_EQ(printed, "12 -3 2\n12 2 2\n12 2 2\n1 6 1\n12 -3 2\n1 1 1\n0 -5 0\n1 1 1\n1 1 1\n12 2 2; 10.5 1 1.5\n");
}

// filterstep takes RSL's name/value pairs after its floats: "width" scales the filter width and
// "filter" is accepted and ignored (the step is box-filtered, as texture() ignores its "filter").
TEST(FilterstepTest, TakesWidthAndFilterOptions) {
  TestBatch b(1);  // u = 0.25, du = 0.01: filterwidth(u) = 0.01
  const std::string printed = evaluate(R"(
displacement f()
{
    printf("%.3f %.3f %.3f\n", filterstep(0.252, u), filterstep(0.252, u, "filter", "gaussian"),
           filterstep(0.252, u, "filter", "catmull-rom", "width", 2));
    printf("%.3f %.3f\n", filterstep(0.252, u, 0.26, "filter", "box"), filterstep(0.252, u, "width", 2, "width", 1));
})",
                                       b);
  EXPECT_EQ(printed, "0.300 0.300 0.400\n0.800 0.300\n");
}

// RSL has no int type and indexes arrays, triples and matrices with floats: they truncate.
TEST(PrintfTest, TakesRslPointColorAndMatrixConversions) {
  const std::string source = R"(
displacement pf()
{
    printf("%p|%.1c|%m|%p\n", point(1, 2, 3), color(0.25, 0.5, 1), matrix(2), 1.5);
})";
  // %p of a float warns (it wants a point, vector or normal); %p, %c and %m of their types do not.
  CompileResult r = compileSource("pf.disp", source);
  EXPECT_EQ(r.diagnostics->numShownWarnings(*r.sources), 1u) << renderDiagnostics(r);
  // %c wants a color as %p wants the spatial types: a point for %c warns (it did not).
  CompileResult c = compileSource("pc.disp", "displacement pc() { printf(\"%c %c\\n\", P, color(1)); }");
  EXPECT_EQ(c.diagnostics->numShownWarnings(*c.sources), 1u) << renderDiagnostics(c);
  EXPECT_NE(renderDiagnostics(c).find("format '%c' expects a color"), std::string::npos) << renderDiagnostics(c);
  EXPECT_NE(renderDiagnostics(r).find("format '%p' expects a point, vector or normal"), std::string::npos)
      << renderDiagnostics(r);
  TestBatch b(1);
  EXPECT_EQ(evaluate(source, b),
            "1.000000 2.000000 3.000000|0.2 0.5 1.0|2.000000 0.000000 0.000000 0.000000 0.000000 2.000000 "
            "0.000000 0.000000 0.000000 0.000000 2.000000 0.000000 0.000000 0.000000 0.000000 2.000000|"
            "1.500000\n");
}

// filterstep(e, x, x2) filters over the interval between x and x2 in either order (it ignored a
// reversed interval: 1 instead of 0.5 below), and its derivative follows the interval's ends.
TEST(FilterstepTest, TwoValuesInEitherOrder) {
  TestBatch b(1);  // u = 0.25, du = 0.01
  const std::string printed = evaluate(R"(
displacement f()
{
    printf("%.3f %.3f %.3f %.3f\n", filterstep(0.3, 0.4, 0.2), filterstep(0.3, 0.2, 0.4),
           filterstep(0.1, 0.4, 0.2), filterstep(0.5, 0.4, 0.2));
    printf("%.3f %.3f\n", Du(filterstep(0.3, 0.6 - u, 0.2)), Du(filterstep(0.3, 0.2, 0.6 - u)));
})",
                                       b);
  // d/du of (hi - e) / (hi - lo) with hi = 0.6 - u = 0.35, lo = 0.2: -(e - lo) / (hi - lo)^2.
  EXPECT_EQ(printed, "0.500 0.500 1.000 0.000\n-4.444 -4.444\n");
}

// A conversion that does not fit its argument prints the argument itself (a string as it is,
// numbers as %g), the same every time: a string given to %f read whatever memory followed the
// float arguments, and through format() that could change P. Long strings print whole.
TEST(PrintfTest, MismatchedConversionsPrintTheArgument) {
  const std::string longText(300, 'x');
  const std::string source = R"(
displacement pm(string fmt = "%d|%f|%s")
{
    printf("%f|%s|%s|%5.1s|%d|%s\n", "abc", 1.5, point(1, 2, 3), "xyz", 7, ")" + longText + R"(");
    printf(concat(fmt, "\n"), "a", "b", 4);
    if (format("%g", "x") != "x") P += N;
})";
  TestBatch b(1);
  for (int run = 0; run < 2; ++run)
    EXPECT_EQ(evaluate(source, b), "abc|1.5|1 2 3|    x|7|" + longText + "\na|b|4\n");
  EXPECT_EQ(b.Pout[2][0], b.P[2][0]);
}

// %d of a float (RSL has no int: `format("tex.%04d.tx", frame)`) prints it converted toward zero,
// saturated; a non-finite value prints as itself.
TEST(PrintfTest, IntegerConversionsOfFloatsTruncate) {
  const std::string source = R"(
displacement pd(float frame = 3.7; float big = 1e38)
{
    printf("%s|%d|%i|%d|%d\n", format("tex.%04d.tx", frame), -2.5, 1e20, point(1.9, -1.9, 0), big * 10);
})";
  TestBatch b(1);
  EXPECT_EQ(evaluate(source, b), "tex.0003.tx|-2|2147483647|1 -1 0|inf\n");
}

// Field widths and precisions above 1024 are taken as 1024: "%999999999f" made snprintf write a
// gigabyte per conversion at every shading point (a render hung), in printf and format alike.
TEST(PrintfTest, HugeFieldWidthsAreCapped) {
  const std::string source = R"(
displacement pw(string fmt = "%2147483647d")
{
    printf("%999999999f|%05.2f|%.99999999f\n", 1.5, 2.25, 0.5);
    printf("%s\n", format(fmt, 7));
})";
  TestBatch b(1);
  const std::string printed = evaluate(source, b);
  ASSERT_EQ(printed.size(), (1024 + 1 + 5 + 1 + 2 + 1024 + 1) + (1024 + 1));
  EXPECT_EQ(printed.substr(1016, 15), "1.500000|02.25|");
  EXPECT_EQ(printed.substr(printed.size() - 3), " 7\n");
}

// §2.2: an RSL tuple takes its type from context as a noise call does (§6.1), on either side
// of an operator: before, a tuple left of `+ - * /` was a point, so a color could not take it.
TEST(TupleTest, TypedByContextOnEitherSideOfAnOperator) {
  const std::string source = R"(
displacement tc()
{
    color a = (1, 2, 3) + color(0.5);
    color b = (1, 2, 3) * 2;
    color c = (1, 2, 3) + 0.5;
    color d; d = (1, 2, 3) * u;
    color e = (u > 0 ? (1, 2, 3) : (0, 0, 0)) + color(0);
    color f = noise(P * 3.7) + (1, 2, 3);
    color g = (1, 2, 3) + noise(P * 3.7);
    printf("%.2c|%.2c|%.2c|%.2c|%.2c|%d\n", a, b, c, d, e, f == g && comp(f, 0) != comp(f, 1));
})";
  TestBatch b(1);
  EXPECT_EQ(evaluate(source, b), "1.50 2.50 3.50|2.00 4.00 6.00|1.50 2.50 3.50|0.25 0.50 0.75|1.00 2.00 3.00|1\n");
  // Beside a color under `*`, `/`, `*=`, `==` and `!=`, and among the arguments of overloaded
  // built-ins, a tuple is a color too (it was a point, which a color does not take).
  const std::string more = R"(
displacement tm()
{
    color Ct = color(1);
    Ct *= (0.3, 0.5, 0.25);
    color d = Ct * (1, 2, 4), e = Ct / (1, 2, 4);
    color m = mix(color(0), (1, 0.5, 0.25), 0.5), m2 = mix((0, 0, 0), (1, 1, 1), 0.5);
    color c = clamp(Ct, (0, 0, 0), (0.3, 0.3, 0.3));
    printf("%.3c|%.3c|%.3c|%.3c|%.3c|%.3c|%d%d\n", Ct, d, e, m, m2, c, Ct != (0, 0, 0), (0, 0, 0) == Ct);
})";
  EXPECT_EQ(evaluate(more, b), "0.300 0.500 0.250|0.300 1.000 1.000|0.300 0.250 0.062|0.500 0.250 0.125|"
                               "0.500 0.500 0.500|0.300 0.300 0.250|10\n");
}

TEST(IndexTest, FloatIndicesTruncateAsRslLoopsNeed) {
  TestBatch b(1);
  const std::string printed = evaluate(R"(
displacement f()
{
    float w[4] = {1, 2, 3, 4};
    float i, sum = 0;
    for (i = 0; i < 4; i += 1) sum += w[i];
    vector q = vector(5, 6, 7);
    matrix m = 2;
    float x = 1.7;
    w[x] = 10;
    printf("%g %g %g %g %g\n", sum, q[x], m[x][1.2], w[1], w[2.9]);
})",
                                       b);
  EXPECT_EQ(printed, "10 6 2 10 3\n");
}

// RSL's break n / continue n leave or continue the n-th enclosing loop; -Wuninitialized follows
// them (k is set on the only way out of the outer loop).
TEST(LoopTest, BreakAndContinueTakeALoopCount) {
  TestBatch b(1);
  const std::string printed = evaluate(R"(
displacement brk()
{
    float found = 0, visits = 0;
    for (int i = 0; i < 4; i += 1) {
        for (int j = 0; j < 4; j += 1) {
            visits += 1;
            if (j == 1) continue 2;
            if (i == 2) { found = i * 10 + j; break 2; }
        }
    }
    float k;
    while (1) { while (1) { k = 3; break 2; } }
    printf("%g %g %g\n", found, visits, k);
})",
                                       b);
  EXPECT_EQ(printed, "20 5 3\n");
}

TEST(StringTest, FormatAndConcatBuildStrings) {
  TestBatch b(1);
  const std::string printed = evaluate(R"(
displacement s(string base = "rock")
{
    string a = concat(base, "_", format("%d", 7), ".exr");
    string c = format("%s at %.2f: %g%%", base, u, vector(1, 2, 3));
    printf("%s|%s|%d|%d\n", a, c, a == "rock_7.exr", concat("") == "");
})",
                                       b);
  EXPECT_EQ(printed, "rock_7.exr|rock at 0.25: 1 2 3%|1|1\n");
}

TEST(MathTest, HyperbolicLogBaseAndModOfInts) {
  TestBatch b(1);
  const std::string printed = evaluate(R"(
displacement s()
{
    printf("%.5f %.5f %.5f %g %g\n", sinh(0.5), cosh(0.5), tanh(0.5), tanh(1000), tanh(-1000));
    printf("%g %g %g\n", log(8, 2), log(1000, 10), log(vector(4, 16, 64), 4));
    printf("%g %g %g %g %g %g %g\n", mod(-1, 3), mod(7, -3), mod(6, 3), mod(5, 0), mod(-1.5, 1), mod(7, 4) / 2, sign(-3) / 2);
    P = point(Du(sinh(u)), Du(cosh(u)), Du(tanh(u)));
})",
                                       b);
  char expected[256];
  std::snprintf(expected, sizeof expected, "%.5f %.5f %.5f 1 -1\n3 3 1 2 3\n2 -2 0 0 0.5 1.5 -0.5\n", std::sinh(0.5),
                std::cosh(0.5), std::tanh(0.5));
  EXPECT_EQ(printed, expected);
  const double u = 0.25;
  EXPECT_NEAR(b.Pout[0][0], std::cosh(u), 1e-6);
  EXPECT_NEAR(b.Pout[1][0], std::sinh(u), 1e-6);
  EXPECT_NEAR(b.Pout[2][0], 1 - std::tanh(u) * std::tanh(u), 1e-6);
}

TEST(NoiseTest, VectorFbmAndTurbulenceDerivativesAreAnalytic) {
  TestBatch b(1);
  evaluate(R"(
displacement s()
{
    point p = point(u * 3 + 0.1234, v * 3 + 0.0567, 0.5371);  // off the lattice: |snoise| has kinks at zeros
    vector f = vfBm(p, 4, 2, 0.5);
    float t = turbulence(p, 3);
    P = point(xcomp(f), Du(xcomp(f)), Dv(zcomp(f)));
    N = normal(t, Du(t), Dv(t));
})",
           b);
  // The same sums written here, with the x and z channels of vector noise (the runtime's noises
  // 0 and 2), differentiated by central differences.
  auto channel = [](double x, double y, double z, int which) {
    float g[3];
    return 2.0 * rlf_noise3(float(x), float(y), float(z), g, which) - 1.0;
  };
  auto fbm = [&](double u, double v, int which, int octaves, bool turbulence) {
    double sum = 0, amp = 1, freq = 1;
    for (int o = 0; o < octaves; ++o) {
      const double n = channel((u * 3 + 0.1234) * freq, (v * 3 + 0.0567) * freq, 0.5371 * freq, which);
      sum += amp * (turbulence ? std::abs(n) : n);
      amp *= 0.5;
      freq *= 2;
    }
    return sum;
  };
  const double u = 0.25, v = 0.5, e = 1e-3;
  // Central differences of float-evaluated noise: good to about 1% here.
  auto near = [](double actual, double expected) { EXPECT_NEAR(actual, expected, 0.01 * std::max(1.0, std::abs(expected))); };
  EXPECT_NEAR(b.Pout[0][0], fbm(u, v, 0, 4, false), 1e-5);
  near(b.Pout[1][0], (fbm(u + e, v, 0, 4, false) - fbm(u - e, v, 0, 4, false)) / (2 * e));
  near(b.Pout[2][0], (fbm(u, v + e, 2, 4, false) - fbm(u, v - e, 2, 4, false)) / (2 * e));
  EXPECT_NEAR(b.Nout[0][0], fbm(u, v, 0, 3, true), 1e-5);
  near(b.Nout[1][0], (fbm(u + e, v, 0, 3, true) - fbm(u - e, v, 0, 3, true)) / (2 * e));
  near(b.Nout[2][0], (fbm(u, v + e, 0, 3, true) - fbm(u, v - e, 0, 3, true)) / (2 * e));
  EXPECT_NE(b.Pout[1][0], 0.0f);  // derivatives really flow (not the zero of a missing lane)
  EXPECT_NE(b.Nout[1][0], 0.0f);
}

// §6.5: noise is 0.5 at the lattice points, in every channel of a triple noise too (channels had
// come from shifted domains, whose lattice points are elsewhere: vector noise(point(1, 2, 3)) was
// (0.5, 0.444, 0.470)); off the lattice the channels differ.
TEST(FunctionTest, EveryChannelOfATripleNoiseIsHalfAtTheLattice) {
  TestBatch b(1);
  const std::string printed = evaluate(R"(
displacement d()
{
    vector a = noise(point(1, 2, 3));
    color c = noise(1.0);
    vector s = snoise(point(-4, 0, 7));
    vector q = pnoise(point(1, 2, 3), point(4, 4, 4));
    vector w = noise(point(1, 2, 3), 5.0);
    vector off = noise(point(1.3, 2.6, 3.2));
    printf("%g %g %g | %g %g | %g %g | %g %g | %g %g | %d %d\n", comp(a, 0), comp(a, 1), comp(a, 2),
           comp(c, 1), comp(c, 2), comp(s, 1), comp(s, 2), comp(q, 1), comp(q, 2), comp(w, 1), comp(w, 2),
           comp(off, 0) != comp(off, 1), comp(off, 1) != comp(off, 2));
})",
                                       b);
  EXPECT_EQ(printed, "0.5 0.5 0.5 | 0.5 0.5 | 0 0 | 0.5 0.5 | 0.5 0.5 | 1 1\n");
}

TEST(TextureTest, FootprintComesFromTheDerivativesOfST) {
  // Stripes one texel wide: a point lookup sees 0 or 1, a footprint of many texels their mean.
  const std::string path = ::testing::TempDir() + "/relief_stripes.exr";
  {
    constexpr int kSize = 256;
    std::vector<float> pixels;
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) pixels.push_back(float(x % 2));
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(kSize, kSize, 1, OIIO::TypeDesc::FLOAT);
    ASSERT_TRUE(out->open(path, spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, pixels.data()));
    out->close();
  }
  CompileResult r = compileSource("stripes.disp", R"(
displacement stripes(string tex = "")
{
    P = point(texture(tex, s, t), texture(tex, 101.5 / 256 + (s - 101.5 / 256) * 0.001, t), 0);
})");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r);
  runtime::ShaderInstance instance(r.shaders.front());
  std::string error;
  ASSERT_TRUE(instance.bind({"tex", runtime::ParamType::String, {}, {path}}, &error)) << error;
  TestBatch b(2);
  for (size_t i = 0; i < 2; ++i) {
    b.s[i] = (101.5f + float(i)) / 256;  // texel centres of columns 101 (value 1) and 102 (value 0)
    b.t[i] = 0.5f;
    b.dsdu[i] = b.dtdv[i] = 1;
    b.du[i] = b.dv[i] = i == 0 ? 1e-4f : 0.1f;  // a tiny footprint, then ~25 texels wide
    b.N[2][i] = b.Ng[2][i] = 1;
  }
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_EQ(status.textureErrors, 0u);
  // A footprint below a texel keeps the stripe (OIIO's bicubic magnification gives 2/3 at the
  // centre of a 1-texel), one of ~25 texels averages it out.
  EXPECT_GT(b.Pout[0][0], 0.6f);
  EXPECT_NEAR(b.Pout[0][1], 0.5f, 0.05f);
  // Scaling s by 0.001 shrinks Du(s), and with it the footprint, a thousandfold: the stripe is back.
  EXPECT_GT(b.Pout[1][1], 0.6f);
}

TEST(ComponentTest, CompAndSetcompTakeFloatIndices) {
  // Classic RSL indexes with floats: `float i; setcomp(c, i, x)` truncates i (§2.1, §6.3).
  TestBatch b(1);
  const std::string printed = evaluate(R"(
displacement d()
{
    color c = color(1, 2, 3);
    float i = 1.7;
    setcomp(c, i, 9);
    matrix m = 1;
    float r = 2;
    setcomp(m, r, 0.5, 5);
    printf("%g %g %g %g %g\n", c[1], comp(c, i), comp(c, 2.9), comp(m, r, 0.0), comp(m, 1.0, 1));
})",
                                       b);
  EXPECT_EQ(printed, "9 9 3 5 1\n");
}

TEST(FunctionTest, OutputArgumentsMayBeAnyLvalue) {
  // §2.1: output arguments are lvalues (§4.1): array elements, v[i] and m[i][j] too. Each index
  // expression runs once although the element is read before the call and written after it.
  TestBatch b(1);
  const std::string printed = evaluate(R"(
void twice(output float x) { x *= 2; }
void setv(output vector w) { w = vector(7, 8, 9); }
void inc(output int k) { k += 1; }
displacement d()
{
    float arr[3] = {1, 2, 3};
    int i = 0;
    twice(arr[1]);
    twice(arr[i + 2]);
    vector v = vector(1, 2, 3);
    twice(v[0]);
    vector vs[2];
    setv(vs[1]);
    twice(vs[1][2]);
    matrix m = 1;
    twice(m[1][1]);
    int counts[2] = {5, 6};
    inc(counts[i++]);
    float plain = 5;
    twice(plain);
    printf("%g %g %g %g %g %g %d %d %d %g\n", arr[1], arr[2], v[0], vs[1][0], vs[1][2], m[1][1], counts[0],
           counts[1], i, plain);
})",
                                       b);
  EXPECT_EQ(printed, "4 6 2 7 18 2 6 6 1 10\n");
}

TEST(FunctionTest, ReadOnlyArrayArgumentsAreValuesEvenWhenTheSameArrayIsWritten) {
  // A read-only parameter is a value (§3): writing the same array through an output parameter,
  // through an extern, or in a later argument must not change what the body reads from it.
  TestBatch b(1);
  const std::string printed = evaluate(R"(
float shift(float src[3]; output float dst[3]) {
    dst[0] = 10;
    return src[0] + dst[0];
}
float bump(output float k[2]) { k[0] = 100; return 0; }
float first(float a[2]; float unused) { return a[0]; }
displacement d()
{
    float a[3] = {1, 2, 3};
    float viaOutput = shift(a, a);
    float e[2] = {4, 5};
    float viaExtern(float src[2]) {
        extern float e[];
        e[0] = 40;
        return src[0];
    }
    float seenExtern = viaExtern(e);
    float g[2] = {7, 8};
    float beforeLater = first(g, bump(g));
    printf("%g %g %g %g %g %g\n", viaOutput, a[0], seenExtern, e[0], beforeLater, g[0]);
})",
                                       b);
  EXPECT_EQ(printed, "11 10 4 40 7 100\n");
}

TEST(FunctionTest, ExternReachesAcrossNestingLevelsInLexicalOrder) {
  // A function nested two deep reaches the shader's local without the one between declaring it;
  // the nearest enclosing declaration wins, locals before globals.
  TestBatch b(1);
  const std::string printed = evaluate(R"(
displacement d()
{
    float k = 1, m = 3;
    float outer() {
        float m = 7;
        float inner() { extern float k, m; k += 1; return 10 * k + m; }
        return inner();
    }
    float got = outer();
    float viaP() { float deeper() { extern point P; return P[0]; } return deeper(); }
    printf("%g %g %g %g\n", got, k, m, viaP());
})",
                                       b);
  EXPECT_EQ(printed, "27 2 3 0.25\n");
}

TEST(FunctionTest, SplineAndIndicesOverUnsizedArrayParameters) {
  // §6.6 takes `T k[]`; through an unsized parameter the knot count is known where the function
  // is inlined: used there, and a count the basis cannot use (or a constant index out of the
  // array) is a run-time problem, reported, not a compile error.
  TestBatch b(1);
  RlfStatus status{};
  const std::string fits = evaluate(R"(
float sp(float x; float k[]) { return spline(x, k); }
float bz(float x; float k[]) { return spline("bezier", x, k); }
displacement d()
{
    float k5[5] = {0, 1, 4, 9, 16};
    float k7[7] = {0, 1, 2, 3, 4, 5, 6};
    printf("%g %g\n", sp(0.5, k5), bz(0.5, k7));
})",
                                    b, &status);
  EXPECT_EQ(fits, "4 3\n");
  EXPECT_EQ(status.splineBasis, 0u);
  EXPECT_EQ(status.indexClamped, 0u);
  const std::string misfits = evaluate(R"(
float sp(float x; float k[]) { return spline(x, k); }
float bz(float x; float k[]) { return spline("bezier", x, k); }
float h(float k[]) { return k[7]; }
displacement d()
{
    float k5[5] = {0, 1, 4, 9, 16};
    float k2[2] = {3, 4};
    printf("%g %g %g\n", bz(0.5, k5), sp(0.5, k2), h(k5));
})",
                                       b, &status);
  EXPECT_EQ(misfits, "4 3 16\n");  // catmull-rom instead of bezier; the first of 2 knots; k[4]
  EXPECT_EQ(status.splineBasis, 2u);
  EXPECT_EQ(status.indexClamped, 1u);
}

// A NaN position passed every clamp of spline() and became a knot index from the conversion of
// NaN: the load far outside the knots crashed the render. Now it is NaN, in every basis and for
// listed and array knots, and infinities still clamp to the ends.
TEST(FunctionTest, SplineAtANanPositionIsNanNotACrash) {
  TestBatch b(1);
  const std::string printed = evaluate(R"(
displacement d()
{
    float big = exp(100);
    float x = big * u - big * u;
    float k[6] = {0, 1, 2, 3, 4, 5};
    string basis = "bspline";
    float a = spline(x, 0, 0.1, 0.2, 0.3);
    float b = spline("linear", x, k);
    float c = spline(basis, x, 7, 8, 9, 10);
    color d = spline("bezier", x, color(0), color(1), color(2), color(3));
    printf("%d %d %d %d %g %g\n", isnan(a), isnan(b), isnan(c), isnan(comp(d, 1)),
           spline(big, 0, 0.1, 0.2, 0.3), spline(-big, 0, 0.1, 0.2, 0.3));
})",
                                       b);
  EXPECT_EQ(printed, "1 1 1 1 0.2 0.1\n");
}

TEST(DisplaceTest, AmountInANamedSpaceScalesWithThatSpace) {
  // §6.8: displace(space, amp) moves amp * length(ntransform(space, normalize(N))) along N, so
  // 0.1 units of an object space scaled 2x (or of a shader space scaled 0.5x) are 0.2 (0.05) in
  // current space.
  for (const auto& [space, scale] : {std::pair<std::string, float>{"object", 2.0f}, {"shader", 0.5f}}) {
    SCOPED_TRACE(space);
    TestBatch b(1);
    float* currentFrom = space == "object" ? b.spaces.currentFromObject : b.spaces.currentFromShader;
    float* fromCurrent = space == "object" ? b.spaces.objectFromCurrent : b.spaces.shaderFromCurrent;
    for (int d = 0; d < 3; ++d) {
      currentFrom[d * 5] = scale;
      fromCurrent[d * 5] = 1 / scale;
    }
    evaluate("displacement d(string sp = \"" + space + "\") { displace(\"" + space + "\", 0.1); }", b);
    EXPECT_FLOAT_EQ(b.Pout[2][0], 0.75f + 0.1f * scale);
    evaluate("displacement d(string sp = \"" + space + "\") { displace(sp, 0.1); }", b);  // looked up at run time
    EXPECT_FLOAT_EQ(b.Pout[2][0], 0.75f + 0.1f * scale);
    EXPECT_FLOAT_EQ(b.Pout[0][0], 0.25f);
  }
}

// §4.1: `a op= b` and `++`/`--` evaluate the lvalue `a` once, index expressions included.
TEST(AssignTest, CompoundAssignmentAndIncrementEvaluateTheirLvalueOnce) {
  TestBatch b(1);
  evaluate(R"(
int next(output int i) { i += 1; return i - 1; }
displacement d()
{
    float k[3] = {1, 2, 3}; int i = 0; int j = 0;
    k[i++]++;            // k[0] = 2, i = 1
    ++k[i++];            // k[1] = 3, i = 2
    k[next(j)] += 10;    // k[0] = 12, j = 1
    matrix m = 1;
    m[j++][0] += 5;      // m[1][0] = 5, j = 2
    point q = point(1, 2, 3);
    q[i++] *= 10;        // q[2] = 30, i = 3
    P = point(k[0] + k[1] * 100 + i * 1000 + j * 10000, comp(m, 1, 0), q[2]);
})",
           b);
  EXPECT_FLOAT_EQ(b.Pout[0][0], 12 + 300 + 3000 + 20000);
  EXPECT_FLOAT_EQ(b.Pout[1][0], 5);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 30);
}

// §6.4: the two-argument atan carries derivatives through both arguments.
TEST(MathTest, TwoArgumentAtanHasDerivatives) {
  TestBatch b(1);
  evaluate("displacement d() { P = point(Du(atan(u, 0.3)), Du(atan(0.3, u)), Dv(atan(v, u))); }", b);
  const double u = 0.25, v = 0.5;
  EXPECT_NEAR(b.Pout[0][0], 0.3 / (u * u + 0.09), 1e-5);
  EXPECT_NEAR(b.Pout[1][0], -0.3 / (u * u + 0.09), 1e-5);
  EXPECT_NEAR(b.Pout[2][0], u / (u * u + v * v), 1e-5);
}

// Matrices carry no derivatives: one built from a varying float (`q * k`) drops them by design,
// and compiles in one pass (it used to rerun code generation forever).
TEST(MatrixTest, MatrixTimesAVaryingFloatCompiles) {
  TestBatch b(1);
  evaluate("displacement d(float k = 2; matrix m = k * matrix(\"object\", \"shader\"))\n"
           "{ float kk = u; matrix q = 1; matrix mm = q * kk; P = point(comp(mm, 0, 0), comp(m, 1, 1), Du(kk)); }",
           b);
  EXPECT_FLOAT_EQ(b.Pout[0][0], 0.25f);
  EXPECT_FLOAT_EQ(b.Pout[1][0], 2.0f);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 1.0f);
}

// §3: defaults may be constructors, also in a named space (RSL's `point "shader" (0, 0, 0)`).
// Such a default, and one that reads it, is evaluated with the batch's spaces unless the host
// binds the parameter; reflection reports it with every space the identity.
TEST(ParamDefaultTest, DefaultsInNamedSpacesUseTheBatchSpaces) {
  CompileResult r = compileSource("lang.disp", R"(
displacement d(float Km = 1; point c = point "shader" (1, 0, 0); vector w = vector "shader" (0, 0, 1);
               point c2 = c + w; matrix m = matrix("shader", "current"); float k = 2 * Km)
{
    P = c;
    N = normal(c2 - c + vector(comp(m, 3, 0), k, Km));
})");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
  const auto& shader = r.shaders.front();
  const runtime::ParamInfo* c = shader->findParam("c");
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->defaultNumbers, (std::vector<double>{1, 0, 0}));
  EXPECT_GE(c->boundFlagOffset, 0);
  EXPECT_GE(shader->findParam("c2")->boundFlagOffset, 0);  // reads c
  EXPECT_GE(shader->findParam("k")->boundFlagOffset, 0);   // reads Km
  EXPECT_GE(shader->findParam("m")->boundFlagOffset, 0);
  EXPECT_EQ(shader->findParam("Km")->boundFlagOffset, -1);

  // Shader space: current = shader scaled 2x, then moved by (10, 20, 30) (row vectors: p * M).
  TestBatch b(1);
  for (int d = 0; d < 3; ++d) b.spaces.currentFromShader[d * 5] = 2, b.spaces.shaderFromCurrent[d * 5] = 0.5f;
  const float move[3] = {10, 20, 30};
  for (int d = 0; d < 3; ++d) {
    b.spaces.currentFromShader[12 + d] = move[d];
    b.spaces.shaderFromCurrent[12 + d] = -0.5f * move[d];
  }
  b.N[2][0] = b.Ng[2][0] = 1;
  RlfStatus status{};
  runtime::ShaderInstance unbound(shader);
  unbound.evaluate(b.all(), status);
  EXPECT_FLOAT_EQ(b.Pout[0][0], 12);  // (1, 0, 0) * 2 + (10, 20, 30)
  EXPECT_FLOAT_EQ(b.Pout[1][0], 20);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 30);
  // N = (c2 - c) + (m[3][0], k, Km) = (0, 0, 2) + (10, 2, 1).
  EXPECT_FLOAT_EQ(b.Nout[0][0], 10);
  EXPECT_FLOAT_EQ(b.Nout[1][0], 2);
  EXPECT_FLOAT_EQ(b.Nout[2][0], 3);

  // Bound, c is the given point as is; c2 still follows c and the spaces.
  runtime::ShaderInstance bound(shader);
  std::string error;
  ASSERT_TRUE(bound.bind({"c", runtime::ParamType::Point, {5, 6, 7}, {}}, &error)) << error;
  ASSERT_TRUE(bound.bind({"Km", runtime::ParamType::Float, {4}, {}}, &error)) << error;
  bound.evaluate(b.all(), status);
  EXPECT_FLOAT_EQ(b.Pout[0][0], 5);
  EXPECT_FLOAT_EQ(b.Pout[1][0], 6);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 7);
  // N = (0, 0, 2) + (10, k, Km) with k = 2 * Km following the bound Km = 4.
  EXPECT_FLOAT_EQ(b.Nout[1][0], 8);
  EXPECT_FLOAT_EQ(b.Nout[2][0], 6);

  // A space-reading default may loop (fBm is a loop in the stdlib): it counts against the loop
  // limit in the entry as in the body. With identity spaces it is the reflected default.
  CompileResult looping = compileSource("loop.disp",
                                        "displacement d(float n = fBm(transform(\"shader\", point(1.3, 2.7, 0.4)), 4, 2, 0.5))"
                                        " { P += n * N; }");
  ASSERT_TRUE(looping.success()) << renderDiagnostics(looping) << looping.internalError;
  TestBatch identity(1);
  identity.N[2][0] = 1;
  runtime::ShaderInstance loopInstance(looping.shaders.front());
  loopInstance.evaluate(identity.all(), status);
  const float reflected = looping.shaders.front()->findParam("n")->defaultNumbers.at(0);
  EXPECT_NE(reflected, 0.0f);
  EXPECT_FLOAT_EQ(identity.Pout[2][0], reflected);

  // Anything else that is not constant stays an error.
  CompileResult bad = compileSource("bad.disp", "displacement d(point c = P) { P = c; }");
  EXPECT_FALSE(bad.success());
}

TEST(SplineTest, BasisNamedAtRunTime) {
  // §6.6 with a basis in a string variable: chosen per call at run time. A name that is unknown or
  // does not fit the knot count (bezier needs 3m+1) falls back to catmull-rom and is counted.
  TestBatch b(1);
  RlfStatus status{};
  const std::string printed = evaluate(R"(
displacement sp(string basis = "linear"; string bad = "cubic")
{
    float k[6] = {9, 0, 10, 20, 30, 9};
    string b2 = "bezier";
    printf("%g %g %g %g\n", spline(basis, 0.5, 9, 0, 10, 20, 9), spline(basis, 0.25, k),
           spline(bad, 0.5, 0, 0, 1, 2, 2), spline("linear", 0.5, 9, 0, 10, 20, 9));
    printf("%g %g\n", spline(b2, 0.5, 0, 1, 2, 3, 4), spline(b2, 0.5, 0, 1, 2, 3));
})",
                                       b, &status);
  EXPECT_EQ(printed, "10 7.5 1 10\n2 1.5\n");
  EXPECT_EQ(status.splineBasis, 2u);
}

TEST(ArrayTest, LengthsAreIntegerConstantExpressions) {
  // §3 `int-const`: constant arithmetic over int literals, as macros produce it.
  TestBatch b(1);
  const std::string printed = evaluate(R"(
#define KNOTS 4
displacement d(float k[KNOTS * 2 - 1] = {1, 2})
{
    float a[(KNOTS + 2) / 3], c[-(-KNOTS) % 3];
    printf("%d %d %d\n", arraylength(k), arraylength(a), arraylength(c));
})",
                                       b);
  EXPECT_EQ(printed, "7 2 1\n");
}

}  // namespace
}  // namespace relief::compiler
