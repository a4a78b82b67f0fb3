// ShaderLibrary: search-path lookup and per-file cache over compileFile (see shader_library.h).
#include "compiler/shader_library.h"

#include <iostream>

#include "compiler/compiler.h"

namespace relief::compiler {

ShaderLibrary::ShaderLibrary(CompileOptions options, std::ostream* diagnosticStream)
    : options_(std::move(options)), out_(diagnosticStream ? diagnosticStream : &std::cerr) {}

ShaderLibrary::~ShaderLibrary() = default;

std::shared_ptr<const runtime::CompiledShader> ShaderLibrary::find(std::string_view name,
                                                                   std::span<const std::string> searchPath,
                                                                   std::string* error) {
  std::string path, shaderName;
  if (!runtime::locateShaderFile(name, searchPath, &path, &shaderName, error)) return nullptr;

  auto it = cache_.find(path);
  if (it == cache_.end()) {
    CompileResult result = compileFile(path, options_);
    const std::string text = renderDiagnostics(result);
    if (!text.empty()) *out_ << text << std::flush;
    CachedFile cached;
    cached.ok = result.success();
    if (!result.internalError.empty()) *out_ << path << ": internal compiler error: " << result.internalError << '\n';
    cached.shaders = result.shaders;
    it = cache_.emplace(path, std::move(cached)).first;
  }
  if (!it->second.ok) {
    if (error) *error = "shader '" + std::string(name) + "' failed to compile (" + path + ")";
    return nullptr;
  }
  for (const auto& s : it->second.shaders)
    if (s->name() == shaderName) return s;
  if (error) *error = runtime::noShaderNamed(path, shaderName, it->second.shaders);
  return nullptr;
}

}  // namespace relief::compiler
