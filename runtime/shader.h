// Host-side view of a compiled displacement shader: parameter reflection, parameter binding and
// batch evaluation. This is all that renderer/ knows of shaders; compiler/ produces CompiledShader
// objects (whose code lives in a JIT kept alive by `keepAlive`). No LLVM here.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/abi.h"

namespace relief::runtime {

enum class ParamType : uint8_t { Float, Int, Point, Vector, Normal, Color, String, Matrix };

std::string_view paramTypeName(ParamType type);
// Number of float (or int) scalars in one element: 1, 3 or 16; strings count 1 (a pointer).
int paramComponents(ParamType type);
// Point, vector or normal: the kinds a transform moves (and that convert into one another).
inline bool isSpatial(ParamType t) {
  return t == ParamType::Point || t == ParamType::Vector || t == ParamType::Normal;
}

// Layout of one parameter in the parameter block. Floats, ints and triples/matrices are stored as
// consecutive 4-byte scalars; strings as `const char*` (8-byte aligned). Arrays are consecutive
// elements.
struct ParamInfo {
  std::string name;
  ParamType type = ParamType::Float;
  int arrayLength = 0;  // 0: not an array
  bool isOutput = false;
  uint32_t offset = 0;  // byte offset in the block
  // Default value, flattened: arrayLength*components numbers, or strings. Doubles, so that an int
  // keeps all its 32 bits (a float holds integers exactly only up to 2^24).
  // A default that reads coordinate spaces (`point "shader" (0, 0, 0)`) or another parameter is
  // reported as its value with every space the identity and the other parameters at their
  // defaults; the shader evaluates it at shading time, with the batch's spaces and the bound
  // values, unless the parameter is bound itself.
  std::vector<double> defaultNumbers;
  std::vector<std::string> defaultStrings;
  // Byte offset in the block of the int32 "bound" flag of such a parameter (bind sets it to 1),
  // or -1: the default is the value in the block.
  int32_t boundFlagOffset = -1;
};

// One compiled shader: immutable, shared by every instance bound from it.
class CompiledShader {
 public:
  CompiledShader(std::string name, RlfShaderEntry entry, std::vector<ParamInfo> params,
                 uint32_t blockSize, std::shared_ptr<void> keepAlive, bool ownNormal = false);

  const std::string& name() const { return name_; }
  RlfShaderEntry entry() const { return entry_; }
  std::span<const ParamInfo> params() const { return params_; }
  const ParamInfo* findParam(std::string_view name) const;
  uint32_t blockSize() const { return blockSize_; }
  // The output N may differ from the displaced surface's own normal (the shader bumps it: it
  // writes N other than as calculatenormal(P)); language.md §5 makes that N the shading normal.
  bool ownNormal() const { return ownNormal_; }

 private:
  std::string name_;
  RlfShaderEntry entry_;
  std::vector<ParamInfo> params_;
  uint32_t blockSize_;
  std::shared_ptr<void> keepAlive_;  // owns the JIT memory holding `entry_`
  bool ownNormal_ = false;
};

// A value given to a parameter by a scene or the command line, typed as written there.
struct ParamValue {
  std::string name;
  ParamType type = ParamType::Float;
  std::vector<double> numbers;  // doubles: an int parameter takes any 32-bit value
  std::vector<std::string> strings;
};

// A shader with its parameters bound (defaults overridden by scene values). Thread-safe to
// evaluate concurrently: evaluation never writes the parameter block.
class ShaderInstance {
 public:
  explicit ShaderInstance(std::shared_ptr<const CompiledShader> shader);
  ShaderInstance(const ShaderInstance&) = delete;
  ShaderInstance& operator=(const ShaderInstance&) = delete;

  const CompiledShader& shader() const { return *shader_; }
  const std::shared_ptr<const CompiledShader>& sharedShader() const { return shader_; }
  const std::string& name() const { return shader_->name(); }

  // Overrides one parameter. Returns false and sets *error (without a location; the caller knows
  // it) for an unknown name or a value that does not fit the declared type. Numeric promotions
  // follow the language: a float fits int (truncated) and triples (splat); point/vector/normal
  // interconvert; color only from color or a scalar. An array takes exactly its length in values.
  bool bind(const ParamValue& value, std::string* error);

  // Evaluates a batch. Never throws; problems are counted in `status`.
  void evaluate(const RlfShadingBatch& batch, RlfStatus& status) const noexcept {
    shader_->entry()(&batch, block_.data(), &status);
  }

  // Bytes of the bound block (for tests and reliefc --eval).
  std::span<const std::byte> block() const { return {block_.data(), block_.size()}; }

 private:
  bool bindValue(const ParamInfo& info, const ParamValue& value, std::string* error);
  void storeNumbers(const ParamInfo& info, std::span<const double> numbers);
  void storeStrings(const ParamInfo& info, std::span<const std::string> strings);

  std::shared_ptr<const CompiledShader> shader_;
  alignas(16) std::vector<std::byte> block_;
  // Owns the text behind `const char*` slots in the block; a deque-like list so pointers stay put.
  std::vector<std::unique_ptr<std::string>> strings_;
};

// Where the renderer gets shaders from by name (implemented in compiler/ by ShaderLibrary, which
// compiles `<name>.disp` found on the search path in process, in tools/ by relief's
// ShaderCompilerProcess, which has reliefc compile it, and by hand-written shaders in tests). Errors come
// back as text for the scene loader to locate; compiler diagnostics are printed by the provider.
class ShaderProvider {
 public:
  virtual ~ShaderProvider() = default;
  virtual std::shared_ptr<const CompiledShader> find(std::string_view name,
                                                     std::span<const std::string> searchPath,
                                                     std::string* error) = 0;
};

// "'path' defines no shader named 'name'", with the names it does define, for a file found by
// name whose shaders are called otherwise.
std::string noShaderNamed(const std::string& path, const std::string& name,
                          std::span<const std::shared_ptr<const CompiledShader>> defined);

// The file of shader `name` on `searchPath` and the shader's name in it. RenderMan accepts a path
// for a shader name ("lib/stone", "/abs/stone.disp"): the file is that path (with .disp added if
// it has no extension), absolute or under each search directory, and the shader is the one named
// by the file's stem. "file:shader" selects another shader of the file (one file may define
// several; a file whose own name has that shape wins), and a bare name with no file of its own is
// looked for among the declarations of the .disp files of each search directory. False with
// *error when no file is found, or when two files of one directory declare a bare name.
bool locateShaderFile(std::string_view name, std::span<const std::string> searchPath, std::string* path,
                      std::string* shaderName, std::string* error);

}  // namespace relief::runtime
