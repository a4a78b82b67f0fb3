// ShaderLibrary: search-path lookup and per-file cache over compileFile (see shader_library.h).
#include "compiler/shader_library.h"

#include <filesystem>
#include <iostream>

#include "compiler/compiler.h"

namespace relief::compiler {

ShaderLibrary::ShaderLibrary(CompileOptions options, std::ostream* diagnosticStream)
    : options_(std::move(options)), out_(diagnosticStream ? diagnosticStream : &std::cerr) {}

ShaderLibrary::~ShaderLibrary() = default;

std::shared_ptr<const runtime::CompiledShader> ShaderLibrary::find(std::string_view name,
                                                                   std::span<const std::string> searchPath,
                                                                   std::string* error) {
  // RenderMan accepts a path for a shader name ("lib/stone", "/abs/stone.disp"): the file is that
  // path (with .disp added if it has no extension), absolute or under each search directory, and
  // the shader is the one named by the file's stem.
  const std::filesystem::path given{std::string(name)};
  std::filesystem::path file = given;
  if (given.extension() != ".disp") file += ".disp";
  const std::string shaderName = given.has_parent_path() || given.extension() == ".disp"
                                     ? given.stem().string()
                                     : std::string(name);
  std::string path;
  std::error_code ec;
  if (file.is_absolute()) {
    if (std::filesystem::is_regular_file(file, ec)) path = file.string();
  } else {
    for (const std::string& dir : searchPath) {
      std::filesystem::path candidate = std::filesystem::path(dir.empty() ? "." : dir) / file;
      if (std::filesystem::is_regular_file(candidate, ec)) {
        path = candidate.string();
        break;
      }
    }
  }
  if (path.empty()) {
    std::string dirs;
    for (const std::string& dir : searchPath) dirs += (dirs.empty() ? "" : ", ") + ("'" + dir + "'");
    if (error)
      *error = file.is_absolute() ? "shader '" + std::string(name) + "' not found: no file '" + file.string() + "'"
                                  : "shader '" + std::string(name) + "' not found: no '" + file.string() +
                                        "' in the search path" + (dirs.empty() ? " (empty)" : " (" + dirs + ")");
    return nullptr;
  }

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
  if (error) *error = "'" + path + "' defines no shader named '" + shaderName + "'";
  return nullptr;
}

}  // namespace relief::compiler
