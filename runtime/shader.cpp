// Parameter reflection and binding for compiled shaders (see shader.h).
#include "runtime/shader.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
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

namespace {

bool isIdentifier(std::string_view s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

// `text` with its comments and string literals blanked, so a look for a declaration skips them.
std::string codeOnly(std::string_view text) {
  std::string code(text);
  for (size_t i = 0; i < code.size(); ++i) {
    if (code.compare(i, 2, "//") == 0) {
      for (; i < code.size() && code[i] != '\n'; ++i) code[i] = ' ';
    } else if (code.compare(i, 2, "/*") == 0) {
      const size_t end = code.find("*/", i + 2);
      const size_t stop = end == std::string::npos ? code.size() : end + 2;
      for (; i < stop; ++i)
        if (code[i] != '\n') code[i] = ' ';
      --i;
    } else if (code[i] == '"') {
      for (code[i++] = ' '; i < code.size() && code[i] != '"' && code[i] != '\n'; ++i) {
        if (code[i] == '\\' && i + 1 < code.size()) code[i++] = ' ';
        code[i] = ' ';
      }
      if (i < code.size() && code[i] == '"') code[i] = ' ';
    }
  }
  return code;
}

// Whether `text` (codeOnly) declares `displacement name(`: a cheap look, not a parse (a
// declaration inside #if 0 is found too, and compiling the file then says it defines no such
// shader).
bool declaresShader(std::string_view text, std::string_view name) {
  constexpr std::string_view kKeyword = "displacement";
  for (size_t at = text.find(kKeyword); at != std::string_view::npos; at = text.find(kKeyword, at + 1)) {
    if (at > 0 && (std::isalnum(static_cast<unsigned char>(text[at - 1])) || text[at - 1] == '_')) continue;
    size_t k = at + kKeyword.size();
    const size_t spaceStart = k;
    while (k < text.size() && std::isspace(static_cast<unsigned char>(text[k]))) ++k;
    if (k == spaceStart || text.substr(k, name.size()) != name) continue;
    k += name.size();
    while (k < text.size() && std::isspace(static_cast<unsigned char>(text[k]))) ++k;
    if (k < text.size() && text[k] == '(') return true;
  }
  return false;
}

// The .disp files of `dir` that declare shader `name`, sorted. Remembered for the process: a
// scene binding one such name in 3,000 Displacement calls read the directory's files each time
// (0.6 s against 0.07 s).
std::vector<std::filesystem::path> filesDeclaring(const std::filesystem::path& dir, std::string_view name) {
  static std::mutex mutex;
  static std::map<std::pair<std::string, std::string>, std::vector<std::filesystem::path>> known;
  const std::pair<std::string, std::string> key{dir.string(), std::string(name)};
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (const auto it = known.find(key); it != known.end()) return it->second;
  }
  std::vector<std::filesystem::path> found;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().extension() != ".disp" || !it->is_regular_file(ec)) continue;
    std::ifstream in(it->path(), std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    if (declaresShader(codeOnly(text.str()), name)) found.push_back(it->path());
  }
  std::sort(found.begin(), found.end());
  std::lock_guard<std::mutex> lock(mutex);
  known.emplace(key, found);
  return found;
}

}  // namespace

std::string noShaderNamed(const std::string& path, const std::string& name,
                          std::span<const std::shared_ptr<const CompiledShader>> defined) {
  std::string text = "'" + path + "' defines no shader named '" + name + "'";
  if (defined.empty()) return text;
  std::string names;
  for (size_t i = 0; i < defined.size(); ++i)
    names += (i == 0 ? "'" : i + 1 == defined.size() ? " and '" : ", '") + defined[i]->name() + "'";
  return text + " (it defines " + names + (defined.size() == 1 ? ")" : "; select one as 'file:shader')");
}

bool locateShaderFile(std::string_view name, std::span<const std::string> searchPath, std::string* path,
                      std::string* shaderName, std::string* error) {
  // The file named `fileName` (.disp added), absolute or under each search directory.
  auto findFile = [&](std::string_view fileName, std::filesystem::path* file) {
    const std::filesystem::path given{std::string(fileName)};
    *file = given;
    if (given.extension() != ".disp") *file += ".disp";
    std::error_code ec;
    if (file->is_absolute()) return std::filesystem::is_regular_file(*file, ec) ? file->string() : std::string();
    for (const std::string& dir : searchPath) {
      std::filesystem::path candidate = std::filesystem::path(dir.empty() ? "." : dir) / *file;
      if (std::filesystem::is_regular_file(candidate, ec)) return candidate.string();
    }
    return std::string();
  };
  auto stemName = [](std::string_view fileName) {
    const std::filesystem::path given{std::string(fileName)};
    return given.has_parent_path() || given.extension() == ".disp" ? given.stem().string() : std::string(fileName);
  };
  std::filesystem::path file;
  *path = findFile(name, &file);
  *shaderName = stemName(name);
  // "lib:other" (or "lib.disp:other", "dir/lib:other") names shader `other` of file lib.disp: a
  // file may define several shaders. A file whose own name has that shape ("/mnt/a:b") wins.
  std::string selected;
  if (const size_t colon = name.rfind(':'); path->empty() && colon != std::string_view::npos && colon > 0 &&
                                            isIdentifier(name.substr(colon + 1))) {
    selected = std::string(name.substr(colon + 1));
    *path = findFile(name.substr(0, colon), &file);
    *shaderName = selected;
  }
  if (!path->empty()) return true;
  std::string dirs;
  for (const std::string& dir : searchPath) dirs += (dirs.empty() ? "" : ", ") + ("'" + dir + "'");
  // A bare name with no file of its own: the shader may be one of several in another file of the
  // search path (the first directory holding one wins, as for files; two there are ambiguous).
  if (selected.empty() && isIdentifier(name)) {
    for (const std::string& dir : searchPath) {
      const std::vector<std::filesystem::path> found = filesDeclaring(dir.empty() ? "." : dir, name);
      if (found.size() == 1) {
        *path = found.front().string();
        return true;
      }
      if (found.size() > 1) {
        if (error)
          *error = "shader '" + std::string(name) + "' is defined by both '" + found[0].string() + "' and '" +
                   found[1].string() + "'; name the file, as in '" + found[0].stem().string() + ":" +
                   std::string(name) + "'";
        return false;
      }
    }
  }
  if (error)
    *error = file.is_absolute() ? "shader '" + std::string(name) + "' not found: no file '" + file.string() + "'"
                                : "shader '" + std::string(name) + "' not found: no '" + file.string() +
                                      "' in the search path" + (dirs.empty() ? " (empty)" : " (" + dirs + ")");
  return false;
}

}  // namespace relief::runtime
