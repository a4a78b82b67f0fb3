// The RIB reader: tokenizer, request parser and scene builder (see rib_reader.h). The graphics
// state follows RenderMan: a left-handed world, transforms that premultiply the current one, and
// the transform in force at WorldBegin taken as cameraFromWorld.
#include "renderer/rib_reader.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <ostream>
#include <set>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "renderer/film.h"
#include "renderer/tessellate.h"

namespace relief {

std::string SceneError::format() const {
  std::string out = file;
  if (line > 0) {
    out += ':';
    out += std::to_string(line);
  }
  out += ": error: ";
  out += message;
  return out;
}

void toRlfMatrix(const glm::mat4& m, float out[16]) {
  // GLM stores columns of the column-vector matrix A; the ABI wants rows of A^T, which are the
  // same numbers in the same order (translation lands in 12..14 either way).
  std::memcpy(out, glm::value_ptr(m), 16 * sizeof(float));
}

namespace {

bool isRequestStart(char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_'; }
bool isRequestChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }
bool isNumberStart(char c) {
  return std::isdigit(static_cast<unsigned char>(c)) || c == '-' || c == '+' || c == '.';
}
bool isNumberChar(char c) {
  return std::isdigit(static_cast<unsigned char>(c)) || c == '-' || c == '+' || c == '.' ||
         c == 'e' || c == 'E';
}

}  // namespace

bool tokenizeRib(std::string_view text, const std::string& fileName, std::vector<RibToken>* tokens,
                 SceneError* error) {
  auto fail = [&](int line, std::string message) {
    *error = SceneError{fileName, line, std::move(message)};
    return false;
  };
  int line = 1;
  size_t i = 0;
  const size_t n = text.size();
  while (i < n) {
    const char c = text[i];
    if (c == '\n') {
      ++line;
      ++i;
    } else if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
      ++i;
    } else if (c == '#') {
      while (i < n && text[i] != '\n') ++i;
    } else if (c == '[' || c == ']') {
      RibToken t;
      t.kind = c == '[' ? RibToken::Kind::OpenBracket : RibToken::Kind::CloseBracket;
      t.line = line;
      tokens->push_back(std::move(t));
      ++i;
    } else if (c == '"') {
      RibToken t;
      t.kind = RibToken::Kind::String;
      t.line = line;
      ++i;
      bool closed = false;
      while (i < n) {
        char d = text[i++];
        if (d == '"') {
          closed = true;
          break;
        }
        if (d == '\n') ++line;
        if (d == '\\' && i < n) {
          const char e = text[i++];
          switch (e) {
            case 'n': d = '\n'; break;
            case 't': d = '\t'; break;
            case 'r': d = '\r'; break;
            case 'b': d = '\b'; break;
            case 'f': d = '\f'; break;
            case '\n': ++line; continue;  // line continuation
            default:
              if (e >= '0' && e <= '7') {
                int value = e - '0';
                for (int k = 0; k < 2 && i < n && text[i] >= '0' && text[i] <= '7'; ++k)
                  value = value * 8 + (text[i++] - '0');
                d = char(value);
              } else {
                d = e;
              }
          }
        }
        t.text.push_back(d);
      }
      if (!closed) return fail(t.line, "unterminated string");
      tokens->push_back(std::move(t));
    } else if (isNumberStart(c)) {
      size_t j = i;
      while (j < n && isNumberChar(text[j])) ++j;
      const std::string word(text.substr(i, j - i));
      char* end = nullptr;
      const double value = std::strtod(word.c_str(), &end);
      if (end != word.c_str() + word.size() || word.empty())
        return fail(line, "malformed number '" + word + "'");
      if (!std::isfinite(value) || std::fabs(value) > 3.0e38)
        return fail(line, "number '" + word + "' is out of range");
      RibToken t;
      t.kind = RibToken::Kind::Number;
      t.number = value;
      t.line = line;
      t.text = word;
      tokens->push_back(std::move(t));
      i = j;
    } else if (isRequestStart(c)) {
      size_t j = i;
      while (j < n && isRequestChar(text[j])) ++j;
      RibToken t;
      t.kind = RibToken::Kind::Request;
      t.text = std::string(text.substr(i, j - i));
      t.line = line;
      tokens->push_back(std::move(t));
      i = j;
    } else {
      const unsigned char u = static_cast<unsigned char>(c);
      if (u < 0x20 || u >= 0x7f) {
        char hex[8];
        std::snprintf(hex, sizeof hex, "0x%02x", u);
        return fail(line, std::string("unexpected byte ") + hex + " (binary RIB is not supported)");
      }
      return fail(line, std::string("unexpected character '") + c + "'");
    }
  }
  RibToken end;
  end.kind = RibToken::Kind::End;
  end.line = line;
  tokens->push_back(std::move(end));
  return true;
}

namespace {

// One argument of a request: a bare value or a bracketed array.
struct Arg {
  enum class Kind { Number, String, Array } kind = Kind::Number;
  std::vector<double> numbers;
  std::vector<std::string> strings;  // a string, or an array of strings
  int line = 0;

