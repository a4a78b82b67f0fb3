// reliefc: checks and compiles .disp shaders (language.md §8); optionally evaluates one point.
// Exit codes: 0 success (warnings allowed), 1 compile errors, 2 usage or I/O error, 3 internal error.
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <iterator>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "compiler/compiler.h"
#include "runtime/abi.h"
#include "runtime/builtins_texture.h"
#include "runtime/shader.h"
#include "runtime/shader_object.h"

namespace {

using relief::compiler::CompileFlags;
using relief::compiler::CompileOptions;
using relief::compiler::CompileResult;

constexpr const char* kUsage =
    "usage: reliefc [options] file.disp...   ('-' reads standard input; '--' ends the options)\n"
    "  -I dir                     add an include directory\n"
    "  -D name[=value]            define a macro\n"
    "  -O0 -O1 -O2 -O3            optimization level (default -O2)\n"
    "  -Werror                    treat warnings as errors\n"
    "  -Werror=<name>             treat one warning as an error (-Wno-error=<name>: never)\n"
    "  -w                         suppress warnings\n"
    "  -W<name>, -Wno-<name>      enable or disable one warning (e.g. -Wno-unused-parameter)\n"
    "  -W<group>                  -Wall, -Wextra, -Wpedantic, -Weverything: accepted (all warnings\n"
    "                             are on by default)\n"
    "  -ferror-limit=N            stop after N errors (default 20, 0: no limit)\n"
    "  -fsyntax-only              check only (what reliefc does without an output option)\n"
    "  -floop-limit=N             loop iterations per shading point before it aborts (default 1048576)\n"
    "  --emit-llvm                print the optimized LLVM IR\n"
    "  -o file                    write what is printed (IR, syntax tree, --eval) to file, and\n"
    "                             only if every input compiled; alone it means --emit-llvm\n"
    "  --emit-ast                 print the syntax tree\n"
    "  --emit-bundle              write the shaders' native code and layouts, as relief loads them\n"
    "  --color=auto|always|never  colored diagnostics\n"
    "  --diagnostics-format=text|json\n"
    "  --eval                     evaluate the (first or --shader) shader at one point:\n"
    "    --shader name            which shader of the file\n"
    "    -p name=value            bind a parameter (value: number, (x,y,z) or text)\n"
    "    --at \"P=(x,y,z) N=(x,y,z) u=.. v=..\"   the shading point (also Ng dPdu dPdv s t du dv);\n"
    "                             default P=N=(0,0,1) dPdu=(1,0,0) dPdv=(0,1,0) u=v=0.5 du=dv=0.01,\n"
    "                             Ng=N, s=u, t=v; an N alone gets tangents perpendicular to it\n"
    "  --version, --help\n";

struct Args {
  CompileOptions options;
  std::vector<std::string> files;
  bool emitLlvm = false;
  bool emitAst = false;
  bool emitBundle = false;  // the shaders' code and layouts for relief (runtime/shader_object.h)
  bool json = false;
  bool eval = false;
  bool syntaxOnly = false;  // -fsyntax-only: check, as without output flags, and say so
  std::string color = "auto";
  std::string shader;
  std::vector<std::pair<std::string, std::string>> params;
  std::string at;
  std::string output;  // -o: empty for standard output
  unsigned errorLimit = 20;
  std::vector<std::string> disabledWarnings;
  std::vector<std::string> errorWarnings, notErrorWarnings;  // -Werror=<name>, -Wno-error=<name>
};

// A count given to an option: digits only, at most 2^31 - 1 (strtoul alone would take "-3" as a
// huge number and "2x" as 2).
bool parseCount(const char* text, uint32_t* out) {
  if (!std::isdigit(static_cast<unsigned char>(*text))) return false;
  char* end = nullptr;
  const unsigned long n = std::strtoul(text, &end, 10);
  if (*end || n > 0x7fffffffUL) return false;
  *out = uint32_t(n);
  return true;
}

// Writes `text` to `path` under a temporary name in the same directory, then renames it into
// place: readers never see a partial file. False with *error set on failure (nothing left behind).
bool writeFileAtomically(const std::string& path, const std::string& text, std::string* error) {
  struct stat st;
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode)) {
    // A device or a pipe (/dev/null, a FIFO): written through, as cc does. Renaming over it would
    // replace it with a regular file (as root, even /dev/null).
    FILE* f = std::fopen(path.c_str(), "wb");
    const bool ok = f && std::fwrite(text.data(), 1, text.size(), f) == text.size();
    const int savedErrno = errno;
    if ((f && std::fclose(f) != 0) || !ok) {
      *error = std::strerror(ok ? errno : savedErrno);
      return false;
    }
    return true;
  }
  const std::string tmp = path + ".reliefc-" + std::to_string(getpid());
  FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) {
    *error = std::strerror(errno);
    return false;
  }
  const bool written = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  const int savedErrno = errno;
  if (std::fclose(f) != 0 || !written) {
    *error = std::strerror(written ? errno : savedErrno);
    std::remove(tmp.c_str());
    return false;
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    *error = std::strerror(errno);
    std::remove(tmp.c_str());
    return false;
  }
  return true;
}

