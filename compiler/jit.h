// ORC LLJIT wrapper: optimizes modules and links them against an explicit table of runtime symbols
// (never the host process' symbols). One ShaderJit per compiled file; CompiledShaders keep it alive.
#pragma once

#include <memory>
#include <string>

namespace llvm {
class LLVMContext;
class Module;
}  // namespace llvm

namespace relief::compiler {

// Sets the host target and data layout on `module`, verifies it and runs the -O pipeline.
// Returns false (with *error) if the module is invalid: an internal compiler error.
bool optimizeModule(llvm::Module& module, int optLevel, std::string* error);
std::string moduleText(const llvm::Module& module);
// The optimized module as an ELF relocatable object for the host, made with the target machine
// the JIT uses (PIC, small code model), so its code is the JIT's. `module` is left as it was.
bool emitObject(const llvm::Module& module, std::string* object, std::string* error);

class ShaderJit {
 public:
  static std::unique_ptr<ShaderJit> create(std::string* error);
  ~ShaderJit();
  ShaderJit(const ShaderJit&) = delete;
  ShaderJit& operator=(const ShaderJit&) = delete;

  bool addModule(std::unique_ptr<llvm::Module> module, std::unique_ptr<llvm::LLVMContext> context,
                 std::string* error);
  // Address of a defined function, or null with *error.
  void* lookup(const std::string& name, std::string* error);

 private:
  struct Impl;
  explicit ShaderJit(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace relief::compiler
