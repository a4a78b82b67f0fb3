// Public facade of compiler/: finds `<name>.disp` on a search path, compiles it (cached per file)
// and hands out runtime::CompiledShaders. What tools/ and tests code against; no LLVM here.
#pragma once

#include <map>
#include <memory>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "runtime/shader.h"

namespace relief::compiler {

struct CompileOptions {
  std::vector<std::string> includeDirs;                      // -I
  std::vector<std::pair<std::string, std::string>> defines;  // -D NAME=value
  int optLevel = 2;                                          // -O0..-O3
  bool warningsAsErrors = false;
  bool noWarnings = false;
  // Loop iterations one invocation may run (all loops together) before it aborts (language.md §7).
  uint32_t loopIterationLimit = 1u << 20;
  // The stdlib directory: library functions compiled with every shader, and the built-in
  // #include directory. Empty: defaultStdlibDir() (prelude.h).
  std::string stdlibDir;
};

// Compiles `<name>.disp` found on a search path (first match wins), caches compiled files, and returns
// the shader named `name` in it. A name with a directory or the .disp extension is a path, absolute
// or under each search directory, naming the shader by its stem (RenderMan's convention). Diagnostics are printed clang-style to `diagnosticStream` (stderr by
// default). Thread-compatible (callers serialize).
class ShaderLibrary : public runtime::ShaderProvider {
 public:
  explicit ShaderLibrary(CompileOptions options = {}, std::ostream* diagnosticStream = nullptr);
  ~ShaderLibrary() override;
  std::shared_ptr<const runtime::CompiledShader> find(std::string_view name,
                                                      std::span<const std::string> searchPath,
                                                      std::string* error) override;

 private:
  struct CachedFile {
    bool ok = false;
    std::vector<std::shared_ptr<const runtime::CompiledShader>> shaders;
  };
  CompileOptions options_;
  std::ostream* out_;
  std::map<std::string, CachedFile> cache_;  // by path as found on the search path
};

}  // namespace relief::compiler
