// JIT tests: bumps.disp against a hand-written C++ version, derivatives (Du/Dv, calculatenormal),
// noise, non-finite results, the loop guard, ShaderLibrary lookup and parameter reflection.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <sstream>
#include <utility>

#include <OpenImageIO/imageio.h>

#include "compiler/compiler.h"
#include "compiler/shader_library.h"
#include "runtime/builtins_noise.h"
#include "runtime/shader.h"
#include "test_batch.h"

namespace relief::compiler {
namespace {

using testing::TestBatch;

constexpr double kPi = 3.14159265358979323846;

std::shared_ptr<const runtime::CompiledShader> compileOne(const std::string& source,
                                                          const std::string& name = "") {
  CompileResult r = compileSource("test.disp", source);
  EXPECT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
  if (!r.success() || r.shaders.empty()) return nullptr;
  return name.empty() ? r.shaders.front() : r.find(name);
}

// The unit sphere P(u, v) = (sinθ cosφ, sinθ sinφ, cosθ), φ = 2πu, θ = πv, with exact seeds.
void fillSphere(TestBatch& b, size_t i, double u, double v) {
  const double phi = 2 * kPi * u, theta = kPi * v;
  const double p[3] = {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
  const double dpdu[3] = {-2 * kPi * std::sin(theta) * std::sin(phi), 2 * kPi * std::sin(theta) * std::cos(phi), 0};
  const double dpdv[3] = {kPi * std::cos(theta) * std::cos(phi), kPi * std::cos(theta) * std::sin(phi),
                          -kPi * std::sin(theta)};
  for (int k = 0; k < 3; ++k) {
    b.P[k][i] = float(p[k]);
    b.N[k][i] = float(p[k]);
    b.Ng[k][i] = float(p[k]);
    b.dPdu[k][i] = float(dpdu[k]);
    b.dPdv[k][i] = float(dpdv[k]);
    b.dNdu[k][i] = float(dpdu[k]);  // N = P on the unit sphere
    b.dNdv[k][i] = float(dpdv[k]);
  }
  b.u[i] = float(u);
  b.v[i] = float(v);
  b.s[i] = float(u);
  b.t[i] = float(v);
  b.dsdu[i] = 1;
  b.dtdv[i] = 1;
  b.du[i] = b.dv[i] = 0.01f;
}

// Evaluates `instance` at one point of the unit sphere, (u, v), into b's first slot.
RlfStatus evaluateAtSpherePoint(const runtime::ShaderInstance& instance, TestBatch& b, double u, double v) {
  fillSphere(b, 0, u, v);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  return status;
}

// Runs `shader` on n points of the sphere at (u, v) = (0.3, 0.4), with u and v themselves
// replaced by uv(i): for tests of derivatives with respect to the parameters.
template <typename UV>
TestBatch evaluateAtUV(const std::shared_ptr<const runtime::CompiledShader>& shader, size_t n, UV uv) {
  runtime::ShaderInstance instance(shader);
  TestBatch b(n);
  for (size_t i = 0; i < n; ++i) {
    fillSphere(b, i, 0.3, 0.4);
    const auto [u, v] = uv(i);
    b.u[i] = float(u);
    b.v[i] = float(v);
  }
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  return b;
}

std::array<double, 3> cross(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
std::array<double, 3> normalized(std::array<double, 3> a) {
  const double l = std::sqrt(dot(a, a));
  return {a[0] / l, a[1] / l, a[2] / l};
}

// hypot as C's: no overflow or underflow in the squares (it was inf at 1e20, 0 at 1e-25).
TEST(JitTest, HypotNeitherOverflowsNorUnderflows) {
  const auto shader = compileOne(
      "displacement d(float a = 1e20, b = 1e-25) { P = point(hypot(a, a), hypot(b, b, b), hypot(3, 4)); }");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(1);
  evaluateAtSpherePoint(instance, b, 0.3, 0.4);
  EXPECT_NEAR(b.Pout[0][0], std::sqrt(2.0) * 1e20, 1e14);
  EXPECT_NEAR(b.Pout[1][0], std::sqrt(3.0) * 1e-25, 1e-31);
  EXPECT_EQ(b.Pout[2][0], 5.0f);
}

// Each link of a long `else if` chain is reached by exactly its own case.
TEST(JitTest, LongElseIfChainTakesItsOwnBranch) {
  std::string source = "displacement d(float k = 0) {\n  float h = -1;\n  if (k == 0) h = 0;\n";
  for (int i = 1; i < 1000; ++i) source += "  else if (k == " + std::to_string(i) + ") h = " + std::to_string(i) + ";\n";
  source += "  else h = 5000;\n  P = point(h, 0, 0);\n}\n";
  const auto shader = compileOne(source);
  ASSERT_TRUE(shader);
  for (float k : {0.0f, 1.0f, 517.0f, 999.0f, 1000.0f}) {
    runtime::ShaderInstance instance(shader);
    std::string error;
    ASSERT_TRUE(instance.bind({"k", runtime::ParamType::Float, {k}, {}}, &error)) << error;
    TestBatch b(1);
    evaluateAtSpherePoint(instance, b, 0.3, 0.4);
    EXPECT_EQ(b.Pout[0][0], k < 1000 ? k : 5000.0f) << k;
  }
}

TEST(JitTest, BumpsMatchesHandWrittenVersion) {
  CompileResult r = compileFile(RELIEF_SOURCE_DIR "/examples/shaders/bumps.disp");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
  auto shader = r.find("bumps");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  const double Km = 0.05, freq = 12;

  constexpr size_t kPoints = 10000;
  TestBatch b(kPoints);
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> uDist(0.0, 1.0), vDist(0.1, 0.9);
  for (size_t i = 0; i < kPoints; ++i) fillSphere(b, i, uDist(rng), vDist(rng));

  RlfStatus status{};
  for (size_t first = 0; first < kPoints; first += 64) {
    RlfShadingBatch view = b.view(first, std::min<size_t>(64, kPoints - first));
    instance.evaluate(view, status);
  }
  EXPECT_EQ(status.nonFinite, 0u);

  double worstP = 0, worstN = 0;
  for (size_t i = 0; i < kPoints; ++i) {
    const double u = b.u[i], v = b.v[i];
    const std::array<double, 3> p{b.P[0][i], b.P[1][i], b.P[2][i]};
    const std::array<double, 3> n = normalized({b.N[0][i], b.N[1][i], b.N[2][i]});
    const std::array<double, 3> dpdu{b.dPdu[0][i], b.dPdu[1][i], b.dPdu[2][i]};
    const std::array<double, 3> dpdv{b.dPdv[0][i], b.dPdv[1][i], b.dPdv[2][i]};
    const double a = freq * 2 * kPi * u, c = freq * kPi * v;
    const double h = Km * std::sin(a) * std::sin(c);
    const double dhdu = Km * freq * 2 * kPi * std::cos(a) * std::sin(c);
    const double dhdv = Km * std::sin(a) * freq * kPi * std::cos(c);
    // d normalize(N)/du = dN/du for a unit N whose derivative is tangent (the sphere).
    std::array<double, 3> Pu, Pv, P;
    for (int k = 0; k < 3; ++k) {
      P[k] = p[k] + h * n[k];
      Pu[k] = dpdu[k] + dhdu * n[k] + h * dpdu[k];
      Pv[k] = dpdv[k] + dhdv * n[k] + h * dpdv[k];
    }
    const double orient = dot(cross(dpdu, dpdv), {b.Ng[0][i], b.Ng[1][i], b.Ng[2][i]}) < 0 ? -1 : 1;
    std::array<double, 3> N = normalized(cross(Pu, Pv));
    for (double& x : N) x *= orient;
    for (int k = 0; k < 3; ++k) {
      worstP = std::max(worstP, std::abs(P[k] - b.Pout[k][i]));
      worstN = std::max(worstN, std::abs(N[k] - b.Nout[k][i]));
    }
  }
  EXPECT_LT(worstP, 1e-5);
  EXPECT_LT(worstN, 1e-5);
}

TEST(JitTest, BatchSizeDoesNotChangeResults) {
  auto shader = compileOne(
      "displacement d(float Km = 0.1) { P += Km * snoise(P * 3) * normalize(N); }");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch a(100), single(100);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> dist(0.05, 0.95);
  for (size_t i = 0; i < 100; ++i) {
    const double u = dist(rng), v = dist(rng);
    fillSphere(a, i, u, v);
    fillSphere(single, i, u, v);
  }
  RlfStatus status{};
  RlfShadingBatch all = a.all();
  instance.evaluate(all, status);
  for (size_t i = 0; i < 100; ++i) {
    RlfShadingBatch one = single.view(i, 1);
    instance.evaluate(one, status);
  }
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(a.Pout[k], single.Pout[k]);  // bit-identical (language.md §7)
    EXPECT_EQ(a.Nout[k], single.Nout[k]);
  }
}

TEST(JitTest, DerivativesOfPolynomialsInUV) {
  // f = u²v + 3u - v³ + 2: Du = 2uv + 3, Dv = u² - 3v². g = u·v·v: Du = v², Dv = 2uv.
  auto shader = compileOne(R"(
displacement d()
{
    float f = u * u * v + 3 * u - v * v * v + 2;
    float g = u * v;
    g *= v;
    P = point(Du(f), Dv(f), Du(g));
    N = normal(Dv(g), Du(u), Dv(u));
})");
  ASSERT_TRUE(shader);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> dist(-2, 2);
  const TestBatch b = evaluateAtUV(shader, 50, [&](size_t) {
    const double u = dist(rng);
    return std::pair{u, dist(rng)};
  });
  for (size_t i = 0; i < 50; ++i) {
    const double u = b.u[i], v = b.v[i];
    EXPECT_NEAR(b.Pout[0][i], 2 * u * v + 3, 1e-4);
    EXPECT_NEAR(b.Pout[1][i], u * u - 3 * v * v, 1e-4);
    EXPECT_NEAR(b.Pout[2][i], v * v, 1e-4);
    EXPECT_NEAR(b.Nout[0][i], 2 * u * v, 1e-4);
    EXPECT_NEAR(b.Nout[1][i], 1, 0);
    EXPECT_NEAR(b.Nout[2][i], 0, 0);
  }
}

// Codegen gives derivative storage only to variables that can receive a non-zero derivative
// (LanePlan, codegen.cpp). Each variable here starts with a uniform value and gets its varying
// one later: in a later loop iteration, through an output parameter, in an array element, and
// through a chain of copies. Their derivatives must survive.
TEST(JitTest, DerivativesReachVariablesThatStartUniform) {
  auto shader = compileOne(R"(
void square(float x; output float r) { r = x * x; }
displacement d(float k = 2)
{
    float a = k, early = 0;
    for (float i = 0; i < 2; i += 1) {
        early = Du(a);
        a = u * u;
    }
    float b = 1;
    square(v, b);
    float arr[2] = {k, k};
    arr[1] = u * v;
    float c1 = k, c2 = c1, c3 = c2;
    c1 = v * 3;
    c2 = c1;
    c3 = c2;
    P = point(early, Dv(b), Du(arr[1]));
    N = normal(Dv(arr[1]), Dv(c3), Du(k));
})");
  ASSERT_TRUE(shader);
  const TestBatch b = evaluateAtUV(shader, 8, [](size_t i) {
    return std::pair{0.1f * float(i) + 0.05f, 0.7f - 0.05f * float(i)};
  });
  for (size_t i = 0; i < 8; ++i) {
    const double u = b.u[i], v = b.v[i];
    EXPECT_NEAR(b.Pout[0][i], 2 * u, 1e-6);
    EXPECT_NEAR(b.Pout[1][i], 2 * v, 1e-6);
    EXPECT_NEAR(b.Pout[2][i], v, 1e-6);
    EXPECT_NEAR(b.Nout[0][i], u, 1e-6);
    EXPECT_NEAR(b.Nout[1][i], 3, 1e-6);
    EXPECT_EQ(b.Nout[2][i], 0);
  }
}

// The lane plan only removes storage that would hold zeros, so every shader of the repository
// (the examples, the spec's examples, the diagnostics cases that compile, and lanes/*.disp,
// written for this) gives the same
// bits with it as with every lane, derivatives included (N comes from calculatenormal).
TEST(JitTest, LanePlanChangesNoResult) {
  std::vector<std::string> files = {RELIEF_TEST_DATA_DIR "/spec/examples.disp"};
  for (const char* dir : {RELIEF_SOURCE_DIR "/examples/shaders", RELIEF_TEST_DATA_DIR "/diagnostics",
                          RELIEF_TEST_DATA_DIR "/lanes"})
    for (const auto& entry : std::filesystem::directory_iterator(dir))
      if (entry.path().extension() == ".disp") files.push_back(entry.path().string());
  std::sort(files.begin(), files.end());
  CompileOptions options;
  options.includeDirs = {RELIEF_TEST_DATA_DIR "/diagnostics"};
  CompileFlags every;
  every.everyDerivativeLane = true;
  size_t compared = 0;
  for (const std::string& file : files) {
    const CompileResult pruned = compileFile(file, options);
    if (!pruned.success()) continue;  // a diagnostics case with errors
    const CompileResult full = compileFile(file, options, every);
    ASSERT_TRUE(full.success()) << file << renderDiagnostics(full) << full.internalError;
    ASSERT_EQ(pruned.shaders.size(), full.shaders.size());
    for (size_t k = 0; k < pruned.shaders.size(); ++k) {
      SCOPED_TRACE(file + ": " + pruned.shaders[k]->name());
      runtime::ShaderInstance a(pruned.shaders[k]), b(full.shaders[k]);
      TestBatch x(48), y(48);
      for (size_t i = 0; i < 48; ++i) {
        const double u = 0.02 + 0.0203 * double(i), v = 0.97 - 0.0191 * double(i);
        fillSphere(x, i, u, v);
        fillSphere(y, i, u, v);
      }
      RlfStatus sa{}, sb{};
      RlfShadingBatch va = x.all(), vb = y.all();
      a.evaluate(va, sa);
      b.evaluate(vb, sb);
      for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < 48; ++i) {
          auto same = [](float p, float q) { return p == q || (std::isnan(p) && std::isnan(q)); };
          EXPECT_TRUE(same(x.Pout[c][i], y.Pout[c][i])) << "P point " << i << ": " << x.Pout[c][i] << " vs " << y.Pout[c][i];
          EXPECT_TRUE(same(x.Nout[c][i], y.Nout[c][i])) << "N point " << i << ": " << x.Nout[c][i] << " vs " << y.Nout[c][i];
        }
      EXPECT_EQ(sa.nonFinite, sb.nonFinite);
      ++compared;
    }
  }
  EXPECT_GE(compared, 20u);
}

// Parameters and constants carry no derivative storage, so the optimised code multiplies nothing
// by a zero derivative (LLVM may not fold 0 * x itself) and normalize() divides once.
TEST(JitTest, UniformDataCostsNoDerivativeArithmetic) {
  CompileFlags flags;
  flags.jit = false;
  flags.emitLlvm = true;
  CompileResult r = compileSource("lanes.disp", R"(
displacement d(float Km = 0.1; float freq = 4)
{
    float f = freq;
    float h = Km * sin(s * f) * f;
    P += h * normalize(N);
})", {}, flags);
  ASSERT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
  std::istringstream ir(r.llvmIr);
  size_t divisions = 0;
  for (std::string line; std::getline(ir, line);) {
    const bool arithmetic = line.find("= fmul") != std::string::npos || line.find("= fadd") != std::string::npos;
    EXPECT_FALSE(arithmetic && line.find(" 0.000000e+00") != std::string::npos) << line;
    divisions += line.find("= fdiv") != std::string::npos;
  }
  // normalize(N) and the final normalize(calculatenormal(P)) divide once each, sqrt's derivative once.
  EXPECT_LE(divisions, 3u) << r.llvmIr;
}

TEST(JitTest, CalculateNormalOfUndisplacedSphereIsItsNormal) {
  auto shader = compileOne("displacement d() { N = normalize(calculatenormal(P)); }");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(200);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> dist(0.05, 0.95);
  for (size_t i = 0; i < 200; ++i) fillSphere(b, i, dist(rng), dist(rng));
  // Flip the parameterization of half the points: the orientation rule must still follow Ng.
  for (size_t i = 0; i < 200; i += 2)
    for (int k = 0; k < 3; ++k) b.dPdu[k][i] = -b.dPdu[k][i];
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  for (size_t i = 0; i < 200; ++i)
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(b.Nout[k][i], b.P[k][i], 1e-5) << "point " << i;
      EXPECT_EQ(b.Pout[k][i], b.P[k][i]);
    }
}

// A sphere 1e9 across has a calculatenormal of 1e19 per component, whose squared length
// overflows a float; one of 1e-25 underflows. normalize() and length() scale such triples first.
TEST(JitTest, NormalizeAndLengthHoldAtAnyScale) {
  auto normal = compileOne("displacement d() { N = normalize(calculatenormal(P)); }");
  auto length = compileOne(
      "displacement d() {\n"
      "  float big = length(P * 1e30) * 1e-30, tiny = length(P * 1e-30) * 1e30;\n"
      "  P += (big - 1) * N + (tiny - 1) * N;\n"
      "}");
  ASSERT_TRUE(normal && length);
  for (float scale : {1.0f, 1e9f, 1e-25f}) {
    SCOPED_TRACE(scale);
    for (bool lengths : {false, true}) {
      if (lengths && scale != 1.0f) continue;
      runtime::ShaderInstance instance(lengths ? length : normal);
      TestBatch b(50);
      for (size_t i = 0; i < 50; ++i) {
        fillSphere(b, i, 0.02 * double(i) + 0.01, 0.35);
        for (int k = 0; k < 3; ++k) b.P[k][i] *= scale, b.dPdu[k][i] *= scale, b.dPdv[k][i] *= scale;
      }
      RlfStatus status{};
      RlfShadingBatch view = b.all();
      instance.evaluate(view, status);
      EXPECT_EQ(status.badNormal, 0u);
      EXPECT_EQ(status.nonFinite, 0u);
      for (size_t i = 0; i < 50; ++i)
        for (int k = 0; k < 3; ++k) {
          EXPECT_NEAR(b.Nout[k][i], b.P[k][i] / scale, 1e-5) << "point " << i;
          if (lengths) {
            EXPECT_NEAR(b.Pout[k][i], b.P[k][i], 1e-5) << "point " << i;
          }
        }
    }
  }
}

TEST(JitTest, HostContractAppendsNormalWhenOnlyPIsAssigned) {
  auto withN = compileOne(
      "displacement d(float Km = 0.05) { P += Km * sin(20 * u) * normalize(N); N = normalize(calculatenormal(P)); }");
  auto withoutN = compileOne("displacement d(float Km = 0.05) { P += Km * sin(20 * u) * normalize(N); }");
  ASSERT_TRUE(withN && withoutN);
  runtime::ShaderInstance a(withN), b(withoutN);
  TestBatch x(20), y(20);
  for (size_t i = 0; i < 20; ++i) {
    fillSphere(x, i, 0.04 * double(i) + 0.01, 0.3);
    fillSphere(y, i, 0.04 * double(i) + 0.01, 0.3);
  }
  RlfStatus status{};
  RlfShadingBatch vx = x.all(), vy = y.all();
  a.evaluate(vx, status);
  b.evaluate(vy, status);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(x.Nout[k], y.Nout[k]);
  // The bumps really tilt the normal, so equality above is not vacuous.
  double tilt = 0;
  for (size_t i = 0; i < 20; ++i)
    for (int k = 0; k < 3; ++k) tilt = std::max(tilt, double(std::abs(y.Nout[k][i] - y.N[k][i])));
  EXPECT_GT(tilt, 0.1);
}

TEST(JitTest, NoiseIsInRangeHalfAtLatticeAndHasExactDerivative) {
  float grad[3];
  for (int channel = 0; channel < 3; ++channel) {
    EXPECT_FLOAT_EQ(rlf_noise3(3, -2, 7, grad, channel), 0.5f);
    EXPECT_FLOAT_EQ(rlf_noise1(-4, grad, channel), 0.5f);
  }
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> dist(-50, 50);
  for (int i = 0; i < 2000; ++i) {
    const float x = dist(rng), y = dist(rng), z = dist(rng);
    const float n = rlf_noise3(x, y, z, grad, 0);
    ASSERT_GE(n, 0.0f);
    ASSERT_LE(n, 1.0f);
    // Central differences in double-spaced steps agree with the analytic gradient.
    const float h = 1e-3f;
    float g2[3];
    const double fd = (double(rlf_noise3(x + h, y, z, g2, 0)) - double(rlf_noise3(x - h, y, z, g2, 0))) / (2 * h);
    EXPECT_NEAR(grad[0], fd, 2e-2) << x << ' ' << y << ' ' << z;
  }
  // Deterministic: same input, same output.
  EXPECT_EQ(rlf_noise3(1.25f, 2.5f, -3.75f, grad, 0), rlf_noise3(1.25f, 2.5f, -3.75f, grad, 0));
}

TEST(JitTest, NoiseDerivativesFlowThroughShaders) {
  auto shader = compileOne(R"(
displacement d()
{
    float n = noise(u * 7.3, v * 5.1);
    P = point(n, Du(n), Dv(n));
})");
  ASSERT_TRUE(shader);
  const TestBatch b = evaluateAtUV(shader, 30, [](size_t i) {
    return std::pair{0.031f * float(i) + 0.01f, 0.027f * float(i) + 0.02f};
  });
  for (size_t i = 0; i < 30; ++i) {
    float g[2];
    const float n = rlf_noise2(b.u[i] * 7.3f, b.v[i] * 5.1f, g, 0);
    EXPECT_FLOAT_EQ(b.Pout[0][i], n);
    EXPECT_NEAR(b.Pout[1][i], 7.3f * g[0], 1e-4);
    EXPECT_NEAR(b.Pout[2][i], 5.1f * g[1], 1e-4);
  }
}

TEST(JitTest, NonFiniteResultKeepsUndisplacedPointAndCounts) {
  auto shader = compileOne("displacement d() { P += exp(1000 * u) * N; }");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(4);
  for (size_t i = 0; i < 4; ++i) fillSphere(b, i, i < 2 ? 0.5 : 0.0, 0.5);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_EQ(status.nonFinite, 2u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(b.Pout[k][0], b.P[k][0]);
    EXPECT_EQ(b.Nout[k][0], b.N[k][0]);
    EXPECT_TRUE(std::isfinite(b.Pout[k][3]));
  }
  EXPECT_NE(b.Pout[2][3], b.P[2][3]);
}

TEST(JitTest, LoopGuardAbortsRunawayLoops) {
  auto shader = compileOne("displacement d() { while (1) { P += 0.001 * N; } }");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(2);
  fillSphere(b, 0, 0.2, 0.3);
  fillSphere(b, 1, 0.4, 0.6);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_EQ(status.loopLimit, 2u);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(b.Pout[k][1], b.P[k][1]);
}

TEST(JitTest, LoopLimitIsConfigurableAndCountsAllLoops) {
  // Two loops of 60 iterations: 120 in all. A limit of 100 aborts (outputs = inputs), 120 does not.
  const char* source = R"(
displacement d()
{
    for (int i = 0; i < 60; ++i) P += 0.001 * N;
    int j = 0;
    while (j < 60) { P += 0.001 * N; j++; }
})";
  for (uint32_t limit : {100u, 120u}) {
    SCOPED_TRACE(limit);
    CompileOptions options;
    options.loopIterationLimit = limit;
    CompileResult r = compileSource("loops.disp", source, options);
    ASSERT_TRUE(r.success()) << renderDiagnostics(r);
    runtime::ShaderInstance instance(r.shaders.front());
    TestBatch b(1);
    fillSphere(b, 0, 0.2, 0.3);
    RlfStatus status{};
    RlfShadingBatch view = b.all();
    instance.evaluate(view, status);
    EXPECT_EQ(status.loopLimit, limit == 100u ? 1u : 0u);
    const float expected = limit == 100u ? b.P[2][0] : b.P[2][0] + 0.12f * b.N[2][0];
    EXPECT_NEAR(b.Pout[2][0], expected, 1e-5);
  }
}