  bool isNumeric() const { return kind == Kind::Number || (kind == Kind::Array && strings.empty()); }
  bool isStringy() const {
    return kind == Kind::String || (kind == Kind::Array && numbers.empty());
  }
  const char* describe() const {
    if (kind == Kind::Number) return "a number";
    if (kind == Kind::String) return "a string";
    return strings.empty() ? "a number array" : "a string array";
  }
};

struct Call {
  std::string name;
  int line = 0;
  std::vector<Arg> args;
};

// A parameter of a request: `"[class] type[n] name" value` or an untyped `"name" value`.
struct Param {
  std::string name;
  std::optional<runtime::ParamType> type;  // as declared in the call (or by Declare)
  int arraySize = 0;
  Arg value;
  int line = 0;
};

std::optional<runtime::ParamType> parseTypeWord(std::string_view word) {
  using runtime::ParamType;
  if (word == "float") return ParamType::Float;
  if (word == "int" || word == "integer") return ParamType::Int;
  if (word == "point") return ParamType::Point;
  if (word == "vector") return ParamType::Vector;
  if (word == "normal") return ParamType::Normal;
  if (word == "color") return ParamType::Color;
  if (word == "string") return ParamType::String;
  if (word == "matrix") return ParamType::Matrix;
  return std::nullopt;
}

bool isClassWord(std::string_view word) {
  return word == "constant" || word == "uniform" || word == "varying" || word == "vertex" ||
         word == "facevarying" || word == "facevertex";
}

std::vector<std::string> splitWords(const std::string& s) {
  std::vector<std::string> words;
  std::istringstream in(s);
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

std::vector<std::string> splitPath(const std::string& s) {
  std::vector<std::string> parts;
  size_t start = 0;
  while (start <= s.size()) {
    const size_t colon = s.find(':', start);
    const size_t end = colon == std::string::npos ? s.size() : colon;
    if (end > start) parts.push_back(s.substr(start, end - start));
    if (colon == std::string::npos) break;
    start = colon + 1;
  }
  return parts;
}

// Largest axis scale of an affine transform: converts a length (e.g. a displacement bound) to the
// destination space conservatively.
float maxScale(const glm::mat4& m) {
  return std::max({glm::length(glm::vec3(m[0])), glm::length(glm::vec3(m[1])),
                   glm::length(glm::vec3(m[2]))});
}

struct AttributeState {
  glm::mat4 ctm{1.0f};  // current space -> world (camera space before WorldBegin)
  glm::vec3 color{1.0f};
  float Ka = 1.0f, Kd = 1.0f;  // RenderMan matte defaults
  std::shared_ptr<const runtime::ShaderInstance> displacement;
  glm::mat4 worldFromShader{1.0f};
  int displacementLine = 0;
  float boundRadius = 0.0f;
  std::string boundSpace = "object";
  float boundNamedScale = 1.0f;  // for a boundSpace made by CoordinateSystem
  float edgeLength = 0.05f;
  float flatness = 0.0f;
};

struct StackEntry {
  AttributeState state;
  bool attribute = true;  // AttributeBegin (else TransformBegin)
  int line = 0;
};

class RibParser {
 public:
  RibParser(const std::string& fileName, const RibReadOptions& options)
      : fileName_(fileName), options_(options), searchPath_(options.defaultShaderPath) {
    const std::filesystem::path p(fileName);
    baseDir_ = p.has_parent_path() ? p.parent_path().string() : std::string(".");
  }

  std::optional<Scene> parse(std::vector<RibToken> tokens, SceneError* error) {
    tokens_ = std::move(tokens);
    runCalls();
    if (failed_) {
      *error = error_;
      return std::nullopt;
    }
    const int eofLine = tokens_.back().line;
    if (!stack_.empty()) {
      const StackEntry& e = stack_.back();
      fail(eofLine, std::string("unexpected end of file: '") +
                        (e.attribute ? "AttributeBegin" : "TransformBegin") + "' at line " +
                        std::to_string(e.line) + " has no '" +
                        (e.attribute ? "AttributeEnd" : "TransformEnd") + "'");
    } else if (inWorld_) {
      fail(eofLine, "unexpected end of file: 'WorldBegin' at line " + std::to_string(worldLine_) +
                        " has no 'WorldEnd'");
    } else if (!worldDone_) {
      fail(eofLine, "no 'WorldBegin'/'WorldEnd' block: nothing to render");
    }
    if (failed_) {
      *error = error_;
      return std::nullopt;
    }
    return std::move(scene_);
  }

 private:
  // Executes the calls of tokens_ from pos_ to the end; false on the first error.
  bool runCalls() {
    Call call;
    while (true) {
      bool end = false;
      if (!nextCall(&call, &end)) return false;
      if (end) return true;
      if (!execute(call)) return false;
    }
  }

  // call -> Request arg*        arg -> Number | String | '[' (Number* | String*) ']'
  bool nextCall(Call* call, bool* end) {
    const RibToken& t = tokens_[pos_];
    if (t.kind == RibToken::Kind::End) {
      *end = true;
      return true;
    }
    if (t.kind != RibToken::Kind::Request)
      return fail(t.line, "expected a request name, found " + describeToken(t));
    call->name = t.text;
    call->line = t.line;
    call->args.clear();
    ++pos_;
    while (true) {
      const RibToken& a = tokens_[pos_];
      if (a.kind == RibToken::Kind::Request || a.kind == RibToken::Kind::End) return true;
      Arg arg;
      arg.line = a.line;
      if (a.kind == RibToken::Kind::Number) {
        arg.kind = Arg::Kind::Number;
        arg.numbers.push_back(a.number);
        ++pos_;
      } else if (a.kind == RibToken::Kind::String) {
        arg.kind = Arg::Kind::String;
        arg.strings.push_back(a.text);
        ++pos_;
      } else if (a.kind == RibToken::Kind::CloseBracket) {
        return fail(a.line, "unexpected ']'");
      } else {
        arg.kind = Arg::Kind::Array;
        ++pos_;
        while (true) {
          const RibToken& e = tokens_[pos_];
          if (e.kind == RibToken::Kind::CloseBracket) {
            ++pos_;
            break;
          }
          if (e.kind == RibToken::Kind::Number) {
            arg.numbers.push_back(e.number);
          } else if (e.kind == RibToken::Kind::String) {
            arg.strings.push_back(e.text);
          } else if (e.kind == RibToken::Kind::End || e.kind == RibToken::Kind::Request) {
            return fail(a.line, "unterminated array: missing ']' for the '[' opened here");
          } else {
            return fail(e.line, "nested arrays are not allowed");
          }
          if (!arg.numbers.empty() && !arg.strings.empty())
            return fail(e.line, "array mixes numbers and strings");
          ++pos_;
        }
      }
      call->args.push_back(std::move(arg));
    }
  }

  static std::string describeToken(const RibToken& t) {
    switch (t.kind) {
      case RibToken::Kind::Number: return "number '" + t.text + "'";
      case RibToken::Kind::String: return "string \"" + t.text + "\"";
      case RibToken::Kind::OpenBracket: return "'['";
      case RibToken::Kind::CloseBracket: return "']'";
      default: return "end of file";
    }
  }

  bool fail(int line, std::string message) {
    if (!failed_) {
      failed_ = true;
      error_ = SceneError{fileName_, line, std::move(message)};
    }
    return false;
  }

  void warn(int line, const std::string& message) {
    if (options_.warnings)
      *options_.warnings << fileName_ << ":" << line << ": warning: " << message << "\n";
  }

  void warnOnce(int line, const std::string& key, const std::string& message) {
    if (warnedKeys_.insert(key).second) warn(line, message);
  }

  // Takes `count` numbers from the leading arguments, bare or bracketed; the rest are parameters.
  bool positionalNumbers(const Call& call, size_t count, std::vector<float>* out, size_t* next) {
    out->clear();
    size_t i = 0;
    while (out->size() < count && i < call.args.size() && call.args[i].isNumeric()) {
      for (double d : call.args[i].numbers) out->push_back(float(d));
      ++i;
    }
    if (out->size() != count) {
      return fail(call.line, "'" + call.name + "' expects " + std::to_string(count) +
                                 " number" + (count == 1 ? "" : "s") + ", got " +
                                 std::to_string(out->size()));
    }
    *next = i;
    return true;
  }

  bool positionalString(const Call& call, size_t index, std::string* out) {
    if (index >= call.args.size() || !call.args[index].isStringy() ||
        call.args[index].strings.size() != 1) {
      return fail(call.line, "'" + call.name + "' expects a string argument" +
                                 (index < call.args.size()
                                      ? std::string(", got ") + call.args[index].describe()
                                      : std::string()));
    }
    *out = call.args[index].strings[0];
    return true;
  }

  bool parseParams(const Call& call, size_t first, std::vector<Param>* params) {
    params->clear();
    for (size_t i = first; i < call.args.size(); i += 2) {
      const Arg& nameArg = call.args[i];
      if (nameArg.kind != Arg::Kind::String)
        return fail(nameArg.line, "'" + call.name + "': expected a parameter name, got " +
                                      nameArg.describe());
      if (i + 1 >= call.args.size())
        return fail(nameArg.line,
                    "'" + call.name + "': parameter '" + nameArg.strings[0] + "' has no value");
      Param p;
      p.value = call.args[i + 1];
      p.line = nameArg.line;
      if (!parseDeclaration(nameArg.strings[0], nameArg.line, &p)) return false;
      params->push_back(std::move(p));
    }
    return true;
  }

  // decl -> [class] type ['[' n ']'] name  |  name
  bool parseDeclaration(const std::string& text, int line, Param* p) {
    std::vector<std::string> words = splitWords(text);
    if (words.empty()) return fail(line, "empty parameter name");
    p->name = words.back();
    words.pop_back();
    if (!words.empty() && isClassWord(words.front())) words.erase(words.begin());
    if (words.empty()) {
      const auto declared = declared_.find(p->name);
      if (declared != declared_.end()) {
        p->type = declared->second.first;
        p->arraySize = declared->second.second;
      }
      return true;
    }
    if (words.size() != 1) return fail(line, "malformed parameter declaration '" + text + "'");
    std::string typeWord = words[0];
    const size_t bracket = typeWord.find('[');
    if (bracket != std::string::npos) {
      const size_t close = typeWord.find(']', bracket);
      if (close == std::string::npos)
        return fail(line, "malformed parameter declaration '" + text + "'");
      p->arraySize = std::atoi(typeWord.substr(bracket + 1, close - bracket - 1).c_str());
      typeWord = typeWord.substr(0, bracket);
    }
    p->type = parseTypeWord(typeWord);
    if (!p->type) return fail(line, "unknown type '" + typeWord + "' in '" + text + "'");
    return true;
  }

  const Param* findParam(const std::vector<Param>& params, std::string_view name) {
    for (const Param& p : params)
      if (p.name == name) return &p;
    return nullptr;
  }

  // Reads a numeric parameter with exactly `count` values (0: any number). `typeName` checks an
  // explicit declaration: a value declared with a different type is an error.
  bool numbersParam(const Call& call, const Param& p, const char* typeName, size_t count,
                    std::vector<float>* out) {
    if (p.type && *p.type == runtime::ParamType::String)
      return fail(p.line, "'" + call.name + "': parameter '" + p.name + "' should be '" +
                              typeName + "', not 'string'");
    if (!p.value.isNumeric())
      return fail(p.line, "'" + call.name + "': parameter '" + p.name + "' expects " + typeName +
                              " values, got " + p.value.describe());
    if (count && p.value.numbers.size() != count)
      return fail(p.line, "'" + call.name + "': parameter '" + p.name + "' expects " +
                              std::to_string(count) + " value" + (count == 1 ? "" : "s") +
                              ", got " + std::to_string(p.value.numbers.size()));
    out->assign(p.value.numbers.begin(), p.value.numbers.end());
    return true;
  }

  bool floatParam(const Call& call, const std::vector<Param>& params, std::string_view name,
                  float* value) {
    const Param* p = findParam(params, name);
    if (!p) return true;
    std::vector<float> v;
    if (!numbersParam(call, *p, "float", 1, &v)) return false;
    *value = v[0];
    return true;
  }

  bool tripleParam(const Call& call, const std::vector<Param>& params, std::string_view name,
                   const char* typeName, glm::vec3* value) {
    const Param* p = findParam(params, name);
    if (!p) return true;
    std::vector<float> v;
    if (!numbersParam(call, *p, typeName, 3, &v)) return false;
    *value = glm::vec3(v[0], v[1], v[2]);
    return true;
  }

  bool stringParam(const Call& call, const std::vector<Param>& params, std::string_view name,
                   std::string* value) {
    const Param* p = findParam(params, name);
    if (!p) return true;
    if ((p->type && *p->type != runtime::ParamType::String) || !p->value.isStringy() ||
        p->value.strings.size() != 1)
      return fail(p->line, "'" + call.name + "': parameter '" + p->name + "' expects a string");
    *value = p->value.strings[0];
    return true;
  }

  void warnUnusedParams(const Call& call, const std::vector<Param>& params,
                        std::initializer_list<std::string_view> known) {
    for (const Param& p : params) {
      if (std::find(known.begin(), known.end(), p.name) == known.end())
        warnOnce(p.line, call.name + "/" + p.name,
                 "'" + call.name + "': parameter '" + p.name + "' is not supported; ignored");
    }
  }

  bool requireWorld(const Call& call) {
    if (!inWorld_) return fail(call.line, "'" + call.name + "' outside WorldBegin/WorldEnd");
    return true;
  }

  bool execute(const Call& call);
  bool executeCamera(const Call& call, bool* handled);
  bool executeTransform(const Call& call, bool* handled);
  bool executeAttributes(const Call& call, bool* handled);
  bool executeGeometry(const Call& call, bool* handled);
  bool doDisplacement(const Call& call);
  bool doLight(const Call& call);
  bool doSphere(const Call& call);
  bool doQuadric(const Call& call);
  bool doPolygons(const Call& call, std::vector<int> nverts, std::vector<int> verts, size_t first);
  bool doPatch(const Call& call);
  bool doReadArchive(const Call& call);
  bool addMesh(Mesh mesh, int line);

  uint32_t materialIndex() {
    Material m;
    m.color = attr_.color;
    m.Ka = attr_.Ka;
    m.Kd = attr_.Kd;
    for (size_t i = 0; i < scene_.materials.size(); ++i) {
      const Material& o = scene_.materials[i];
      if (o.color == m.color && o.Ka == m.Ka && o.Kd == m.Kd) return uint32_t(i);
    }
    scene_.materials.push_back(m);
    return uint32_t(scene_.materials.size() - 1);
  }

  bool displacementIndex(int line, uint32_t* index) {
    *index = UINT32_MAX;
    if (!attr_.displacement) return true;
    Displacement d;
    d.shader = attr_.displacement;
    const glm::mat4& worldFromObject = attr_.ctm;
    const std::string& space = attr_.boundSpace;
    float scale = attr_.boundNamedScale;
    if (space == "world" || space == "current")
      scale = 1.0f;
    else if (space == "object")
      scale = maxScale(worldFromObject);
    else if (space == "shader")
      scale = maxScale(attr_.worldFromShader);
    else if (space == "camera" || space == "screen" || space == "raster")
      scale = maxScale(scene_.camera.worldFromCamera);
    d.boundWorld = attr_.boundRadius * scale;
    d.edgeLength = attr_.edgeLength;
    d.flatness = attr_.flatness;
    toRlfMatrix(worldFromObject, d.spaces.currentFromObject);
    toRlfMatrix(glm::inverse(worldFromObject), d.spaces.objectFromCurrent);
    toRlfMatrix(attr_.worldFromShader, d.spaces.currentFromShader);
    toRlfMatrix(glm::inverse(attr_.worldFromShader), d.spaces.shaderFromCurrent);
    toRlfMatrix(scene_.camera.worldFromCamera, d.spaces.currentFromCamera);
    toRlfMatrix(glm::inverse(scene_.camera.worldFromCamera), d.spaces.cameraFromCurrent);
    d.sourceFile = fileName_;
    d.sourceLine = attr_.displacementLine;
    if (d.boundWorld <= 0.0f)
      warnOnce(line, "zerobound" + std::to_string(attr_.displacementLine),
               "displacement shader '" + d.shader->name() +
                   "' has no 'displacementbound'; displaced geometry may be clipped");
    if (!scene_.displacements.empty()) {
      const Displacement& last = scene_.displacements.back();
      if (last.shader == d.shader && last.boundWorld == d.boundWorld &&
          last.edgeLength == d.edgeLength && last.flatness == d.flatness &&
          std::memcmp(&last.spaces, &d.spaces, sizeof d.spaces) == 0) {
        *index = uint32_t(scene_.displacements.size() - 1);
        return true;
      }
    }
    scene_.displacements.push_back(std::move(d));
    *index = uint32_t(scene_.displacements.size() - 1);
    return true;
  }

  std::string fileName_;
  std::string baseDir_;
  const RibReadOptions& options_;
  std::vector<RibToken> tokens_;
  size_t pos_ = 0;
  bool failed_ = false;
  SceneError error_;

  Scene scene_;
  AttributeState attr_;
  std::vector<StackEntry> stack_;
  std::vector<std::string> searchPath_;
  std::map<std::string, std::pair<runtime::ParamType, int>> declared_;
  std::set<std::string> warnedKeys_;
  bool inWorld_ = false, worldDone_ = false;
  int worldLine_ = 0;
  int archiveDepth_ = 0;
  std::map<std::string, glm::mat4> coordinateSystems_;  // name -> worldFromNamed (or camera)
  float frameAspect_ = 0.0f;
  float pixelAspect_ = 1.0f;
};

bool RibParser::execute(const Call& call) {
  bool handled = false;
  if (!executeCamera(call, &handled) || handled) return !failed_;
  if (!executeTransform(call, &handled) || handled) return !failed_;
  if (!executeAttributes(call, &handled) || handled) return !failed_;
  if (!executeGeometry(call, &handled) || handled) return !failed_;
  const std::string& n = call.name;
  if (n == "version" || n == "FrameBegin" || n == "FrameEnd" || n == "Sides" ||
      n == "Orientation" || n == "ReverseOrientation")
    return true;  // harmless: one frame, and shading is two-sided
  warnOnce(call.line, "request/" + n, "unsupported request '" + n + "' ignored");
  return true;
}

bool RibParser::executeCamera(const Call& call, bool* handled) {
  *handled = true;
  const std::string& n = call.name;
  std::vector<float> v;
  size_t next = 0;
  if (n == "Format") {
    if (!positionalNumbers(call, 3, &v, &next)) return false;
    if (v[0] < 1 || v[1] < 1 || v[0] > 65536 || v[1] > 65536)
      return fail(call.line, "'Format' resolution must be between 1 and 65536");
    if (uint64_t(v[0]) * uint64_t(v[1]) > kMaxPixels)
      return fail(call.line, "'Format' asks for more than " + std::to_string(kMaxPixels) +
                                 " pixels");
    scene_.width = int(v[0]);
    scene_.height = int(v[1]);
    pixelAspect_ = v[2] > 0 ? v[2] : 1.0f;
  } else if (n == "PixelSamples") {
    if (!positionalNumbers(call, 2, &v, &next)) return false;
    const int xs = std::max(1, int(std::lround(v[0]))), ys = std::max(1, int(std::lround(v[1])));
    if (xs * ys > 4096) return fail(call.line, "'PixelSamples' asks for too many samples");
    scene_.pixelSamples = xs * ys;
  } else if (n == "Projection") {
    std::string type;
    if (!positionalString(call, 0, &type)) return false;
    std::vector<Param> params;
    if (!parseParams(call, 1, &params)) return false;
    if (type == "perspective") {
      scene_.camera.perspective = true;
      if (!floatParam(call, params, "fov", &scene_.camera.fovDegrees)) return false;
      if (!(scene_.camera.fovDegrees > 0 && scene_.camera.fovDegrees < 180))
        return fail(call.line, "'Projection': 'fov' must be in (0, 180) degrees");
      warnUnusedParams(call, params, {"fov"});
    } else if (type == "orthographic") {
      scene_.camera.perspective = false;
      warnUnusedParams(call, params, {});
    } else {
      return fail(call.line, "unsupported projection '" + type + "'");
    }
  } else if (n == "Clipping") {
    if (!positionalNumbers(call, 2, &v, &next)) return false;
    if (!(v[0] > 0 && v[1] > v[0]))
      return fail(call.line, "'Clipping' needs 0 < near < far");
    scene_.camera.nearClip = v[0];
    scene_.camera.farClip = v[1];
  } else if (n == "ScreenWindow") {
    if (!positionalNumbers(call, 4, &v, &next)) return false;
    if (v[0] == v[1] || v[2] == v[3]) return fail(call.line, "'ScreenWindow' is empty");
    std::copy(v.begin(), v.end(), scene_.camera.screenWindow);
    scene_.camera.screenWindowSet = true;
  } else if (n == "FrameAspectRatio") {
    if (!positionalNumbers(call, 1, &v, &next)) return false;
    if (!(v[0] > 0)) return fail(call.line, "'FrameAspectRatio' must be positive");
    frameAspect_ = v[0];
  } else if (n == "Display") {
    std::string name, type, mode;
    if (!positionalString(call, 0, &name) || !positionalString(call, 1, &type) ||
        !positionalString(call, 2, &mode))
      return false;
    if (type != "file" && type != "framebuffer" && type != "tiff" && type != "openexr" &&
        type != "png")
      warnOnce(call.line, "display/" + type, "display type '" + type + "' treated as 'file'");
    if (mode != "rgb" && mode != "rgba") {
      warnOnce(call.line, "mode/" + mode, "display mode '" + mode + "' written as 'rgb'");
      mode = "rgb";
    }
    if (!name.empty() && name[0] == '+') {
      name = name.substr(1);
    } else {
      scene_.displays.clear();
      scene_.displayModes.clear();
    }
    if (name.empty()) return fail(call.line, "'Display' needs a file name");
    // There is no window to show a framebuffer in; a name without a format gets PNG.
    if (!std::filesystem::path(name).has_extension()) {
      warn(call.line, "display '" + name + "' has no image extension; writing '" + name + ".png'");
      name += ".png";
    }
    scene_.displays.push_back(name);
    scene_.displayModes.push_back(mode);
  } else if (n == "Option") {
    std::string category;
    if (!positionalString(call, 0, &category)) return false;
    std::vector<Param> params;
    if (!parseParams(call, 1, &params)) return false;
    if (category != "searchpath") {
      warnOnce(call.line, "option/" + category, "unsupported option '" + category + "' ignored");
      return true;
    }
    for (const Param& p : params) {
      if (p.name != "shader") {
        warnOnce(p.line, "searchpath/" + p.name,
                 "search path '" + p.name + "' is not supported; ignored");
        continue;
      }
      if ((p.type && *p.type != runtime::ParamType::String) || !p.value.isStringy() ||
          p.value.strings.size() != 1)
        return fail(p.line, "'Option \"searchpath\"': 'shader' expects one string");
      std::vector<std::string> path;
      for (const std::string& dir : splitPath(p.value.strings[0])) {
        if (dir == "&") {
          path.insert(path.end(), searchPath_.begin(), searchPath_.end());
        } else if (dir == "@") {
          path.insert(path.end(), options_.defaultShaderPath.begin(),
                      options_.defaultShaderPath.end());
        } else if (std::filesystem::path(dir).is_relative()) {
          path.push_back((std::filesystem::path(baseDir_) / dir).lexically_normal().string());
        } else {
          path.push_back(dir);
        }
      }
      searchPath_ = std::move(path);
    }
  } else if (n == "WorldBegin") {
    if (inWorld_) return fail(call.line, "nested 'WorldBegin'");
    if (worldDone_) return fail(call.line, "only one world block per file is supported");
    if (!stack_.empty())
      return fail(call.line, "'WorldBegin' inside an unclosed '" +
                                 std::string(stack_.back().attribute ? "AttributeBegin"
                                                                     : "TransformBegin") +
                                 "' (line " + std::to_string(stack_.back().line) + ")");
    inWorld_ = true;
    worldLine_ = call.line;
    scene_.camera.worldFromCamera = glm::inverse(attr_.ctm);
    attr_.ctm = glm::mat4(1.0f);
    if (!scene_.camera.screenWindowSet && frameAspect_ > 0) {
      const float a = frameAspect_;
      const float sw[4] = {a >= 1 ? -a : -1.0f, a >= 1 ? a : 1.0f, a >= 1 ? -1.0f : -1.0f / a,
                           a >= 1 ? 1.0f : 1.0f / a};
      std::copy(sw, sw + 4, scene_.camera.screenWindow);
      scene_.camera.screenWindowSet = true;
    }
  } else if (n == "WorldEnd") {
    if (!inWorld_) return fail(call.line, "'WorldEnd' without 'WorldBegin'");
    if (!stack_.empty())
      return fail(call.line, "'WorldEnd' inside an unclosed '" +
                                 std::string(stack_.back().attribute ? "AttributeBegin"
                                                                     : "TransformBegin") +
                                 "' (line " + std::to_string(stack_.back().line) + ")");
    inWorld_ = false;
    worldDone_ = true;
  } else {
    *handled = false;
  }
  return true;
}

bool RibParser::executeTransform(const Call& call, bool* handled) {
  *handled = true;
  const std::string& n = call.name;
  std::vector<float> v;
  size_t next = 0;
  if (n == "Identity") {
    attr_.ctm = glm::mat4(1.0f);
  } else if (n == "Transform" || n == "ConcatTransform") {
    if (!positionalNumbers(call, 16, &v, &next)) return false;
    const glm::mat4 m = glm::make_mat4(v.data());
    if (std::fabs(glm::determinant(m)) < 1e-12f)
      return fail(call.line, "'" + n + "' matrix is singular");
    attr_.ctm = n == "Transform" ? m : attr_.ctm * m;
  } else if (n == "Translate") {
    if (!positionalNumbers(call, 3, &v, &next)) return false;
    attr_.ctm = glm::translate(attr_.ctm, glm::vec3(v[0], v[1], v[2]));
  } else if (n == "Rotate") {
    if (!positionalNumbers(call, 4, &v, &next)) return false;
    const glm::vec3 axis(v[1], v[2], v[3]);
    if (glm::length(axis) == 0.0f) return fail(call.line, "'Rotate' axis is zero");
    attr_.ctm = glm::rotate(attr_.ctm, glm::radians(v[0]), glm::normalize(axis));
  } else if (n == "Scale") {
    if (!positionalNumbers(call, 3, &v, &next)) return false;
    if (v[0] == 0 || v[1] == 0 || v[2] == 0) return fail(call.line, "'Scale' by zero");
    attr_.ctm = glm::scale(attr_.ctm, glm::vec3(v[0], v[1], v[2]));
  } else if (n == "CoordinateSystem" || n == "ScopedCoordinateSystem") {
    std::string name;
    if (!positionalString(call, 0, &name)) return false;
    coordinateSystems_[name] = attr_.ctm;
  } else if (n == "CoordSysTransform") {
    std::string name;
    if (!positionalString(call, 0, &name)) return false;
    if (name == "world" && inWorld_) {
      attr_.ctm = glm::mat4(1.0f);
    } else if (name == "camera" && inWorld_) {
      attr_.ctm = scene_.camera.worldFromCamera;
    } else if (auto it = coordinateSystems_.find(name); it != coordinateSystems_.end()) {
      attr_.ctm = it->second;
    } else {
      return fail(call.line, "unknown coordinate system '" + name + "'");
    }
  } else if (n == "TransformBegin" || n == "AttributeBegin") {
    stack_.push_back(StackEntry{attr_, n == "AttributeBegin", call.line});
  } else if (n == "TransformEnd" || n == "AttributeEnd") {
    const bool attribute = n == "AttributeEnd";
    if (stack_.empty())
      return fail(call.line, "'" + n + "' without '" +
                                 (attribute ? "AttributeBegin" : "TransformBegin") + "'");
    if (stack_.back().attribute != attribute)
      return fail(call.line, "'" + n + "' closes '" +
                                 (attribute ? "TransformBegin" : "AttributeBegin") +
                                 "' at line " + std::to_string(stack_.back().line));
    if (attribute)
      attr_ = stack_.back().state;
    else
      attr_.ctm = stack_.back().state.ctm;
    stack_.pop_back();
  } else {
    *handled = false;
  }
  return true;
}

bool RibParser::executeAttributes(const Call& call, bool* handled) {
  *handled = true;
  const std::string& n = call.name;
  std::vector<float> v;
  size_t next = 0;
  if (n == "Color") {
    if (!positionalNumbers(call, 3, &v, &next)) return false;
    attr_.color = glm::vec3(v[0], v[1], v[2]);
  } else if (n == "Surface") {
    std::string name;
    if (!positionalString(call, 0, &name)) return false;
    std::vector<Param> params;
    if (!parseParams(call, 1, &params)) return false;
    if (name != "matte")
      warnOnce(call.line, "surface/" + name, "surface '" + name + "' is not supported; using 'matte'");
    attr_.Ka = 1.0f;
    attr_.Kd = 1.0f;
    if (!floatParam(call, params, "Ka", &attr_.Ka) || !floatParam(call, params, "Kd", &attr_.Kd))
      return false;
    if (name == "matte") warnUnusedParams(call, params, {"Ka", "Kd"});
  } else if (n == "LightSource") {
    return doLight(call);
  } else if (n == "Displacement") {
    return doDisplacement(call);
  } else if (n == "Declare") {
    std::string name, decl;
    if (!positionalString(call, 0, &name) || !positionalString(call, 1, &decl)) return false;
    Param p;
    if (!parseDeclaration(decl + " " + name, call.line, &p)) return false;
    if (!p.type) return fail(call.line, "'Declare' needs a type");
    declared_[name] = {*p.type, p.arraySize};
  } else if (n == "Attribute") {
    std::string category;
    if (!positionalString(call, 0, &category)) return false;
    std::vector<Param> params;
    if (!parseParams(call, 1, &params)) return false;
    if (category == "displacementbound") {
      if (!floatParam(call, params, "sphere", &attr_.boundRadius)) return false;
      std::string space = "object";
      if (!stringParam(call, params, "coordinatesystem", &space)) return false;
      if (auto named = coordinateSystems_.find(space); named != coordinateSystems_.end()) {
        attr_.boundNamedScale = maxScale(named->second);
      } else if (space != "object" && space != "world" && space != "current" &&
                 space != "shader" && space != "camera") {
        return fail(call.line, "'displacementbound': unknown coordinate system '" + space + "'");
      }
      if (attr_.boundRadius < 0) return fail(call.line, "'displacementbound' must be >= 0");
      attr_.boundSpace = space;
      warnUnusedParams(call, params, {"sphere", "coordinatesystem"});
    } else if (category == "relief") {
      if (!floatParam(call, params, "edgelength", &attr_.edgeLength) ||
          !floatParam(call, params, "flatness", &attr_.flatness))
        return false;
      if (!(attr_.edgeLength > 0)) return fail(call.line, "'edgelength' must be positive");
      if (!(attr_.flatness >= 0)) return fail(call.line, "'flatness' must be >= 0");
      warnUnusedParams(call, params, {"edgelength", "flatness"});
    } else {
      warnOnce(call.line, "attribute/" + category,
               "unsupported attribute '" + category + "' ignored");
    }
  } else {
    *handled = false;
  }
  return true;
}

bool RibParser::doLight(const Call& call) {
  std::string name;
  if (!positionalString(call, 0, &name)) return false;
  // RIB gives a light handle (number or string) after the name; parameters come in pairs, so an
  // even argument count means the handle is there.
  const size_t first = call.args.size() % 2 == 0 ? 2 : 1;
  std::vector<Param> params;
  if (!parseParams(call, first, &params)) return false;
  if (!inWorld_) {
    warnOnce(call.line, "light-outside", "'LightSource' before 'WorldBegin' ignored");
    return true;
  }
  float intensity = 1.0f;
  glm::vec3 color(1.0f);
  if (!floatParam(call, params, "intensity", &intensity) ||
      !tripleParam(call, params, "lightcolor", "color", &color))
    return false;
  if (name == "distantlight") {
    glm::vec3 from(0.0f), to(0.0f, 0.0f, 1.0f);
    if (!tripleParam(call, params, "from", "point", &from) ||
        !tripleParam(call, params, "to", "point", &to))
      return false;
    const glm::vec3 fromW = glm::vec3(attr_.ctm * glm::vec4(from, 1.0f));
    const glm::vec3 toW = glm::vec3(attr_.ctm * glm::vec4(to, 1.0f));
    const glm::vec3 dir = toW - fromW;
    if (glm::length(dir) == 0.0f)
      return fail(call.line, "'distantlight': 'from' and 'to' coincide");
    DistantLight light;
    light.directionToLight = -glm::normalize(dir);
    light.color = color * intensity;
    scene_.distantLights.push_back(light);
    warnUnusedParams(call, params, {"intensity", "lightcolor", "from", "to"});
  } else if (name == "ambientlight") {
    scene_.ambientColor += intensity * color;
    scene_.ambient = (scene_.ambientColor.r + scene_.ambientColor.g + scene_.ambientColor.b) / 3.0f;
    warnUnusedParams(call, params, {"intensity", "lightcolor"});
  } else {
    warnOnce(call.line, "light/" + name, "light source '" + name + "' is not supported; ignored");
  }
  return true;
}

bool RibParser::doDisplacement(const Call& call) {
  std::string name;
  if (!positionalString(call, 0, &name)) return false;
  std::vector<Param> params;
  if (!parseParams(call, 1, &params)) return false;
  if (name.empty() || name == "null") {
    attr_.displacement.reset();
    return true;
  }
  if (!options_.shaders)
    return fail(call.line, "cannot load displacement shader '" + name + "': no shader provider");
  std::string why;
  std::shared_ptr<const runtime::CompiledShader> compiled =
      options_.shaders->find(name, searchPath_, &why);
  if (!compiled) {
    std::string path;
    for (const std::string& d : searchPath_) path += (path.empty() ? "" : ":") + d;
    return fail(call.line, "cannot load displacement shader '" + name + "'" +
                               (why.empty() ? std::string() : ": " + why) +
                               " (search path: '" + path + "')");
  }
  // Binding errors are located at the Displacement call, as shader loading errors are: that is
  // the line a user looks for, even when the parameter list continues on later lines.
  auto instance = std::make_shared<runtime::ShaderInstance>(compiled);
  for (const Param& p : params) {
    runtime::ParamValue value;
    value.name = p.name;
    if (p.type) {
      value.type = *p.type;
    } else if (const runtime::ParamInfo* info = compiled->findParam(p.name)) {
      value.type = info->type;
    } else {
      return fail(call.line, "shader '" + name + "' has no parameter '" + p.name + "'");
    }
    if (value.type == runtime::ParamType::String) {
      if (!p.value.isStringy())
        return fail(call.line, "parameter '" + p.name + "' of shader '" + name +
                                "' expects strings, got " + p.value.describe());
      value.strings = p.value.strings;
    } else {
      if (!p.value.isNumeric())
        return fail(call.line, "parameter '" + p.name + "' of shader '" + name +
                                "' expects numbers, got " + p.value.describe());
      value.numbers.assign(p.value.numbers.begin(), p.value.numbers.end());
    }
    std::string error;
    if (!instance->bind(value, &error)) return fail(call.line, error);
  }
  attr_.displacement = std::move(instance);
  attr_.worldFromShader = attr_.ctm;
  attr_.displacementLine = call.line;
  return true;
}

bool RibParser::executeGeometry(const Call& call, bool* handled) {
  *handled = true;
  const std::string& n = call.name;
  if (n == "Cylinder" || n == "Cone" || n == "Disk" || n == "Torus" || n == "Paraboloid" ||
      n == "Hyperboloid") {
    if (!requireWorld(call)) return false;
    return doQuadric(call);
  }
  if (n == "Sphere") {
    if (!requireWorld(call)) return false;
    return doSphere(call);
  }
  if (n == "PointsPolygons") {
    if (!requireWorld(call)) return false;
    if (call.args.size() < 2 || !call.args[0].isNumeric() || !call.args[1].isNumeric())
      return fail(call.line, "'PointsPolygons' expects [nverts] [vertices] then parameters");
    std::vector<int> nverts, verts;
    for (double d : call.args[0].numbers) nverts.push_back(int(d));
    for (double d : call.args[1].numbers) verts.push_back(int(d));
    return doPolygons(call, std::move(nverts), std::move(verts), 2);
  }
  if (n == "Polygon") {
    if (!requireWorld(call)) return false;
    return doPolygons(call, {}, {}, 0);
  }
  if (n == "GeneralPolygon") {
    if (!requireWorld(call)) return false;
    if (call.args.empty() || !call.args[0].isNumeric())
      return fail(call.line, "'GeneralPolygon' expects [nloops] then parameters");
    if (call.args[0].numbers.size() != 1) {
      warnOnce(call.line, "generalpolygon-holes",
               "'GeneralPolygon' with holes is not supported; skipped");
      return true;
    }
    return doPolygons(call, {}, {}, 1);
  }
  if (n == "Patch") {
    if (!requireWorld(call)) return false;
    return doPatch(call);
  }
  if (n == "ReadArchive") return doReadArchive(call);
  *handled = false;
  return true;
}

bool RibParser::doSphere(const Call& call) {
  std::vector<float> v;
  size_t next = 0;
  if (!positionalNumbers(call, 4, &v, &next)) return false;
  std::vector<Param> params;
  if (!parseParams(call, next, &params)) return false;
  warnUnusedParams(call, params, {});
  const float radius = v[0];
  float zmin = std::clamp(std::min(v[1], v[2]), -std::fabs(radius), std::fabs(radius));
  float zmax = std::clamp(std::max(v[1], v[2]), -std::fabs(radius), std::fabs(radius));
  const float thetamax = std::clamp(v[3], -360.0f, 360.0f);
  if (radius == 0 || zmin == zmax || thetamax == 0) {
    warn(call.line, "degenerate 'Sphere' skipped");
    return true;
  }
  // Displaced: input triangles about 64 target edge lengths across (six 1-to-4 levels of
  // subdivision). Undisplaced: the facets are what gets shaded (face normals), so more of them.
  // Both with a floor so spheres look round and a cap for very large ones.
  const bool displaced = attr_.displacement != nullptr;
  const float worldRadius = std::fabs(radius) * maxScale(attr_.ctm);
  const float target = (displaced ? 16.0f : 4.0f) * attr_.edgeLength;
  const int minU = 256, minV = 128;
  const float sweep = std::fabs(thetamax) / 360.0f;
  const float vFraction =
      (std::acos(zmin / std::fabs(radius)) - std::acos(zmax / std::fabs(radius))) / float(M_PI);
  const float arcU = 2.0f * float(M_PI) * worldRadius * sweep;
  const float arcV = float(M_PI) * worldRadius * std::fabs(vFraction);
  const int nu = std::clamp(int(std::ceil(arcU / target)), std::max(4, int(float(minU) * sweep)), 1024);
  const int nv =
      std::clamp(int(std::ceil(arcV / target)), std::max(2, int(float(minV) * vFraction)), 512);
  Mesh mesh = tessellateSphere(radius, zmin, zmax, thetamax, nu, nv, attr_.ctm);
  return addMesh(std::move(mesh), call.line);
}

// Cylinder, Cone, Disk and Torus by their RI-spec parametric definitions: a grid in (u, v) with
// u = theta / thetamax, N = dPdu x dPdv (outward for positive sweeps, as the sphere's), seam
// vertices duplicated so each vertex has one (u, v). Curved directions get the sphere's angular
// resolution; straight ones are cut to the subdivision target length.
bool RibParser::doQuadric(const Call& call) {
  const std::string& n = call.name;
  const size_t count = n == "Hyperboloid" ? 7 : n == "Torus" ? 5
                       : n == "Cylinder" || n == "Paraboloid" ? 4
                                                              : 3;
  std::vector<float> v;
  size_t next = 0;
  if (!positionalNumbers(call, count, &v, &next)) return false;
  std::vector<Param> params;
  if (!parseParams(call, next, &params)) return false;
  warnUnusedParams(call, params, {});
  const float thetamax = glm::radians(std::clamp(v[count - 1], -360.0f, 360.0f));
  if (thetamax == 0.0f) {
    warn(call.line, "degenerate '" + n + "' skipped");
    return true;
  }
  std::function<glm::vec3(float, float)> position;
  bool curvedV = false;
  float lengthV = 0.0f;  // object-space length of a v line, for straight v directions
  float radiusU = 0.0f;  // largest object-space radius swept by u
  if (n == "Cylinder") {
    const float r = v[0], z0 = v[1], z1 = v[2];
    position = [=](float u, float t) {
      return glm::vec3(r * std::cos(u * thetamax), r * std::sin(u * thetamax), z0 + t * (z1 - z0));
    };
    lengthV = std::fabs(z1 - z0);
    radiusU = std::fabs(r);
  } else if (n == "Cone" || n == "Disk") {
    const bool cone = n == "Cone";
    const float h = v[0], r = v[1];
    position = [=](float u, float t) {
      const float rr = r * (1.0f - t);
      return glm::vec3(rr * std::cos(u * thetamax), rr * std::sin(u * thetamax), cone ? t * h : h);
    };
    lengthV = cone ? std::sqrt(h * h + r * r) : std::fabs(r);
    radiusU = std::fabs(r);
  } else if (n == "Paraboloid") {
    const float rmax = v[0], z0 = v[1], z1 = v[2];
    if (!(z1 > 0.0f) || z0 < 0.0f || z0 == z1) {
      warn(call.line, "degenerate 'Paraboloid' skipped");
      return true;
    }
    position = [=](float u, float t) {
      const float z = z0 + t * (z1 - z0);
      const float r = rmax * std::sqrt(z / z1);
      return glm::vec3(r * std::cos(u * thetamax), r * std::sin(u * thetamax), z);
    };
    curvedV = true;
    lengthV = std::hypot(std::fabs(rmax), std::fabs(z1 - z0));
    radiusU = std::fabs(rmax);
  } else if (n == "Hyperboloid") {
    const glm::vec3 p1(v[0], v[1], v[2]), p2(v[3], v[4], v[5]);
    position = [=](float u, float t) {
      const glm::vec3 p = p1 + t * (p2 - p1);
      const float c = std::cos(u * thetamax), s = std::sin(u * thetamax);
      return glm::vec3(p.x * c - p.y * s, p.x * s + p.y * c, p.z);
    };
    lengthV = glm::length(p2 - p1);
    radiusU = std::max(std::hypot(p1.x, p1.y), std::hypot(p2.x, p2.y));
  } else {
    const float major = v[0], minor = v[1];
    const float phi0 = glm::radians(v[2]), phi1 = glm::radians(v[3]);
    position = [=](float u, float t) {
      const float phi = phi0 + t * (phi1 - phi0);
      const float rr = major + minor * std::cos(phi);
      return glm::vec3(rr * std::cos(u * thetamax), rr * std::sin(u * thetamax),
                       minor * std::sin(phi));
    };
    curvedV = true;
    lengthV = std::fabs(minor * (phi1 - phi0));
    radiusU = std::fabs(major) + std::fabs(minor);
    if (phi0 == phi1) {
      warn(call.line, "degenerate 'Torus' skipped");
      return true;
    }
  }
  if (radiusU == 0.0f || (n != "Disk" && lengthV == 0.0f)) {
    warn(call.line, "degenerate '" + n + "' skipped");
    return true;
  }
  const float scale = maxScale(attr_.ctm);
  const bool displaced = attr_.displacement != nullptr;
  const float target = (displaced ? 16.0f : 4.0f) * attr_.edgeLength;
  const float sweep = std::fabs(thetamax) / (2.0f * float(M_PI));
  const int nu = std::clamp(int(std::ceil(std::fabs(thetamax) * radiusU * scale / target)),
                            std::max(4, int(256.0f * sweep)), 1024);
  const int minV = curvedV ? std::max(2, int(256.0f * std::fabs(glm::radians(v[3] - v[2])) /
                                             (2.0f * float(M_PI))))
                           : 1;
  const int nv = std::clamp(int(std::ceil(lengthV * scale / target)), minV, 512);

  // Normals from central differences of the exact surface, nudged off the rim/apex where
  // dPdu vanishes (cone tip, disk centre).
  auto normalAt = [&](float u, float t) {
    const float e = 1e-3f;
    const float tc = std::clamp(t, e, 1.0f - e);
    const glm::vec3 dPdu = position(u + e, tc) - position(u - e, tc);
    const glm::vec3 dPdv = position(u, tc + e) - position(u, tc - e);
    return glm::cross(dPdu, dPdv);
  };
  const glm::mat3 normalFromObject = glm::transpose(glm::inverse(glm::mat3(attr_.ctm)));
  Mesh mesh;
  for (int j = 0; j <= nv; ++j)
    for (int i = 0; i <= nu; ++i) {
      const float u = float(i) / float(nu), t = float(j) / float(nv);
      mesh.P.push_back(glm::vec3(attr_.ctm * glm::vec4(position(u, t), 1.0f)));
      glm::vec3 normal = normalFromObject * normalAt(u, t);
      const float len = glm::length(normal);
      mesh.N.push_back(len > 0.0f ? normal / len : glm::vec3(0, 0, 1));
      mesh.uv.emplace_back(u, t);
    }
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const uint32_t a = uint32_t(j * (nu + 1) + i), b = a + 1, c = a + uint32_t(nu + 1), d = c + 1;
      mesh.indices.insert(mesh.indices.end(), {a, b, d, a, d, c});
    }
  return addMesh(std::move(mesh), call.line);
}

bool RibParser::doPolygons(const Call& call, std::vector<int> nverts, std::vector<int> verts,
                           size_t first) {
  std::vector<Param> params;
  if (!parseParams(call, first, &params)) return false;
  const Param* pParam = findParam(params, "P");
  if (!pParam) return fail(call.line, "'" + call.name + "' needs a \"P\" parameter");
  std::vector<float> P;
  if (!numbersParam(call, *pParam, "point", 0, &P)) return false;
  if (P.empty() || P.size() % 3 != 0)
    return fail(pParam->line, "'" + call.name + "': \"P\" needs a multiple of 3 numbers, got " +
                                  std::to_string(P.size()));
  const size_t numPoints = P.size() / 3;
  if (call.name == "Polygon" || call.name == "GeneralPolygon") {
    nverts = {int(numPoints)};
    for (size_t i = 0; i < numPoints; ++i) verts.push_back(int(i));
  }
  size_t total = 0;
  for (int c : nverts) {
    if (c < 3) return fail(call.line, "'" + call.name + "': a polygon needs at least 3 vertices");
    total += size_t(c);
  }
  if (total != verts.size())
    return fail(call.line, "'" + call.name + "': nverts sum to " + std::to_string(total) +
                               " but " + std::to_string(verts.size()) + " vertex indices given");
  for (int idx : verts) {
    if (idx < 0 || size_t(idx) >= numPoints)
      return fail(call.line, "'" + call.name + "': vertex index " + std::to_string(idx) +
                                 " out of range (\"P\" has " + std::to_string(numPoints) +
                                 " points)");
  }

  Mesh mesh;
  const glm::mat3 normalFromObject = glm::transpose(glm::inverse(glm::mat3(attr_.ctm)));
  for (size_t i = 0; i < numPoints; ++i)
    mesh.P.push_back(glm::vec3(attr_.ctm * glm::vec4(P[3 * i], P[3 * i + 1], P[3 * i + 2], 1.0f)));
  auto perVertex = [&](const Param& p, size_t components, const char* typeName,
                       std::vector<float>* out) {
    if (!numbersParam(call, p, typeName, 0, out)) return false;
    if (out->size() != numPoints * components)
      return fail(p.line, "'" + call.name + "': \"" + p.name + "\" needs " +
                              std::to_string(numPoints * components) + " numbers (one " +
                              typeName + " per vertex), got " + std::to_string(out->size()));
    return true;
  };
  std::vector<float> s, t;
  for (const Param& p : params) {
    std::vector<float> values;
    if (p.name == "P") continue;
    if (p.name == "N") {
      if (!perVertex(p, 3, "normal", &values)) return false;
      for (size_t i = 0; i < numPoints; ++i) {
        const glm::vec3 n =
            normalFromObject * glm::vec3(values[3 * i], values[3 * i + 1], values[3 * i + 2]);
        if (glm::length(n) == 0.0f)
          return fail(p.line, "'" + call.name + "': zero-length normal at vertex " +
                                  std::to_string(i));
        mesh.N.push_back(glm::normalize(n));
      }
    } else if (p.name == "st") {
      if (!perVertex(p, 2, "float pair", &values)) return false;
      for (size_t i = 0; i < numPoints; ++i) mesh.st.emplace_back(values[2 * i], values[2 * i + 1]);
    } else if (p.name == "Cs") {
      if (!numbersParam(call, p, "color", 0, &values)) return false;
      if (values.size() == 3 * numPoints) {
        for (size_t i = 0; i < numPoints; ++i)
          mesh.Cs.emplace_back(values[3 * i], values[3 * i + 1], values[3 * i + 2]);
      } else if (values.size() == 3) {
        mesh.Cs.assign(numPoints, glm::vec3(values[0], values[1], values[2]));
      } else {
        return fail(p.line, "'" + call.name + "': \"Cs\" needs one color per vertex (" +
                                std::to_string(3 * numPoints) + " numbers) or one in all, got " +
                                std::to_string(values.size()));
      }
    } else if (p.name == "s") {
      if (!perVertex(p, 1, "float", &s)) return false;
    } else if (p.name == "t") {
      if (!perVertex(p, 1, "float", &t)) return false;
    } else {
      warnOnce(p.line, call.name + "/" + p.name,
               "'" + call.name + "': primitive variable '" + p.name + "' is not supported; ignored");
    }
  }
  if (mesh.st.empty() && (!s.empty() || !t.empty())) {
    for (size_t i = 0; i < numPoints; ++i)
      mesh.st.emplace_back(s.empty() ? 0.0f : s[i], t.empty() ? 0.0f : t[i]);
  }
  size_t start = 0;
  for (int c : nverts) {
    for (int k = 1; k + 1 < c; ++k) {
      mesh.indices.push_back(uint32_t(verts[start]));
      mesh.indices.push_back(uint32_t(verts[start + k]));
      mesh.indices.push_back(uint32_t(verts[start + k + 1]));
    }
    start += size_t(c);
  }
  return addMesh(std::move(mesh), call.line);
}

bool RibParser::doPatch(const Call& call) {
  std::string type;
  if (!positionalString(call, 0, &type)) return false;
  if (type != "bilinear") {
    warnOnce(call.line, "patch/" + type, "'Patch \"" + type + "\"' is not supported; skipped");
    return true;
  }
  std::vector<Param> params;
  if (!parseParams(call, 1, &params)) return false;
  // RenderMan's corner order: P0 (u0, v0), P1 (u1, v0), P2 (u0, v1), P3 (u1, v1).
  auto corners = [&](const char* name, size_t components, const char* typeName,
                     std::vector<float>* out) {
    const Param* p = findParam(params, name);
    if (!p) return true;
    if (!numbersParam(call, *p, typeName, 4 * components, out)) return false;
    return true;
  };
  std::vector<float> P, st, s, t, Cs;
  if (!findParam(params, "P")) return fail(call.line, "'Patch' needs a \"P\" parameter");
  if (!corners("P", 3, "point", &P) || !corners("st", 2, "float", &st) ||
      !corners("s", 1, "float", &s) || !corners("t", 1, "float", &t) ||
      !corners("Cs", 3, "color", &Cs))
    return false;
  warnUnusedParams(call, params, {"P", "st", "s", "t", "Cs"});
  auto corner3 = [](const std::vector<float>& v, int i) {
    return glm::vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
  };
  auto bilerp = [](auto a, auto b, auto c, auto d, float u, float v) {
    return (1 - v) * ((1 - u) * a + u * b) + v * ((1 - u) * c + u * d);
  };
  const glm::vec3 p0 = corner3(P, 0), p1 = corner3(P, 1), p2 = corner3(P, 2), p3 = corner3(P, 3);
  // A warped patch is sampled finely enough to follow its curvature; a flat one needs 2 triangles.
  const float warp = std::fabs(glm::dot(p3 - p0, glm::cross(p1 - p0, p2 - p0)));
  const float size = std::max(glm::length(p3 - p0), glm::length(p2 - p1));
  const int n = warp > 1e-6f * size * size * size ? 16 : 1;
  Mesh mesh;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const float u = float(i) / float(n), v = float(j) / float(n);
      const glm::vec3 pObject = bilerp(p0, p1, p2, p3, u, v);
      mesh.P.push_back(glm::vec3(attr_.ctm * glm::vec4(pObject, 1.0f)));
      mesh.uv.emplace_back(u, v);
      glm::vec2 stValue(u, v);
      if (!st.empty()) {
        stValue = bilerp(glm::vec2(st[0], st[1]), glm::vec2(st[2], st[3]), glm::vec2(st[4], st[5]),
                         glm::vec2(st[6], st[7]), u, v);
      } else if (!s.empty() || !t.empty()) {
        stValue = glm::vec2(s.empty() ? u : bilerp(s[0], s[1], s[2], s[3], u, v),
                            t.empty() ? v : bilerp(t[0], t[1], t[2], t[3], u, v));
      }
      mesh.st.push_back(stValue);
      if (!Cs.empty())
        mesh.Cs.push_back(bilerp(corner3(Cs, 0), corner3(Cs, 1), corner3(Cs, 2), corner3(Cs, 3), u, v));
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
      mesh.indices.insert(mesh.indices.end(), {a, b, d, a, d, c});
    }
  return addMesh(std::move(mesh), call.line);
}

