// Parameter reflection and binding for compiled shaders (see shader.h).
#include "runtime/shader.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>

namespace relief::runtime {

std::string_view paramTypeName(ParamType type) {
  switch (type) {
    case ParamType::Float: return "float";
    case ParamType::Int: return "int";
    case ParamType::Point: return "point";
    case ParamType::Vector: return "vector";
    case ParamType::Normal: return "normal";
    case ParamType::Color: return "color";
    case ParamType::String: return "string";
    case ParamType::Matrix: return "matrix";
  }
  return "?";
}

int paramComponents(ParamType type) {
  switch (type) {
    case ParamType::Point:
    case ParamType::Vector:
    case ParamType::Normal:
    case ParamType::Color: return 3;
    case ParamType::Matrix: return 16;
    default: return 1;
  }
}

static bool isSpatial(ParamType t) {
  return t == ParamType::Point || t == ParamType::Vector || t == ParamType::Normal;
}
static bool isScalar(ParamType t) { return t == ParamType::Float || t == ParamType::Int; }

CompiledShader::CompiledShader(std::string name, RlfShaderEntry entry, std::vector<ParamInfo> params,
                               uint32_t blockSize, std::shared_ptr<void> keepAlive, bool ownNormal)
    : name_(std::move(name)),
      entry_(entry),
      params_(std::move(params)),
      blockSize_(blockSize),
      keepAlive_(std::move(keepAlive)),
      ownNormal_(ownNormal) {}

const ParamInfo* CompiledShader::findParam(std::string_view name) const {
  for (const ParamInfo& p : params_)
    if (p.name == name) return &p;
  return nullptr;
}

ShaderInstance::ShaderInstance(std::shared_ptr<const CompiledShader> shader)
    : shader_(std::move(shader)), block_(std::max<uint32_t>(shader_->blockSize(), 16)) {
  for (const ParamInfo& p : shader_->params()) {
    if (p.type == ParamType::String)
      storeStrings(p, p.defaultStrings);
    else
      storeNumbers(p, p.defaultNumbers);
  }
}

void ShaderInstance::storeNumbers(const ParamInfo& info, std::span<const double> numbers) {
  const size_t count = size_t(std::max(info.arrayLength, 1)) * paramComponents(info.type);
  std::byte* dst = block_.data() + info.offset;
  for (size_t i = 0; i < count; ++i) {
    const double d = i < numbers.size() ? numbers[i] : 0.0;
    if (info.type == ParamType::Int) {
      // Toward zero, as C's conversion; saturated, since beyond int32 the conversion is undefined.
      const int32_t v = !std::isfinite(d) ? 0
                        : d >= 2147483647.0 ? INT32_MAX
                        : d <= -2147483648.0 ? INT32_MIN
                                             : int32_t(d);
      std::memcpy(dst + 4 * i, &v, 4);
    } else {
      const float f = float(d);
      std::memcpy(dst + 4 * i, &f, 4);
    }
  }
}

void ShaderInstance::storeStrings(const ParamInfo& info, std::span<const std::string> strings) {
  const size_t count = size_t(std::max(info.arrayLength, 1));
  std::byte* dst = block_.data() + info.offset;
  for (size_t i = 0; i < count; ++i) {
    strings_.push_back(std::make_unique<std::string>(i < strings.size() ? strings[i] : ""));
    const char* p = strings_.back()->c_str();
    std::memcpy(dst + 8 * i, &p, sizeof p);
  }
}

bool ShaderInstance::bind(const ParamValue& value, std::string* error) {
  const ParamInfo* info = shader_->findParam(value.name);
  if (!info) {
    *error = "shader '" + shader_->name() + "' has no parameter '" + value.name + "'";
    return false;
  }
  if (!bindValue(*info, value, error)) return false;
  if (info->boundFlagOffset >= 0) {
    // The bound value replaces a default the shader would otherwise evaluate at shading time.
    const int32_t bound = 1;
    std::memcpy(block_.data() + info->boundFlagOffset, &bound, 4);
  }
  return true;
}

bool ShaderInstance::bindValue(const ParamInfo& info, const ParamValue& value, std::string* error) {
  const size_t elements = size_t(std::max(info.arrayLength, 1));
  auto mismatch = [&] {
    // Appended piecewise: GCC 12 reports a false -Wrestrict on long operator+ chains at -O3.
    std::string declared(paramTypeName(info.type));
    if (info.arrayLength) declared.append("[").append(std::to_string(info.arrayLength)).append("]");
    error->assign("parameter '").append(value.name).append("' of shader '");
    error->append(shader_->name()).append("' is declared '").append(declared);
    if (value.type == info.type) {
      // The right type with the wrong count (`"color c" 0.1`): say the count.
      const bool strings = value.type == ParamType::String;
      const size_t need = strings ? elements : size_t(paramComponents(info.type)) * elements;
      const char* unit = strings ? (need == 1 ? " string" : " strings") : (need == 1 ? " number" : " numbers");
      error->append("' (").append(std::to_string(need)).append(unit);
      error->append(") but was given ").append(std::to_string(strings ? value.strings.size() : value.numbers.size()));
      return false;
    }
    error->append("' but was given '").append(paramTypeName(value.type)).append("'");
    return false;
  };
  if (info.type == ParamType::String || value.type == ParamType::String) {
    // Arrays take all their elements, as RenderMan binds them: a short list would leave the
    // rest at their defaults without a word.
    if (info.type != value.type || value.strings.size() != elements) return mismatch();
    storeStrings(info, value.strings);
    return true;
  }
  if (value.type == ParamType::Int)
    for (double d : value.numbers)
      if (d != std::trunc(d)) {
        // `"int Km" [2.5]`: the call's own declaration contradicts its value; binding 2.5 (or 2)
        // would hide the slip.
        std::ostringstream given;
        given << d;
        error->assign("parameter '").append(value.name).append("' is declared 'int' but was given ");
        error->append(given.str());
        return false;
      }
  const bool compatible = info.type == value.type ||
                          (isScalar(value.type) && info.type != ParamType::Matrix) ||
                          (isSpatial(info.type) && isSpatial(value.type));
  if (!compatible) return mismatch();

  const int components = paramComponents(info.type);
  const int given = paramComponents(value.type);
  std::vector<double> numbers;
  if (given == components) {
    numbers = value.numbers;
  } else if (given == 1) {  // splat scalars into triples
    for (double f : value.numbers)
      for (int c = 0; c < components; ++c) numbers.push_back(f);
  } else {
    return mismatch();
  }
  if (numbers.size() != elements * components) return mismatch();
  storeNumbers(info, numbers);
  return true;
}

bool locateShaderFile(std::string_view name, std::span<const std::string> searchPath, std::string* path,
                      std::string* shaderName, std::string* error) {
  const std::filesystem::path given{std::string(name)};
  std::filesystem::path file = given;
  if (given.extension() != ".disp") file += ".disp";
  *shaderName = given.has_parent_path() || given.extension() == ".disp" ? given.stem().string() : std::string(name);
  path->clear();
  std::error_code ec;
  if (file.is_absolute()) {
    if (std::filesystem::is_regular_file(file, ec)) *path = file.string();
  } else {
    for (const std::string& dir : searchPath) {
      std::filesystem::path candidate = std::filesystem::path(dir.empty() ? "." : dir) / file;
      if (std::filesystem::is_regular_file(candidate, ec)) {
        *path = candidate.string();
        break;
      }
    }
  }
  if (!path->empty()) return true;
  std::string dirs;
  for (const std::string& dir : searchPath) dirs += (dirs.empty() ? "" : ", ") + ("'" + dir + "'");
  if (error)
    *error = file.is_absolute() ? "shader '" + std::string(name) + "' not found: no file '" + file.string() + "'"
                                : "shader '" + std::string(name) + "' not found: no '" + file.string() +
                                      "' in the search path" + (dirs.empty() ? " (empty)" : " (" + dirs + ")");
  return false;
}

}  // namespace relief::runtime
