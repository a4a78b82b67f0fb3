// Lower-level compile API (used by reliefc, ShaderLibrary and tests): one source file in, its
// diagnostics and every shader it defines out, JIT-compiled. No LLVM here.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "compiler/ast.h"
#include "compiler/diagnostics.h"
#include "compiler/shader_library.h"
#include "compiler/source_manager.h"
#include "runtime/shader.h"
#include "runtime/shader_object.h"

namespace relief::compiler {

struct Prelude;

struct CompileFlags {
  bool jit = true;         // false: stop after the optimized IR (reliefc --emit-llvm without --eval)
  bool emitLlvm = false;   // keep the optimized IR text in CompileResult::llvmIr
  // Keep the code as an ELF relocatable object in CompileResult::object, with the shaders' layouts
  // (reliefc --emit-bundle; runtime/shader_object.h loads it without LLVM).
  bool emitObject = false;
  bool keepAst = false;    // keep the checked AST in CompileResult::ast
  unsigned errorLimit = 20;
  // Give every variable derivative storage (no LanePlan pruning, codegen.h): for tests that check
  // the pruning changes no result.
  bool everyDerivativeLane = false;
  std::vector<std::string> disabledWarnings;  // -Wno-<name>, without the "-Wno-"
  std::vector<std::string> errorWarnings;     // -Werror=<name>, without the "-Werror="
  std::vector<std::string> notErrorWarnings;  // -Wno-error=<name>: stays a warning under -Werror
  // Called with the type-checked AST before codegen (tools that inspect it, tests).
  std::function<void(const TranslationUnit&)> onChecked;
};

struct CompileResult {
  std::shared_ptr<SourceManager> sources;
  std::unique_ptr<DiagnosticsEngine> diagnostics;
  std::unique_ptr<TranslationUnit> ast;
  std::shared_ptr<const Prelude> prelude;  // the stdlib functions `ast` may call
  std::string llvmIr;
  std::string object;                                // CompileFlags::emitObject
  std::vector<runtime::ShaderLayoutInfo> layouts;    // CompileFlags::emitObject
  // Every shader of the file, in source order; empty unless compilation succeeded.
  std::vector<std::shared_ptr<const runtime::CompiledShader>> shaders;
  bool ioError = false;       // the input or the stdlib could not be read (diagnostic recorded)
  // LLVM/JIT failure or an exception inside the compiler: a compiler bug, not a user error.
  std::string internalError;

  bool success() const { return !ioError && internalError.empty() && !diagnostics->hasErrors(); }
  std::shared_ptr<const runtime::CompiledShader> find(std::string_view name) const;
};

// Neither throws: what goes wrong inside the compiler ends up in CompileResult::internalError.
CompileResult compileSource(std::string name, std::string text, const CompileOptions& options = {},
                            const CompileFlags& flags = {});
CompileResult compileFile(const std::string& path, const CompileOptions& options = {},
                          const CompileFlags& flags = {});

// All diagnostics, clang-style and sorted, followed by the summary line if there is anything to sum.
std::string renderDiagnostics(const CompileResult& result, bool color = false);

}  // namespace relief::compiler
