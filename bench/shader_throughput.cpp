// Shader benchmarks: points per second of the JIT-compiled §9 example shaders (all seven) through the batch ABI,
// against the same formulas hand-written in C++ (with the derivative work the shader implies), and
// the parse+check+codegen+JIT latency of each shader at -O2, and the noise's two implementations. Targets: JIT throughput within 1.25x of
// C++; compile latency under 30 ms (docs/performance.md).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "compiler/compiler.h"
#include "runtime/abi.h"
#include <OpenImageIO/imageio.h>

#include "runtime/builtins_noise.h"
#include "runtime/builtins_texture.h"
#include "runtime/shader.h"

namespace relief::bench {
namespace {

constexpr float kPi = 3.14159265358979f;
// Every benchmark shades the same pool of points; batch size only changes how it is sliced.
constexpr uint32_t kPoolSize = 4096;

// Forward-mode dual number in (u, v), the hand-written mirror of what the compiler generates.
struct D {
  float v, du, dv;
};
inline D operator+(D a, D b) { return {a.v + b.v, a.du + b.du, a.dv + b.dv}; }
inline D operator-(D a, D b) { return {a.v - b.v, a.du - b.du, a.dv - b.dv}; }
inline D operator*(D a, D b) { return {a.v * b.v, a.du * b.v + a.v * b.du, a.dv * b.v + a.v * b.dv}; }
inline D operator*(D a, float k) { return {a.v * k, a.du * k, a.dv * k}; }
inline D dsqrt(D a) {
  const float r = a.v > 0 ? std::sqrt(a.v) : 0.0f;
  const float k = r > 0 ? 0.5f / r : 0.0f;
  return {r, a.du * k, a.dv * k};
}
inline D dinv(D a) {
  if (a.v == 0) return {0, 0, 0};
  const float r = 1.0f / a.v;
  return {r, -a.du * r * r, -a.dv * r * r};
}
struct V3 {
  D x, y, z;
};
inline V3 operator+(const V3& a, const V3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator-(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator*(const V3& a, D k) { return {a.x * k, a.y * k, a.z * k}; }
inline D dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 normalize(const V3& a) { return a * dinv(dsqrt(dot(a, a))); }
inline float length3(float x, float y, float z) { return std::sqrt(x * x + y * y + z * z); }

// Row vector times a row-major 4x4 matrix: points (w = 1) and vectors (w = 0).
inline V3 xformPoint(const V3& p, const float* m) {
  auto c = [&](int j) { return p.x * m[j] + p.y * m[4 + j] + p.z * m[8 + j] + D{m[12 + j], 0, 0}; };
  return {c(0), c(1), c(2)};
}
// Normals go by the inverse transpose: n' = n * transpose(inverse(M)), `inv` = inverse(M).
inline V3 xformNormal(const V3& n, const float* inv) {
  auto c = [&](int j) { return n.x * inv[j * 4] + n.y * inv[j * 4 + 1] + n.z * inv[j * 4 + 2]; };
  return {c(0), c(1), c(2)};
}

// The batch's globals at point i, seeded as the compiled entry seeds them (language.md §6.4).
struct Globals {
  V3 P, N;
  D u, v, s, t;
  float du, dv;
  float orientation;  // calculatenormal's sign: undisplaced dPdu ^ dPdv faces like Ng
};
inline Globals load(const RlfShadingBatch& b, uint32_t i) {
  Globals g;
  g.P = {{b.P.x[i], b.dPdu.x[i], b.dPdv.x[i]}, {b.P.y[i], b.dPdu.y[i], b.dPdv.y[i]},
         {b.P.z[i], b.dPdu.z[i], b.dPdv.z[i]}};
  g.N = {{b.N.x[i], b.dNdu.x[i], b.dNdv.x[i]}, {b.N.y[i], b.dNdu.y[i], b.dNdv.y[i]},
         {b.N.z[i], b.dNdu.z[i], b.dNdv.z[i]}};
  g.u = {b.u[i], 1, 0};
  g.v = {b.v[i], 0, 1};
  g.s = {b.s[i], b.dsdu[i], b.dsdv[i]};
  g.t = {b.t[i], b.dtdu[i], b.dtdv[i]};
  g.du = b.du[i];
  g.dv = b.dv[i];
  const float gx = b.dPdu.y[i] * b.dPdv.z[i] - b.dPdu.z[i] * b.dPdv.y[i];
  const float gy = b.dPdu.z[i] * b.dPdv.x[i] - b.dPdu.x[i] * b.dPdv.z[i];
  const float gz = b.dPdu.x[i] * b.dPdv.y[i] - b.dPdu.y[i] * b.dPdv.x[i];
  g.orientation = gx * b.Ng.x[i] + gy * b.Ng.y[i] + gz * b.Ng.z[i] < 0 ? -1.0f : 1.0f;
  return g;
}
// Stores P and N = normalize(calculatenormal(P)).
inline void storeWithNormal(const RlfShadingBatch& b, uint32_t i, const V3& P, float orientation) {
  const float nx = (P.y.du * P.z.dv - P.z.du * P.y.dv) * orientation;
  const float ny = (P.z.du * P.x.dv - P.x.du * P.z.dv) * orientation;
  const float nz = (P.x.du * P.y.dv - P.y.du * P.x.dv) * orientation;
  const float len = length3(nx, ny, nz);
  const float k = len > 0 ? 1.0f / len : 0.0f;
  b.Pout.x[i] = P.x.v;
  b.Pout.y[i] = P.y.v;
  b.Pout.z[i] = P.z.v;
  b.Nout.x[i] = nx * k;
  b.Nout.y[i] = ny * k;
  b.Nout.z[i] = nz * k;
}

inline D dsin(D a) {
  const float c = std::cos(a.v);
  return {std::sin(a.v), a.du * c, a.dv * c};
}
inline D snoise3(const V3& p) {
  float g[3];
  const float n = rlf_noise3(p.x.v, p.y.v, p.z.v, g);
  return {2 * n - 1, 2 * (g[0] * p.x.du + g[1] * p.y.du + g[2] * p.z.du),
          2 * (g[0] * p.x.dv + g[1] * p.y.dv + g[2] * p.z.dv)};
}
inline D dclamp01(D a) { return a.v < 0 ? D{0, 0, 0} : a.v > 1 ? D{1, 0, 0} : a; }
// filterstep(edge, x) with the width from x's derivatives, as codegen does it.
inline D filterstep(float edge, D x, float du, float dv) {
  const float w = std::fabs(x.du * du) + std::fabs(x.dv * dv);
  if (w <= 0) return {x.v < edge ? 0.0f : 1.0f, 0, 0};
  const D hi = x + D{w * 0.5f, 0, 0};
  return dclamp01((hi - D{edge, 0, 0}) * (1.0f / w));
}
// displace("object", amp): the amplitude is divided by the length of the unit normal in object
// space (codegen.cpp), then P += amp * normalize(N).
inline V3 displaceInSpace(const V3& P, const V3& n, D amp, const RlfSpaces& sp) {
  const V3 no = xformNormal(n, sp.currentFromObject);
  const D len = dsqrt(dot(no, no));
  amp = len.v == 0 ? D{0, 0, 0} : amp * dinv(len);
  return P + n * amp;
}

// ---- Hand-written references, one per example shader (defaults of language.md §9).
void cppBumps(const RlfShadingBatch& b) {
  const float Km = 0.05f, freq = 12;
  for (uint32_t i = 0; i < b.count; ++i) {
    const Globals g = load(b, i);
    const D h = dsin(g.u * (freq * 2 * kPi)) * dsin(g.v * (freq * kPi)) * Km;
    storeWithNormal(b, i, g.P + normalize(g.N) * h, g.orientation);
  }
}

void cppGlassbumps(const RlfShadingBatch& b) {
  const float Km = 0.01f, cells = 8;
  for (uint32_t i = 0; i < b.count; ++i) {
    const Globals g = load(b, i);
    const D cs = g.s * cells, ct = g.t * cells;
    const D fx = cs - D{std::floor(cs.v) + 0.5f, 0, 0};
    const D fy = ct - D{std::floor(ct.v) + 0.5f, 0, 0};
    const D r = dsqrt(fx * fx + fy * fy);
    const float cell[2] = {cs.v, ct.v};
    const float cn = rlf_cellnoise(cell, 2, 0);
    // smoothstep(0, 0.5, r): cubic Hermite of x = r / 0.5, clamped.
    D x = dclamp01(r * 2.0f);
    const D ss = x * x * (D{3, 0, 0} - x * 2.0f);
    const D amp = (D{1, 0, 0} - ss) * (Km * (0.5f + 0.5f * cn));
    const V3 n = normalize(g.N);
    storeWithNormal(b, i, g.P + n * amp, g.orientation);
  }
}

void cppGrooves(const RlfShadingBatch& b) {
  const float depth = 0.02f, count = 10, gw = 0.15f, rough = 0.003f;
  for (uint32_t i = 0; i < b.count; ++i) {
    const Globals g = load(b, i);
    const D sc = g.s * count;
    const D ss = sc - D{std::floor(sc.v), 0, 0};  // mod(x, 1) = x - floor(x)
    const D gr = filterstep(0.5f - gw / 2, ss, g.du, g.dv) - filterstep(0.5f + gw / 2, ss, g.du, g.dv);
    const V3 Ps = xformPoint(g.P, b.spaces->shaderFromCurrent);
    const D amp = gr * (-depth) + snoise3(Ps * D{40, 0, 0}) * rough;
    storeWithNormal(b, i, displaceInSpace(g.P, normalize(g.N), amp, *b.spaces), g.orientation);
  }
}

void cppCraggy(const RlfShadingBatch& b) {
  const float Km = 0.15f, freq = 3;
  const int octaves = 6;
  const float lacunarity = 2.17f, gain = 0.5f;
  for (uint32_t i = 0; i < b.count; ++i) {
    const Globals g = load(b, i);
    const V3 p = xformPoint(g.P, b.spaces->shaderFromCurrent) * D{freq, 0, 0};
    D f{0, 0, 0};
    float amp = 1, fr = 1;
    for (int o = 0; o < octaves; ++o) {
      f = f + snoise3(p * D{fr, 0, 0}) * amp;
      amp *= gain;
      fr *= lacunarity;
    }
    // sign(f) * pow(|f|, 1.5), derivative 1.5 * |f|^0.5 * f'.
    const float a = std::fabs(f.v);
    const float sq = std::sqrt(a);
    const float sgn = f.v > 0 ? 1.0f : f.v < 0 ? -1.0f : 0.0f;
    const D h{Km * sgn * a * sq, Km * 1.5f * sq * f.du, Km * 1.5f * sq * f.dv};
    storeWithNormal(b, i, g.P + normalize(g.N) * h, g.orientation);
  }
}

// The texture files of heightmap and vectordisp: smooth 256x256 patterns written at startup.
std::string textureFile(int channels) {
  const std::string path = "/tmp/relief_bench_tex" + std::to_string(channels) + "_" + std::to_string(getpid()) + ".exr";
  static std::map<int, std::string> written;
  if (written.count(channels)) return written[channels];
  constexpr int kSize = 256;
  std::vector<float> pixels;
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x)
      for (int c = 0; c < channels; ++c)
        pixels.push_back(0.5f + 0.5f * std::sin(float(x + 3 * c) * 0.05f) * std::cos(float(y) * 0.07f));
  auto out = OIIO::ImageOutput::create(path);
  OIIO::ImageSpec spec(kSize, kSize, channels, OIIO::TypeDesc::FLOAT);
  if (!out || !out->open(path, spec) || !out->write_image(OIIO::TypeDesc::FLOAT, pixels.data()))
    std::fprintf(stderr, "bench: cannot write %s\n", path.c_str());
  if (out) out->close();
  return written[channels] = path;
}

// texture(file, s, t, ...) as codegen calls it: footprint from the derivatives of s and t, result
// derivatives by the chain rule through the texture system's d/ds and d/dt.
inline void lookup(const char* file, const Globals& g, const RlfTextureOptions& opt, int n, D* out) {
  float v[4], ds[4], dt[4];
  rlf_texture(nullptr, file, g.s.v, g.t.v, g.s.du * g.du, g.t.du * g.du, g.s.dv * g.dv, g.t.dv * g.dv, &opt, n, v,
              ds, dt);
  for (int k = 0; k < n; ++k)
    out[k] = {v[k], g.s.du * ds[k] + g.t.du * dt[k], g.s.dv * ds[k] + g.t.dv * dt[k]};
}
RlfTextureOptions defaultTextureOptions() {
  RlfTextureOptions o{};
  o.swidth = o.twidth = 1;
  return o;
}

void cppHeightmap(const RlfShadingBatch& b) {
  const float Km = 0.1f, mid = 0.5f;
  static const std::string file = textureFile(1);
  RlfTextureOptions opt = defaultTextureOptions();
  opt.swrap = opt.twrap = "periodic";
  for (uint32_t i = 0; i < b.count; ++i) {
    const Globals g = load(b, i);
    D h;
    lookup(file.c_str(), g, opt, 1, &h);
    storeWithNormal(b, i, displaceInSpace(g.P, normalize(g.N), (h - D{mid, 0, 0}) * Km, *b.spaces), g.orientation);
  }
}

void cppVectordisp(const RlfShadingBatch& b) {
  const float scale = 1;
  static const std::string file = textureFile(3);
  RlfTextureOptions opt = defaultTextureOptions();
  opt.hasMissingColor = 1;
  for (uint32_t i = 0; i < b.count; ++i) {
    const Globals g = load(b, i);
    // dPdu carries no derivatives (second derivatives are not seeded).
    const V3 T = normalize(V3{{b.dPdu.x[i], 0, 0}, {b.dPdu.y[i], 0, 0}, {b.dPdu.z[i], 0, 0}});
    const V3 n = normalize(g.N);
    const V3 B{n.y * T.z - n.z * T.y, n.z * T.x - n.x * T.z, n.x * T.y - n.y * T.x};
    D c[3];
    lookup(file.c_str(), g, opt, 3, c);
    const V3 off = T * c[0] + B * c[1] + n * c[2];
    storeWithNormal(b, i, g.P + off * D{scale, 0, 0}, g.orientation);
  }
}

void cppRoundedbox(const RlfShadingBatch& b) {
  const float radius = 0.1f, half = 1;
  const float lo = radius - half, hi = half - radius;
  for (uint32_t i = 0; i < b.count; ++i) {
    const Globals g = load(b, i);
    const V3 Po = xformPoint(g.P, b.spaces->objectFromCurrent);
    auto clampD = [&](D a) { return a.v < lo ? D{lo, 0, 0} : a.v > hi ? D{hi, 0, 0} : a; };
    const V3 q{clampD(Po.x), clampD(Po.y), clampD(Po.z)};
    const V3 d = Po - q;
    V3 P = g.P;
    if (length3(d.x.v, d.y.v, d.z.v) > 0)
      P = xformPoint(q + normalize(d) * D{radius, 0, 0}, b.spaces->currentFromObject);
    storeWithNormal(b, i, P, g.orientation);
  }
}

// ---- Inputs: a pool of points on the unit sphere, u = longitude, v = colatitude (poles avoided).
struct Pool {
  static constexpr int kArrays = 36;
  std::vector<float> data[kArrays];
  RlfSpaces spaces{};
  // Index names for the arrays above.
  enum : int {
    Px, Py, Pz, Nx, Ny, Nz, Ngx, Ngy, Ngz, Ux, Uy, Uz, Vx, Vy, Vz, U, V, S, T, Du, Dv,
    Dsdu, Dsdv, Dtdu, Dtdv, NUx, NUy, NUz, NVx, NVy, NVz, Ox, Oy, Oz, Mx, My
  };

  Pool() {
    for (auto& a : data) a.assign(kPoolSize, 0.0f);
    std::mt19937 rng(12345);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (uint32_t i = 0; i < kPoolSize; ++i) {
      const float u = unit(rng), v = 0.05f + 0.9f * unit(rng);
      const float phi = 2 * kPi * u, theta = kPi * v;
      const float st = std::sin(theta), ct = std::cos(theta), sp = std::sin(phi), cp = std::cos(phi);
      const float P[3] = {st * cp, st * sp, ct};
      const float dPdu[3] = {-2 * kPi * st * sp, 2 * kPi * st * cp, 0};
      const float dPdv[3] = {kPi * ct * cp, kPi * ct * sp, -kPi * st};
      for (int k = 0; k < 3; ++k) {
        data[Px + k][i] = P[k];
        data[Nx + k][i] = P[k];  // unit sphere: N = P, so dN = dP
        data[Ngx + k][i] = P[k];
        data[Ux + k][i] = dPdu[k];
        data[Vx + k][i] = dPdv[k];
        data[NUx + k][i] = dPdu[k];
        data[NVx + k][i] = dPdv[k];
      }
      data[U][i] = data[S][i] = u;
      data[V][i] = data[T][i] = v;
      data[Du][i] = data[Dv][i] = 1.0f / 256;  // a 256x256 tessellation grid
      data[Dsdu][i] = data[Dtdv][i] = 1;
    }
    for (float* m : {spaces.currentFromObject, spaces.objectFromCurrent, spaces.currentFromShader,
                     spaces.shaderFromCurrent, spaces.currentFromCamera, spaces.cameraFromCurrent})
      for (int k = 0; k < 4; ++k) m[k * 5] = 1;
  }

  // A batch over [first, first + count) writing to the pool's output arrays.
  RlfShadingBatch batch(uint32_t first, uint32_t count, bool jitOutputs) {
    auto at = [&](int a) { return data[a].data() + first; };
    auto triple = [&](int a) { return RlfFloat3Array{at(a), at(a + 1), at(a + 2)}; };
    RlfShadingBatch b{};
    b.count = count;
    b.P = triple(Px);
    b.N = triple(Nx);
    b.Ng = triple(Ngx);
    b.dPdu = triple(Ux);
    b.dPdv = triple(Vx);
    b.u = at(U);
    b.v = at(V);
    b.s = at(S);
    b.t = at(T);
    b.du = at(Du);
    b.dv = at(Dv);
    b.dsdu = at(Dsdu);
    b.dsdv = at(Dsdv);
    b.dtdu = at(Dtdu);
    b.dtdv = at(Dtdv);
    b.dNdu = triple(NUx);
    b.dNdv = triple(NVx);
    b.spaces = &spaces;
    b.services = nullptr;
    const Outputs& o = jitOutputs ? jit : cpp;
    b.Pout = {o.p[0].data() + first, o.p[1].data() + first, o.p[2].data() + first};
    b.Nout = {o.n[0].data() + first, o.n[1].data() + first, o.n[2].data() + first};
    return b;
  }

  struct Outputs {
    mutable std::vector<float> p[3], n[3];
    Outputs() {
      for (auto& a : p) a.assign(kPoolSize, 0.0f);
      for (auto& a : n) a.assign(kPoolSize, 0.0f);
    }
  };
  Outputs jit, cpp;
};

Pool& pool() {
  static Pool p;
  return p;
}

using CppShader = void (*)(const RlfShadingBatch&);
struct Example {
  const char* name;
  CppShader reference;
  const char* textureParam;  // bound to a generated texture of `textureChannels` channels
  int textureChannels;
};
// The seven examples of language.md §9 (examples/shaders/ holds them verbatim).
constexpr Example kExamples[] = {
    {"sinebumps", cppBumps, nullptr, 0},        {"roundedbox", cppRoundedbox, nullptr, 0},
    {"grooves", cppGrooves, nullptr, 0},        {"craggy", cppCraggy, nullptr, 0},
    {"glassbumps", cppGlassbumps, nullptr, 0},  {"heightmap", cppHeightmap, "texname", 1},
    {"vectordisp", cppVectordisp, "vdmap", 3},
};

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
std::string shaderPath(const char* name) {
  return std::string(RELIEF_EXAMPLE_SHADERS_DIR) + "/" + name + ".disp";
}

// Compiled once per process; a shader that does not compile skips its benchmarks.
runtime::ShaderInstance* instanceFor(const Example& ex) {
  const char* name = ex.name;
  static std::map<std::string, std::unique_ptr<runtime::ShaderInstance>> cache;
  auto it = cache.find(name);
  if (it != cache.end()) return it->second.get();
  compiler::CompileResult r = compiler::compileFile(shaderPath(name));
  std::unique_ptr<runtime::ShaderInstance> inst;
  if (r.success() && r.find(name)) inst = std::make_unique<runtime::ShaderInstance>(r.find(name));
  else std::fprintf(stderr, "bench: %s does not compile:\n%s", name, compiler::renderDiagnostics(r).c_str());
  if (inst && ex.textureParam) {
    std::string error;
    if (!inst->bind({ex.textureParam, runtime::ParamType::String, {}, {textureFile(ex.textureChannels)}}, &error))
      std::fprintf(stderr, "bench: %s: %s\n", name, error.c_str());
  }
  return (cache[name] = std::move(inst)).get();
}

void shadePool(uint32_t batchSize, bool jit, const runtime::ShaderInstance* inst, CppShader ref,
               RlfStatus& status) {
  for (uint32_t first = 0; first < kPoolSize; first += batchSize) {
    const RlfShadingBatch b = pool().batch(first, batchSize, jit);
    if (jit) inst->evaluate(b, status);
    else ref(b);
  }
}

// Largest |JIT - C++| over the pool, P and N: evidence that both sides compute the same thing.
void compareOutputs(benchmark::State& state) {
  float dp = 0, dn = 0;
  const Pool& p = pool();
  for (int k = 0; k < 3; ++k)
    for (uint32_t i = 0; i < kPoolSize; ++i) {
      dp = std::max(dp, std::fabs(p.jit.p[k][i] - p.cpp.p[k][i]));
      dn = std::max(dn, std::fabs(p.jit.n[k][i] - p.cpp.n[k][i]));
    }
  state.counters["maxdP"] = dp;
  state.counters["maxdN"] = dn;
}

void BM_Shade(benchmark::State& state, const Example& ex, bool jit) {
  const uint32_t batchSize = uint32_t(state.range(0));
  runtime::ShaderInstance* inst = instanceFor(ex);
  if (!inst) {
    state.SkipWithError("shader does not compile");
    return;
  }
  RlfStatus status{};
  for (auto _ : state) {
    shadePool(batchSize, jit, inst, ex.reference, status);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * kPoolSize);
  // Both outputs filled (the other side's run may not have happened yet): compute and compare.
  RlfStatus s2{};
  shadePool(kPoolSize, true, inst, ex.reference, s2);
  shadePool(kPoolSize, false, inst, ex.reference, s2);
  compareOutputs(state);
  state.counters["nonFinite"] = s2.nonFinite;
  state.counters["textureErrors"] = s2.textureErrors;
}

// parse + check + codegen + JIT of one example file at -O2, source already in memory.
void BM_Compile(benchmark::State& state, const Example& ex) {
  const std::string text = readText(shaderPath(ex.name));
  compiler::CompileOptions options;
  options.optLevel = 2;
  for (auto _ : state) {
    compiler::CompileResult r = compiler::compileSource(shaderPath(ex.name), text, options);
    if (!r.success()) {
      state.SkipWithError("shader does not compile");
      return;
    }
    benchmark::DoNotOptimize(r.shaders.data());
  }
}

// rlf_noise3's two implementations on the same points (the portable one and the AVX2 one, which
// agree to the bit): calls per second, so one run gives their ratio.
void BM_Noise3(benchmark::State& state, bool vectorised) {
  if (vectorised && !noise_detail::noise3Avx2Available()) {
    state.SkipWithError("this CPU has no AVX2");
    return;
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> dist(-40, 40);
  std::vector<float> points(3 * kPoolSize);
  for (float& v : points) v = dist(rng);
  auto fn = vectorised ? noise_detail::noise3Avx2 : noise_detail::noise3Portable;
  for (auto _ : state) {
    float sum = 0, grad[3];
    for (uint32_t i = 0; i < kPoolSize; ++i) sum += fn(&points[3 * i], grad) + grad[0];
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * kPoolSize);
}

// The other dimensions' noise through the shaders' entry points: calls per second.
void BM_NoiseDims(benchmark::State& state, int dims) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> dist(-40, 40);
  std::vector<float> points(4 * kPoolSize);
  for (float& v : points) v = dist(rng);
  for (auto _ : state) {
    float sum = 0, grad[4];
    for (uint32_t i = 0; i < kPoolSize; ++i) {
      const float* p = &points[4 * i];
      sum += dims == 1   ? rlf_noise1(p[0], grad)
             : dims == 2 ? rlf_noise2(p[0], p[1], grad)
                         : rlf_noise4(p[0], p[1], p[2], p[3], grad);
      sum += grad[0];
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * kPoolSize);
}

void registerAll() {
  benchmark::RegisterBenchmark("noise3/portable", BM_Noise3, false);
  benchmark::RegisterBenchmark("noise3/avx2", BM_Noise3, true);
  for (int dims : {1, 2, 4})
    benchmark::RegisterBenchmark(("noise" + std::to_string(dims)).c_str(), BM_NoiseDims, dims);
  for (const Example& ex : kExamples) {
    for (int batch : {256, 4096}) {
      benchmark::RegisterBenchmark((std::string("shade/") + ex.name + "/jit").c_str(), BM_Shade, ex, true)
          ->Arg(batch);
      benchmark::RegisterBenchmark((std::string("shade/") + ex.name + "/cpp").c_str(), BM_Shade, ex, false)
          ->Arg(batch);
    }
  }
  for (const Example& ex : kExamples)
    benchmark::RegisterBenchmark((std::string("compile/") + ex.name).c_str(), BM_Compile, ex)
        ->Unit(benchmark::kMillisecond);
}

}  // namespace
}  // namespace relief::bench

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  relief::bench::registerAll();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
