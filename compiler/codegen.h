// Codegen: the type-checked AST to an LLVM module (one batch entry and one defaults function per
// shader). Every varying float/triple value is a dual number (value, d/du, d/dv): forward-mode
// differentiation as in language.md §6.4. Only codegen.cpp and jit.cpp include LLVM headers.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "compiler/ast.h"
#include "runtime/shader.h"

namespace llvm {
class LLVMContext;
class Module;
}  // namespace llvm

namespace relief::compiler {

// What the host needs to know of one generated shader.
struct ShaderLayout {
  std::string name;
  std::string entrySymbol;     // RlfShaderEntry
  std::string defaultsSymbol;  // void(void* block): writes every parameter's default into a block
  std::vector<runtime::ParamInfo> params;  // defaults filled in after running defaultsSymbol
  uint32_t blockSize = 0;
  bool ownNormal = false;  // ShaderDecl::ownNormal
};

// Limits named in language.md §7.
inline constexpr uint32_t kLoopIterationLimit = 1u << 20;

// `loopLimit`: loop iterations allowed per invocation (all loops together) before it aborts.
// `pruneLanes`: derivative storage only for variables that can hold a non-zero derivative (the
// lane plan, codegen.cpp); false gives every float/triple variable both lanes.
std::unique_ptr<llvm::Module> generateModule(const TranslationUnit& unit, llvm::LLVMContext& context,
                                             std::vector<ShaderLayout>& layouts,
                                             uint32_t loopLimit = kLoopIterationLimit,
                                             bool pruneLanes = true);

}  // namespace relief::compiler