bool RibParser::doReadArchive(const Call& call) {
  // Nesting guard: an archive that reads itself would otherwise recurse until the stack runs out.
  constexpr int kMaxArchiveDepth = 32;
  std::string name;
  if (!positionalString(call, 0, &name)) return false;
  if (archiveDepth_ >= kMaxArchiveDepth)
    return fail(call.line, "'ReadArchive' nested more than " + std::to_string(kMaxArchiveDepth) +
                               " deep (does an archive read itself?)");
  const std::filesystem::path currentDir = std::filesystem::path(fileName_).parent_path();
  const std::string path = std::filesystem::path(name).is_relative()
                               ? (currentDir / name).lexically_normal().string()
                               : name;
  std::ifstream in(path, std::ios::binary);
  if (!in || !std::filesystem::is_regular_file(path))
    return fail(call.line, "cannot open archive '" + path + "'");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  std::vector<RibToken> tokens;
  SceneError tokenError;
  if (!tokenizeRib(buffer.str(), path, &tokens, &tokenError)) {
    failed_ = true;
    error_ = tokenError;
    return false;
  }
  std::vector<RibToken> savedTokens = std::move(tokens_);
  const size_t savedPos = pos_;
  const std::string savedFile = fileName_;
  tokens_ = std::move(tokens);
  pos_ = 0;
  fileName_ = path;
  ++archiveDepth_;
  const bool ok = runCalls();
  --archiveDepth_;
  tokens_ = std::move(savedTokens);
  pos_ = savedPos;
  fileName_ = savedFile;
  return ok;
}

bool RibParser::addMesh(Mesh mesh, int line) {
  if (mesh.indices.empty()) return true;
  for (const glm::vec3& p : mesh.P)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      return fail(line, "geometry has non-finite coordinates after transformation");
  mesh.materialIndex = materialIndex();
  if (!displacementIndex(line, &mesh.displacementIndex)) return false;
  scene_.meshes.push_back(std::move(mesh));
  return true;
}

}  // namespace

std::optional<Scene> readRibString(std::string_view text, const std::string& fileName,
                                   const RibReadOptions& options, SceneError* error) {
  std::vector<RibToken> tokens;
  if (!tokenizeRib(text, fileName, &tokens, error)) return std::nullopt;
  RibParser parser(fileName, options);
  return parser.parse(std::move(tokens), error);
}

std::optional<Scene> readRibFile(const std::string& path, const RibReadOptions& options,
                                 SceneError* error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    *error = SceneError{path, 0, std::string("cannot open scene file: ") + std::strerror(errno)};
    return std::nullopt;
  }
  if (std::filesystem::is_directory(path)) {
    *error = SceneError{path, 0, "cannot open scene file: it is a directory"};
    return std::nullopt;
  }
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return readRibString(buffer.str(), path, options, error);
}

}  // namespace relief
