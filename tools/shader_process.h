// relief's shader provider: has reliefc compile each shader file in a child process
// (`reliefc --emit-bundle`) and loads the native code it returns (runtime/shader_object.h).
//
// Why not compile in process: LLVM, once it has compiled a shader, keeps ~40 MB of its code and
// data resident in the process for the rest of its life, more than the geometry cache holds at
// a 10% budget (docs/performance.md). The child's memory is returned when it exits, before the
// render starts. reliefc prints its diagnostics on the shared standard error, as the in-process
// ShaderLibrary does.
#pragma once

#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/shader.h"

namespace relief::tools {

struct ShaderCompilerOptions {
  std::vector<std::string> includeDirs;  // -I
  bool noWarnings = false;               // -w
  // reliefc to run; empty: RELIEF_COMPILER from the environment, else `reliefc` beside this
  // executable, else the one of the build tree relief was built in, else on PATH. A name without
  // a '/' is looked up on PATH.
  std::string compiler;
};

class ShaderCompilerProcess : public runtime::ShaderProvider {
 public:
  explicit ShaderCompilerProcess(ShaderCompilerOptions options);
  std::shared_ptr<const runtime::CompiledShader> find(std::string_view name, std::span<const std::string> searchPath,
                                                      std::string* error) override;

 private:
  struct CachedFile {
    bool ok = false;
    std::string error;  // why the file gave no shaders (beyond what reliefc printed)
    std::vector<std::shared_ptr<const runtime::CompiledShader>> shaders;
  };
  CachedFile compile(const std::string& path);

  ShaderCompilerOptions options_;
  std::map<std::string, CachedFile> cache_;  // by path as found on the search path
};

}  // namespace relief::tools