int usageError(const std::string& message) {
  // One line of usage, as relief and clang give: the whole help buries the error.
  std::cerr << "reliefc: error: " << message << "\nusage: reliefc [options] file.disp... (see reliefc --help)\n";
  return 2;
}

// Parses "x", "(x,y,z)" or "x y z" into numbers; false if any is not a number.
bool parseNumbers(std::string text, std::vector<double>* out) {
  for (char& c : text)
    if (c == '(' || c == ')' || c == ',') c = ' ';
  std::istringstream in(text);
  std::string word;
  while (in >> word) {
    char* end = nullptr;
    // Read as a double, so that an int parameter gets all its digits; 1e39, inf and nan are
    // not values of either type.
    const double d = std::strtod(word.c_str(), &end);
    if (!end || *end || !std::isfinite(d) || !std::isfinite(float(d))) return false;
    out->push_back(d);
  }
  return !out->empty();
}

int evaluate(const Args& args, const CompileResult& result) {
  std::shared_ptr<const relief::runtime::CompiledShader> shader =
      args.shader.empty() ? (result.shaders.empty() ? nullptr : result.shaders.front()) : result.find(args.shader);
  if (!shader) {
    std::cerr << "reliefc: error: no shader '" << args.shader << "' to evaluate\n";
    return 2;
  }
  relief::runtime::ShaderInstance instance(shader);
  for (const auto& [name, value] : args.params) {
    relief::runtime::ParamValue pv;
    pv.name = name;
    const relief::runtime::ParamInfo* info = shader->findParam(name);
    if (info && info->type == relief::runtime::ParamType::String) {
      pv.type = relief::runtime::ParamType::String;
      pv.strings.push_back(value);
    } else if (!parseNumbers(value, &pv.numbers)) {
      std::cerr << "reliefc: error: bad value '" << value << "' for parameter '" << name << "'\n";
      return 2;
    } else if (info && info->type == relief::runtime::ParamType::Matrix &&
               (pv.numbers.size() == 16 || pv.numbers.size() == 1)) {
      // 16 numbers row-major, or one number for the diagonal (as the language's matrix(f)).
      if (pv.numbers.size() == 1) {
        const double f = pv.numbers[0];
        pv.numbers.assign(16, 0.0f);
        for (int k = 0; k < 4; ++k) pv.numbers[size_t(k) * 5] = f;
      }
      pv.type = relief::runtime::ParamType::Matrix;
    } else {
      pv.type = pv.numbers.size() == 3 && info ? info->type : relief::runtime::ParamType::Float;
    }
    // A triple given a count that no triple value has: say what it takes, not that a float came.
    if (info && pv.type != relief::runtime::ParamType::String && pv.numbers.size() > 1) {
      const size_t each = size_t(relief::runtime::paramComponents(info->type));
      const size_t whole = each * size_t(std::max(info->arrayLength, 1));
      if (each > 1 && pv.numbers.size() != whole && pv.numbers.size() != each) {
        std::cerr << "reliefc: error: parameter '" << name << "' is a " << relief::runtime::paramTypeName(info->type)
                  << (info->arrayLength > 0 ? "[" + std::to_string(info->arrayLength) + "]" : std::string())
                  << ": give " << whole << " numbers, not " << pv.numbers.size() << " ('" << value << "')\n";
        return 2;
      }
    }
    // A fraction for an int parameter truncates (the language's float -> int), as RIB values do,
    // but here the user typed it: say so.
    if (info && info->type == relief::runtime::ParamType::Int)
      for (double x : pv.numbers)
        if (x != std::trunc(x)) {
          std::cerr << "reliefc: warning: parameter '" << name << "' is an int; " << value << " is truncated to "
                    << static_cast<long long>(std::trunc(x)) << "\n";
          break;
        }
    std::string error;
    if (!instance.bind(pv, &error)) {
      std::cerr << "reliefc: error: " << error << "\n";
      return 2;
    }
  }
  // The default point: the top of a unit sphere parameterized so that dPdu ^ dPdv = N.
  std::map<std::string, std::vector<float>> at = {
      {"P", {0, 0, 1}},   {"N", {0, 0, 1}},  {"Ng", {}},     {"dPdu", {1, 0, 0}}, {"dPdv", {0, 1, 0}},
      {"u", {0.5f}},      {"v", {0.5f}},     {"s", {}},      {"t", {}},           {"du", {0.01f}},
      {"dv", {0.01f}}};
  std::string spec = args.at;
  std::set<std::string> given;
  for (size_t i = 0; i < spec.size();) {
    while (i < spec.size() && spec[i] == ' ') ++i;
    if (i >= spec.size()) break;
    size_t eq = spec.find('=', i);
    if (eq == std::string::npos) return usageError("bad --at item '" + spec.substr(i) + "'");
    std::string key = spec.substr(i, eq - i);
    while (!key.empty() && key.back() == ' ') key.pop_back();  // "P = (0,0,1)"
    while (eq + 1 < spec.size() && spec[eq + 1] == ' ') ++eq;
    size_t end = eq + 1;
    if (end < spec.size() && spec[end] == '(') {
      end = spec.find(')', end);
      if (end == std::string::npos) return usageError("unbalanced '(' in --at");
      ++end;
    } else {
      end = spec.find(' ', end);
      if (end == std::string::npos) end = spec.size();
    }
    const std::string value = spec.substr(eq + 1, end - eq - 1);
    std::vector<double> numbers;
    auto it = at.find(key);
    if (it == at.end()) return usageError("unknown --at name '" + key + "'");
    const size_t want = (key == "P" || key == "N" || key == "Ng" || key == "dPdu" || key == "dPdv") ? 3 : 1;
    if (!parseNumbers(value, &numbers) || numbers.size() != want)
      return usageError("bad --at value '" + value + "' for '" + key + "'");
    it->second.assign(numbers.begin(), numbers.end());
    given.insert(key);
    i = end;
  }
  // A normal given without tangents gets tangents perpendicular to it (dPdu ^ dPdv along N), so
  // calculatenormal agrees with it rather than with the default frame's (0,0,1).
  if (given.count("N") && !given.count("dPdu") && !given.count("dPdv")) {
    const glm::dvec3 given(at["N"][0], at["N"][1], at["N"][2]);
    if (glm::length(given) > 0.0) {
      const glm::dvec3 n = glm::normalize(given);
      // dPdu: the x axis made perpendicular to N (the y axis where N is along x); dPdv = N ^ dPdu.
      const glm::dvec3 axis = std::fabs(n.x) > 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
      const glm::dvec3 u = glm::normalize(axis - glm::dot(axis, n) * n), v = glm::cross(n, u);
      at["dPdu"] = {float(u.x), float(u.y), float(u.z)};
      at["dPdv"] = {float(v.x), float(v.y), float(v.z)};
    }
  }
  if (at["Ng"].empty()) at["Ng"] = at["N"];
  if (at["s"].empty()) at["s"] = at["u"];
  if (at["t"].empty()) at["t"] = at["v"];

  float P[3], N[3], Ng[3], dPdu[3], dPdv[3], Pout[3], Nout[3];
  for (int k = 0; k < 3; ++k) {
    P[k] = at["P"][k];
    N[k] = at["N"][k];
    Ng[k] = at["Ng"][k];
    dPdu[k] = at["dPdu"][k];
    dPdv[k] = at["dPdv"][k];
  }
  float u = at["u"][0], v = at["v"][0], s = at["s"][0], t = at["t"][0], du = at["du"][0], dv = at["dv"][0];
  float one = 1, zero = 0;
  RlfSpaces spaces{};
  for (int m = 0; m < 6; ++m)
    for (int d = 0; d < 4; ++d) (&spaces.currentFromObject)[m][d * 5] = 1;
  RlfShadingBatch batch{};
  batch.count = 1;
  auto set3 = [](RlfFloat3Array& a, float* p) { a = {p, p + 1, p + 2}; };
  set3(batch.P, P);
  set3(batch.N, N);
  set3(batch.Ng, Ng);
  set3(batch.dPdu, dPdu);
  set3(batch.dPdv, dPdv);
  set3(batch.Pout, Pout);
  set3(batch.Nout, Nout);
  batch.u = &u;
  batch.v = &v;
  batch.s = &s;
  batch.t = &t;
  batch.du = &du;
  batch.dv = &dv;
  batch.dsdu = &one;  // s = u and t = v unless given otherwise
  batch.dsdv = &zero;
  batch.dtdu = &zero;
  batch.dtdv = &one;
  batch.spaces = &spaces;
  // printf() output goes to stdout.
  RlfHostServices services{};
  // Through std::cout, which -o collects: the shader's printf output and P and N are what
  // --eval prints.
  services.print = [](void*, const char* text) { std::cout << text; };
  batch.services = &services;
  RlfStatus status{};
  instance.evaluate(batch, status);
  char line[160];
  std::snprintf(line, sizeof line, "P = (%.9g, %.9g, %.9g)\nN = (%.9g, %.9g, %.9g)\n", Pout[0], Pout[1], Pout[2],
                Nout[0], Nout[1], Nout[2]);
  std::cout << line << std::flush;
  // Runtime problems name the shader, as the renderer's warnings do (language.md §7), at its
  // definition (file:line:col), as compile diagnostics are.
  std::string where = "reliefc";
  if (result.ast && result.sources)
    for (const auto& decl : result.ast->shaders)
      if (decl->name == shader->name()) {
        const relief::compiler::PresumedLoc p = result.sources->presumed(decl->nameRange.begin);
        if (p.isValid()) where = std::string(p.file) + ":" + std::to_string(p.line) + ":" + std::to_string(p.column);
        break;
      }
  if (status.nonFinite)
    std::cerr << where << ": warning: shader '" << shader->name()
              << "' produced a non-finite P; the undisplaced point and input N were used\n";
  if (status.badNormal)
    std::cerr << where << ": warning: shader '" << shader->name()
              << "' produced a non-finite or zero N; the input N was returned (a renderer uses the "
                 "displaced surface's own normal)\n";
  if (status.loopLimit)
    std::cerr << where << ": error: shader '" << shader->name()
              << "' exceeded the loop iteration limit; outputs reverted to the inputs\n";
  if (status.textureErrors)
    std::cerr << where << ": warning: shader '" << shader->name() << "': " << status.textureErrors
              << " texture lookup(s) failed\n";
  const std::pair<uint32_t, const char*> warnings[] = {
      {status.splineBasis, "spline basis name unknown or unfit for the knot count; catmull-rom was used (with fewer than 4 knots, the first knot)"},
      {status.indexClamped, "array or component indices were clamped into range"},
      {status.unknownSpace,
       "lookups of a coordinate space name other than \"current\", \"world\", \"common\", \"object\", "
       "\"shader\" or \"camera\" were treated as 'current'"}};
  for (const auto& [count, what] : warnings)
    if (count) std::cerr << where << ": warning: shader '" << shader->name() << "': " << what << "\n";
  // The loop limit is a run-time error (§7): the printed point is the undisplaced input.
  return status.loopLimit ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  relief::runtime::setTextureMessageProgram("reliefc");
  Args args;
  std::vector<std::string> optionWarnings;  // reported once the output format is known
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const std::string& flag, std::string* out) {
      if (a.size() > flag.size()) {
        *out = a.substr(flag.size());
        return true;
      }
      if (i + 1 >= argc) return false;
      *out = argv[++i];
      return true;
    };
    std::string v;
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "--version") {
      std::cout << "reliefc 0.1.0 (.disp language v1, ABI " << kRlfAbiVersion << ", LLVM 19)\n";
      return 0;
    } else if (a.rfind("-I", 0) == 0) {
      if (!value("-I", &v)) return usageError("missing directory after '-I'");
      args.options.includeDirs.push_back(v);
    } else if (a.rfind("-D", 0) == 0) {
      if (!value("-D", &v) || v.empty()) return usageError("missing macro name after '-D'");
      const size_t eq = v.find('=');
      const std::string macro = v.substr(0, eq);
      if (macro.empty() || !(std::isalpha(static_cast<unsigned char>(macro[0])) || macro[0] == '_') ||
          !std::all_of(macro.begin(), macro.end(),
                       [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }))
        return usageError("macro name '" + macro + "' after '-D' is not an identifier");
      args.options.defines.emplace_back(v.substr(0, eq), eq == std::string::npos ? "1" : v.substr(eq + 1));
    } else if (a == "-O0" || a == "-O1" || a == "-O2" || a == "-O3") {
      args.options.optLevel = a[2] - '0';
    } else if (a == "-Werror") {
      args.options.warningsAsErrors = true;
    } else if (a == "-Wno-error") {
      args.options.warningsAsErrors = false;  // as in clang: cancels an earlier -Werror
    } else if (a == "-w") {
      args.options.noWarnings = true;
    } else if (a.rfind("-W", 0) == 0 && a.size() > 2) {
      // -W<name> enables (every warning is on by default), -Wno-<name> disables, -Werror=<name>
      // makes one warning an error, -Wno-error=<name> keeps it a warning under -Werror.
      const bool error = a.rfind("-Werror=", 0) == 0, noError = a.rfind("-Wno-error=", 0) == 0;
      const bool off = !noError && a.rfind("-Wno-", 0) == 0;
      const std::string name = a.substr(error ? 8 : noError ? 11 : off ? 5 : 2);
      // As in clang, the last flag naming a warning wins: each one undoes what earlier ones said
      // of it (-Werror=<name> also enables it).
      const auto known = relief::compiler::warningFlags();
      auto drop = [&name](std::vector<std::string>& list) { std::erase(list, name); };
      // The groups build scripts pass (-Wall -Wextra): every warning is on by default already.
      const bool group = name == "all" || name == "extra" || name == "pedantic" || name == "everything";
      if (group && !error && !noError) {
        if (off) optionWarnings.push_back("'" + a + "' does not turn warnings off here: use -w or -Wno-<name>");
      } else if (std::find(known.begin(), known.end(), name) == known.end()) {
        optionWarnings.push_back("unknown warning option '" + a + "'");
      } else if (error) {
        drop(args.notErrorWarnings), drop(args.disabledWarnings);
        args.errorWarnings.push_back(name);
      } else if (noError) {
        drop(args.errorWarnings);
        args.notErrorWarnings.push_back(name);
      } else if (off) {
        drop(args.disabledWarnings);
        args.disabledWarnings.push_back(name);
      } else {
        drop(args.disabledWarnings);
      }
    } else if (a.rfind("-floop-limit=", 0) == 0) {
      uint32_t n = 0;
      if (!parseCount(a.c_str() + 13, &n) || n == 0)
        return usageError("bad value for -floop-limit: '" + a.substr(13) + "'");
      args.options.loopIterationLimit = n;
    } else if (a.rfind("-ferror-limit=", 0) == 0 || a == "-ferror-limit") {
      uint32_t n = 0;  // 0: no limit
      if (a == "-ferror-limit" && i + 1 >= argc) return usageError("missing count after '-ferror-limit'");
      const std::string count = a == "-ferror-limit" ? std::string(argv[++i]) : a.substr(14);
      if (!parseCount(count.c_str(), &n)) return usageError("bad value for -ferror-limit: '" + count + "'");
      args.errorLimit = n;
    } else if (a == "-fsyntax-only") {
      args.syntaxOnly = true;
    } else if (a == "-o" || (a.rfind("-o", 0) == 0 && a.size() > 2)) {
      if (a == "-o" && i + 1 >= argc) return usageError("missing file name after '-o'");
      if (!args.output.empty()) return usageError("'-o' given more than once");
      args.output = a == "-o" ? argv[++i] : a.substr(2);
      if (args.output.empty()) return usageError("empty file name after '-o'");
    } else if (a == "--emit-llvm") {
      args.emitLlvm = true;
    } else if (a == "--emit-bundle") {
      args.emitBundle = true;
    } else if (a == "--emit-ast") {
      args.emitAst = true;
    } else if (a.rfind("--color=", 0) == 0 || a == "--color") {
      if (a == "--color" && i + 1 >= argc) return usageError("missing value after '--color'");
      args.color = a == "--color" ? std::string(argv[++i]) : a.substr(8);
      if (args.color != "auto" && args.color != "always" && args.color != "never")
        return usageError("bad value for --color: '" + args.color + "'");
    } else if (a.rfind("--diagnostics-format=", 0) == 0 || a == "--diagnostics-format") {
      if (a == "--diagnostics-format" && i + 1 >= argc) return usageError("missing value after '--diagnostics-format'");
      const std::string f = a == "--diagnostics-format" ? std::string(argv[++i]) : a.substr(21);
      if (f != "text" && f != "json") return usageError("bad value for --diagnostics-format: '" + f + "'");
      args.json = f == "json";
    } else if (a == "--eval") {
      args.eval = true;
    } else if (a == "--shader") {
      if (i + 1 >= argc) return usageError("missing name after '--shader'");
      args.shader = argv[++i];
    } else if (a == "-p") {
      if (i + 1 >= argc) return usageError("missing name=value after '-p'");
      const std::string p = argv[++i];
      const size_t eq = p.find('=');
      if (eq == std::string::npos || eq == 0) return usageError("expected name=value after '-p', got '" + p + "'");
      args.params.emplace_back(p.substr(0, eq), p.substr(eq + 1));
    } else if (a == "--at") {
      if (i + 1 >= argc) return usageError("missing point after '--at'");
      args.at = argv[++i];
    } else if (a == "--") {
      // Everything after is a file, even a name starting with '-'.
      for (++i; i < argc; ++i) args.files.push_back(argv[i]);
    } else if (a.size() > 1 && a[0] == '-') {
      return usageError("unknown option '" + a + "'");
    } else {
      args.files.push_back(a);  // "-" is standard input
    }
  }
  if (args.files.empty()) return usageError("no input files");
  if (std::count(args.files.begin(), args.files.end(), "-") > 1)
    return usageError("standard input ('-') named more than once: it can be read only once");
  if (args.eval && args.files.size() != 1) return usageError("--eval takes exactly one file");
  // As clang says of arguments unused during compilation: a value that changes nothing is a slip.
  if (!args.eval && (!args.params.empty() || !args.at.empty()))
    optionWarnings.push_back(std::string(args.params.empty() ? "--at only applies" : args.at.empty() ? "-p only applies" : "-p and --at only apply") +
                             " with --eval; ignored");
  if (args.emitLlvm && args.emitAst) return usageError("--emit-llvm and --emit-ast both print: give one");
  if (args.syntaxOnly && (args.emitLlvm || args.emitAst || args.emitBundle || args.eval || !args.output.empty()))
    return usageError("-fsyntax-only writes nothing: it takes no --emit-*, --eval or -o");
  // `reliefc shader.disp -o shader.ll` asks for the IR, as clang's -S -emit-llvm would give it.
  if (!args.output.empty() && !args.emitAst && !args.eval && !args.emitBundle) {
    args.emitLlvm = true;
    const std::string ext = std::filesystem::path(args.output).extension().string();
    if (ext == ".o" || ext == ".obj" || ext == ".bc" || ext == ".so")
      optionWarnings.push_back("'-o " + args.output + "' gets LLVM IR text (.ll), not object code or bitcode; "
                               "relief compiles shaders itself (--emit-bundle writes what it loads)");
  }
  if (args.emitBundle && (args.files.size() != 1 || args.eval || args.emitAst || args.emitLlvm))
    return usageError("--emit-bundle takes exactly one file and no other output");
  // Binary code is no use on a terminal (and can upset it), as clang refuses for bitcode.
  if (args.emitBundle && (args.output.empty() || args.output == "-") && isatty(STDOUT_FILENO))
    return usageError("--emit-bundle writes binary code: give -o FILE or redirect standard output");
  // What would go to standard output is collected and written to the -o file at the end, so a
  // failed compile leaves no file (and an earlier one intact) rather than a partial one.
  std::ostringstream collected;
  std::streambuf* const stdoutBuffer = args.output.empty() || args.output == "-" ? nullptr
                                                                                : std::cout.rdbuf(collected.rdbuf());

  // Problems with the options themselves, in the format asked for (JSON Lines stay valid).
  for (const std::string& message : optionWarnings) {
    if (args.json)
      std::cerr << "{\"severity\":\"warning\",\"message\":" << relief::compiler::jsonQuoted(message) << "}\n";
    else
      std::cerr << "reliefc: warning: " << message << "\n";
  }
  const bool color = args.color == "always" || (args.color == "auto" && isatty(STDERR_FILENO));
  unsigned warnings = 0, errors = 0;
  int exitCode = 0;
  for (const std::string& file : args.files) {
    CompileFlags flags;
    flags.emitLlvm = args.emitLlvm;
    flags.keepAst = args.emitAst || args.eval;  // --eval names a shader's definition in run-time messages
    flags.emitObject = args.emitBundle;
    flags.jit = args.eval;
    flags.errorLimit = args.errorLimit;
    flags.disabledWarnings = args.disabledWarnings;
    flags.errorWarnings = args.errorWarnings;
    flags.notErrorWarnings = args.notErrorWarnings;
    CompileResult result;
    if (file == "-") {
      // Standard input, named "<stdin>" in diagnostics (as clang does).
      // Read with the cap a file has (an endless pipe must not fill the memory).
      std::string text;
      char chunk[65536];
      while (std::cin.read(chunk, sizeof chunk) || std::cin.gcount() > 0) {
        text.append(chunk, size_t(std::cin.gcount()));
        if (text.size() > relief::compiler::SourceManager::kMaxSourceBytes) {
          std::cerr << "reliefc: error: standard input is larger than "
                    << (relief::compiler::SourceManager::kMaxSourceBytes >> 20) << " MiB\n";
          return 2;
        }
      }
      result = relief::compiler::compileSource("<stdin>", std::move(text), args.options, flags);
    } else {
      result = relief::compiler::compileFile(file, args.options, flags);
    }
    const auto& diags = *result.diagnostics;
    if (args.json) {
      for (const auto& d : diags.sorted(*result.sources)) relief::compiler::renderJson(std::cerr, *result.sources, d);
    } else {
      relief::compiler::TextDiagnosticOptions topts;
      topts.color = color;
      relief::compiler::renderAllText(std::cerr, *result.sources, diags, topts);
    }
    warnings += diags.numShownWarnings(*result.sources);
    errors += diags.numShownErrors();
    if (result.ioError) {
      exitCode = std::max(exitCode, 2);
      continue;
    }
    if (!result.internalError.empty()) {
      std::cerr << file << ": internal compiler error: " << result.internalError << "\n";
      exitCode = 3;
      continue;
    }
    if (diags.hasErrors()) {
      exitCode = std::max(exitCode, 1);
      continue;
    }
    if (args.emitAst && result.ast) relief::compiler::dump(std::cout, *result.ast);
    if (args.emitLlvm) std::cout << result.llvmIr;
    if (args.emitBundle) std::cout << relief::runtime::encodeShaderBundle(result.layouts, result.object);
    if (args.eval) {
      const int rc = evaluate(args, result);
      if (rc) exitCode = std::max(exitCode, rc);
    }
  }
  // A bundle cut short (a full disk, a reader gone) must not look like success.
  if (!stdoutBuffer && !std::cout.flush()) {
    std::cerr << "reliefc: error: cannot write to standard output\n";
    exitCode = std::max(exitCode, 2);
  }
  if (stdoutBuffer) {
    std::cout.rdbuf(stdoutBuffer);
    if (exitCode == 0) {
      std::string error;
      if (!writeFileAtomically(args.output, collected.str(), &error)) {
        std::cerr << "reliefc: error: cannot write '" << args.output << "': " << error << "\n";
        exitCode = 2;
      }
    }
  }
  if (!args.json) {
    const std::string summary = relief::compiler::summaryLine(warnings, errors);
    if (!summary.empty()) std::cerr << summary << "\n";
  }
  return exitCode;
}
