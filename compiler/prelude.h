// The library written in the language (stdlib/*.disp: fBm, distance, ...; language.md §6): parsed
// and type-checked once per process and directory, then shared read-only by every compilation,
// whose calls inline its functions like user functions. Used by compiler.cpp and the type checker.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "compiler/ast.h"
#include "compiler/source_manager.h"

namespace relief::compiler {

struct Prelude {
  std::string dir;
  std::shared_ptr<SourceManager> sources;  // its locations never reach a user's diagnostics
  std::vector<std::unique_ptr<TranslationUnit>> units;  // one per file, in file-name order
  // The overloads of each name language.md lists; other stdlib functions are private helpers.
  std::unordered_map<std::string, std::vector<FunctionDecl*>> visible;

  const std::vector<FunctionDecl*>* find(std::string_view name) const {
    auto it = visible.find(std::string(name));
    return it == visible.end() ? nullptr : &it->second;
  }
};

// Where the stdlib is: $RELIEF_STDLIB_DIR, else <binary>/../share/relief/stdlib (an installed
// reliefc or relief), else the source tree's stdlib/ (binaries run from the build tree).
std::string defaultStdlibDir();

// The prelude of `dir`, loaded on first use and cached for the process (thread-safe). On failure
// returns null and sets `error` ("no such directory", or the stdlib's own diagnostics) and
// `broken` (the files are there but do not compile: a bug, not a setup problem).
std::shared_ptr<const Prelude> loadPrelude(const std::string& dir, std::string* error, bool* broken);

}  // namespace relief::compiler