TEST(JitTest, ControlFlowAndIntegerArithmetic) {
  auto shader = compileOne(R"(
displacement d(int n = 5)
{
    int sum = 0;
    for (int i = 0; i < n; i++) {
        if (i == 3) continue;
        sum += i;
    }
    int k = 0;
    while (k < 100) { k++; if (k >= 7) break; }
    float x = 7 / 2;
    float y = 1 / 0;
    int z = -7 % 3;
    P = point(sum, k, x);
    N = normal(y, z, u > 0.5 && v < 0.5 ? 1 : -1);
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(2);
  fillSphere(b, 0, 0.7, 0.2);
  fillSphere(b, 1, 0.2, 0.2);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_EQ(b.Pout[0][0], 0 + 1 + 2 + 4);
  EXPECT_EQ(b.Pout[1][0], 7);
  EXPECT_EQ(b.Pout[2][0], 3);  // int division truncates
  EXPECT_EQ(b.Nout[0][0], 0);  // division by zero yields 0
  EXPECT_EQ(b.Nout[1][0], -1);
  EXPECT_EQ(b.Nout[2][0], 1);
  EXPECT_EQ(b.Nout[2][1], -1);
}

TEST(JitTest, ReflectionReportsParametersAndDefaults) {
  CompileResult r = compileSource("p.disp", R"(
displacement p(float Km = 0.5, freq = Km * 4; point c = point(1, 2, 3), color k = 0.25;
               string name = "hello"; int octaves = 6)
{
    P += Km * freq * (c - P) * octaves + vector(k);
    if (name == "x") P = c;
})");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r);
  auto shader = r.find("p");
  ASSERT_TRUE(shader);
  auto params = shader->params();
  ASSERT_EQ(params.size(), 6u);
  EXPECT_EQ(params[0].name, "Km");
  EXPECT_EQ(params[0].defaultNumbers, std::vector<double>{0.5f});
  EXPECT_EQ(params[1].defaultNumbers, std::vector<double>{2.0f});
  EXPECT_EQ(params[2].type, runtime::ParamType::Point);
  EXPECT_EQ(params[2].defaultNumbers, (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(params[3].type, runtime::ParamType::Color);
  EXPECT_EQ(params[3].defaultNumbers, (std::vector<double>{0.25f, 0.25f, 0.25f}));
  EXPECT_EQ(params[4].type, runtime::ParamType::String);
  EXPECT_EQ(params[4].defaultStrings, std::vector<std::string>{"hello"});
  EXPECT_EQ(params[4].offset % 8, 0u);
  EXPECT_EQ(params[5].type, runtime::ParamType::Int);
  EXPECT_EQ(params[5].defaultNumbers, std::vector<double>{6});

  // Binding a string parameter changes behavior.
  runtime::ShaderInstance instance(shader);
  std::string error;
  ASSERT_TRUE(instance.bind({"name", runtime::ParamType::String, {}, {"x"}}, &error)) << error;
  ASSERT_TRUE(instance.bind({"Km", runtime::ParamType::Float, {0}, {}}, &error)) << error;
  TestBatch b(1);
  fillSphere(b, 0, 0.1, 0.5);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_EQ(b.Pout[0][0], 1);
  EXPECT_EQ(b.Pout[1][0], 2);
  EXPECT_EQ(b.Pout[2][0], 3);
}

// An int parameter holds every 32-bit value, as a default, reflected, and bound (it was kept as a
// float: 123456789 became 123456792 and 2147483647 became -2147483648). The shader's P.x receives
// the difference from the expected value, in ints, so any lost bit shows.
TEST(JitTest, IntParametersKeepAll32Bits) {
  CompileResult r = compileSource("ints.disp", R"(
displacement ints(int seed = 123456789; int big = 2147483647; int a[2] = {16777217, -2147483647})
{
    P = point(seed - 123456789, big - 2147483647, (a[0] - 16777217) + (a[1] + 2147483647));
})");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r);
  auto shader = r.find("ints");
  ASSERT_TRUE(shader);
  EXPECT_EQ(shader->findParam("seed")->defaultNumbers, std::vector<double>{123456789});
  EXPECT_EQ(shader->findParam("big")->defaultNumbers, std::vector<double>{2147483647});
  EXPECT_EQ(shader->findParam("a")->defaultNumbers, (std::vector<double>{16777217, -2147483647}));
  runtime::ShaderInstance defaults(shader);
  TestBatch b(1);
  evaluateAtSpherePoint(defaults, b, 0.1, 0.5);
  EXPECT_EQ(b.Pout[0][0], 0);
  EXPECT_EQ(b.Pout[1][0], 0);
  EXPECT_EQ(b.Pout[2][0], 0);
  // Bound: the same values as the defaults' plus one, and a value beyond int32 saturates.
  runtime::ShaderInstance bound(shader);
  std::string error;
  ASSERT_TRUE(bound.bind({"seed", runtime::ParamType::Int, {123456790}, {}}, &error)) << error;
  ASSERT_TRUE(bound.bind({"big", runtime::ParamType::Float, {3e10}, {}}, &error)) << error;
  ASSERT_TRUE(bound.bind({"a", runtime::ParamType::Int, {16777218, -2147483646}, {}}, &error)) << error;
  evaluateAtSpherePoint(bound, b, 0.1, 0.5);
  EXPECT_EQ(b.Pout[0][0], 1);
  EXPECT_EQ(b.Pout[1][0], 0);
  EXPECT_EQ(b.Pout[2][0], 2);
}

// PI is a constant, so a default that uses only it is not evaluated again at shading time: the
// defaults function must give it its value (it once read an uninitialised slot: 0, or NaN).
TEST(JitTest, PiInDefaultsIsPi) {
  CompileResult r = compileSource("pi.disp", R"(
displacement pi(float h = 2 * PI; float g = degrees(PI); point q = point(PI, 0, 0); float a[2] = {PI, 1})
{
    P += N * (h + g + xcomp(q) + a[0]);
})");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r);
  auto shader = r.find("pi");
  ASSERT_TRUE(shader);
  auto params = shader->params();
  ASSERT_EQ(params.size(), 4u);
  EXPECT_NEAR(params[0].defaultNumbers.at(0), 2 * kPi, 1e-5);
  EXPECT_NEAR(params[1].defaultNumbers.at(0), 180.0, 1e-4);
  EXPECT_NEAR(params[2].defaultNumbers.at(0), kPi, 1e-6);
  EXPECT_NEAR(params[3].defaultNumbers.at(0), kPi, 1e-6);
  runtime::ShaderInstance instance(shader);
  TestBatch b(1);
  evaluateAtSpherePoint(instance, b, 0.0, 0.0);
  EXPECT_NEAR(b.Pout[2][0], 1 + 4 * kPi + 180.0, 1e-3);
}

TEST(JitTest, DefinesReplaceIdentifiers) {
  CompileOptions options;
  options.defines = {{"AMOUNT", "0.5"}};
  CompileResult r = compileSource("d.disp", "displacement d() { P += AMOUNT * M_PI * N; }", options);
  ASSERT_TRUE(r.success()) << renderDiagnostics(r);
  runtime::ShaderInstance instance(r.shaders.front());
  TestBatch b(1);
  fillSphere(b, 0, 0.0, 0.0);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_NEAR(b.Pout[2][0], 1 + 0.5 * kPi, 1e-6);
}

TEST(JitTest, UserFunctionsAreInlinedWithOverloadsOutputsAndExtern) {
  auto shader = compileOne(R"(
float sq(float x) { return x * x; }
float sq2(float x) { return sq(x) * 2; }
vector sq(vector x) { return x * x; }
void bump(output point q; float amount) { q += amount * N; }
float firstPositive(float a, float b) { if (a > 0) return a; return b; }

displacement f(float Km = 0.5)
{
    float twice(float y) { extern float Km; return 2 * y * Km; }
    point q = P;
    bump(q, sq(2) + sq2(1));
    P = q + vector(twice(1), sq(sq(3)), firstPositive(-1, 7)) + sq(vector(1, 2, 3));
    N = normal(sq(u), Du(sq(u)), 0);
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(1);
  fillSphere(b, 0, 0.25, 0.0);  // P = N = (0, 0, 1)
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_FLOAT_EQ(b.Pout[0][0], 1 + 1);       // twice(1) = 2 * 0.5, plus 1²
  EXPECT_FLOAT_EQ(b.Pout[1][0], 81 + 4);      // sq(sq(3)) plus 2²
  EXPECT_FLOAT_EQ(b.Pout[2][0], 7 + 7 + 9);   // q.z = 1 + 6, firstPositive, 3²
  EXPECT_FLOAT_EQ(b.Nout[0][0], 0.0625f);
  EXPECT_FLOAT_EQ(b.Nout[1][0], 0.5f);        // derivatives flow through inlined calls
}

// Long arrays are zeroed, copied and loaded from the parameter block by loops, not element by
// element (a 16384-element copy once took minutes to optimise); the values are the same.
TEST(JitTest, LongArraysCopyAndLoadTheirParameters) {
  auto shader = compileOne(R"(
float at(float x[]; float i) { return x[int(i)]; }
displacement big(float k[20000] = {3, 4}; point corners[40] = {point(1, 2, 3)})
{
    float a[20000], b[20000];
    string names[30];
    a[int(u * 10)] = u;
    b = a;
    a = k;
    P += N * (b[3] + a[1] + a[19999] + at(b, 3) + arraylength(b) + ycomp(corners[0]) + ycomp(corners[39]));
    if (names[29] != "") P = 0;
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(1);
  evaluateAtSpherePoint(instance, b, 0.35, 0.0);  // u = 0.35: a[3] = u
  EXPECT_NEAR(b.Pout[2][0], 1 + 0.35 + 4 + 0 + 0.35 + 20000 + 2 + 0, 1e-2);
}

// A long initializer of numbers is a table: copied from constant data in one go (element by
// element, 8,000 of them took the optimiser 7 s), with the same values: signs, ints converted,
// tuples for colours, short lists zero-filled. Lists with a variable in them are stored in order.
TEST(JitTest, LongLiteralInitializersAreTablesWithTheSameValues) {
  std::string table = "{";
  for (int i = 0; i < 5000; ++i) table += (i ? ", " : "") + std::to_string(i % 7 == 0 ? -i : i) + (i % 2 ? ".5" : "");
  table += "}";
  auto shader = compileOne(R"(
displacement tables(float k = 2)
{
    float a[6000] = )" + table + R"(;
    color c[20] = {(1, 2, 3), 4, (5, 6, 7), -8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, (0.5, 0.25, 0.125)};
    int n[18] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, -17};
    float v[17] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, k, u};
    P = point(a[7] + a[4999] + a[5000], comp(c[0], 1) + comp(c[3], 2) + comp(c[16], 2) + comp(c[19], 0),
              n[16] + n[17] + v[15] + v[16]);
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(1);
  evaluateAtSpherePoint(instance, b, 0.25, 0.0);
  EXPECT_FLOAT_EQ(b.Pout[0][0], -7.5f + 4999.5f + 0);
  EXPECT_FLOAT_EQ(b.Pout[1][0], 2 - 8 + 0.125f + 0);
  EXPECT_FLOAT_EQ(b.Pout[2][0], -17 + 0 + 2 + 0.25f);
}

// §2.1: an array of any length may be passed to an unsized `T a[]` parameter, `output` ones
// included. §6: among candidates needing only int->float conversions, the fewest wins.
TEST(JitTest, UnsizedOutputArraysAndFewestIntToFloatConversions) {
  auto shader = compileOne(R"(
void fill(output float a[]; float last) { a[0] = 1; a[arraylength(a) - 1] = last; }
float pick(float a, float b) { return 10 + 0 * (a + b); }
float pick(int a, float b) { return 20 + 0 * (a + b); }
float pick3(float a, float b, float c) { return 100 + 0 * (a + b + c); }
float pick3(int a, int b, float c) { return 200 + 0 * (a + b + c); }
displacement d()
{
    float c[3], e[5];
    c[1] = 5;
    fill(c, 7);
    fill(e, 9);
    P = point(c[0] + c[1] + c[2] + e[4], pick(1, 2) + pick3(1, 2, 3), pick(1.0, 2));
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(1);
  evaluateAtSpherePoint(instance, b, 0.25, 0.0);
  EXPECT_FLOAT_EQ(b.Pout[0][0], 1 + 5 + 7 + 9);
  EXPECT_FLOAT_EQ(b.Pout[1][0], 20 + 200);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 10);  // pick(1.0, 2): float->int is no candidate's
}

TEST(JitTest, FunctionWritingPTriggersTheHostContract) {
  auto shader = compileOne(R"(
void push(float h) { P += h * N; }
displacement d() { push(0.1 * sin(10 * u)); })");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(8);
  for (size_t i = 0; i < 8; ++i) fillSphere(b, i, 0.1 * double(i) + 0.05, 0.4);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  double tilt = 0;
  for (size_t i = 0; i < 8; ++i)
    for (int k = 0; k < 3; ++k) tilt = std::max(tilt, double(std::abs(b.Nout[k][i] - b.N[k][i])));
  EXPECT_GT(tilt, 0.05);  // N was recomputed from the displaced P
}

TEST(JitTest, ComponentSettersDerivRotateDistanceAndRandom) {
  auto shader = compileOne(R"(
displacement b1()
{
    vector w = vector(1, 2, 3);
    setycomp(w, 5);
    setcomp(w, 2, comp(w, 0) + 10);
    float r1 = random();
    float r2 = random();
    float dd = Deriv(u * u * 3, u);
    point q = rotate(point(1, 0, 0), PI / 2, point(0, 0, 0), point(0, 0, 1));
    P = point(w) + vector(q) * 100;
    N = normal(dd, distance(point(0,0,0), point(2,0,0), point(1,1,0)), r1 != r2 && r1 >= 0 && r1 < 1);
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(2);
  fillSphere(b, 0, 0.5, 0.3);
  fillSphere(b, 1, 0.5, 0.3);  // identical inputs: identical random numbers (purity, §7)
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_NEAR(b.Pout[0][0], 1, 1e-5);
  EXPECT_NEAR(b.Pout[1][0], 105, 1e-4);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 11);
  EXPECT_NEAR(b.Nout[0][0], 3, 1e-5);  // Deriv(3u², u) = 6u
  EXPECT_FLOAT_EQ(b.Nout[1][0], 1);
  EXPECT_FLOAT_EQ(b.Nout[2][0], 1);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(b.Pout[k][0], b.Pout[k][1]);
}

TEST(JitTest, ArraysLocalsParametersAndFunctionArguments) {
  CompileResult r = compileSource("arr.disp", R"(
float total(float a[]) { float sum = 0; for (int i = 0; i < arraylength(a); i++) sum += a[i]; return sum; }
void twice(output float a[4]) { for (int i = 0; i < 4; i++) a[i] *= 2; }
displacement arr(float k[4] = {1, 2, 3}; point corners[2] = {point(1, 2, 3), 4}; int idx = 5)
{
    float local[4] = k;
    local[3] = 10;
    twice(local);
    vector vs[3];
    vs[1] = vector(1, 2, 3);
    vs[1][2] = 7;
    float clamped = k[idx];
    P = point(total(local), vs[1][2] + vs[0][0], clamped) + vector(corners[1]);
    N = normal(local[0], arraylength(k), u * 0);
})");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r);
  auto shader = r.find("arr");
  const runtime::ParamInfo* k = shader->findParam("k");
  ASSERT_TRUE(k);
  EXPECT_EQ(k->arrayLength, 4);
  EXPECT_EQ(k->defaultNumbers, (std::vector<double>{1, 2, 3, 0}));
  EXPECT_EQ(shader->findParam("corners")->defaultNumbers, (std::vector<double>{1, 2, 3, 4, 4, 4}));
  runtime::ShaderInstance instance(shader);
  TestBatch b(1);
  fillSphere(b, 0, 0.3, 0.3);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_FLOAT_EQ(b.Pout[0][0], 2 + 4 + 6 + 20 + 4);
  EXPECT_FLOAT_EQ(b.Pout[1][0], 7 + 4);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 0 + 4);  // k[5] clamps to k[3]
  EXPECT_FLOAT_EQ(b.Nout[0][0], 2);
  EXPECT_FLOAT_EQ(b.Nout[1][0], 4);
  EXPECT_EQ(status.indexClamped, 1u);

  // Scene values bind whole arrays.
  std::string error;
  ASSERT_TRUE(instance.bind({"k", runtime::ParamType::Float, {5, 6, 7, 8}, {}}, &error)) << error;
  instance.evaluate(view, status);
  EXPECT_FLOAT_EQ(b.Nout[0][0], 10);
}

TEST(JitTest, PeriodicNoiseRepeatsWithItsPeriod) {
  auto shader = compileOne(R"(
displacement pn()
{
    float a = pnoise(u * 8, 4);
    float b = pnoise(u * 8 + 4, 4);
    vector c = psnoise(P * 3, point(2, 2, 2));
    vector d = psnoise((P + vector(2/3.0, 0, -2/3.0)) * 3, point(2, 2, 2));
    P = point(a, b, length(c - d));
    N = normal(Du(a), Du(b), length(c));
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(16);
  for (size_t i = 0; i < 16; ++i) fillSphere(b, i, 0.06 * double(i) + 0.01, 0.37);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  for (size_t i = 0; i < 16; ++i) {
    EXPECT_NEAR(b.Pout[0][i], b.Pout[1][i], 1e-5);
    EXPECT_NEAR(b.Pout[2][i], 0, 1e-4);
    EXPECT_NEAR(b.Nout[0][i], b.Nout[1][i], 1e-3);
    EXPECT_GT(b.Nout[2][i], 0);  // not trivially zero
  }
}

TEST(JitTest, SplinesInterpolateKnotsWithDerivatives) {
  auto shader = compileOne(R"(
displacement sp()
{
    float k[5] = {0, 0, 1, 2, 2};
    float a = spline(u, 0, 0, 1, 2, 2);
    float b = spline("linear", u, 9, 0, 10, 20, 9);
    float c = spline(u, k);
    color d = spline("bezier", u, color(0), color(1), color(2), color(3));
    P = point(a, b, c);
    N = normal(d) + normal(Du(a), 0, 0);
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(2);
  fillSphere(b, 0, 0.25, 0.5);
  fillSphere(b, 1, 0.5, 0.5);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  // Catmull-Rom over (0, 0, 1, 2) at t = 0.5, and its derivative 1.125 per t (2 spans per u).
  EXPECT_FLOAT_EQ(b.Pout[0][0], 0.4375f);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 0.4375f);
  EXPECT_FLOAT_EQ(b.Pout[1][0], 5);
  EXPECT_FLOAT_EQ(b.Nout[1][0], 0.75f);
  EXPECT_FLOAT_EQ(b.Nout[0][0], 0.75f + 2.25f);
  EXPECT_FLOAT_EQ(b.Pout[0][1], 1);
  EXPECT_FLOAT_EQ(b.Pout[1][1], 10);
}

TEST(JitTest, PrintfFormatsThroughHostServices) {
  auto shader = compileOne(R"(
displacement pf(string name = "bumps"; int n = 3)
{
    printf("%s: n=%d u=%.2f P=%g [%5.1f%%]\n", name, n, u, P, 12.345);
    P += 0.01 * N;
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(2);
  fillSphere(b, 0, 0.5, 0.0);
  fillSphere(b, 1, 0.25, 0.0);
  for (size_t i = 0; i < 2; ++i) b.P[0][i] = b.P[1][i] = 0.0f;  // the pole, without negative zeros
  std::string printed;
  RlfHostServices services{};
  services.context = &printed;
  services.print = [](void* context, const char* text) { *static_cast<std::string*>(context) += text; };
  RlfShadingBatch view = b.all();
  view.services = &services;
  RlfStatus status{};
  instance.evaluate(view, status);
  EXPECT_EQ(printed, "bumps: n=3 u=0.50 P=0 0 1 [ 12.3%]\nbumps: n=3 u=0.25 P=0 0 1 [ 12.3%]\n");
  // Without services the message is dropped and results are unaffected.
  view.services = nullptr;
  instance.evaluate(view, status);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 1.01f);
}

TEST(JitTest, EveryExampleShaderCompilesAndEvaluatesFinite) {
  int numFiles = 0;
  for (const auto& entry : std::filesystem::directory_iterator(RELIEF_SOURCE_DIR "/examples/shaders")) {
    if (entry.path().extension() != ".disp") continue;
    ++numFiles;
    SCOPED_TRACE(entry.path().filename().string());
    CompileResult r = compileFile(entry.path().string());
    ASSERT_TRUE(r.success()) << renderDiagnostics(r) << r.internalError;
    for (const auto& shader : r.shaders) {
      runtime::ShaderInstance instance(shader);
      TestBatch b(64);
      for (size_t i = 0; i < 64; ++i) fillSphere(b, i, 0.013 * double(i) + 0.05, 0.011 * double(i) + 0.1);
      RlfStatus status{};
      RlfShadingBatch view = b.all();
      instance.evaluate(view, status);
      EXPECT_EQ(status.nonFinite, 0u);
      EXPECT_EQ(status.loopLimit, 0u);
      for (size_t i = 0; i < 64; ++i) {
        const double len = std::sqrt(double(b.Nout[0][i]) * b.Nout[0][i] + double(b.Nout[1][i]) * b.Nout[1][i] +
                                     double(b.Nout[2][i]) * b.Nout[2][i]);
        EXPECT_NEAR(len, 1.0, 1e-4) << "point " << i;
        // Displacement stays small for these shaders on the unit sphere.
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(b.Pout[k][i], b.P[k][i], 0.5);
      }
    }
  }
  EXPECT_GE(numFiles, 6);
}

TEST(JitTest, TransformsUseTheBatchSpaces) {
  auto shader = compileOne(R"(
displacement d()
{
    point o = transform("object", P);
    vector w = vtransform("object", vector(1, 0, 0));
    P = o + w;
    N = point "object" (0, 0, 0);
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(1);
  fillSphere(b, 0, 0.0, 0.0);  // P = (0, 0, 1)
  // object = current scaled by 2 and moved by (10, 0, 0): p_current = p_object * 2 + (10, 0, 0).
  float* cfo = b.spaces.currentFromObject;
  float* ofc = b.spaces.objectFromCurrent;
  for (int i = 0; i < 16; ++i) cfo[i] = ofc[i] = 0;
  cfo[0] = cfo[5] = cfo[10] = 2, cfo[15] = 1, cfo[12] = 10;
  ofc[0] = ofc[5] = ofc[10] = 0.5f, ofc[15] = 1, ofc[12] = -5;
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_FLOAT_EQ(b.Pout[0][0], -5 + 0.5f);  // object-space P plus the object-space x axis
  EXPECT_FLOAT_EQ(b.Pout[1][0], 0);
  EXPECT_FLOAT_EQ(b.Pout[2][0], 0.5f);
  EXPECT_FLOAT_EQ(b.Nout[0][0], 10);  // the object origin in current space
  EXPECT_FLOAT_EQ(b.Nout[2][0], 0);
}

// Writes `pixels` (of type `given`) as the image `spec` describes, in the test's temporary
// directory; returns its path.
std::string writeImage(const std::string& name, const OIIO::ImageSpec& spec, OIIO::TypeDesc given,
                       const void* pixels) {
  const std::string path = ::testing::TempDir() + "/" + name;
  auto out = OIIO::ImageOutput::create(path);
  EXPECT_TRUE(out);
  if (!out) return path;
  EXPECT_TRUE(out->open(path, spec));
  EXPECT_TRUE(out->write_image(given, pixels));
  out->close();
  return path;
}

// Writes a constant 4x4 float image of `value.size()` channels.
std::string writeConstantImage(const std::string& name, const std::vector<float>& value) {
  std::vector<float> pixels;
  for (int i = 0; i < 16; ++i) pixels.insert(pixels.end(), value.begin(), value.end());
  return writeImage(name, OIIO::ImageSpec(4, 4, int(value.size()), OIIO::TypeDesc::FLOAT), OIIO::TypeDesc::FLOAT,
                    pixels.data());
}

TEST(JitTest, TextureLookupsReadFilesAndReportMissingOnes) {
  const std::string gray = writeConstantImage("relief_gray.exr", {0.75f});
  const std::string rgb = writeConstantImage("relief_rgb.exr", {0.1f, 0.2f, 0.3f});
  CompileResult r = compileSource("tex.disp", R"(
displacement tex(string a = ""; string b = ""; string missing = "/no/such/texture.exr"; float ch = 1.5)
{
    float h = texture(a, s, t, "blur", 0.01, "wrap", "periodic");
    color c = texture(b, "wrap", "clamp");
    color m = texture(missing, 0.5, 0.5, "missingcolor", color(7, 8, 9));
    float f = texture(missing, "fill", 0.25);
    float g = texture(b[2], s, t, "wrap", "clamp");  // RSL channel selection
    float gf = texture(b[ch], s, t, "wrap", "clamp");  // ... by a float, as RSL shaders write it
    P = point(h, f, m[2]) + point(0, 1000 * gf, 0);
    N = normal(c) + normal(0, 0, 100 * g);
})");
  ASSERT_TRUE(r.success()) << renderDiagnostics(r);
  runtime::ShaderInstance instance(r.shaders.front());
  std::string error;
  ASSERT_TRUE(instance.bind({"a", runtime::ParamType::String, {}, {gray}}, &error)) << error;
  ASSERT_TRUE(instance.bind({"b", runtime::ParamType::String, {}, {rgb}}, &error)) << error;
  TestBatch b(2);
  fillSphere(b, 0, 0.3, 0.4);
  fillSphere(b, 1, 0.6, 0.7);
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_NEAR(b.Pout[0][i], 0.75f, 1e-4);
    EXPECT_NEAR(b.Pout[1][i], 0.25f + 1000 * 0.2f, 0.1f);  // fill of the missing file + channel int(1.5)
    EXPECT_FLOAT_EQ(b.Pout[2][i], 9);      // missingcolor
    EXPECT_NEAR(b.Nout[0][i], 0.1f, 1e-4);
    EXPECT_NEAR(b.Nout[1][i], 0.2f, 1e-4);
    EXPECT_NEAR(b.Nout[2][i], 0.3f + 100 * 0.3f, 1e-2);
  }
  EXPECT_EQ(status.textureErrors, 2u);  // one failing lookup per point; "missingcolor" is silent
}

// A lookup without footprint ("width" 0, or s and t that do not vary) is a point sample: a texel's
// centre gives the texel, a boundary between equal texels gives them (OpenImageIO's default
// B-spline magnification blurred 1 into 0.69 there); with a footprint, filtering is as before.
TEST(JitTest, TextureWithoutFootprintSamplesTexelsExactly) {
  std::vector<float> pixels(16, 0.5f);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 2; ++x) pixels[size_t(4 * y + x)] = 1.0f;  // a white 2x2 block, top left
  const std::string path = writeImage("relief_block.exr", OIIO::ImageSpec(4, 4, 1, OIIO::TypeDesc::FLOAT),
                                      OIIO::TypeDesc::FLOAT, pixels.data());
  const auto shader = compileOne(R"(
displacement d(string file = ""; float ss = 0.125, tt = 0.125)
{
    float a = texture(file, s, t, "width", 0);
    float b = texture(file, ss, tt);
    float c = texture(file, s, t);
    P = point(a, b, c);
})");
  ASSERT_TRUE(shader);
  struct Case {
    float s, t, inside;
  };
  for (const Case& c : {Case{0.125f, 0.125f, 1.0f}, Case{0.25f, 0.25f, 1.0f}, Case{0.625f, 0.375f, 0.5f}}) {
    const struct {
      float x, y;
    } st{c.s, c.t};
    const float inside = c.inside;
    runtime::ShaderInstance instance(shader);
    std::string error;
    ASSERT_TRUE(instance.bind({"file", runtime::ParamType::String, {}, {path}}, &error)) << error;
    ASSERT_TRUE(instance.bind({"ss", runtime::ParamType::Float, {st.x}, {}}, &error)) << error;
    ASSERT_TRUE(instance.bind({"tt", runtime::ParamType::Float, {st.y}, {}}, &error)) << error;
    TestBatch b(1);
    fillSphere(b, 0, 0.3, 0.4);
    b.s[0] = st.x, b.t[0] = st.y;
    b.du[0] = b.dv[0] = 0.05f;
    RlfStatus status{};
    RlfShadingBatch view = b.all();
    instance.evaluate(view, status);
    EXPECT_FLOAT_EQ(b.Pout[0][0], inside) << st.x << " " << st.y;
    EXPECT_FLOAT_EQ(b.Pout[1][0], inside) << st.x << " " << st.y;
    if (inside == 1.0f && st.x == 0.125f) {
      EXPECT_LT(b.Pout[2][0], 1.0f);  // a footprint filters
    }
    EXPECT_EQ(status.textureErrors, 0u);
  }
}

// A channel the file does not have is the fill value (language.md 6.7), also as the first
// channel: OpenImageIO asserted there (and read out of bounds) when minifying. So is a negative
// channel computed at run time (it read the texel before, or crashed; a constant one is a compile
// error).
TEST(JitTest, TextureChannelsBeyondTheFileAreTheFill) {
  const std::vector<float> pixels(64 * 64, 0.75f);
  OIIO::ImageSpec spec(64, 64, 1, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "Linear");
  const std::string path = writeImage("relief_gray64.tif", spec, OIIO::TypeDesc::FLOAT, pixels.data());
  const auto shader = compileOne(R"(
displacement d(string file = ""; float ch = -3)
{
    float a = texture(file[1], s, t) + texture(file[ch], s, t, "fill", 0.125);
    float b = texture(file, s, t, "firstchannel", 2, "fill", 0.5);
    color c = texture(file, s, t, "firstchannel", 1, "fill", 0.25);
    float g = texture(file[0], s, t, "wrap", "clamp");
    P = point(a, b, g);
    N = normal(c);
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  std::string error;
  ASSERT_TRUE(instance.bind({"file", runtime::ParamType::String, {}, {path}}, &error)) << error;
  TestBatch b(3);
  fillSphere(b, 0, 0.3, 0.4);
  fillSphere(b, 1, 0.6, 0.7);
  fillSphere(b, 2, 0.999, 0.999);  // the last texel of the last tile
  for (size_t i = 0; i < 3; ++i) b.du[i] = b.dv[i] = 0.3f;  // a footprint of many texels: minified
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(b.Pout[0][i], 0.125f);
    EXPECT_EQ(b.Pout[1][i], 0.5f);
    EXPECT_NEAR(b.Pout[2][i], 0.75f, 0.003f);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(b.Nout[k][i], 0.25f);
  }
  EXPECT_EQ(status.textureErrors, 0u);
}

// Texture channels are data: an RGBA file's colour is read as stored, not multiplied by alpha.
TEST(JitTest, TextureColourIsNotMultipliedByAlpha) {
  std::vector<uint8_t> pixels;
  for (int i = 0; i < 16; ++i) pixels.insert(pixels.end(), {255, 200, 100, 128});
  OIIO::ImageSpec spec(4, 4, 4, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:UnassociatedAlpha", 1);  // the bytes as given, not divided by alpha
  const std::string path = writeImage("relief_rgba.png", spec, OIIO::TypeDesc::UINT8, pixels.data());
  const auto shader = compileOne(R"(
displacement d(string file = "")
{
    color c = texture(file, 0.5, 0.5);
    P = point(comp(c, 0), comp(c, 1), float texture(file[3], 0.5, 0.5));
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  std::string error;
  ASSERT_TRUE(instance.bind({"file", runtime::ParamType::String, {}, {path}}, &error)) << error;
  TestBatch b(1);
  evaluateAtSpherePoint(instance, b, 0.3, 0.4);
  EXPECT_NEAR(b.Pout[0][0], 1.0f, 1e-3f);
  EXPECT_NEAR(b.Pout[1][0], 200.0f / 255, 1e-3f);
  EXPECT_NEAR(b.Pout[2][0], 128.0f / 255, 1e-3f);
}

TEST(JitTest, SpaceNamesMayBeRunTimeStrings) {
  auto shader = compileOne(R"(
displacement d(string space = "object")
{
    point o = transform(space, P);
    P = o + vector(space, 1, 0, 0);
})");
  ASSERT_TRUE(shader);
  runtime::ShaderInstance instance(shader);
  TestBatch b(1);
  fillSphere(b, 0, 0.0, 0.0);  // P = (0, 0, 1)
  float* cfo = b.spaces.currentFromObject;
  float* ofc = b.spaces.objectFromCurrent;
  for (int i = 0; i < 16; ++i) cfo[i] = ofc[i] = 0;
  cfo[0] = cfo[5] = cfo[10] = 2, cfo[15] = 1, cfo[12] = 10;
  ofc[0] = ofc[5] = ofc[10] = 0.5f, ofc[15] = 1, ofc[12] = -5;
  RlfStatus status{};
  RlfShadingBatch view = b.all();
  instance.evaluate(view, status);
  EXPECT_FLOAT_EQ(b.Pout[0][0], -5 + 2);  // object-space P plus the object x axis in current space
  EXPECT_FLOAT_EQ(b.Pout[2][0], 0.5f);
  EXPECT_EQ(status.unknownSpace, 0u);

  std::string error;
  ASSERT_TRUE(instance.bind({"space", runtime::ParamType::String, {}, {"nowhere"}}, &error)) << error;
  instance.evaluate(view, status);
  EXPECT_FLOAT_EQ(b.Pout[0][0], 1);  // identity
  EXPECT_FLOAT_EQ(b.Pout[2][0], 1);
  EXPECT_EQ(status.unknownSpace, 2u);  // two lookups of an unknown name
}

TEST(ShaderLibraryTest, FindsCompilesAndCaches) {
  std::ostringstream diagnostics;
  ShaderLibrary library({}, &diagnostics);
  const std::vector<std::string> path = {RELIEF_SOURCE_DIR "/does/not/exist", RELIEF_SOURCE_DIR "/examples/shaders"};
  std::string error;
  auto a = library.find("bumps", path, &error);
  ASSERT_TRUE(a) << error;
  EXPECT_EQ(a->name(), "bumps");
  ASSERT_TRUE(a->findParam("Km"));
  EXPECT_EQ(a->findParam("Km")->defaultNumbers, std::vector<double>{0.05f});
  EXPECT_EQ(library.find("bumps", path, &error), a);  // cached
  EXPECT_FALSE(library.find("nosuchshader", path, &error));
  EXPECT_NE(error.find("nosuchshader"), std::string::npos);
  EXPECT_TRUE(diagnostics.str().empty()) << diagnostics.str();

  // A name with a directory or the extension is a path (RenderMan's convention), relative to the
  // search directories or absolute; the shader is the file's stem.
  const std::vector<std::string> root = {RELIEF_SOURCE_DIR};
  auto relative = library.find("examples/shaders/bumps", root, &error);
  ASSERT_TRUE(relative) << error;
  EXPECT_EQ(relative->name(), "bumps");
  auto absolute = library.find(RELIEF_SOURCE_DIR "/examples/shaders/bumps.disp", {}, &error);
  ASSERT_TRUE(absolute) << error;
  EXPECT_EQ(absolute->name(), "bumps");
  EXPECT_TRUE(library.find("bumps.disp", path, &error));
  EXPECT_FALSE(library.find("/no/such/stone.disp", path, &error));
  EXPECT_EQ(error, "shader '/no/such/stone.disp' not found: no file '/no/such/stone.disp'");
}

TEST(ShaderLibraryTest, ReportsCompileErrorsToTheStream) {
  const std::string dir = ::testing::TempDir() + "/relief_shaderlib";
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/broken.disp") << "displacement broken() { P += Kn; }\n";
  std::ostringstream diagnostics;
  ShaderLibrary library({}, &diagnostics);
  std::string error;
  EXPECT_FALSE(library.find("broken", std::vector<std::string>{dir}, &error));
  EXPECT_NE(error.find("failed to compile"), std::string::npos);
  EXPECT_NE(diagnostics.str().find("broken.disp:1:30: error: use of undeclared identifier 'Kn'"), std::string::npos)
      << diagnostics.str();
}

}  // namespace
}  // namespace relief::compiler
