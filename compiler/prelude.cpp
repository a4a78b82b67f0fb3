// Loading and caching the stdlib/ prelude (see prelude.h).
#include "compiler/prelude.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <sstream>

#include "compiler/diagnostics.h"
#include "compiler/parser.h"
#include "compiler/preprocessor.h"
#include "compiler/typecheck.h"

namespace relief::compiler {

namespace {

namespace fs = std::filesystem;

// The functions of language.md §6 written in stdlib/. A stdlib without one of them is not ours;
// any other function there is a helper the shaders do not see.
constexpr std::string_view kListed[] = {
    "fBm", "vfBm", "turbulence",                                                  // §6.5
    "linearstep", "hypot",                                                        // §6.2
    "distance", "ptlined", "reflect", "faceforward", "rotate", "luminance",  // §6.3
    "area",                                                                       // §6.4
};

std::shared_ptr<const Prelude> build(const std::string& dir, std::string* error, bool* broken) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    *error = "cannot load the standard library: no directory '" + dir + "'";
    return nullptr;
  }
  std::vector<fs::path> files;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    if (it->path().extension() == ".disp") files.push_back(it->path());
  std::sort(files.begin(), files.end());

  auto prelude = std::make_shared<Prelude>();
  prelude->dir = dir;
  prelude->sources = std::make_shared<SourceManager>();
  DiagnosticOptions unlimited;
  unlimited.errorLimit = 0;
  DiagnosticsEngine diags(unlimited);
  // Functions of earlier files, visible to later ones (helpers included).
  Prelude sofar;
  for (const fs::path& path : files) {
    SourceManager::FileId file = 0;
    std::string reason;
    if (!prelude->sources->addFile(path.string(), &file, &reason)) {
      *error = "cannot load the standard library: '" + path.string() + "': " + reason;
      return nullptr;
    }
    PreprocessorOptions options;
    options.builtinIncludeDir = dir;
    std::vector<Token> tokens = Preprocessor(*prelude->sources, diags, options).run(file);
    std::unique_ptr<TranslationUnit> unit = Parser(std::move(tokens), path.string(), diags).parseTranslationUnit();
    typeCheck(*unit, diags, &sofar);
    for (const auto& f : unit->functions) {
      f->isLibrary = true;
      sofar.visible[f->name].push_back(f.get());
    }
    if (!unit->shaders.empty())
      diags.report(DiagId::ErrUserError, unit->shaders.front()->keywordLoc).arg("the standard library defines no shaders");
    prelude->units.push_back(std::move(unit));
  }
  if (diags.hasErrors()) {
    std::ostringstream out;
    out << "the standard library in '" << dir << "' does not compile:\n";
    renderAllText(out, *prelude->sources, diags);
    *error = out.str();
    *broken = true;
    return nullptr;
  }
  for (std::string_view name : kListed) {
    auto it = sofar.visible.find(std::string(name));
    if (it == sofar.visible.end()) {
      *error = "cannot load the standard library: '" + dir + "' does not define '" + std::string(name) + "'";
      return nullptr;
    }
    prelude->visible.insert(*it);
  }
  return prelude;
}

}  // namespace

std::string defaultStdlibDir() {
  if (const char* env = std::getenv("RELIEF_STDLIB_DIR"); env && *env) return env;
  // An installed binary: RELIEF_STDLIB_FROM_BIN is the stdlib's path relative to the bin directory.
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = exe.parent_path() / RELIEF_STDLIB_FROM_BIN;
    if (fs::is_directory(installed, ec)) return installed.lexically_normal().string();
  }
  return RELIEF_STDLIB_DIR;
}

std::shared_ptr<const Prelude> loadPrelude(const std::string& dir, std::string* error, bool* broken) {
  // Compilations may run on several threads; the first one for a directory loads it, the others
  // wait. Failures are not cached, so a fixed installation is picked up.
  static std::mutex mutex;
  static std::map<std::string, std::shared_ptr<const Prelude>> cache;
  *broken = false;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find(dir);
  if (it != cache.end()) return it->second;
  std::shared_ptr<const Prelude> prelude = build(dir, error, broken);
  if (prelude) cache.emplace(dir, prelude);
  return prelude;
}

}  // namespace relief::compiler
