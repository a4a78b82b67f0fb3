// Compiled shaders as bytes: what reliefc writes (`--emit-bundle`) and a renderer loads without
// LLVM. A bundle is the shaders' layouts (names, entry symbols, parameter blocks) and one x86-64
// ELF relocatable object holding their code, as the JIT would have made it. The loader places the
// object's sections in memory of its own, resolves its undefined symbols against
// runtimeSymbols() only, applies the relocations and seals the code read-only and executable.
//
// Why: a process that JIT-compiles keeps ~40 MB of LLVM code and data resident for its whole life
// (docs/performance.md). `relief` compiles in a reliefc child process instead and loads the result
// here, so its memory is the renderer's alone.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/shader.h"

namespace relief::runtime {

// One shader of a compiled file, as codegen laid it out. `params` carry no defaults: loading runs
// the defaults function and fills them in (reflectDefaults), as the JIT path does.
struct ShaderLayoutInfo {
  std::string name;
  std::string entrySymbol;     // RlfShaderEntry
  std::string defaultsSymbol;  // void(void* block): writes every parameter's default into a block
  std::vector<ParamInfo> params;
  uint32_t blockSize = 0;
  bool ownNormal = false;
};

// Runs `defaults` on a zeroed parameter block and stores each parameter's default value in it.
void reflectDefaults(std::vector<ParamInfo>& params, uint32_t blockSize, void (*defaults)(void*));

std::string encodeShaderBundle(const std::vector<ShaderLayoutInfo>& shaders, std::string_view object);

// Loads a bundle: every shader of it, in order, or false with *error (a malformed bundle or
// object, an unsupported relocation, a symbol shader code may not call).
bool loadShaderBundle(std::string_view bundle, std::vector<std::shared_ptr<const CompiledShader>>* shaders,
                      std::string* error);

}  // namespace relief::runtime
