// The RIB reader: tokenizer, request parser and scene builder (see rib_reader.h). The graphics
// state follows RenderMan: a left-handed world, transforms that premultiply the current one, and
// the transform in force at WorldBegin taken as cameraFromWorld.
#include "renderer/rib_reader.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <ostream>
#include <optional>
#include <set>
#include <sstream>
#include <unordered_map>
#include <utility>

#include <zlib.h>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "renderer/film.h"
#include "renderer/filter.h"
#include "renderer/obj_mesh.h"
#include "renderer/rib_geometry.h"
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
// The words strtod would read as NaN or infinity, which RIB does not have.
bool isNonFiniteWord(const std::string& word) {
  std::string lower;
  for (char c : word) lower.push_back(char(std::tolower(static_cast<unsigned char>(c))));
  return lower == "nan" || lower == "inf" || lower == "infinity";
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
  // A UTF-8 byte-order mark, as Windows editors write, is not part of the stream.
  if (text.substr(0, 3) == "\xEF\xBB\xBF") i = 3;
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
      // A letter straight after a number is a typo ('36O', '0x168'), not a request: 'Sphere 1 -1 1
      // 36O' must not render a wedge and warn about a request 'O'.
      if (j < n && isRequestStart(text[j])) {
        size_t k = j;
        while (k < n && isRequestChar(text[k])) ++k;
        return fail(line, "malformed number '" + std::string(text.substr(i, k - i)) + "'");
      }
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
  // The bare word that ended the arguments when it is on the same line (`Sphere nan 1 -1 360`
  // reads as `Sphere` and a request `nan`): named when the arguments fall short.
  std::string wordAfter;
};

// A parameter of a request: `"[class] type[n] name" value` or an untyped `"name" value`.
struct Param {
  std::string name;
  std::optional<runtime::ParamType> type;  // as declared in the call (or by Declare)
  int arraySize = 0;
  std::string storageClass;  // "vertex", "uniform", ... as declared; empty: not given
  bool homogeneous = false;  // declared "hpoint": four numbers per point (x y z w)
  int declaredLine = 0;      // the Declare that typed an untyped name, if one did (0: none)
  const std::string* declaredFile = nullptr;  // its file (the Declare's own record)
  Arg value;
  int line = 0;
};

// A gzip-compressed RIB file (.rib.gz, as PRMan and 3Delight read) is inflated in place; other
// text is left as it is. False with *error for a damaged stream.
bool inflateIfGzipped(std::string* text, std::string* error) {
  if (text->size() < 2 || uint8_t((*text)[0]) != 0x1f || uint8_t((*text)[1]) != 0x8b) return true;
  // A RIB that large is no scene this renderer could hold; a stream that inflates past it is
  // damaged or hostile.
  constexpr size_t kMaxInflated = size_t(2) << 30;
  z_stream z{};
  if (inflateInit2(&z, 15 + 32) != Z_OK) {
    *error = "cannot inflate the gzip-compressed scene";
    return false;
  }
  std::string out;
  std::vector<char> chunk(1 << 16);
  // Input is fed in pieces that fit zlib's 32-bit counts (a file over 4 GiB was cut short).
  size_t consumed = 0;
  auto feed = [&] {
    const size_t piece = std::min<size_t>(text->size() - consumed, size_t(1) << 30);
    z.next_in = reinterpret_cast<Bytef*>(text->data() + consumed);
    z.avail_in = uInt(piece);
    consumed += piece;
  };
  feed();
  int status = Z_OK;
  for (;;) {
    z.next_out = reinterpret_cast<Bytef*>(chunk.data());
    z.avail_out = uInt(chunk.size());
    status = inflate(&z, Z_NO_FLUSH);
    if (status != Z_OK && status != Z_STREAM_END) break;
    out.append(chunk.data(), chunk.size() - z.avail_out);
    if (out.size() > kMaxInflated) {
      inflateEnd(&z);
      *error = "the gzip-compressed scene inflates to more than 2 GiB";
      return false;
    }
    if (z.avail_in == 0 && consumed < text->size()) feed();
    const size_t left = z.avail_in + (text->size() - consumed);
    if (status == Z_STREAM_END) {
      if (left == 0) break;
      // Members one after another (`cat a.gz b.gz`, pigz) make one file, as zcat reads them;
      // anything else after the stream is damage, not something to drop without a word.
      const size_t at = text->size() - left;
      if (left < 2 || uint8_t((*text)[at]) != 0x1f || uint8_t((*text)[at + 1]) != 0x8b) {
        inflateEnd(&z);
        *error = "the gzip-compressed scene has " + std::to_string(left) + " bytes of trailing data after its stream";
        return false;
      }
      inflateReset(&z);
      continue;
    }
    if (z.avail_in == 0 && z.avail_out != 0) break;  // all input read, no end: truncated
  }
  inflateEnd(&z);
  if (status != Z_STREAM_END) {
    *error = std::string("the gzip-compressed scene is damaged or truncated") + (z.msg ? std::string(" (") + z.msg + ")" : "");
    return false;
  }
  *text = std::move(out);
  return true;
}

// The requests of the RenderMan Interface (3.2, 3.4 and PRMan's RIS additions): a name among
// them that Relief does not handle is skipped as unsupported; any other name is a slip, and the
// warning suggests the request it most likely meant.
constexpr std::string_view kRiRequests[] = {
    "AreaLightSource", "ArchiveBegin", "ArchiveEnd", "ArchiveRecord", "Atmosphere", "Attribute",
    "AttributeBegin", "AttributeEnd", "Basis", "Blobby", "Bound", "Bxdf", "Camera", "Clipping",
    "ClippingPlane", "Color", "ColorSamples", "ConcatTransform", "Cone", "CoordSysTransform",
    "CoordinateSystem", "CropWindow", "Curves", "Cylinder", "Declare", "Deformation", "DepthOfField",
    "Detail", "DetailRange", "Disk", "Displacement", "Display", "DisplayChannel", "DisplayFilter",
    "EditAttributeBegin", "EditAttributeEnd", "EditBegin", "EditEnd", "EditWorldBegin", "EditWorldEnd",
    "Else", "ElseIf", "ErrorHandler", "Exposure", "Exterior", "Format", "FrameAspectRatio",
    "FrameBegin", "FrameEnd", "GeneralPolygon", "GeometricApproximation", "Geometry",
    "HierarchicalSubdivisionMesh", "Hider", "Hyperboloid", "Identity", "IfBegin", "IfEnd",
    "Illuminate", "Imager", "Integrator", "Interior", "Light", "LightFilter", "LightSource",
    "MakeBrickMap", "MakeBump", "MakeCubeFaceEnvironment", "MakeLatLongEnvironment", "MakeShadow",
    "MakeTexture", "Matte", "MotionBegin", "MotionEnd", "NuPatch", "ObjectBegin", "ObjectEnd",
    "ObjectInstance", "Opacity", "Option", "Orientation", "Paraboloid", "Patch", "PatchMesh",
    "Pattern", "Perspective", "PixelFilter", "PixelSampleImager", "PixelSamples", "PixelVariance",
    "Points", "PointsGeneralPolygons", "PointsPolygons", "Polygon", "Procedural", "Procedural2",
    "Projection", "Quantize", "ReadArchive", "RelativeDetail", "Resource", "ResourceBegin",
    "ResourceEnd", "ReverseOrientation", "Rotate", "SampleFilter", "Scale", "ScopedCoordinateSystem",
    "ScreenWindow", "Shader", "ShaderLayer", "ConnectShaderLayers", "ShadingInterpolation",
    "ShadingRate", "Shutter", "Sides", "Skew", "SolidBegin", "SolidEnd", "Sphere",
    "SubdivisionMesh", "Surface", "System", "TextureCoordinates", "Torus", "Transform",
    "TransformBegin", "TransformEnd", "Translate", "TrimCurve", "VPAtmosphere", "VPInterior",
    "VPSurface", "Volume", "VolumePixelSamples", "WorldBegin", "WorldEnd", "version"};

// Optimal-string-alignment distance (edits and adjacent swaps), compared case-blind.
size_t editDistance(std::string_view a, std::string_view b) {
  auto lower = [](char c) { return char(std::tolower(static_cast<unsigned char>(c))); };
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i)
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t cost = lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && lower(a[i - 1]) == lower(b[j - 2]) && lower(a[i - 2]) == lower(b[j - 1]))
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// The warning for a request Relief does not handle: a RenderMan request it skips, or a name
// RenderMan does not have (with the likeliest meant one: requests are case-sensitive).
std::string unhandledRequestMessage(const std::string& name) {
  if (std::find(std::begin(kRiRequests), std::end(kRiRequests), name) != std::end(kRiRequests)) {
    std::string text = "unsupported request '" + name + "' ignored";
    if (name == "ShadingRate" || name == "GeometricApproximation")
      text += " (Relief dices displacement by world-space edge length: Attribute \"relief\" \"float "
              "edgelength\", or --edge-length)";
    return text;
  }
  std::string_view best;
  size_t bestDistance = std::max<size_t>(2, name.size() / 4) + 1;
  for (std::string_view request : kRiRequests) {
    // The lengths alone bound the distance from below (and keep a 200,000-letter word cheap).
    const size_t lengthGap = name.size() > request.size() ? name.size() - request.size() : request.size() - name.size();
    if (lengthGap >= bestDistance) continue;
    const size_t distance = editDistance(name, request);
    if (distance < bestDistance) best = request, bestDistance = distance;
  }
  std::string text = "unknown request '" + name + "' ignored";
  if (!best.empty()) text += " (did you mean '" + std::string(best) + "'?)";
  return text;
}

// A type word of a declaration. "hpoint" is a point with a fourth, homogeneous coordinate
// (*homogeneous is set); "bool" is stored as an int, as RenderMan's bool parameters are 0 or 1.
std::optional<runtime::ParamType> parseTypeWord(std::string_view word, bool* homogeneous) {
  using runtime::ParamType;
  *homogeneous = false;
  if (word == "float") return ParamType::Float;
  if (word == "int" || word == "integer" || word == "bool") return ParamType::Int;
  if (word == "hpoint") {
    *homogeneous = true;
    return ParamType::Point;
  }
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

// A number as a user would write it in a message (0.001, not 0.001000).
std::string formatNumber(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
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

CubicBasis bezierBasis() {
  CubicBasis basis;
  namedCubicBasis("bezier", &basis);
  return basis;
}

// Largest axis scale of an affine transform: converts a length (e.g. a displacement bound) to the
// destination space conservatively.
float maxScale(const glm::mat4& m) {
  return std::max({glm::length(glm::vec3(m[0])), glm::length(glm::vec3(m[1])),
                   glm::length(glm::vec3(m[2]))});
}

// A transform that flattens space (Scale 0 0 0, which exporters use to hide objects, or any
// rank-deficient matrix): it has no inverse, so normals under it are undefined. Judged by the
// volume of the unit cube's image against the product of its edge lengths, so uniformly tiny but
// well-shaped scales are not singular.
bool singular(const glm::mat4& m) {
  const glm::dvec3 a{glm::vec3(m[0])}, b{glm::vec3(m[1])}, c{glm::vec3(m[2])};
  const double edges = glm::length(a) * glm::length(b) * glm::length(c);
  return !(edges > 0.0) || !(std::fabs(glm::dot(a, glm::cross(b, c))) > 1e-7 * edges);
}

// RenderMan's matte: the default surface, whose Ka and Kd are 1 (Material's own defaults are not).
Material matteMaterial() {
  Material m;
  m.Ka = 1.0f;
  m.Kd = 1.0f;
  return m;
}

// How a primitive variable's values map onto a polygon mesh or patch mesh (RenderMan's storage
// classes; "varying" and "vertex" coincide on polygons).
enum class PrimvarClass { Constant, Uniform, Vertex, Varying, FaceVarying };

struct Primvar {
  std::string name;
  int components = 0;
  PrimvarClass storage = PrimvarClass::Vertex;
  std::vector<float> values;
  const float* at(size_t i) const { return values.data() + i * size_t(components); }
};

struct AttributeState {
  glm::mat4 ctm{1.0f};  // current space -> world (camera space before WorldBegin)
  Material material = matteMaterial();  // Color, Opacity, Surface, Sides, Orientation
  bool orientationInside = false;        // Orientation "inside"/"rh"
  bool reversed = false;                 // an odd number of ReverseOrientation calls
  std::vector<uint32_t> lightsOn;        // Scene::lights indices lit by Illuminate, sorted
  CubicBasis uBasis = bezierBasis(), vBasis = bezierBasis();
  std::shared_ptr<const runtime::ShaderInstance> displacement;
  std::vector<runtime::ParamValue> displacementValues;  // what the Displacement call bound
  glm::mat4 worldFromShader{1.0f};
  int displacementLine = 0;
  std::string displacementFile;  // the file of the Displacement call (a ReadArchive may differ)
  float boundRadius = 0.0f;
  bool boundGiven = false;  // a bound of 0 given is a statement, not an omission
  std::string boundSpace = "object";
  float boundNamedScale = 1.0f;  // for a boundSpace made by CoordinateSystem
  float edgeLength = 0.05f;
  float flatness = 0.0f;
  bool lightShadows = true;  // Attribute "light" "shadows" (BMRT): for lights declared from here
};

struct StackEntry {
  AttributeState state;
  bool attribute = true;  // AttributeBegin (else TransformBegin)
  int line = 0;
  std::string file;  // where the block opened: an archive's blocks may be left open
  // ScopedCoordinateSystem names defined in this attribute block, with what they meant before
  // (nothing: undefined), restored at its AttributeEnd.
  std::vector<std::pair<std::string, std::optional<glm::mat4>>> scopedSpaces;
};

class RibParser {
 public:
  // listFrames: read no frame block, only number them (readRibFrameNumbers).
  RibParser(const std::string& fileName, const RibReadOptions& options, bool listFrames = false)
      : fileName_(fileName),
        options_(options),
        searchPath_(options.defaultShaderPath),
        listFrames_(listFrames),
        selectedFrame_(listFrames ? -1 : options.frame) {
    const std::filesystem::path p(fileName);
    baseDir_ = p.has_parent_path() ? p.parent_path().string() : std::string(".");
    archivePath_ = {baseDir_};
    scene_.camera.perspective = false;  // RenderMan's default projection
    scene_.pixelSamples = 4;            // and its default PixelSamples 2 2
    scene_.texturePath = options.defaultTexturePath;
  }

  std::optional<Scene> parse(std::vector<RibToken> tokens, SceneError* error) {
    tokens_ = std::move(tokens);
    runCalls();
    if (failed_) {
      *error = error_;
      return std::nullopt;
    }
    const int eofLine = tokens_.back().line;
    if (motionLine_ > 0) {
      fail(eofLine, "unexpected end of file: 'MotionBegin' at " +
                        lineRef(motionLine_, motionFile_) + " has no 'MotionEnd'");
    } else if (!stack_.empty()) {
      const StackEntry& e = stack_.back();
      fail(eofLine, std::string("unexpected end of file: '") +
                        (e.attribute ? "AttributeBegin" : "TransformBegin") + "' at " +
                        lineRef(e.line, e.file) + " has no '" +
                        (e.attribute ? "AttributeEnd" : "TransformEnd") + "'");
    } else if (recording_) {
      fail(eofLine, "unexpected end of file: " + unclosedRecording());
    } else if (inWorld_) {
      fail(eofLine, "unexpected end of file: 'WorldBegin' at " + lineRef(worldLine_, worldFile_) +
                        " has no 'WorldEnd'");
    } else if (frameDepth_ > 0) {
      fail(eofLine, "unexpected end of file: 'FrameBegin' at " + lineRef(frameLine_, frameFile_) +
                        " has no 'FrameEnd'");
    } else if (listFrames_) {
      // Frames are numbered, not read: there is no world to ask for.
    } else if (selectedFrame_ < 0 || selectedFrame_ >= numFrames()) {
      fail(0, "no frame with index " + std::to_string(selectedFrame_) + ": the file has " +
                  std::to_string(numFrames()) + (numFrames() == 1 ? " frame" : " frames"));
    } else if (!worldDone_ && !scene_.frameNumbers.empty()) {
      fail(selectedFrameLine_, "frame " + std::to_string(scene_.frameNumbers[selectedFrame_]) +
                                   " has no 'WorldBegin'/'WorldEnd' block: nothing to render");
    } else if (!worldDone_) {
      fail(eofLine, "no 'WorldBegin'/'WorldEnd' block: nothing to render");
    }
    if (failed_) {
      *error = error_;
      return std::nullopt;
    }
    warnLightsThatLightNothing();
    // The older view of the lights, for readers that have not moved to Scene::lights.
    for (const Light& light : scene_.lights) {
      if (light.type == LightType::Distant) {
        DistantLight d;
        d.directionToLight = -light.direction;
        d.color = light.color;
        scene_.distantLights.push_back(d);
      } else if (light.type == LightType::Ambient) {
        scene_.ambientColor += light.color;
      }
    }
    scene_.ambient = (scene_.ambientColor.r + scene_.ambientColor.g + scene_.ambientColor.b) / 3.0f;
    scene_.frameIndex = std::max(selectedFrame_, 0);
    return std::move(scene_);
  }

 private:
  int numFrames() const { return scene_.numFrames(); }

  // FrameBegin n: numbers every frame, reads only the selected one.
  bool beginFrame(const Call& call) {
    if (frameDepth_ > 0) return fail(call.line, "nested 'FrameBegin'");
    ++frameDepth_;
    frameLine_ = call.line;
    frameFile_ = fileName_;
    const int index = int(scene_.frameNumbers.size());
    scene_.frameNumbers.push_back(frameNumber(call));
    skipping_ = index != selectedFrame_;
    if (!skipping_) selectedFrameLine_ = call.line;
    return true;
  }

  // RIB numbers frames with an integer. Exporters always give one, so a missing or fractional
  // number is only warned about and the frame takes its position (1-based) instead.
  int frameNumber(const Call& call) {
    const int position = int(scene_.frameNumbers.size()) + 1;
    if (call.args.size() == 1 && call.args[0].isNumeric() && call.args[0].numbers.size() == 1) {
      const double n = call.args[0].numbers[0];
      if (n == std::floor(n) && std::fabs(n) <= 1e9) return int(n);
    }
    warn(call.line, "'FrameBegin' expects an integer frame number; numbering this frame " +
                        std::to_string(position));
    return position;
  }

  // Executes the calls of tokens_ from pos_ to the end; false on the first error.
  bool runCalls() {
    Call call;
    while (true) {
      bool end = false;
      if (!nextCall(&call, &end)) return false;
      if (end) return true;
      try {
        if (!execute(call)) return false;
      } catch (const std::bad_alloc&) {
        // Named at the request that ran out (the innermost archive's, when they nest).
        return fail(call.line, "out of memory at '" + call.name + "' (" + std::to_string(inputTriangles_) +
                                   " input triangles read so far)");
      }
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
    call->wordAfter.clear();
    ++pos_;
    while (true) {
      const RibToken& a = tokens_[pos_];
      if (a.kind == RibToken::Kind::Request && a.line == call->line) call->wordAfter = a.text;
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
          } else if (e.kind == RibToken::Kind::Request && isNonFiniteWord(e.text)) {
            return fail(e.line, "'" + e.text + "' is not a number: RIB numbers must be finite");
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

  // A light on for no geometry at all is most likely one declared inside an attribute block:
  // RenderMan switches it off at the block's AttributeEnd, and features.rib lost two area lights
  // so without a word.
  void warnLightsThatLightNothing() {
    if (!options_.warnings || scene_.meshes.empty()) return;
    std::vector<uint8_t> used(scene_.lights.size(), 0);
    for (const Mesh& mesh : scene_.meshes) {
      if (!mesh.lightsSet) return;  // every light reaches it
      for (uint32_t l : mesh.lights)
        if (l < used.size()) used[l] = 1;
    }
    for (size_t l = 0; l < scene_.lights.size() && l < lightOrigins_.size(); ++l) {
      if (used[l]) continue;
      const Light& light = scene_.lights[l];
      const std::string name = light.handle.empty() ? "a light" : "light '" + light.handle + "'";
      *options_.warnings << lightOrigins_[l].first << ":" << lightOrigins_[l].second << ": warning: " << name
                         << " lights no geometry: it is off wherever geometry is declared (RenderMan "
                            "switches a light off at the AttributeEnd of the block declaring it; "
                         << (light.handle.empty() ? std::string("give it a handle and Illuminate it")
                                                  : "'Illuminate \"" + light.handle + "\" 1'")
                         << " turns it on)\n";
    }
  }

  void warnOnce(int line, const std::string& key, const std::string& message) {
    if (warnedKeys_.insert(key).second) warn(line, message);
  }

  // Takes `count` numbers from the leading arguments, bare or bracketed; the rest are parameters.
  // Numbers beyond `count` before the first parameter are dropped with a warning.
  bool positionalNumbers(const Call& call, size_t count, std::vector<float>* out, size_t* next) {
    out->clear();
    size_t i = 0;
    while (out->size() < count && i < call.args.size() && call.args[i].isNumeric()) {
      for (double d : call.args[i].numbers) out->push_back(float(d));
      ++i;
    }
    if (out->size() < count) {
      return fail(call.line, "'" + call.name + "' expects " + std::to_string(count) +
                                 " number" + (count == 1 ? "" : "s") + ", got " +
                                 std::to_string(out->size()) +
                                 (i < call.args.size() && call.args[i].kind == Arg::Kind::String
                                      ? " (then '" + call.args[i].strings[0] + "', a string)"
                                  : i == call.args.size() && !call.wordAfter.empty()
                                      ? " ('" + call.wordAfter + "' is not a number)"
                                      : ""));
    }
    size_t extra = out->size() - count;
    for (; i < call.args.size() && call.args[i].isNumeric(); ++i)
      extra += call.args[i].numbers.size();
    if (extra > 0) {
      warnOnce(call.line, "extra/" + call.name,
               "'" + call.name + "' takes " + std::to_string(count) + " number" +
                   (count == 1 ? "" : "s") + "; " + std::to_string(extra) + " more ignored");
      out->resize(count);
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

  // Reads the `"decl" value` pairs from argument `first` on. A parameter whose type word is unknown
  // is left out, with a warning unless `quiet` (the parameters of shaders Relief does not have are
  // not its business).
  bool parseParams(const Call& call, size_t first, std::vector<Param>* params,
                   bool quiet = false) {
    params->clear();
    // By name, for the duplicate check: a linear search made a call of 50K parameters take 5 s.
    std::unordered_map<std::string, size_t> position;
    std::vector<char> replaced;  // per params entry: a later one of the same name took its place
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
      std::string unknownType;
      if (!parseDeclaration(nameArg.strings[0], nameArg.line, &p, &unknownType)) return false;
      if (!unknownType.empty()) {
        if (!quiet)
          warnOnce(nameArg.line, "type/" + unknownType,
                   "'" + call.name + "': unknown type '" + unknownType + "' in '" +
                       nameArg.strings[0] + "'; parameter ignored");
        continue;
      }
      // A declared array of one value per element (`"float[2] Ks" [0.5 0.2]`) holds exactly that.
      // Primitive variables of other classes hold one such array per face or vertex.
      if (p.arraySize > 0 && p.type && *p.type != runtime::ParamType::String &&
          (p.storageClass.empty() || p.storageClass == "constant") && p.value.isNumeric()) {
        const size_t need = size_t(p.arraySize) * size_t(runtime::paramComponents(*p.type)) *
                            (p.homogeneous ? 4 : 1) / (p.homogeneous ? 3 : 1);
        if (p.value.numbers.size() != need)
          return fail(nameArg.line, "'" + call.name + "': parameter '" + nameArg.strings[0] + "' expects " +
                                        std::to_string(need) + " value" + (need == 1 ? "" : "s") + ", got " +
                                        std::to_string(p.value.numbers.size()));
      }
      // A name given twice is most likely a copy-and-paste slip: the later value wins, as the
      // later of two settings does everywhere else, and the user hears about it.
      const auto [earlier, fresh] = position.try_emplace(p.name, params->size());
      if (!fresh) {
        warn(nameArg.line, "'" + call.name + "': parameter '" + p.name + "' is given twice; the later value is used");
        replaced[earlier->second] = 1;
        earlier->second = params->size();
      }
      params->push_back(std::move(p));
      replaced.push_back(0);
    }
    // The replaced ones go, the rest keep their order (the later value where the earlier was
    // dropped, as an erase and an append would leave them).
    size_t kept = 0;
    for (size_t k = 0; k < params->size(); ++k)
      if (!replaced[k]) {
        if (kept != k) (*params)[kept] = std::move((*params)[k]);
        ++kept;
      }
    params->resize(kept);
    return true;
  }

  // decl -> [class] type ['[' n ']'] name  |  name
  // A type word outside the known set is returned in *unknownType (p->type stays empty).
  bool parseDeclaration(const std::string& text, int line, Param* p, std::string* unknownType) {
    unknownType->clear();
    std::vector<std::string> words = splitWords(text);
    if (words.empty()) return fail(line, "empty parameter name");
    p->name = words.back();
    words.pop_back();
    if (!words.empty() && isClassWord(words.front())) {
      p->storageClass = words.front() == "facevertex" ? "facevarying" : words.front();
      words.erase(words.begin());
    }
    if (words.empty()) {
      const auto declared = declared_.find(p->name);
      if (declared != declared_.end()) {
        p->type = declared->second.type;
        p->arraySize = declared->second.arraySize;
        p->homogeneous = declared->second.homogeneous;
        p->declaredLine = declared->second.line, p->declaredFile = &declared->second.file;
        if (p->storageClass.empty()) p->storageClass = declared->second.storageClass;
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
      // A whole number from 1 to a million, and nothing after the bracket: `float[2x]`,
      // `float[-1]` and `float[0x10]` are slips, not sizes.
      const std::string size = typeWord.substr(bracket + 1, close - bracket - 1);
      const bool digits = !size.empty() && size.size() <= 7 &&
                          std::all_of(size.begin(), size.end(), [](char c) { return c >= '0' && c <= '9'; });
      const int n = digits ? std::stoi(size) : 0;
      if (n < 1 || n > 1000000 || close + 1 != typeWord.size())
        return fail(line, "malformed parameter declaration '" + text +
                              "': the array size must be a whole number from 1 to 1000000");
      p->arraySize = n;
      typeWord = typeWord.substr(0, bracket);
    }
    p->type = parseTypeWord(typeWord, &p->homogeneous);
    if (!p->type) *unknownType = typeWord;
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

  // The control points of a geometry call, 3 numbers each: "P", or else "Pw" (x y z w, RenderMan's
  // homogeneous points, taken as (x/w, y/w, z/w)). `count` points are expected (0: any number).
  bool positions(const Call& call, const std::vector<Param>& params, size_t count,
                 std::vector<float>* P) {
    if (const Param* p = findParam(params, "P")) {
      if (!numbersParam(call, *p, "point", count * 3, P)) return false;
      if (P->empty() || P->size() % 3 != 0)
        return fail(p->line, "'" + call.name + "': \"P\" needs a multiple of 3 numbers, got " +
                                 std::to_string(P->size()));
      return true;
    }
    const Param* pw = findParam(params, "Pw");
    if (!pw) return fail(call.line, "'" + call.name + "' needs a \"P\" (or \"Pw\") parameter");
    std::vector<float> h;
    if (!numbersParam(call, *pw, "hpoint", count * 4, &h)) return false;
    if (h.empty() || h.size() % 4 != 0)
      return fail(pw->line, "'" + call.name + "': \"Pw\" needs 4 numbers (x y z w) per point, got " +
                                std::to_string(h.size()));
    P->clear();
    for (size_t i = 0; i < h.size(); i += 4) {
      const float w = h[i + 3];
      if (w == 0.0f)
        return fail(pw->line, "'" + call.name + "': \"Pw\" point " + std::to_string(i / 4) +
                                  " has w = 0");
      P->insert(P->end(), {h[i] / w, h[i + 1] / w, h[i + 2] / w});
    }
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
                        const std::vector<std::string_view>& known) {
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
  bool doSubdivisionMesh(const Call& call);
  bool doNuPatch(const Call& call);
  // Moves a point, vector or normal value (any number of triples) by `to`, as its kind moves.
  static void moveSpatial(const glm::mat4& to, runtime::ParamValue* value);
  bool shaderParamValue(int line, const runtime::CompiledShader& compiled, const Param& p,
                        runtime::ParamValue* out);
  bool doDisplacement(const Call& call);
  bool doLight(const Call& call);
  bool doReliefOption(const Call& call, const std::vector<Param>& params);
  bool doSurface(const Call& call);
  bool doBasis(const Call& call);
  bool doProcedural(const Call& call);
  bool doObjectInstance(const Call& call);
  bool readArchive(const Call& call, const std::string& name);
  // "'ObjectBegin' at line N has no 'ObjectEnd'" (or ArchiveBegin's) for the open recording.
  // "line N", and the file too when the block opened in another one (an archive).
  std::string lineRef(int line, const std::string& file) const {
    return "line " + std::to_string(line) + (file != fileName_ ? " of '" + file + "'" : "");
  }
  // For a value that does not fit its type: where the type came from, when a Declare gave it.
  std::string declareNote(const Param& p) const {
    return p.declaredLine ? " (typed by the 'Declare' at " + lineRef(p.declaredLine, *p.declaredFile) + ")" : "";
  }
  std::string unclosedRecording() const {
    const char* what = recordingArchive_ ? "Archive" : "Object";
    return std::string("'") + what + "Begin' at " + lineRef(recordingLine_, recordingFile_) + " has no '" + what + "End'";
  }
  struct RecordedCall;
  bool replay(const std::vector<RecordedCall>& calls);
  bool buildPolygonMesh(const Call& call, const std::vector<int>& nloops,
                        const std::vector<int>& nverts, const std::vector<int>& verts,
                        size_t first);

  // A light handle: RIB allows a number or a string; numbers are kept as their integer text.
  static bool lightHandle(const Arg& arg, std::string* handle) {
    if (arg.kind == Arg::Kind::String) {
      *handle = arg.strings[0];
      return true;
    }
    if (arg.isNumeric() && arg.numbers.size() == 1) {
      const double d = arg.numbers[0];
      *handle = d == std::floor(d) && std::fabs(d) < 1e15 ? std::to_string(int64_t(d))
                                                          : std::to_string(d);
      return true;
    }
    if (arg.isStringy() && arg.strings.size() == 1) {
      *handle = arg.strings[0];
      return true;
    }
    return false;
  }
  bool doSphere(const Call& call);
  bool doQuadric(const Call& call);
  struct PrimvarCounts {
    size_t uniform, vertex, varying, faceVarying;
  };
  bool shaderPrimvar(const Call& call, const Param& p, const PrimvarCounts& counts);
  bool readPrimvars(const Call& call, const std::vector<Param>& params,
                    const PrimvarCounts& counts, std::vector<Primvar>* out);
  // Finds a file named by the file being read (an archive, an OBJ mesh). A relative name is
  // tried against that file's directory, then along Option "searchpath" "archive" (by default
  // the scene's directory), then from the working directory. Returns the first regular file, or
  // "" with *tried listing where it looked.
  std::string findFile(const std::string& name, std::string* tried) const {
    namespace fs = std::filesystem;
    std::vector<fs::path> candidates;
    if (fs::path(name).is_absolute()) {
      candidates.push_back(name);
    } else {
      candidates.push_back(fs::path(fileName_).parent_path() / name);
      for (const std::string& dir : archivePath_) candidates.push_back(fs::path(dir) / name);
      candidates.push_back(name);
    }
    std::vector<std::string> seen, notes;
    for (const fs::path& candidate : candidates) {
      const std::string path = candidate.lexically_normal().string();
      if (std::find(seen.begin(), seen.end(), path) != seen.end()) continue;
      std::error_code ec;
      if (fs::is_regular_file(path, ec)) return path;
      seen.push_back(path);
      // A device or directory there is not "missing": say what it is (scene-format.md).
      notes.push_back(fs::exists(path, ec) ? ": not a regular file" : "");
    }
    tried->clear();
    for (size_t i = 0; i < seen.size(); ++i) *tried += (tried->empty() ? "'" : ", '") + seen[i] + "'" + notes[i];
    return std::string();
  }
  // Quadrics take st, s, t and Cs as constant (1 value) or varying/vertex (4 values at the
  // corners of the (u, v) range, interpolated bilinearly).
  bool quadricPrimvars(const Call& call, const std::vector<Param>& params,
                       std::vector<Primvar>* vars) {
    if (!readPrimvars(call, params, PrimvarCounts{1, 4, 4, 4}, vars)) return false;
    for (const Primvar& v : *vars)
      if (v.name == "N")
        return fail(call.line, "'" + call.name + "': \"N\" is not supported on quadrics");
    return true;
  }
  static void applyQuadricPrimvars(const std::vector<Primvar>& vars, Mesh* mesh) {
    auto value = [](const Primvar& v, glm::vec2 uv, int c) {
      if (v.values.size() == size_t(v.components)) return v.values[size_t(c)];
      const float* p[4] = {v.at(0), v.at(1), v.at(2), v.at(3)};
      return (1 - uv.y) * ((1 - uv.x) * p[0][c] + uv.x * p[1][c]) +
             uv.y * ((1 - uv.x) * p[2][c] + uv.x * p[3][c]);
    };
    const Primvar *st = nullptr, *s = nullptr, *t = nullptr, *Cs = nullptr;
    for (const Primvar& v : vars) {
      if (v.name == "st") st = &v;
      if (v.name == "s") s = &v;
      if (v.name == "t") t = &v;
      if (v.name == "Cs") Cs = &v;
    }
    if (st || s || t) {
      mesh->st.clear();
      for (glm::vec2 uv : mesh->uv)
        mesh->st.emplace_back(st ? value(*st, uv, 0) : s ? value(*s, uv, 0) : uv.x,
                              st ? value(*st, uv, 1) : t ? value(*t, uv, 0) : uv.y);
    }
    if (Cs)
      for (glm::vec2 uv : mesh->uv)
        mesh->Cs.emplace_back(value(*Cs, uv, 0), value(*Cs, uv, 1), value(*Cs, uv, 2));
  }
  bool buildPatchMesh(const Call& call, bool bicubic, int nu, bool uPeriodic, int nv,
                      bool vPeriodic, size_t first);
  bool doGeometry(const Call& call);
  // Adds a primitive's world-space mesh with the current attributes. `wound`: its winding already
  // accounts for a mirroring current transform (tessellateSphere does that itself).
  bool addMesh(Mesh mesh, int line, bool wound = false);

  uint32_t materialIndex() {
    Material m = attr_.material;
    m.reverseOrientation = attr_.orientationInside != attr_.reversed;
    auto same = [](const Material& a, const Material& b) {
      return a.type == b.type && a.color == b.color && a.opacity == b.opacity && a.Ka == b.Ka &&
             a.Kd == b.Kd && a.Ks == b.Ks && a.roughness == b.roughness &&
             a.specularColor == b.specularColor && a.Kr == b.Kr && a.Kt == b.Kt &&
             a.eta == b.eta && a.transmitColor == b.transmitColor && a.twoSided == b.twoSided &&
             a.reverseOrientation == b.reverseOrientation && a.castsShadows == b.castsShadows &&
             a.opaqueShadows == b.opaqueShadows;
    };
    for (size_t i = 0; i < scene_.materials.size(); ++i) {
      if (same(scene_.materials[i], m)) return uint32_t(i);
    }
    scene_.materials.push_back(m);
    return uint32_t(scene_.materials.size() - 1);
  }

  bool displacementIndex(int line, uint32_t* index) {
    *index = UINT32_MAX;
    if (!attr_.displacement) return true;
    Displacement d;
    d.shader = attr_.displacement;
    if (!primvarParams_.empty()) {
      // An instance per distinct set of values: the Displacement call's, then the primitive's.
      // The entry keeps the call's instance alive, so that its address (in the key) is not reused
      // by a later call's: after an AttributeEnd freed it, the next block's Displacement got its
      // address and found the old block's values. Strings are length-prefixed, so none can
      // imitate another's key.
      std::string key = std::to_string(reinterpret_cast<uintptr_t>(attr_.displacement.get()));
      for (const runtime::ParamValue& v : primvarParams_) {
        key += "|" + std::to_string(v.name.size()) + ":" + v.name;
        for (double x : v.numbers) {
          char text[32];
          std::snprintf(text, sizeof text, " %.17g", x);
          key += text;
        }
        for (const std::string& x : v.strings) key += " " + std::to_string(x.size()) + ":" + x;
      }
      auto& [source, instance] = boundInstances_[key];
      if (!instance) {
        source = attr_.displacement;
        auto fresh = std::make_shared<runtime::ShaderInstance>(attr_.displacement->sharedShader());
        std::string error;
        for (const runtime::ParamValue& v : attr_.displacementValues) fresh->bind(v, &error);
        for (const runtime::ParamValue& v : primvarParams_)
          if (!fresh->bind(v, &error)) return fail(line, error);
        instance = std::move(fresh);
      }
      d.shader = instance;
    }
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
    // Boxes grown by a bound near float's limit overflow to infinity, and then no ray meets any
    // voxel: a black image without a word (a bound of 2e38).
    if (!(d.boundWorld < 1e30f))
      return fail(line, "the displacement bound is " + formatNumber(d.boundWorld) +
                            " world units, beyond any scene Relief can render (at most 1e30; Attribute "
                            "\"displacementbound\")");
    d.edgeLength = attr_.edgeLength;
    d.flatness = attr_.flatness;
    d.reverseOrientation = attr_.orientationInside != attr_.reversed;
    toRlfMatrix(worldFromObject, d.spaces.currentFromObject);
    toRlfMatrix(glm::inverse(worldFromObject), d.spaces.objectFromCurrent);
    toRlfMatrix(attr_.worldFromShader, d.spaces.currentFromShader);
    toRlfMatrix(glm::inverse(attr_.worldFromShader), d.spaces.shaderFromCurrent);
    toRlfMatrix(scene_.camera.worldFromCamera, d.spaces.currentFromCamera);
    toRlfMatrix(glm::inverse(scene_.camera.worldFromCamera), d.spaces.cameraFromCurrent);
    d.sourceFile = attr_.displacementFile;
    d.sourceLine = attr_.displacementLine;
    if (!attr_.boundGiven)
      warnOnce(line, "zerobound" + attr_.displacementFile + ":" + std::to_string(attr_.displacementLine),
               "displacement shader '" + d.shader->name() +
                   "' has no 'displacementbound'; displaced geometry may be clipped");
    if (!scene_.displacements.empty()) {
      const Displacement& last = scene_.displacements.back();
      if (last.shader == d.shader && last.boundWorld == d.boundWorld &&
          last.edgeLength == d.edgeLength && last.flatness == d.flatness &&
          last.reverseOrientation == d.reverseOrientation &&
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
  // The current primitive's primitive variables named like parameters of its displacement shader
  // (RenderMan binds them over the Displacement call's values), and the instances made for them.
  std::vector<runtime::ParamValue> primvarParams_;
  // Instances with primitive variables bound: key -> (the Displacement call's instance, kept
  // alive so that its address stays unique; the bound instance).
  std::map<std::string, std::pair<std::shared_ptr<const runtime::ShaderInstance>,
                                  std::shared_ptr<const runtime::ShaderInstance>>>
      boundInstances_;
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
  std::vector<std::string> archivePath_;  // Option "searchpath" "archive"; see findFile
  struct Declared {
    runtime::ParamType type;
    int arraySize = 0;
    bool homogeneous = false;
    std::string storageClass;
    int line = 0;  // of the Declare
    std::string file;
  };
  std::map<std::string, Declared> declared_;  // Declare "name" "[class] type"
  std::map<std::string, uint32_t> lightHandles_;  // handle -> Scene::lights index
  std::set<std::string> skippedLightHandles_;      // of lights the reader skipped
  std::vector<size_t> lightsBeforeWorld_;          // in camera space until WorldBegin
  std::vector<std::pair<std::string, int>> lightOrigins_;  // per Scene::lights entry: file, line
  // ObjectBegin/End: the recorded calls of each object, replayed by ObjectInstance.
  struct RecordedCall {
    Call call;
    std::string file;
  };
  std::map<std::string, std::vector<RecordedCall>> objects_;
  std::vector<RecordedCall>* recording_ = nullptr;
  bool recordingArchive_ = false;  // recording_ is an inline archive, ended by ArchiveEnd
  std::map<std::string, std::vector<RecordedCall>> inlineArchives_;  // ArchiveBegin/End, for ReadArchive
  std::string recordingName_;
  int recordingLine_ = 0;
  std::string recordingFile_;
  std::vector<std::pair<std::string, int>> recordingBlocks_;  // blocks open in the object (name, line)
  int instanceDepth_ = 0;
  // Budgets on what a scene expands to (execute, addMesh), past which reading stops with an error.
  static constexpr uint64_t kMaxExpandedRequests = uint64_t(1) << 24;
  // 2^26 input triangles take about 4 GB as meshes, before the grid lists them.
  static constexpr uint64_t kMaxInputTriangles = uint64_t(1) << 26;
  uint64_t executedCalls_ = 0, inputTriangles_ = 0;
  int frameDepth_ = 0;
  int frameLine_ = 0;
  std::string frameFile_;
  const bool listFrames_;
  const int selectedFrame_;     // index into scene_.frameNumbers; -1: none (listFrames_)
  int selectedFrameLine_ = 0;   // its FrameBegin
  bool skipping_ = false;       // inside a frame block other than the selected one
  bool frameDone_ = false;      // the selected frame and its world have ended
  int motionLine_ = 0;     // line of the open MotionBegin; 0: outside motion blocks
  std::string motionFile_;
  bool motionSampleTaken_ = false;  // the open motion block's first sample has run
  std::set<std::string> warnedKeys_;
  bool inWorld_ = false, worldDone_ = false;
  int worldLine_ = 0;
  std::string worldFile_;
  int archiveDepth_ = 0;
  // name -> worldFromNamed; before WorldBegin, cameraFromNamed for the names in
  // spacesBeforeWorld_ (the world is not placed yet), made world-relative at WorldBegin.
  std::map<std::string, glm::mat4> coordinateSystems_;
  std::set<std::string> spacesBeforeWorld_;
  float frameAspect_ = 0.0f;
};

bool RibParser::execute(const Call& call) {
  const std::string& name = call.name;
  // Nested ObjectInstance and ReadArchive multiply: 32 levels of two instances each are 4 billion
  // requests. A budget on what the scene expands to keeps such a file from running for hours.
  if (++executedCalls_ > kMaxExpandedRequests)
    return fail(call.line, "the scene expands to more than " + std::to_string(kMaxExpandedRequests) +
                               " requests (ObjectInstance or ReadArchive nested within each other?)");
  // Calls that cannot reach the frame being read: another frame's (FrameEnd restores the options
  // and the world ends inside the frame), or any after the frame was rendered. Only frame blocks
  // are followed, so that all are numbered and each must be closed.
  if (skipping_ || frameDone_) {
    if (name == "FrameBegin") return beginFrame(call);
    // A world block after the last frame block would be a further image; reading past it in
    // silence hid it and every error inside it.
    if (name == "WorldBegin" && frameDepth_ == 0)
      return fail(call.line, "'WorldBegin' outside 'FrameBegin'/'FrameEnd' in a file of frame blocks: "
                             "put this image in a frame block of its own");
    if (name == "FrameEnd") {
      if (frameDepth_ == 0) return fail(call.line, "'FrameEnd' without 'FrameBegin'");
      --frameDepth_;
      skipping_ = false;
    }
    return true;
  }
  if (recording_ && recordingArchive_) {
    // An inline archive (ArchiveBegin "name" ... ArchiveEnd) is text kept for ReadArchive "name",
    // which runs it where it is read, like an archive file.
    if (name == "ArchiveBegin")
      return fail(call.line, "'ArchiveBegin' inside 'ArchiveBegin' (line " + std::to_string(recordingLine_) + ")");
    if (name == "ArchiveEnd") {
      recording_ = nullptr;
      recordingArchive_ = false;
      return true;
    }
    recording_->push_back(RecordedCall{call, fileName_});
    return true;
  }
  if (recording_) {
    // An object's blocks must balance within it: checked here, where the lines are known, and even
    // if the object is never instanced.
    if (name == "ObjectEnd") {
      if (!recordingBlocks_.empty())
        return fail(call.line, "'ObjectEnd' leaves '" + recordingBlocks_.back().first + "' (line " +
                                   std::to_string(recordingBlocks_.back().second) + ") open in object '" +
                                   recordingName_ + "'");
      recording_ = nullptr;
      return true;
    }
    if (name == "AttributeBegin" || name == "TransformBegin" || name == "MotionBegin") {
      recordingBlocks_.emplace_back(name, call.line);
    } else if (name == "AttributeEnd" || name == "TransformEnd" || name == "MotionEnd") {
      const std::string opener = name.substr(0, name.size() - 3) + "Begin";
      if (recordingBlocks_.empty())
        return fail(call.line, "'" + name + "' without '" + opener + "' in object '" + recordingName_ +
                                   "' (ObjectBegin at line " + std::to_string(recordingLine_) + ")");
      if (recordingBlocks_.back().first != opener)
        return fail(call.line, "'" + name + "' closes '" + recordingBlocks_.back().first + "' (line " +
                                   std::to_string(recordingBlocks_.back().second) + ") in object '" +
                                   recordingName_ + "'");
      recordingBlocks_.pop_back();
    }
    if (name == "ObjectBegin" || name == "WorldBegin" || name == "WorldEnd" ||
        name == "FrameBegin" || name == "FrameEnd" || name == "ArchiveBegin")
      return fail(call.line, "'" + name + "' inside 'ObjectBegin' (line " +
                                 std::to_string(recordingLine_) + ")");
    recording_->push_back(RecordedCall{call, fileName_});
    return true;
  }
  if (name == "ArchiveBegin") {
    std::string archive;
    if (call.args.empty() || !positionalString(call, 0, &archive))
      return fail(call.line, "'ArchiveBegin' expects a name");
    recording_ = &inlineArchives_[archive];
    recording_->clear();
    recordingArchive_ = true;
    recordingName_ = archive;
    recordingLine_ = call.line;
    recordingFile_ = fileName_;
    return true;
  }
  if (name == "ArchiveEnd") return fail(call.line, "'ArchiveEnd' without 'ArchiveBegin'");
  if (name == "ObjectBegin") {
    std::string handle;
    if (call.args.size() != 1 || !lightHandle(call.args[0], &handle))
      return fail(call.line, "'ObjectBegin' expects one handle (a number or a string)");
    recording_ = &objects_[handle];
    recording_->clear();
    recordingName_ = handle;
    recordingLine_ = call.line;
    recordingFile_ = fileName_;
    recordingBlocks_.clear();
    return true;
  }
  // MotionBegin [times] sample... MotionEnd: each call inside is one sample of the same request.
  // Without motion blur the scene is the one at the first time, so only the first call counts.
  if (name == "MotionBegin") {
    if (motionLine_ > 0)
      return fail(call.line, "nested 'MotionBegin' (the block at " +
                                 lineRef(motionLine_, motionFile_) + " is still open)");
    warnOnce(call.line, "motion",
             "motion blur is not supported; each motion block uses its first sample");
    motionLine_ = call.line;
    motionFile_ = fileName_;
    motionSampleTaken_ = false;
    return true;
  }
  if (name == "MotionEnd") {
    if (motionLine_ == 0) return fail(call.line, "'MotionEnd' without 'MotionBegin'");
    motionLine_ = 0;
    return true;
  }
  if (motionLine_ > 0) {
    if (motionSampleTaken_) return true;
    motionSampleTaken_ = true;
  }
  if (name == "ObjectEnd") return fail(call.line, "'ObjectEnd' without 'ObjectBegin'");
  if (name == "ObjectInstance") return doObjectInstance(call);
  if (name == "FrameBegin") return beginFrame(call);
  if (name == "FrameEnd") {
    if (frameDepth_ == 0) return fail(call.line, "'FrameEnd' without 'FrameBegin'");
    if (inWorld_)
      return fail(call.line, "'FrameEnd' inside the world block (" +
                                 lineRef(worldLine_, worldFile_) + ")");
    --frameDepth_;
    // Only the selected frame's FrameEnd gets here. Calls after it would come after its image in
    // RenderMan; a frame whose world follows the block (not RIB, but accepted) keeps reading.
    frameDone_ = worldDone_;
    return true;
  }
  bool handled = false;
  if (!executeCamera(call, &handled) || handled) return !failed_;
  if (!executeTransform(call, &handled) || handled) return !failed_;
  if (!executeAttributes(call, &handled) || handled) return !failed_;
  primvarParams_.clear();  // a primitive's shader-parameter primvars are its own
  if (!executeGeometry(call, &handled) || handled) return !failed_;
  const std::string& n = call.name;
  if (n == "version") return true;
  // The message is made only the first time: its suggestion costs an edit distance to every
  // request name (100,000 unknown calls took 23 s when it was made for each).
  if (warnedKeys_.insert("request/" + n).second) warn(call.line, unhandledRequestMessage(n));
  return true;
}

bool RibParser::executeCamera(const Call& call, bool* handled) {
  *handled = true;
  const std::string& n = call.name;
  // Options are frozen at WorldBegin (RI spec): one inside the world block is reported and
  // ignored, as RenderMan's default error handler does, never applied half-way through.
  static const char* const kOptions[] = {"Format", "PixelSamples", "PixelFilter", "Projection",
                                         "Clipping", "ScreenWindow", "FrameAspectRatio",
                                         "Display", "Option", "CropWindow", "Exposure",
                                         "Hider", "PixelVariance", "Quantize", "DepthOfField",
                                         "Shutter"};
  if (inWorld_ && std::find(std::begin(kOptions), std::end(kOptions), n) != std::end(kOptions)) {
    warnOnce(call.line, "inworld/" + fileName_ + ":" + std::to_string(call.line) + "/" + n,
             "'" + n + "' inside the world block (WorldBegin at " + lineRef(worldLine_, worldFile_) +
                 ") is ignored: options must come before WorldBegin");
    return true;
  }
  std::vector<float> v;
  size_t next = 0;
  if (n == "Format") {
    if (!positionalNumbers(call, 3, &v, &next)) return false;
    if (v[0] < 1 || v[1] < 1 || v[0] > 65536 || v[1] > 65536 || v[0] != std::floor(v[0]) ||
        v[1] != std::floor(v[1]))
      return fail(call.line, "'Format' resolution must be whole numbers between 1 and 65536");
    if (uint64_t(v[0]) * uint64_t(v[1]) > kMaxPixels)
      return fail(call.line, "'Format' asks for more than " + std::to_string(kMaxPixels) +
                                 " pixels");
    scene_.width = int(v[0]);
    scene_.height = int(v[1]);
    if (!(v[2] > 0)) {
      // -1 asks for the default (RI convention); other values are probably mistakes.
      if (v[2] != -1.0f)
        warnOnce(call.line, "pixelaspect", "'Format' pixel aspect ratio must be positive; 1 used");
      v[2] = 1.0f;
    }
    scene_.camera.pixelAspect = v[2];
  } else if (n == "CropWindow") {
    if (!positionalNumbers(call, 4, &v, &next)) return false;
    for (float& f : v) f = std::clamp(f, 0.0f, 1.0f);
    if (!(v[0] < v[1]) || !(v[2] < v[3]))
      return fail(call.line, "'CropWindow' expects xmin < xmax and ymin < ymax within [0, 1]");
    std::copy(v.begin(), v.begin() + 4, scene_.cropWindow);
    scene_.cropSource = fileName_ + ":" + std::to_string(call.line);
  } else if (n == "Exposure") {
    if (!positionalNumbers(call, 2, &v, &next)) return false;
    if (!std::isfinite(v[0]) || v[0] < 0.0f || !std::isfinite(v[1]) || !(v[1] > 0.0f))
      return fail(call.line, "'Exposure' expects a gain of 0 or more and a gamma above 0");
    scene_.exposureGain = v[0];
    scene_.exposureGamma = v[1];
  } else if (n == "PixelSamples") {
    if (!positionalNumbers(call, 2, &v, &next)) return false;
    // Clamped before rounding so that absurd counts reach the check below without overflowing.
    const int xs = int(std::lround(std::clamp(v[0], 1.0f, 4096.0f)));
    const int ys = int(std::lround(std::clamp(v[1], 1.0f, 4096.0f)));
    if (xs * ys > 4096) return fail(call.line, "'PixelSamples' asks for too many samples");
    // Relief samples whole grids: a rate that is not a whole number of at least 1 is rounded,
    // which the user should hear about.
    if (float(xs) != v[0] || float(ys) != v[1])
      warn(call.line, "'PixelSamples " + formatNumber(v[0]) + " " + formatNumber(v[1]) + "' takes " +
                          std::to_string(xs) + " x " + std::to_string(ys) + " samples per pixel");
    scene_.pixelSamples = xs * ys;
  } else if (n == "PixelFilter") {
    // RenderMan's filters that Relief has keep their fixed support; the rest fall back to the
    // default with a warning, as any call outside the subset does.
    std::string name;
    if (!positionalString(call, 0, &name)) return false;
    std::vector<float> widths;
    for (size_t i = 1; i < call.args.size() && call.args[i].isNumeric(); ++i)
      for (double d : call.args[i].numbers) widths.push_back(float(d));
    if (widths.size() < 2)
      return fail(call.line, "'PixelFilter' expects a filter name and 2 widths, got " +
                                 std::to_string(widths.size()) + " width" + (widths.size() == 1 ? "" : "s"));
    FilterType type = FilterType::Gaussian;
    if (parseFilter(name, &type)) {
      scene_.pixelFilter = name;
      const float support = PixelFilter::make(type).width;
      if (widths.size() >= 2 && (widths[0] != support || widths[1] != support))
        warnOnce(call.line, "PixelFilter/width",
                 "'PixelFilter': widths ignored, '" + name + "' uses " + std::to_string(int(support)) +
                     " x " + std::to_string(int(support)) + " pixels");
    } else {
      warnOnce(call.line, "PixelFilter/" + name,
               "unsupported pixel filter '" + name + "'; using gaussian (supported: gaussian, "
               "blackman-harris, box)");
    }
  } else if (n == "Projection") {
    std::string type;
    if (!positionalString(call, 0, &type)) return false;
    // RI spec: the transforms given before Projection act on screen space (after projecting), and
    // the current transform starts again from the identity for the camera transform. Only their
    // part within the screen plane changes a ray tracer's picture (a z scale only reorders depth).
    const glm::mat4& m = attr_.ctm;
    // A depth translation changes nothing either, but it is the usual slip of a camera
    // `Translate 0 0 5` written before Projection rather than after it: said as well.
    if (m[2][0] != 0.0f || m[2][1] != 0.0f || m[0][3] != 0.0f || m[1][3] != 0.0f || m[2][3] != 0.0f ||
        m[3][2] != 0.0f)
      warn(call.line, "'Projection': the transforms before it act on screen space; only their part "
                      "within the screen plane is used (the camera's own transform goes between "
                      "Projection and WorldBegin)");
    scene_.camera.screenFromProjected = m;
    attr_.ctm = glm::mat4(1.0f);
    if (type != "perspective" && type != "orthographic") {
      warnOnce(call.line, "projection/" + type,
               "unsupported projection '" + type + "'; using orthographic");
      scene_.camera.perspective = false;
      return true;
    }
    std::vector<Param> params;
    if (!parseParams(call, 1, &params)) return false;
    if (type == "perspective") {
      scene_.camera.perspective = true;
      scene_.camera.fovDegrees = 90.0f;  // RI default: each Projection starts afresh
      if (!floatParam(call, params, "fov", &scene_.camera.fovDegrees)) return false;
      if (!(scene_.camera.fovDegrees > 0 && scene_.camera.fovDegrees < 180))
        return fail(call.line, "'Projection': 'fov' must be in (0, 180) degrees");
      warnUnusedParams(call, params, {"fov"});
    } else {
      scene_.camera.perspective = false;
      warnUnusedParams(call, params, {});
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
    if (mode == "Z") mode = "z";
    if (mode != "rgb" && mode != "rgba" && mode != "rgbz" && mode != "rgbaz" && mode != "a" && mode != "az" &&
        mode != "z" && mode != "N" && mode != "cachemiss") {
      warnOnce(call.line, "mode/" + mode, "display mode '" + mode + "' written as 'rgb'");
      mode = "rgb";
    }
    const bool added = !name.empty() && name[0] == '+';
    if (added) {
      name = name.substr(1);
    } else {
      scene_.displays.clear();
      scene_.displayModes.clear();
      scene_.displaySources.clear();
    }
    if (name.empty()) return fail(call.line, "'Display' needs a file name");
    // There is no window to show a framebuffer in; a name without a format gets PNG.
    if (!std::filesystem::path(name).has_extension()) {
      if (added || !options_.mainDisplayReplaced)
        warn(call.line, "display '" + name + "' has no image extension; writing '" + name + ".png'");
      name += ".png";
    }
    scene_.displays.push_back(name);
    scene_.displayModes.push_back(mode);
    scene_.displaySources.push_back(fileName_ + ":" + std::to_string(call.line));
  } else if (n == "Option") {
    std::string category;
    if (!positionalString(call, 0, &category)) return false;
    // Checked before the parameters are read: another renderer's options may use types and
    // values Relief has no reason to understand.
    if (category != "relief" && category != "searchpath") {
      warnOnce(call.line, "option/" + category, "unsupported option '" + category + "' ignored");
      return true;
    }
    std::vector<Param> params;
    if (!parseParams(call, 1, &params)) return false;
    if (category == "relief") return doReliefOption(call, params);
    for (const Param& p : params) {
      if (p.name != "shader" && p.name != "texture" && p.name != "archive") {
        warnOnce(p.line, "searchpath/" + p.name,
                 "search path '" + p.name + "' is not supported; ignored");
        continue;
      }
      if ((p.type && *p.type != runtime::ParamType::String) || !p.value.isStringy() ||
          p.value.strings.size() != 1)
        return fail(p.line, "'Option \"searchpath\"': '" + p.name + "' expects one string");
      std::vector<std::string>& previous = p.name == "shader"    ? searchPath_
                                           : p.name == "texture" ? scene_.texturePath
                                                                 : archivePath_;
      const std::vector<std::string> sceneDir = {baseDir_};
      const std::vector<std::string>& defaults = p.name == "shader"    ? options_.defaultShaderPath
                                                 : p.name == "texture" ? options_.defaultTexturePath
                                                                       : sceneDir;
      std::vector<std::string> path;
      for (const std::string& dir : splitPath(p.value.strings[0])) {
        if (dir == "&") {
          path.insert(path.end(), previous.begin(), previous.end());
        } else if (dir == "@") {
          path.insert(path.end(), defaults.begin(), defaults.end());
        } else if (std::filesystem::path(dir).is_relative()) {
          path.push_back((std::filesystem::path(baseDir_) / dir).lexically_normal().string());
        } else {
          path.push_back(dir);
        }
      }
      // A directory named twice is searched once, at its first place: "&:&" repeated would
      // otherwise double the path each time (30 times: a billion entries).
      std::vector<std::string> unique;
      std::set<std::string> seen;
      for (std::string& dir : path)
        if (seen.insert(dir).second) unique.push_back(std::move(dir));
      previous = std::move(unique);
    }
  } else if (n == "WorldBegin") {
    if (inWorld_) return fail(call.line, "nested 'WorldBegin'");
    if (worldDone_)
      return fail(call.line, frameDepth_ > 0 ? "only one world block per frame is supported"
                                             : "only one world block per file is supported");
    if (!stack_.empty())
      return fail(call.line, "'WorldBegin' inside an unclosed '" +
                                 std::string(stack_.back().attribute ? "AttributeBegin"
                                                                     : "TransformBegin") +
                                 "' (" + lineRef(stack_.back().line, stack_.back().file) + ")");
    if (singular(attr_.ctm)) return fail(call.line, "the camera transform is singular");
    const glm::mat4 worldFromCamera = glm::inverse(attr_.ctm);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        if (!std::isfinite(attr_.ctm[c][r]) || !std::isfinite(worldFromCamera[c][r]))
          return fail(call.line, "the camera transform has non-finite entries");
    inWorld_ = true;
    worldLine_ = call.line;
    worldFile_ = fileName_;
    scene_.camera.worldFromCamera = worldFromCamera;
    attr_.ctm = glm::mat4(1.0f);
    const glm::mat4& w = scene_.camera.worldFromCamera;
    for (size_t index : lightsBeforeWorld_) {
      Light& l = scene_.lights[index];
      l.position = glm::vec3(w * glm::vec4(l.position, 1.0f));
      l.corner = glm::vec3(w * glm::vec4(l.corner, 1.0f));
      l.edgeU = glm::vec3(w * glm::vec4(l.edgeU, 0.0f));
      l.edgeV = glm::vec3(w * glm::vec4(l.edgeV, 0.0f));
      l.direction = glm::normalize(glm::vec3(w * glm::vec4(l.direction, 0.0f)));
      l.radius *= maxScale(w);
    }
    lightsBeforeWorld_.clear();
    if (attr_.displacement) {
      // A Displacement before WorldBegin was given in camera space (the transform then is the
      // camera's being built), as lights and named spaces there are: its shader space and its
      // points, vectors and normals move to world now. It had been taken as world.
      attr_.worldFromShader = w * attr_.worldFromShader;
      auto moved = std::make_shared<runtime::ShaderInstance>(attr_.displacement->sharedShader());
      for (runtime::ParamValue& v : attr_.displacementValues) {
        moveSpatial(w, &v);
        std::string error;
        if (!moved->bind(v, &error)) return fail(attr_.displacementLine, error);
      }
      attr_.displacement = std::move(moved);
    }
    for (const std::string& name : spacesBeforeWorld_)
      if (const auto space = coordinateSystems_.find(name); space != coordinateSystems_.end())
        space->second = w * space->second;
    spacesBeforeWorld_.clear();
    // FrameAspectRatio shapes the default frame unless ScreenWindow says; without either, the
    // camera derives it from the rendered resolution and Format's pixel aspect ratio (which a
    // command-line resolution may still change).
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
                                 "' (" + lineRef(stack_.back().line, stack_.back().file) + ")");
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
    // A singular matrix is kept: geometry under it is skipped (see executeGeometry).
    glm::mat4 m = glm::make_mat4(v.data());
    // RI matrices are homogeneous: [2 0 0 0 0 2 0 0 0 0 2 0 0 0 0 2] is the identity. A uniform
    // w is divided out; a projective matrix, which would bend straight edges, is refused.
    if (m[0][3] != 0.0f || m[1][3] != 0.0f || m[2][3] != 0.0f || !(m[3][3] != 0.0f))
      return fail(call.line, "'" + n + "': projective matrices (a last column other than [0 0 0 w], "
                             "w nonzero) are not supported");
    if (m[3][3] != 1.0f) m *= 1.0f / m[3][3];
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
    attr_.ctm = glm::scale(attr_.ctm, glm::vec3(v[0], v[1], v[2]));
  } else if (n == "CoordinateSystem" || n == "ScopedCoordinateSystem") {
    std::string name;
    if (!positionalString(call, 0, &name)) return false;
    if (n == "ScopedCoordinateSystem") {
      // Scoped to the innermost attribute block (PRMan): remember what the name meant before.
      for (auto entry = stack_.rbegin(); entry != stack_.rend(); ++entry) {
        if (!entry->attribute) continue;
        auto& saved = entry->scopedSpaces;
        if (std::none_of(saved.begin(), saved.end(), [&](const auto& p) { return p.first == name; })) {
          const auto old = coordinateSystems_.find(name);
          saved.emplace_back(name, old == coordinateSystems_.end() ? std::nullopt
                                                                   : std::optional<glm::mat4>(old->second));
        }
        break;
      }
    }
    coordinateSystems_[name] = attr_.ctm;
    if (inWorld_)
      spacesBeforeWorld_.erase(name);
    else
      spacesBeforeWorld_.insert(name);
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
    stack_.push_back(StackEntry{attr_, n == "AttributeBegin", call.line, fileName_, {}});
  } else if (n == "TransformEnd" || n == "AttributeEnd") {
    const bool attribute = n == "AttributeEnd";
    if (stack_.empty())
      return fail(call.line, "'" + n + "' without '" +
                                 (attribute ? "AttributeBegin" : "TransformBegin") + "'");
    if (stack_.back().attribute != attribute)
      return fail(call.line, "'" + n + "' closes '" +
                                 (attribute ? "TransformBegin" : "AttributeBegin") +
                                 "' at " + lineRef(stack_.back().line, stack_.back().file));
    if (attribute)
      attr_ = stack_.back().state;
    else
      attr_.ctm = stack_.back().state.ctm;
    for (auto restore = stack_.back().scopedSpaces.rbegin(); restore != stack_.back().scopedSpaces.rend(); ++restore) {
      // An attribute block lies wholly before or inside the world block, so the value restored
      // is relative to the same space as the block's own.
      if (restore->second) {
        coordinateSystems_[restore->first] = *restore->second;
        if (inWorld_)
          spacesBeforeWorld_.erase(restore->first);
        else
          spacesBeforeWorld_.insert(restore->first);
      } else {
        coordinateSystems_.erase(restore->first);
        spacesBeforeWorld_.erase(restore->first);
      }
    }
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
    attr_.material.color = glm::vec3(v[0], v[1], v[2]);
  } else if (n == "Opacity") {
    if (!positionalNumbers(call, 3, &v, &next)) return false;
    attr_.material.opacity = glm::clamp(glm::vec3(v[0], v[1], v[2]), 0.0f, 1.0f);
  } else if (n == "Surface") {
    return doSurface(call);
  } else if (n == "Sides") {
    if (!positionalNumbers(call, 1, &v, &next)) return false;
    if (v[0] != 1 && v[0] != 2) return fail(call.line, "'Sides' must be 1 or 2");
    attr_.material.twoSided = v[0] == 2;
  } else if (n == "Orientation") {
    std::string o;
    if (!positionalString(call, 0, &o)) return false;
    // The orientation is kept relative to the current coordinate system's handedness (the two
    // flip together under mirroring transforms): "lh" and "rh" are inside out exactly when the
    // current coordinate system has the other handedness. Camera space is left-handed.
    const glm::mat3 toCamera =
        inWorld_ ? glm::mat3(glm::inverse(scene_.camera.worldFromCamera) * attr_.ctm) : glm::mat3(attr_.ctm);
    const bool rightHanded = glm::determinant(toCamera) < 0.0f;
    if (o == "outside") {
      attr_.orientationInside = false;
    } else if (o == "inside") {
      attr_.orientationInside = true;
    } else if (o == "lh") {
      attr_.orientationInside = rightHanded;
    } else if (o == "rh") {
      attr_.orientationInside = !rightHanded;
    } else {
      return fail(call.line, "'Orientation' must be \"outside\", \"inside\", \"lh\" or \"rh\"");
    }
    attr_.reversed = false;
  } else if (n == "ReverseOrientation") {
    if (!call.args.empty())
      warnOnce(call.line, "args/ReverseOrientation", "'ReverseOrientation' takes no arguments; ignored them");
    attr_.reversed = !attr_.reversed;
  } else if (n == "Illuminate") {
    if (call.args.size() != 2 || !call.args[1].isNumeric() || call.args[1].numbers.size() != 1)
      return fail(call.line, "'Illuminate' expects a light handle and 0 or 1");
    std::string handle;
    if (!lightHandle(call.args[0], &handle))
      return fail(call.line, "'Illuminate' expects a light handle (a number or a string)");
    const auto light = lightHandles_.find(handle);
    if (light == lightHandles_.end() && skippedLightHandles_.count(handle)) {
      warnOnce(call.line, "illuminate/" + handle,
               "'Illuminate': light '" + handle + "' was skipped; ignored");
      return true;
    }
    if (light == lightHandles_.end())
      return fail(call.line, "'Illuminate': no light with handle '" + handle + "'");
    std::vector<uint32_t>& on = attr_.lightsOn;
    const auto at = std::lower_bound(on.begin(), on.end(), light->second);
    const bool isOn = at != on.end() && *at == light->second;
    if (call.args[1].numbers[0] != 0 && !isOn) on.insert(at, light->second);
    if (call.args[1].numbers[0] == 0 && isOn) on.erase(at);
  } else if (n == "Basis") {
    return doBasis(call);
  } else if (n == "LightSource" || n == "AreaLightSource") {
    return doLight(call);
  } else if (n == "Displacement") {
    return doDisplacement(call);
  } else if (n == "Declare") {
    std::string name, decl;
    if (!positionalString(call, 0, &name) || !positionalString(call, 1, &decl)) return false;
    Param p;
    std::string unknownType;
    if (!parseDeclaration(decl + " " + name, call.line, &p, &unknownType)) return false;
    if (!unknownType.empty()) {
      warnOnce(call.line, "type/" + unknownType,
               "'Declare': unknown type '" + unknownType + "'; '" + name + "' left undeclared");
      return true;
    }
    if (!p.type) return fail(call.line, "'Declare' needs a type");
    declared_[name] = Declared{*p.type, p.arraySize, p.homogeneous, p.storageClass, call.line, fileName_};
  } else if (n == "Attribute") {
    std::string category;
    if (!positionalString(call, 0, &category)) return false;
    if (category != "displacementbound" && category != "bound" && category != "relief" &&
        category != "visibility" && category != "light") {
      // Before reading the parameters, as for Option.
      warnOnce(call.line, "attribute/" + category,
               "unsupported attribute '" + category + "' ignored");
      return true;
    }
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
      attr_.boundGiven = attr_.boundGiven || findParam(params, "sphere");
      attr_.boundSpace = space;
      warnUnusedParams(call, params, {"sphere", "coordinatesystem"});
    } else if (category == "bound") {
      // The pre-3.2 spelling: Attribute "bound" "displacement" [r], r in object space.
      if (!floatParam(call, params, "displacement", &attr_.boundRadius)) return false;
      if (attr_.boundRadius < 0) return fail(call.line, "'bound' 'displacement' must be >= 0");
      attr_.boundGiven = attr_.boundGiven || findParam(params, "displacement");
      attr_.boundSpace = "object";
      warnUnusedParams(call, params, {"displacement"});
    } else if (category == "relief") {
      if (!floatParam(call, params, "edgelength", &attr_.edgeLength) ||
          !floatParam(call, params, "flatness", &attr_.flatness))
        return false;
      if (!(attr_.edgeLength > 0)) return fail(call.line, "'edgelength' must be positive");
      if (!(attr_.flatness >= 0)) return fail(call.line, "'flatness' must be >= 0");
      warnUnusedParams(call, params, {"edgelength", "flatness"});
    } else if (category == "light") {
      // BMRT's (and Aqsis') switch for the lights declared after it: "on" traces shadow rays, as
      // every Relief light does by default; "off" lights without them, as RenderMan's standard
      // lights do (they have no shadow() call).
      if (findParam(params, "shadows")) {
        std::string mode;
        if (!stringParam(call, params, "shadows", &mode)) return false;
        if (mode != "on" && mode != "off")
          return fail(call.line, "'light': 'shadows' must be \"on\" or \"off\", not '" + mode + "'");
        attr_.lightShadows = mode == "on";
      }
      warnUnusedParams(call, params, {"shadows"});
    } else if (category == "visibility") {
      // Shadow casting. PRMan 11+ says "int transmission" [0|1]; older RIB says "string
      // transmission" ["transparent"|"opaque"|"Os"|"shader"]. Other ray kinds are all visible.
      if (const Param* t = findParam(params, "transmission")) {
        if (t->value.isStringy()) {
          std::string mode;
          if (!stringParam(call, params, "transmission", &mode)) return false;
          if (mode != "transparent" && mode != "opaque" && mode != "Os" && mode != "shader")
            return fail(call.line, "'visibility': unknown transmission '" + mode +
                                       "' (expected transparent, opaque, Os or shader)");
          attr_.material.castsShadows = mode != "transparent";
          attr_.material.opaqueShadows = mode == "opaque";
        } else {
          float on = 1.0f;
          if (!floatParam(call, params, "transmission", &on)) return false;
          attr_.material.castsShadows = on != 0.0f;
          attr_.material.opaqueShadows = false;
        }
      }
      for (const Param& q : params)
        if (q.name != "transmission")
          warnOnce(call.line, "visibility/" + q.name,
                   "'visibility' '" + q.name + "' ignored: surfaces are visible to every ray "
                   "but, with \"transmission\" 0, to shadow rays");
    }
  } else {
    *handled = false;
  }
  return true;
}

// LightSource name [handle] params: RenderMan's standard light shaders plus "arealight". Points
// and directions are in the space current at the call; before WorldBegin that is camera space,
// converted to world space when the camera is known (at WorldBegin).
bool RibParser::doLight(const Call& call) {
  std::string name;
  if (!positionalString(call, 0, &name)) return false;
  // RIB gives a light handle (number or string) after the name; parameters come in pairs, so an
  // even argument count means the handle is there.
  const size_t first = call.args.size() % 2 == 0 ? 2 : 1;
  std::string handle;
  if (first == 2 && !lightHandle(call.args[1], &handle))
    return fail(call.line, "'LightSource': the light handle must be a number or a string");
  const bool known = call.name == "LightSource" &&
                     (name == "distantlight" || name == "ambientlight" || name == "pointlight" ||
                      name == "spotlight" || name == "arealight");
  if (!known || singular(attr_.ctm)) {
    // Skipped before its parameters are read (they belong to a shader Relief does not have). The
    // handle is remembered so that an Illuminate of it is a no-op rather than an error.
    ++scene_.skippedLights;
    if (call.name == "AreaLightSource")
      warnOnce(call.line, "AreaLightSource",
               "'AreaLightSource' is not supported (use LightSource \"arealight\"); skipped");
    else if (!known)
      warnOnce(call.line, "light/" + name,
               "light source '" + name + "' is not supported; ignored");
    else
      warnOnce(call.line, "singularlight",
               "light source '" + name + "' under a singular transform; skipped");
    if (!handle.empty()) {
      lightHandles_.erase(handle);
      skippedLightHandles_.insert(handle);
    }
    return true;
  }
  std::vector<Param> params;
  if (!parseParams(call, first, &params)) return false;
  float intensity = 1.0f;
  glm::vec3 color(1.0f);
  if (!floatParam(call, params, "intensity", &intensity) ||
      !tripleParam(call, params, "lightcolor", "color", &color))
    return false;
  Light light;
  light.color = color * intensity;
  light.handle = handle;
  light.sourceFile = fileName_;
  light.sourceLine = call.line;
  light.shadows = attr_.lightShadows;
  const glm::mat4& m = attr_.ctm;
  auto point = [&](glm::vec3 p) { return glm::vec3(m * glm::vec4(p, 1.0f)); };
  glm::vec3 from(0.0f), to(0.0f, 0.0f, 1.0f);
  if (!tripleParam(call, params, "from", "point", &from) ||
      !tripleParam(call, params, "to", "point", &to))
    return false;
  auto direction = [&]() -> bool {
    const glm::vec3 d = point(to) - point(from);
    if (!std::isfinite(d.x) || !std::isfinite(d.y) || !std::isfinite(d.z))
      return fail(call.line, "'" + name + "': 'from' or 'to' is not finite");
    if (!(glm::length(d) > 0.0f)) {
      // RenderMan's solar()/illuminate() along a zero axis light nothing; the frame still renders.
      warn(call.line, "'" + name + "': 'from' and 'to' coincide: the light has no direction and lights nothing");
      light.color = glm::vec3(0.0f);
      return true;
    }
    light.direction = glm::normalize(d);
    return true;
  };
  if (name == "distantlight") {
    light.type = LightType::Distant;
    if (!direction()) return false;
    warnUnusedParams(call, params, {"intensity", "lightcolor", "from", "to"});
  } else if (name == "ambientlight") {
    light.type = LightType::Ambient;
    warnUnusedParams(call, params, {"intensity", "lightcolor"});
  } else if (name == "pointlight") {
    light.type = LightType::Point;
    light.position = point(from);
    warnUnusedParams(call, params, {"intensity", "lightcolor", "from"});
  } else if (name == "spotlight") {
    light.type = LightType::Spot;
    light.position = point(from);
    if (!direction() || !floatParam(call, params, "coneangle", &light.coneAngle) ||
        !floatParam(call, params, "conedeltaangle", &light.coneDeltaAngle) ||
        !floatParam(call, params, "beamdistribution", &light.beamDistribution))
      return false;
    if (!(light.coneAngle > 0.0f && light.coneAngle <= float(M_PI)))
      return fail(call.line, "'spotlight': 'coneangle' must be in (0, pi] radians");
    if (!(light.coneDeltaAngle >= 0.0f && light.coneDeltaAngle <= light.coneAngle))
      return fail(call.line, "'spotlight': 'conedeltaangle' must be in [0, coneangle]");
    if (!(light.beamDistribution >= 0.0f))
      return fail(call.line, "'spotlight': 'beamdistribution' must be >= 0");
    warnUnusedParams(call, params, {"intensity", "lightcolor", "from", "to", "coneangle",
                                    "conedeltaangle", "beamdistribution"});
  } else if (name == "arealight") {
    // An emitter in the z = 0 plane of the current space, centred at "from", emitting towards +z.
    light.type = LightType::Area;
    std::string shape = "rectangle";
    float width = 1.0f, height = 1.0f, radius = 0.5f, samples = 16.0f;
    if (!stringParam(call, params, "shape", &shape) ||
        !floatParam(call, params, "width", &width) ||
        !floatParam(call, params, "height", &height) ||
        !floatParam(call, params, "radius", &radius) ||
        !floatParam(call, params, "samples", &samples))
      return false;
    if (!(samples >= 1.0f && samples <= 4096.0f))
      return fail(call.line, "'arealight': 'samples' must be between 1 and 4096");
    light.samples = int(samples);
    const glm::mat3 normalFromObject = glm::transpose(glm::inverse(glm::mat3(m)));
    light.direction = glm::normalize(normalFromObject * glm::vec3(0, 0, 1));
    light.position = point(from);
    if (shape == "rectangle") {
      if (!(width > 0.0f && height > 0.0f))
        return fail(call.line, "'arealight': 'width' and 'height' must be positive");
      light.shape = AreaShape::Rectangle;
      light.corner = point(from - glm::vec3(width * 0.5f, height * 0.5f, 0.0f));
      light.edgeU = glm::vec3(m * glm::vec4(width, 0, 0, 0));
      light.edgeV = glm::vec3(m * glm::vec4(0, height, 0, 0));
      // The emitting side is +z; keep edgeU x edgeV pointing there even under a mirroring
      // transform.
      if (glm::dot(glm::cross(light.edgeU, light.edgeV), light.direction) < 0.0f) {
        light.corner += light.edgeU;
        light.edgeU = -light.edgeU;
      }
    } else if (shape == "disk") {
      if (!(radius > 0.0f)) return fail(call.line, "'arealight': 'radius' must be positive");
      light.shape = AreaShape::Disk;
      light.radius = radius * maxScale(m);
    } else {
      return fail(call.line, "'arealight': 'shape' must be \"rectangle\" or \"disk\"");
    }
    warnUnusedParams(call, params, {"intensity", "lightcolor", "from", "shape", "width", "height",
                                    "radius", "samples"});
  }
  const uint32_t index = uint32_t(scene_.lights.size());
  scene_.lights.push_back(light);
  lightOrigins_.push_back({fileName_, call.line});
  if (!inWorld_) lightsBeforeWorld_.push_back(index);
  if (!handle.empty()) {
    lightHandles_[handle] = index;
    skippedLightHandles_.erase(handle);
  }
  // A new light is on for the current attribute block (RiLightSource turns it on).
  attr_.lightsOn.insert(std::lower_bound(attr_.lightsOn.begin(), attr_.lightsOn.end(), index),
                        index);
  return true;
}

// Surface name params: RenderMan's standard surfaces with their default parameters. Any other
// surface is matte, keeping only a Ka and Kd that are single floats: its parameters belong to a
// shader Relief does not have, so their types are not checked.
bool RibParser::doSurface(const Call& call) {
  std::string name;
  if (!positionalString(call, 0, &name)) return false;
  const bool isKnown = name == "matte" || name == "plastic" || name == "metal" ||
                       name == "shinymetal" || name == "mirror" || name == "glass" ||
                       name == "constant";
  std::vector<Param> params;
  if (!parseParams(call, 1, &params, !isKnown)) return false;
  // A new shader with its own parameters; what other requests set (Color, Opacity, Sides, the
  // visibility attribute) stays: a Surface after the visibility attribute used to cast shadows.
  Material m = matteMaterial();
  m.color = attr_.material.color;
  m.opacity = attr_.material.opacity;
  m.twoSided = attr_.material.twoSided;
  m.castsShadows = attr_.material.castsShadows;
  m.opaqueShadows = attr_.material.opaqueShadows;
  std::vector<std::string_view> known = {"Ka", "Kd"};
  if (name == "matte") {
  } else if (name == "plastic") {
    m.type = SurfaceType::Plastic;
    m.Kd = 0.5f, m.Ks = 0.5f, m.roughness = 0.1f;
    known = {"Ka", "Kd", "Ks", "roughness", "specularcolor"};
  } else if (name == "metal") {
    m.type = SurfaceType::Metal;
    m.Kd = 0.0f, m.Ks = 1.0f, m.roughness = 0.1f;
    known = {"Ka", "Ks", "roughness"};
  } else if (name == "shinymetal") {
    m.type = SurfaceType::Mirror;
    m.Kd = 0.0f, m.Ks = 1.0f, m.Kr = 1.0f, m.roughness = 0.1f;
    known = {"Ka", "Ks", "Kr", "roughness"};
  } else if (name == "mirror") {
    m.type = SurfaceType::Mirror;
    m.Ka = 0.0f, m.Kd = 0.0f, m.Ks = 0.0f, m.Kr = 1.0f;
    known = {"Ka", "Kd", "Ks", "Kr", "roughness"};
  } else if (name == "glass") {
    m.type = SurfaceType::Glass;
    m.Ka = 0.2f, m.Kd = 0.0f, m.Ks = 0.5f, m.Kr = 1.0f, m.Kt = 1.0f, m.roughness = 0.05f;
    m.eta = 1.5f;
    known = {"Ka", "Kd", "Ks", "Kr", "Kt", "roughness", "eta", "specularcolor", "transmitcolor"};
  } else if (name == "constant") {
    m.type = SurfaceType::Constant;
    known = {};
  } else {
    warnOnce(call.line, "surface/" + name, "surface '" + name + "' is not supported; using 'matte'");
    for (const auto& [pname, field] : {std::pair{"Ka", &m.Ka}, std::pair{"Kd", &m.Kd}}) {
      const Param* p = findParam(params, pname);
      if (p && (!p->type || *p->type == runtime::ParamType::Float) && p->value.isNumeric() &&
          p->value.numbers.size() == 1)
        *field = float(p->value.numbers[0]);
    }
    attr_.material = m;
    return true;
  }
  auto has = [&](std::string_view p) {
    return std::find(known.begin(), known.end(), p) != known.end();
  };
  const std::pair<const char*, float*> floats[] = {
      {"Ka", &m.Ka}, {"Kd", &m.Kd}, {"Ks", &m.Ks}, {"Kr", &m.Kr},
      {"Kt", &m.Kt}, {"roughness", &m.roughness}, {"eta", &m.eta}};
  for (const auto& [pname, field] : floats)
    if (has(pname) && !floatParam(call, params, pname, field)) return false;
  if (has("specularcolor") &&
      !tripleParam(call, params, "specularcolor", "color", &m.specularColor))
    return false;
  if (has("transmitcolor") &&
      !tripleParam(call, params, "transmitcolor", "color", &m.transmitColor))
    return false;
  // Exporters write 0 for a perfect mirror-like highlight; the highlight exponent is 1/roughness.
  constexpr float kMinRoughness = 1e-3f;
  if (!(m.roughness >= kMinRoughness)) {
    warn(call.line, "'" + name + "': 'roughness' " + formatNumber(m.roughness) +
                        (m.roughness > 0.0f ? " is below " + formatNumber(kMinRoughness) : std::string(" is not positive")) +
                        "; using " + formatNumber(kMinRoughness));
    m.roughness = kMinRoughness;
  }
  if (!(m.eta > 0.0f)) return fail(call.line, "'" + name + "': 'eta' must be positive");
  if (isKnown) warnUnusedParams(call, params, known);
  attr_.material = m;
  return true;
}

// Basis ubasis ustep vbasis vstep: each basis a name or 16 numbers (row-major).
bool RibParser::doBasis(const Call& call) {
  CubicBasis bases[2];
  size_t arg = 0;
  for (CubicBasis& basis : bases) {
    if (arg >= call.args.size())
      return fail(call.line, "'Basis' expects ubasis ustep vbasis vstep");
    const Arg& a = call.args[arg++];
    if (a.kind == Arg::Kind::String) {
      if (!namedCubicBasis(a.strings[0], &basis))
        return fail(a.line, "'Basis': unknown basis '" + a.strings[0] + "'");
    } else if (a.isNumeric() && a.numbers.size() == 16) {
      for (int i = 0; i < 16; ++i) basis.matrix[i / 4][i % 4] = float(a.numbers[size_t(i)]);
    } else {
      return fail(a.line, "'Basis': a basis is a name or 16 numbers, got " + std::string(a.describe()));
    }
    if (arg >= call.args.size() || !call.args[arg].isNumeric() ||
        call.args[arg].numbers.size() != 1)
      return fail(call.line, "'Basis' expects a step after each basis");
    const double step = call.args[arg++].numbers[0];
    if (step < 1 || step > 4 || step != std::floor(step))
      return fail(call.line, "'Basis': a step must be 1, 2, 3 or 4");
    basis.step = int(step);
  }
  if (arg != call.args.size()) return fail(call.line, "'Basis' has extra arguments");
  attr_.uBasis = bases[0];
  attr_.vBasis = bases[1];
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
                               (why.empty() ? " (search path: '" + path + "')" : ": " + why));
  }
  // Binding errors are located at the Displacement call, as shader loading errors are: that is
  // the line a user looks for, even when the parameter list continues on later lines.
  auto instance = std::make_shared<runtime::ShaderInstance>(compiled);
  std::vector<runtime::ParamValue> bound;
  for (const Param& p : params) {
    // A name the shader lacks warns and is skipped, as in PRMan and 3Delight: exporters write
    // extras (`"string __instanceid"`), and one stopped the whole render.
    if (!compiled->findParam(p.name)) {
      warnOnce(call.line, "noparam/" + fileName_ + ":" + std::to_string(call.line) + "/" + p.name,
               "shader '" + compiled->name() + "' has no parameter '" + p.name + "'; ignored");
      continue;
    }
    runtime::ParamValue value;
    if (!shaderParamValue(call.line, *compiled, p, &value)) return false;
    std::string error;
    if (!instance->bind(value, &error)) {
      // `Declare "freq" "color"` then `"freq" [3]`: the type the message names came from there.
      return fail(call.line, error + declareNote(p));
    }
    bound.push_back(std::move(value));
  }
  attr_.displacement = std::move(instance);
  attr_.displacementValues = std::move(bound);
  attr_.worldFromShader = attr_.ctm;
  attr_.displacementLine = call.line;
  attr_.displacementFile = fileName_;
  return true;
}

// A scene value for parameter p.name of `compiled`: typed by its declaration or the shader's,
// spatial types moved from the current space to the shader's "current" space (world).
bool RibParser::shaderParamValue(int line, const runtime::CompiledShader& compiled, const Param& p,
                                 runtime::ParamValue* out) {
  const std::string& name = compiled.name();
  runtime::ParamValue value;
  value.name = p.name;
  {
    if (p.type) {
      value.type = *p.type;
    } else if (const runtime::ParamInfo* info = compiled.findParam(p.name)) {
      value.type = info->type;
    } else {
      return fail(line, "shader '" + name + "' has no parameter '" + p.name + "'");
    }
    if (value.type == runtime::ParamType::String) {
      if (!p.value.isStringy())
        return fail(line, "parameter '" + p.name + "' of shader '" + name +
                                "' expects strings, got " + p.value.describe());
      value.strings = p.value.strings;
    } else {
      if (!p.value.isNumeric())
        return fail(line, "parameter '" + p.name + "' of shader '" + name +
                                "' expects numbers, got " + p.value.describe());
      value.numbers.assign(p.value.numbers.begin(), p.value.numbers.end());
      // An "hpoint" value is (x y z w) per point, the point (x/w, y/w, z/w), as "Pw" is.
      if (p.homogeneous) {
        if (value.numbers.size() % 4 != 0)
          return fail(line, "parameter '" + p.name + "' of shader '" + name + "' is an hpoint: 4 numbers (x y z w) per point, got " +
                                std::to_string(value.numbers.size()));
        std::vector<double> cartesian;
        for (size_t i = 0; i < value.numbers.size(); i += 4) {
          const double w = value.numbers[i + 3];
          if (w == 0.0) return fail(line, "parameter '" + p.name + "' of shader '" + name + "': an hpoint with w = 0");
          cartesian.insert(cartesian.end(), {value.numbers[i] / w, value.numbers[i + 1] / w, value.numbers[i + 2] / w});
        }
        value.numbers = std::move(cartesian);
      }
      // As in RenderMan, points, vectors and normals are given in the space current at the call
      // and the shader sees them in its "current" space (world): each triple moves as its declared
      // kind does (a point with the translation, a vector without, a normal by the inverse
      // transpose). Scalars splatted into a triple are left as given.
      // A triple moves as the shader's parameter is declared (a "point" given to a normal
      // parameter is a normal to the shader; it had moved as a point, with the translation).
      const runtime::ParamInfo* info = compiled.findParam(p.name);
      const runtime::ParamType given = value.type;
      if (info && runtime::isSpatial(info->type) && runtime::isSpatial(given)) value.type = info->type;
      moveSpatial(attr_.ctm, &value);
      value.type = given;
    }
  }
  *out = std::move(value);
  return true;
}

void RibParser::moveSpatial(const glm::mat4& to, runtime::ParamValue* value) {
  const glm::mat3 linear(to);
  const bool spatial = value->type == runtime::ParamType::Point ||
                       value->type == runtime::ParamType::Vector || value->type == runtime::ParamType::Normal;
  if (!spatial || value->numbers.size() % 3 != 0) return;
  // (Geometry under a singular transform is skipped; its normals stay as given.)
  const glm::mat3 normalMatrix = singular(to) ? glm::mat3(1.0f) : glm::transpose(glm::inverse(linear));
  for (size_t i = 0; i < value->numbers.size(); i += 3) {
    const glm::vec3 x(value->numbers[i], value->numbers[i + 1], value->numbers[i + 2]);
    const glm::vec3 y = value->type == runtime::ParamType::Point  ? glm::vec3(to * glm::vec4(x, 1.0f))
                        : value->type == runtime::ParamType::Vector ? linear * x
                                                                    : normalMatrix * x;
    value->numbers[i] = y.x, value->numbers[i + 1] = y.y, value->numbers[i + 2] = y.z;
  }
}

bool RibParser::executeGeometry(const Call& call, bool* handled) {
  *handled = true;
  const std::string& n = call.name;
  // Counts and indices: a fraction or a number beyond a billion is a slip, not something to
  // truncate or clamp (an index of 1.5 quietly became 1).
  auto intArray = [&](const Arg& a, const char* what, std::vector<int>* out) {
    out->clear();
    for (double d : a.numbers) {
      if (d != std::floor(d) || std::fabs(d) > 1e9) {
        char text[32];
        std::snprintf(text, sizeof text, "%.10g", d);
        return fail(a.line, "'" + n + "': " + what + " must be whole numbers up to 1e9, got " + text);
      }
      out->push_back(int(d));
    }
    return true;
  };

  static const std::set<std::string> kShapes = {
      "Sphere",         "Cylinder",       "Cone",     "Disk",     "Torus",
      "Paraboloid",     "Hyperboloid",    "Polygon",  "GeneralPolygon",
      "PointsPolygons", "PointsGeneralPolygons",    "Patch",    "PatchMesh",
      "Geometry",       "SubdivisionMesh", "NuPatch"};
  if (kShapes.count(n)) {
    if (!requireWorld(call)) return false;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        if (!std::isfinite(attr_.ctm[c][r]))
          return fail(call.line, "'" + n + "': the current transform is not finite (transforms overflowed float: " +
                                     "a Scale or ConcatTransform too large?)");
    if (singular(attr_.ctm)) {
      warnOnce(call.line, "singular/" + n,
               "'" + n + "' under a singular transform (such as Scale 0 0 0) skipped");
      return true;
    }
  }
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
    std::vector<int> nverts, vertices;
    if (!intArray(call.args[0], "vertex counts", &nverts) || !intArray(call.args[1], "vertex indices", &vertices))
      return false;
    return buildPolygonMesh(call, std::vector<int>(nverts.size(), 1), nverts, vertices, 2);
  }
  if (n == "SubdivisionMesh") return doSubdivisionMesh(call);
  if (n == "NuPatch") return doNuPatch(call);
  if (n == "TrimCurve") {
    warnOnce(call.line, "request/TrimCurve", "'TrimCurve' is not supported; NuPatches render untrimmed");
    *handled = true;
    return true;
  }
  if (n == "PointsGeneralPolygons") {
    if (!requireWorld(call)) return false;
    if (call.args.size() < 3 || !call.args[0].isNumeric() || !call.args[1].isNumeric() ||
        !call.args[2].isNumeric())
      return fail(call.line,
                  "'PointsGeneralPolygons' expects [nloops] [nverts] [vertices] then parameters");
    std::vector<int> nloops, nverts, vertices;
    if (!intArray(call.args[0], "loop counts", &nloops) || !intArray(call.args[1], "vertex counts", &nverts) ||
        !intArray(call.args[2], "vertex indices", &vertices))
      return false;
    return buildPolygonMesh(call, nloops, nverts, vertices, 3);
  }
  if (n == "Polygon" || n == "GeneralPolygon") {
    if (!requireWorld(call)) return false;
    const bool general = n == "GeneralPolygon";
    if (general && (call.args.empty() || !call.args[0].isNumeric()))
      return fail(call.line, "'GeneralPolygon' expects [nverts] then parameters");
    const size_t first = general ? 1 : 0;
    std::vector<int> nverts;
    if (general) {
      if (!intArray(call.args[0], "vertex counts", &nverts)) return false;
    } else {
      // The point count comes from "P"; the indices are the points in order.
      std::vector<Param> params;
      std::vector<float> P;
      if (!parseParams(call, first, &params) || !positions(call, params, 0, &P)) return false;
      nverts = {int(P.size() / 3)};
    }
    int total = 0;
    for (int c : nverts) total += std::max(c, 0);
    std::vector<int> verts(size_t(std::max(total, 0)));
    for (size_t i = 0; i < verts.size(); ++i) verts[i] = int(i);
    return buildPolygonMesh(call, {int(nverts.size())}, nverts, verts, first);
  }
  if (n == "Patch") {
    if (!requireWorld(call)) return false;
    std::string type;
    if (!positionalString(call, 0, &type)) return false;
    if (type != "bilinear" && type != "bicubic")
      return fail(call.line, "'Patch' type must be \"bilinear\" or \"bicubic\", got '" + type + "'");
    const int size = type == "bilinear" ? 2 : 4;
    return buildPatchMesh(call, type == "bicubic", size, false, size, false, 1);
  }
  if (n == "PatchMesh") {
    if (!requireWorld(call)) return false;
    std::string type, uwrap, vwrap;
    if (!positionalString(call, 0, &type) || call.args.size() < 5 ||
        !call.args[1].isNumeric() || call.args[1].numbers.size() != 1 ||
        !positionalString(call, 2, &uwrap) || !call.args[3].isNumeric() ||
        call.args[3].numbers.size() != 1 || !positionalString(call, 4, &vwrap))
      return fail(call.line, "'PatchMesh' expects type nu uwrap nv vwrap then parameters");
    if (type != "bilinear" && type != "bicubic")
      return fail(call.line, "'PatchMesh' type must be \"bilinear\" or \"bicubic\", got '" + type +
                                 "'");
    for (const std::string* wrap : {&uwrap, &vwrap})
      if (*wrap != "periodic" && *wrap != "nonperiodic")
        return fail(call.line, "'PatchMesh' wrap must be \"periodic\" or \"nonperiodic\", got '" +
                                   *wrap + "'");
    const double nu = call.args[1].numbers[0], nv = call.args[3].numbers[0];
    if (nu != std::floor(nu) || nv != std::floor(nv) || nu < 1 || nv < 1)
      return fail(call.line, "'PatchMesh': nu and nv must be positive integers");
    if (nu > 1e6 || nv > 1e6)
      return fail(call.line, "'PatchMesh': nu and nv must be at most 1000000 (got " +
                                 std::to_string(int64_t(std::min(nu, 9e18))) + " x " +
                                 std::to_string(int64_t(std::min(nv, 9e18))) + ")");
    return buildPatchMesh(call, type == "bicubic", int(nu), uwrap == "periodic", int(nv),
                          vwrap == "periodic", 5);
  }
  if (n == "Geometry") {
    if (!requireWorld(call)) return false;
    return doGeometry(call);
  }
  if (n == "ReadArchive") {
    std::string name;
    if (!positionalString(call, 0, &name)) return false;
    return readArchive(call, name);
  }
  if (n == "Procedural") return doProcedural(call);
  *handled = false;
  return true;
}

// SubdivisionMesh "catmull-clark" [nverts] [verts] [tags nargs intargs floatargs] params: the
// control mesh is subdivided a few levels (as quadrics are cut: about (displaced ? 16 : 4) edge
// lengths apart, at least 2 levels, at most 6 and 4M faces), with point normals of the result,
// then moved to the limit surface and read as PointsPolygons with what the levels made: vertex
// primitive variables subdivide with the points, varying ones bilinearly, facevarying ones
// linearly over each control face, uniform ones go to every face their face makes, constant ones
// stay. Tags "crease", "corner" and "hole" as rib_geometry.h says; boundaries are always
// interpolated (RenderMan's "interpolateboundary"); other tags and the "loop" scheme are warned
// about and ignored.
bool RibParser::doSubdivisionMesh(const Call& call) {
  if (!requireWorld(call)) return false;
  std::string scheme;
  if (!positionalString(call, 0, &scheme)) return false;
  if (call.args.size() < 3 || !call.args[1].isNumeric() || !call.args[2].isNumeric())
    return fail(call.line, "'SubdivisionMesh' expects a scheme, [nverts] [vertices] then tags and parameters");
  std::vector<int> nverts, verts;
  for (const auto& [arg, out] : {std::pair{&call.args[1], &nverts}, std::pair{&call.args[2], &verts}})
    for (double d : arg->numbers) {
      if (d != std::floor(d) || d < 0 || d > 1e9)
        return fail(arg->line, "'SubdivisionMesh': counts and indices must be whole numbers up to 1e9");
      out->push_back(int(d));
    }
  size_t first = 3;
  struct Tag {
    std::string name;
    std::vector<int> ints;
    std::vector<float> floats;
    int line;
  };
  std::vector<Tag> tags;
  if (call.args.size() > 3 && call.args[3].kind == Arg::Kind::Array) {
    // tags nargs intargs floatargs: per tag, its count of integer and of float arguments.
    if (call.args.size() < 7) return fail(call.line, "'SubdivisionMesh': tags need [nargs] [intargs] [floatargs]");
    const Arg &names = call.args[3], &nargs = call.args[4], &ints = call.args[5], &floats = call.args[6];
    if (!names.numbers.empty() || !nargs.strings.empty() || !ints.strings.empty() || !floats.strings.empty())
      return fail(names.line, "'SubdivisionMesh': tags are strings, [nargs] [intargs] [floatargs] numbers");
    if (nargs.numbers.size() != 2 * names.strings.size())
      return fail(nargs.line, "'SubdivisionMesh': " + std::to_string(names.strings.size()) + " tags need " +
                                  std::to_string(2 * names.strings.size()) + " nargs (integer and float counts), got " +
                                  std::to_string(nargs.numbers.size()));
    size_t nextInt = 0, nextFloat = 0;
    for (size_t k = 0; k < names.strings.size(); ++k) {
      const double ni = nargs.numbers[2 * k], nf = nargs.numbers[2 * k + 1];
      if (ni < 0 || nf < 0 || ni != std::floor(ni) || nf != std::floor(nf) || nextInt + ni > ints.numbers.size() ||
          nextFloat + nf > floats.numbers.size())
        return fail(nargs.line, "'SubdivisionMesh': the nargs of tag '" + names.strings[k] +
                                    "' do not match the intargs and floatargs given");
      Tag tag{names.strings[k], {}, {}, names.line};
      for (size_t i = 0; i < size_t(ni); ++i) {
        const double d = ints.numbers[nextInt + i];
        if (d != std::floor(d) || std::fabs(d) > 1e9)
          return fail(ints.line, "'SubdivisionMesh': intargs must be whole numbers");
        tag.ints.push_back(int(d));
      }
      for (size_t i = 0; i < size_t(nf); ++i) tag.floats.push_back(float(floats.numbers[nextFloat + i]));
      nextInt += size_t(ni), nextFloat += size_t(nf);
      tags.push_back(std::move(tag));
    }
    if (nextInt != ints.numbers.size() || nextFloat != floats.numbers.size())
      return fail(nargs.line, "'SubdivisionMesh': the nargs account for " + std::to_string(nextInt) + " intargs and " +
                                  std::to_string(nextFloat) + " floatargs, but " + std::to_string(ints.numbers.size()) +
                                  " and " + std::to_string(floats.numbers.size()) + " are given");
    first = 7;
  }
  if (scheme != "catmull-clark" && scheme != "bilinear")
    warnOnce(call.line, "scheme/" + scheme,
             "'SubdivisionMesh' scheme '" + scheme + "' is not supported; the control mesh is subdivided as catmull-clark");
  std::vector<Param> params;
  std::vector<float> P;
  if (!parseParams(call, first, &params) || !positions(call, params, 0, &P)) return false;
  const size_t numPoints = P.size() / 3;
  size_t total = 0;
  for (int k : nverts) {
    if (k < 3) return fail(call.line, "'SubdivisionMesh': a face needs at least 3 vertices");
    total += size_t(k);
  }
  if (total != verts.size())
    return fail(call.line, "'SubdivisionMesh': nverts sum to " + std::to_string(total) + " but " +
                               std::to_string(verts.size()) + " vertex indices given");
  SubdivisionSurface surface;
  for (size_t i = 0; i < numPoints; ++i) surface.P.emplace_back(P[3 * i], P[3 * i + 1], P[3 * i + 2]);
  size_t at = 0;
  for (int k : nverts) {
    std::vector<uint32_t> face;
    for (int j = 0; j < k; ++j, ++at) {
      if (size_t(verts[at]) >= numPoints)
        return fail(call.line, "'SubdivisionMesh': vertex index " + std::to_string(verts[at]) + " is out of range (" +
                                   std::to_string(numPoints) + " points)");
      face.push_back(uint32_t(verts[at]));
    }
    surface.faces.push_back(std::move(face));
  }
  // Tags: creases (chains of edges, one sharpness or one per edge), corners (points, one sharpness
  // or one each), holes (faces). The boundary is always interpolated.
  for (const Tag& tag : tags) {
    auto pointIndex = [&](int i) { return i >= 0 && size_t(i) < numPoints; };
    if (tag.name == "crease") {
      if (tag.ints.size() < 2 || (tag.floats.size() != 1 && tag.floats.size() != tag.ints.size() - 1))
        return fail(tag.line, "'SubdivisionMesh': a crease takes a chain of at least 2 points and 1 sharpness "
                              "(or one per edge)");
      for (size_t i = 0; i + 1 < tag.ints.size(); ++i) {
        if (!pointIndex(tag.ints[i]) || !pointIndex(tag.ints[i + 1]))
          return fail(tag.line, "'SubdivisionMesh': crease point " +
                                    std::to_string(pointIndex(tag.ints[i]) ? tag.ints[i + 1] : tag.ints[i]) +
                                    " is out of range (" + std::to_string(numPoints) + " points)");
        const float sharpness = tag.floats.size() == 1 ? tag.floats[0] : tag.floats[i];
        float& slot = surface.creases[SubdivisionSurface::edgeKey(uint32_t(tag.ints[i]), uint32_t(tag.ints[i + 1]))];
        slot = std::max(slot, std::isfinite(sharpness) ? sharpness : kInfiniteSharpness);
      }
    } else if (tag.name == "corner") {
      if (tag.ints.empty() || (tag.floats.size() != 1 && tag.floats.size() != tag.ints.size()))
        return fail(tag.line, "'SubdivisionMesh': a corner tag takes points and 1 sharpness (or one per point)");
      surface.corners.resize(numPoints, 0.0f);
      for (size_t i = 0; i < tag.ints.size(); ++i) {
        if (!pointIndex(tag.ints[i]))
          return fail(tag.line, "'SubdivisionMesh': corner point " + std::to_string(tag.ints[i]) + " is out of range (" +
                                    std::to_string(numPoints) + " points)");
        const float sharpness = tag.floats.size() == 1 ? tag.floats[0] : tag.floats[i];
        surface.corners[size_t(tag.ints[i])] = std::isfinite(sharpness) ? sharpness : kInfiniteSharpness;
      }
    } else if (tag.name == "hole") {
      surface.holes.resize(nverts.size(), 0);
      for (int f : tag.ints) {
        if (f < 0 || size_t(f) >= nverts.size())
          return fail(tag.line, "'SubdivisionMesh': hole face " + std::to_string(f) + " is out of range (" +
                                    std::to_string(nverts.size()) + " faces)");
        surface.holes[size_t(f)] = 1;
      }
    } else if (tag.name != "interpolateboundary" && tag.name != "facevaryinginterpolateboundary" &&
               tag.name != "facevaryingpropagatecorners") {
      warnOnce(call.line, "subdivtag/" + tag.name, "'SubdivisionMesh' tag '" + tag.name + "' is not supported; ignored");
    }
  }
  // Primitive variables: point-based ones become channels; the others are passed on as they are.
  std::vector<Param> passed;
  std::vector<std::pair<size_t, const Param*>> channelOf;  // channel index, its parameter
  std::vector<std::pair<size_t, const Param*>> faceVaryingOf;  // facevarying channel, its parameter
  std::vector<const Param*> uniforms;
  for (const Param& p : params) {
    if (p.name == "P" || p.name == "Pw") continue;
    if (p.value.isStringy()) {
      passed.push_back(p);
      continue;
    }
    const bool spatial = p.type && (*p.type == runtime::ParamType::Point || *p.type == runtime::ParamType::Vector ||
                                    *p.type == runtime::ParamType::Normal || *p.type == runtime::ParamType::Color);
    // Undeclared, st is two floats and Cs or N three; declared, the type says ("float[2] st").
    int components = spatial ? 3 : p.type ? 1 : p.name == "st" ? 2 : p.name == "Cs" || p.name == "N" ? 3 : 1;
    if (p.arraySize > 1) components *= p.arraySize;
    const size_t count = p.value.numbers.size();
    const std::string& cls = p.storageClass;
    if ((cls == "vertex" || cls == "varying" || cls.empty()) && count == numPoints * size_t(components) && numPoints > 1) {
      if (p.name == "N") {
        warnOnce(p.line, "subdivN", "'SubdivisionMesh': \"N\" is ignored; the subdivided surface's normals are used");
        continue;
      }
      SubdivisionSurface::Channel c;
      c.components = components;
      c.smooth = cls != "varying";
      c.values.assign(p.value.numbers.begin(), p.value.numbers.end());
      channelOf.emplace_back(surface.channels.size(), &p);
      surface.channels.push_back(std::move(c));
    } else if ((cls == "uniform" || cls.empty()) && count == nverts.size() * size_t(components) && nverts.size() > 1) {
      uniforms.push_back(&p);
    } else if ((cls == "facevarying" || cls == "facevertex" || cls.empty()) && count == total * size_t(components) &&
               count != size_t(components)) {
      if (p.name == "N") {
        warnOnce(p.line, "subdivN", "'SubdivisionMesh': \"N\" is ignored; the subdivided surface's normals are used");
        continue;
      }
      SubdivisionSurface::Channel c;
      c.components = components;
      c.values.assign(p.value.numbers.begin(), p.value.numbers.end());
      faceVaryingOf.emplace_back(surface.faceVarying.size(), &p);
      surface.faceVarying.push_back(std::move(c));
    } else {
      passed.push_back(p);  // constant: as it is
    }
  }
  // Levels: until the control mesh's longest edge is near the target, within [2, 6] and 4M faces.
  float longest = 0.0f;
  for (const std::vector<uint32_t>& face : surface.faces)
    for (size_t k = 0; k < face.size(); ++k)
      longest = std::max(longest, glm::length(surface.P[face[k]] - surface.P[face[(k + 1) % face.size()]]));
  const float target = (attr_.displacement ? 16.0f : 4.0f) * attr_.edgeLength;
  int levels = scheme == "bilinear" ? 0 : 2;
  while (scheme != "bilinear" && levels < 6 && std::ldexp(longest * maxScale(attr_.ctm), -levels) > target) ++levels;
  while (levels > 1 && double(total) * std::ldexp(1.0, 2 * levels) > 4e6) --levels;
  const bool bilinear = scheme == "bilinear";
  for (int l = 0; l < levels; ++l) {
    if (bilinear)
      for (SubdivisionSurface::Channel& c : surface.channels) c.smooth = false;
    surface = subdivideCatmullClark(surface);
  }
  if (levels > 0 && !bilinear) projectToLimit(surface);
  // Faces that are holes are left out (their points stay, unused).
  std::vector<uint8_t> kept(surface.faces.size(), 1);
  for (size_t f = 0; f < surface.holes.size(); ++f) kept[f] = !surface.holes[f];
  // The result as PointsPolygons: quads (or the control faces), positions, point normals, and
  // the channels, uniform values following each face's parent.
  Call polygons;
  polygons.name = call.name;
  polygons.line = call.line;
  Arg counts, indices;
  counts.kind = indices.kind = Arg::Kind::Array;
  counts.line = indices.line = call.line;
  size_t keptFaces = 0;
  for (size_t f = 0; f < surface.faces.size(); ++f) {
    if (!kept[f]) continue;
    ++keptFaces;
    counts.numbers.push_back(double(surface.faces[f].size()));
    for (uint32_t p : surface.faces[f]) indices.numbers.push_back(double(p));
  }
  if (keptFaces == 0) {
    warn(call.line, "'SubdivisionMesh' has only holes; skipped");
    return true;
  }
  polygons.args = {counts, indices};
  auto addParam = [&](const std::string& declaration, std::vector<double> values) {
    Arg name;
    name.kind = Arg::Kind::String;
    name.strings = {declaration};
    name.line = call.line;
    Arg value;
    value.kind = Arg::Kind::Array;
    value.numbers = std::move(values);
    value.line = call.line;
    polygons.args.push_back(std::move(name));
    polygons.args.push_back(std::move(value));
  };
  std::vector<double> positionsOut, normalsOut;
  for (const glm::vec3& p : surface.P) positionsOut.insert(positionsOut.end(), {p.x, p.y, p.z});
  addParam("vertex point P", std::move(positionsOut));
  if (levels > 0) {
    // A mesh folded onto itself (a card of two back-to-back faces) has points whose faces cancel:
    // no normal there. It renders with face normals (it had failed as "zero-length normal").
    bool folded = false;
    for (const glm::vec3& n : pointNormals(surface)) {
      folded = folded || !(glm::length(n) > 0.0f) || !std::isfinite(glm::length(n));
      normalsOut.insert(normalsOut.end(), {n.x, n.y, n.z});
    }
    if (folded)
      warn(call.line, "'SubdivisionMesh': the surface folds back onto itself (the normals of its faces cancel "
                      "at some points); it is shaded and displaced with face normals");
    else
      addParam("vertex normal N", std::move(normalsOut));
  }
  auto typeWord = [](const Param& p) {
    if (!p.type) return std::string(p.name == "Cs" ? "color" : "float");
    switch (*p.type) {
      case runtime::ParamType::Point: return std::string("point");
      case runtime::ParamType::Vector: return std::string("vector");
      case runtime::ParamType::Normal: return std::string("normal");
      case runtime::ParamType::Color: return std::string("color");
      case runtime::ParamType::Int: return std::string("int");
      case runtime::ParamType::String: return std::string("string");
      case runtime::ParamType::Matrix: return std::string("matrix");
      default: return std::string("float");
    }
  };
  auto arrayWord = [](const Param& p) { return p.arraySize > 1 ? "[" + std::to_string(p.arraySize) + "]" : std::string(); };
  for (const auto& [c, p] : channelOf) {
    const SubdivisionSurface::Channel& channel = surface.channels[c];
    addParam("vertex " + typeWord(*p) + arrayWord(*p) + " " + p->name,
             std::vector<double>(channel.values.begin(), channel.values.end()));
  }
  for (const Param* p : uniforms) {
    const size_t components = p->value.numbers.size() / nverts.size();
    std::vector<double> values;
    for (size_t f = 0; f < surface.faces.size(); ++f) {
      if (!kept[f]) continue;
      const size_t parent = surface.parent.empty() ? f : surface.parent[f];
      values.insert(values.end(), p->value.numbers.begin() + std::ptrdiff_t(parent * components),
                    p->value.numbers.begin() + std::ptrdiff_t((parent + 1) * components));
    }
    addParam("uniform " + typeWord(*p) + arrayWord(*p) + " " + p->name, std::move(values));
  }
  for (const auto& [c, p] : faceVaryingOf) {
    const SubdivisionSurface::Channel& channel = surface.faceVarying[c];
    const size_t m = size_t(channel.components);
    std::vector<double> values;
    size_t corner = 0;
    for (size_t f = 0; f < surface.faces.size(); ++f) {
      const size_t n = surface.faces[f].size();
      if (kept[f])
        values.insert(values.end(), channel.values.begin() + std::ptrdiff_t(corner * m),
                      channel.values.begin() + std::ptrdiff_t((corner + n) * m));
      corner += n;
    }
    addParam("facevarying " + typeWord(*p) + arrayWord(*p) + " " + p->name, std::move(values));
  }
  for (const Param& p : passed) {
    Arg name;
    name.kind = Arg::Kind::String;
    name.strings = {(p.storageClass.empty() ? std::string() : p.storageClass + " ") +
                    (p.type ? typeWord(p) + arrayWord(p) + " " : std::string()) + p.name};
    name.line = p.line;
    polygons.args.push_back(std::move(name));
    polygons.args.push_back(p.value);
  }
  const size_t before = scene_.meshes.size();
  if (!buildPolygonMesh(polygons, std::vector<int>(keptFaces, 1),
                        std::vector<int>(counts.numbers.begin(), counts.numbers.end()),
                        std::vector<int>(indices.numbers.begin(), indices.numbers.end()), 2))
    return false;
  // The normals are the limit surface's own, not the scene's: they turn with the orientation, and
  // the shader's Ng follows them as on any smooth surface.
  for (size_t m = before; m < scene_.meshes.size(); ++m) {
    scene_.meshes[m].givenNormals = false;
    scene_.meshes[m].smoothSurface = !scene_.meshes[m].N.empty();
  }
  return true;
}

// NuPatch nu uorder uknot umin umax nv vorder vknot vmin vmax params: a non-uniform rational
// B-spline patch ("P", or "Pw" for rational weights), tessellated on a grid of parameter values
// (every knot span in [umin, umax] cut into as many steps as a bicubic patch would be) with its
// analytic normals. u and v are the knot parameters, and st defaults to them (RI). Vertex
// primitive variables follow the patch's basis and weights, varying ones interpolate linearly
// between the segment corners, constant ones stay; uniform and facevarying ones are warned about
// and ignored. Closed patches (seams and poles, as NURBS spheres and cylinders have) get points
// and normals that are bit-identical across the seam, so displacement does not crack them.
bool RibParser::doNuPatch(const Call& call) {
  if (!requireWorld(call)) return false;
  // The ten positional arguments: counts and orders are numbers, knots arrays.
  if (call.args.size() < 10)
    return fail(call.line, "'NuPatch' expects nu uorder [uknot] umin umax nv vorder [vknot] vmin vmax then parameters");
  for (size_t k = 0; k < 10; ++k)
    if (!call.args[k].isNumeric() || ((k == 2 || k == 7) ? call.args[k].kind != Arg::Kind::Array : call.args[k].numbers.size() != 1))
      return fail(call.args[k].line, "'NuPatch' expects nu uorder [uknot] umin umax nv vorder [vknot] vmin vmax then parameters");
  struct Direction {
    int n, order;
    std::vector<float> knots;
    float lo, hi;
    std::vector<float> breaks;  // the distinct knots in [lo, hi], lo and hi included
  };
  Direction dir[2];
  for (int d = 0; d < 2; ++d) {
    const size_t a = size_t(5 * d);
    const double n = call.args[a].numbers[0], order = call.args[a + 1].numbers[0];
    const char* name = d == 0 ? "u" : "v";
    if (n != std::floor(n) || order != std::floor(order) || order < 1 || order > kMaxNurbsOrder || n < order || n > 1e6)
      return fail(call.args[a].line, std::string("'NuPatch': n") + name + " " + std::to_string(int64_t(n)) + " and " + name +
                                         "order " + std::to_string(int64_t(order)) + " must be whole, the order from 1 to " +
                                         std::to_string(kMaxNurbsOrder) + " and at most the count");
    Direction& D = dir[d];
    D.n = int(n), D.order = int(order);
    for (double k : call.args[a + 2].numbers) D.knots.push_back(float(k));
    if (D.knots.size() != size_t(D.n + D.order))
      return fail(call.args[a + 2].line, std::string("'NuPatch': ") + name + "knot needs n" + name + " + " + name + "order = " +
                                             std::to_string(D.n + D.order) + " values, got " + std::to_string(D.knots.size()));
    for (size_t k = 0; k < D.knots.size(); ++k)
      if (!std::isfinite(D.knots[k]) || (k > 0 && D.knots[k] < D.knots[k - 1]))
        return fail(call.args[a + 2].line, std::string("'NuPatch': ") + name + "knot must be finite and non-decreasing");
    const float first = D.knots[size_t(D.order - 1)], last = D.knots[size_t(D.n)];
    D.lo = std::max(float(call.args[a + 3].numbers[0]), first);
    D.hi = std::min(float(call.args[a + 4].numbers[0]), last);
    if (!(D.lo < D.hi))
      return fail(call.args[a + 3].line, std::string("'NuPatch': the ") + name + " range [" + std::to_string(call.args[a + 3].numbers[0]) +
                                             ", " + std::to_string(call.args[a + 4].numbers[0]) + "] holds none of the knot range [" +
                                             std::to_string(first) + ", " + std::to_string(last) + "]");
    D.breaks.push_back(D.lo);
    for (float k : D.knots)
      if (k > D.breaks.back() && k < D.hi) D.breaks.push_back(k);
    D.breaks.push_back(D.hi);
  }
  const int nu = dir[0].n, nv = dir[1].n;
  const size_t count = size_t(nu) * size_t(nv);
  std::vector<Param> params;
  std::vector<float> P;
  if (!parseParams(call, 10, &params) || !positions(call, params, count, &P)) return false;
  // Homogeneous control points: RenderMan's Pw is (w x, w y, w z, w).
  std::vector<glm::vec4> H(count);
  const Param* pw = findParam(params, "P") ? nullptr : findParam(params, "Pw");
  for (size_t i = 0; i < count; ++i) {
    const float w = pw ? float(pw->value.numbers[4 * i + 3]) : 1.0f;
    H[i] = glm::vec4(glm::vec3(P[3 * i], P[3 * i + 1], P[3 * i + 2]) * w, w);
  }
  const size_t segU = size_t(nu - dir[0].order + 1), segV = size_t(nv - dir[1].order + 1);
  // RI: facevarying counts as varying on a NuPatch (one value per segment corner).
  PrimvarCounts counts{segU * segV, count, (segU + 1) * (segV + 1), (segU + 1) * (segV + 1)};
  std::vector<Primvar> vars;
  if (!readPrimvars(call, params, counts, &vars)) return false;
  const Primvar *st = nullptr, *s = nullptr, *t = nullptr, *Cs = nullptr, *N = nullptr;
  for (const Primvar& v : vars) {
    if (v.storage == PrimvarClass::Uniform || v.storage == PrimvarClass::FaceVarying) {
      warnOnce(call.line, "nupatch/" + v.name, "'NuPatch': uniform and facevarying \"" + v.name + "\" are not supported; ignored");
      continue;
    }
    if (v.name == "st") st = &v;
    if (v.name == "s") s = &v;
    if (v.name == "t") t = &v;
    if (v.name == "Cs") Cs = &v;
    if (v.name == "N") N = &v;
  }
  // Steps per knot span, from the control hull as for bicubic patches.
  const glm::mat4& m = attr_.ctm;
  float hull = 0.0f;
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const glm::vec3 p(P[3 * (size_t(j) * size_t(nu) + size_t(i))], P[3 * (size_t(j) * size_t(nu) + size_t(i)) + 1],
                        P[3 * (size_t(j) * size_t(nu) + size_t(i)) + 2]);
      if (i + 1 < nu) {
        const size_t k = 3 * (size_t(j) * size_t(nu) + size_t(i) + 1);
        hull = std::max(hull, glm::length(glm::vec3(P[k], P[k + 1], P[k + 2]) - p));
      }
      if (j + 1 < nv) {
        const size_t k = 3 * ((size_t(j) + 1) * size_t(nu) + size_t(i));
        hull = std::max(hull, glm::length(glm::vec3(P[k], P[k + 1], P[k + 2]) - p));
      }
    }
  if (!std::isfinite(hull)) return fail(call.line, "'NuPatch': control points must be finite");
  const float target = (attr_.displacement ? 16.0f : 4.0f) * attr_.edgeLength;
  // Order 2 both ways is bilinear per span, exactly two triangles where that map is affine: equal
  // weights (else P is a projective function of (u, v)) and parallelogram spans (else the
  // isoparametric lines bend, as on a bilinear Patch). Other spans are sampled like curved ones.
  bool affine = true;
  for (const glm::vec4& h : H) affine = affine && h.w == H[0].w;
  for (int j = 0; j + 1 < nv && affine; ++j)
    for (int i = 0; i + 1 < nu && affine; ++i) {
      auto at = [&](int a, int b) {
        const size_t k = 3 * (size_t(b) * size_t(nu) + size_t(a));
        return glm::vec3(P[k], P[k + 1], P[k + 2]);
      };
      const glm::vec3 p00 = at(i, j), p10 = at(i + 1, j), p01 = at(i, j + 1), p11 = at(i + 1, j + 1);
      const glm::vec3 skew = glm::abs((p00 + p11) - (p10 + p01));
      const float scale = std::max({glm::length(p10 - p00), glm::length(p01 - p00), glm::length(p11 - p00)});
      affine = std::max({skew.x, skew.y, skew.z}) <= 1e-5f * scale;
    }
  const int linear = dir[0].order <= 2 && dir[1].order <= 2 && affine;
  const int steps = linear ? 1 : std::clamp(int(std::ceil(hull * maxScale(m) * 3.0f / target)), 8, 32);
  std::vector<float> params1[2];
  for (int d = 0; d < 2; ++d) {
    const std::vector<float>& b = dir[d].breaks;
    for (size_t k = 0; k + 1 < b.size(); ++k)
      for (int q = 0; q < steps; ++q) params1[d].push_back(b[k] + (b[k + 1] - b[k]) * float(q) / float(steps));
    params1[d].push_back(b.back());
  }
  const size_t columns = params1[0].size(), rows = params1[1].size();
  if (columns * rows > (size_t(1) << 24)) return fail(call.line, "'NuPatch' is too large to tessellate");

  // Vertex values at a grid point: sum of basis * weight * value over the nonzero functions,
  // divided by the weights' sum (the same rational map as P).
  struct Basis {
    int first;
    float value[kMaxNurbsOrder], derivative[kMaxNurbsOrder];
  };
  auto basisAt = [&](int d, float x) {
    Basis b;
    b.first = nurbsBasis(dir[d].knots, dir[d].order, dir[d].n, x, b.value, b.derivative);
    return b;
  };
  // Varying values: linear between the segment corners, which sit at knots order-1 .. n.
  auto varyingAt = [&](const Primvar& v, float x, float y, float* out) {
    float w[2][2];
    size_t index[2][2];
    for (int d = 0; d < 2; ++d) {
      const Direction& D = dir[d];
      const float param = d == 0 ? x : y;
      size_t k = 0;
      const size_t segments = size_t(D.n - D.order + 1);
      while (k + 1 < segments && D.knots[size_t(D.order) + k] <= param) ++k;
      const float a = D.knots[size_t(D.order - 1) + k], b = D.knots[size_t(D.order) + k];
      const float f = b > a ? std::clamp((param - a) / (b - a), 0.0f, 1.0f) : 0.0f;
      w[d][0] = 1.0f - f, w[d][1] = f;
      index[d][0] = k, index[d][1] = k + 1;
    }
    for (int c = 0; c < v.components; ++c) out[c] = 0.0f;
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) {
        const float* value = v.at(index[1][j] * (segU + 1) + index[0][i]);
        for (int c = 0; c < v.components; ++c) out[c] += w[0][i] * w[1][j] * value[c];
      }
  };
  auto valueAt = [&](const Primvar& v, const Basis& bu, const Basis& bv, float x, float y, float* out) {
    if (v.storage == PrimvarClass::Constant) {
      std::copy(v.at(0), v.at(0) + v.components, out);
    } else if (v.storage == PrimvarClass::Varying) {
      varyingAt(v, x, y, out);
    } else {
      float weight = 0.0f;
      for (int c = 0; c < v.components; ++c) out[c] = 0.0f;
      for (int j = 0; j < dir[1].order; ++j)
        for (int i = 0; i < dir[0].order; ++i) {
          const size_t k = size_t(bv.first + j) * size_t(nu) + size_t(bu.first + i);
          const float b = bu.value[i] * bv.value[j] * H[k].w;
          weight += b;
          for (int c = 0; c < v.components; ++c) out[c] += b * v.at(k)[c];
        }
      for (int c = 0; c < v.components; ++c) out[c] = weight != 0.0f ? out[c] / weight : 0.0f;
    }
  };
  const glm::mat3 normalFromObject = glm::transpose(glm::inverse(glm::mat3(m)));
  Mesh mesh;
  mesh.P.resize(columns * rows);
  mesh.N.resize(columns * rows);
  mesh.uv.resize(columns * rows);
  mesh.st.resize(columns * rows);
  mesh.dPdu.resize(columns * rows);
  mesh.dPdv.resize(columns * rows);
  if (Cs) mesh.Cs.resize(columns * rows);
  std::vector<uint8_t> degenerate(columns * rows, 0);
  for (size_t row = 0; row < rows; ++row) {
    const float y = params1[1][row];
    const Basis bv = basisAt(1, y);
    for (size_t col = 0; col < columns; ++col) {
      const float x = params1[0][col];
      const Basis bu = basisAt(0, x);
      glm::dvec4 S(0.0), Su(0.0), Sv(0.0);
      for (int j = 0; j < dir[1].order; ++j)
        for (int i = 0; i < dir[0].order; ++i) {
          const glm::dvec4 h(H[size_t(bv.first + j) * size_t(nu) + size_t(bu.first + i)]);
          S += double(bu.value[i]) * double(bv.value[j]) * h;
          Su += double(bu.derivative[i]) * double(bv.value[j]) * h;
          Sv += double(bu.value[i]) * double(bv.derivative[j]) * h;
        }
      const size_t k = row * columns + col;
      const glm::dvec3 p = glm::dvec3(S) / S.w;
      // The quotient rule: d(A / w) = (dA - dw (A / w)) / w.
      const glm::dvec3 du = (glm::dvec3(Su) - Su.w * p) / S.w, dv = (glm::dvec3(Sv) - Sv.w * p) / S.w;
      mesh.P[k] = glm::vec3(m * glm::vec4(glm::vec3(p), 1.0f));
      mesh.dPdu[k] = glm::mat3(m) * glm::vec3(du), mesh.dPdv[k] = glm::mat3(m) * glm::vec3(dv);
      glm::vec3 normal = N ? glm::vec3(0.0f) : normalFromObject * glm::vec3(glm::cross(du, dv));
      if (N) {
        float value[3];
        valueAt(*N, bu, bv, x, y, value);
        normal = normalFromObject * glm::vec3(value[0], value[1], value[2]);
      }
      const float len = glm::length(normal);
      degenerate[k] = !(len > 1e-20f && std::isfinite(len)) || !std::isfinite(S.w) || S.w == 0.0;
      mesh.N[k] = degenerate[k] ? glm::vec3(0.0f) : normal / len;
      mesh.uv[k] = glm::vec2(x, y);
      mesh.st[k] = mesh.uv[k];
      float value[3];
      if (st) valueAt(*st, bu, bv, x, y, value), mesh.st[k] = glm::vec2(value[0], value[1]);
      if (!st && s) valueAt(*s, bu, bv, x, y, value), mesh.st[k].x = value[0];
      if (!st && t) valueAt(*t, bu, bv, x, y, value), mesh.st[k].y = value[0];
      if (Cs) valueAt(*Cs, bu, bv, x, y, value), mesh.Cs[k] = glm::vec3(value[0], value[1], value[2]);
    }
  }
  for (const glm::vec3& p : mesh.P)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      return fail(call.line, "'NuPatch' evaluates to non-finite points (zero or negative weights?)");
  // Seams and poles: the displacement of a point follows its position and normal, so points that
  // coincide must agree bit for bit. Within a relative tolerance of the patch's size, a last
  // column (row) equal to the first becomes its copy, and a row (column) collapsed to one point
  // becomes that point, its normal the mean of the neighbouring row's.
  glm::vec3 lo = mesh.P[0], hi = mesh.P[0];
  for (const glm::vec3& p : mesh.P) lo = glm::min(lo, p), hi = glm::max(hi, p);
  const float tolerance = 1e-6f * glm::length(hi - lo);
  auto at = [&](size_t row, size_t col) { return row * columns + col; };
  auto close = [&](size_t a, size_t b) { return glm::length(mesh.P[a] - mesh.P[b]) <= tolerance; };
  for (int d = 0; d < 2; ++d) {
    const size_t along = d == 0 ? rows : columns, across = d == 0 ? columns : rows;
    auto index = [&](size_t i, size_t j) { return d == 0 ? at(i, j) : at(j, i); };  // i along, j across
    bool seam = across > 2;
    for (size_t i = 0; seam && i < along; ++i) seam = close(index(i, 0), index(i, across - 1));
    if (!seam) continue;
    for (size_t i = 0; i < along; ++i) {
      const size_t a = index(i, 0), b = index(i, across - 1);
      const glm::vec3 sum = mesh.N[a] + mesh.N[b];
      const float len = glm::length(sum);
      if (len > 1e-6f) mesh.N[a] = sum / len, degenerate[a] = 0;
      mesh.P[b] = mesh.P[a], mesh.N[b] = mesh.N[a], degenerate[b] = degenerate[a];
    }
  }
  for (int d = 0; d < 2; ++d) {
    const size_t along = d == 0 ? rows : columns, across = d == 0 ? columns : rows;
    auto index = [&](size_t i, size_t j) { return d == 0 ? at(i, j) : at(j, i); };
    for (size_t i : {size_t(0), along - 1}) {
      bool pole = along > 1;
      for (size_t j = 1; pole && j < across; ++j) pole = close(index(i, 0), index(i, j));
      if (!pole) continue;
      const size_t next = i == 0 ? 1 : along - 2;
      glm::vec3 sum(0.0f);
      for (size_t j = 0; j + (across > 2 ? 1 : 0) < across; ++j) sum += mesh.N[index(next, j)];
      const float len = glm::length(sum);
      for (size_t j = 0; j < across; ++j) {
        const size_t k = index(i, j);
        mesh.P[k] = mesh.P[index(i, 0)];
        if (len > 1e-6f) mesh.N[k] = sum / len, degenerate[k] = 0;
      }
    }
  }
  if (std::find(degenerate.begin(), degenerate.end(), 1) != degenerate.end()) mesh.N.clear();
  mesh.givenNormals = N != nullptr && !mesh.N.empty();
  for (size_t j = 0; j + 1 < rows; ++j)
    for (size_t i = 0; i + 1 < columns; ++i) {
      const uint32_t a = uint32_t(at(j, i)), b = a + 1, c = uint32_t(at(j + 1, i)), d = c + 1;
      mesh.indices.insert(mesh.indices.end(), {a, b, d, a, d, c});
    }
  mesh.smoothSurface = !mesh.givenNormals && !mesh.N.empty();
  return addMesh(std::move(mesh), call.line);
}

bool RibParser::doSphere(const Call& call) {
  std::vector<float> v;
  size_t next = 0;
  if (!positionalNumbers(call, 4, &v, &next)) return false;
  std::vector<Param> params;
  if (!parseParams(call, next, &params)) return false;
  std::vector<Primvar> vars;
  if (!quadricPrimvars(call, params, &vars)) return false;
  const float radius = v[0];
  // In the order given: swapped bounds run v downward and turn the sphere inside-out (RI).
  float zmin = std::clamp(v[1], -std::fabs(radius), std::fabs(radius));
  float zmax = std::clamp(v[2], -std::fabs(radius), std::fabs(radius));
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
      std::fabs(std::acos(zmin / std::fabs(radius)) - std::acos(zmax / std::fabs(radius))) / float(M_PI);
  const float arcU = 2.0f * float(M_PI) * worldRadius * sweep;
  const float arcV = float(M_PI) * worldRadius * std::fabs(vFraction);
  const int nu = std::clamp(int(std::ceil(arcU / target)), std::max(4, int(float(minU) * sweep)), 1024);
  const int nv =
      std::clamp(int(std::ceil(arcV / target)), std::max(2, int(float(minV) * vFraction)), 512);
  Mesh mesh = tessellateSphere(radius, zmin, zmax, thetamax, nu, nv, attr_.ctm);
  applyQuadricPrimvars(vars, &mesh);
  mesh.smoothSurface = !mesh.N.empty();
  return addMesh(std::move(mesh), call.line, /*wound=*/true);
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
  std::vector<Primvar> vars;
  if (!quadricPrimvars(call, params, &vars)) return false;
  const float thetamax = glm::radians(std::clamp(v[count - 1], -360.0f, 360.0f));
  if (thetamax == 0.0f) {
    warn(call.line, "degenerate '" + n + "' skipped");
    return true;
  }
  std::function<glm::vec3(float, float)> position;
  // dP/dv of the surface (every quadric turns about z with u: dP/du = thetamax (-y, x, 0)).
  std::function<glm::vec3(float, float)> alongV;
  bool curvedV = false;
  float lengthV = 0.0f;  // object-space length of a v line, for straight v directions
  float radiusU = 0.0f;  // largest object-space radius swept by u
  if (n == "Cylinder") {
    const float r = v[0], z0 = v[1], z1 = v[2];
    position = [=](float u, float t) {
      return glm::vec3(r * std::cos(u * thetamax), r * std::sin(u * thetamax), z0 + t * (z1 - z0));
    };
    alongV = [=](float, float) { return glm::vec3(0.0f, 0.0f, z1 - z0); };
    lengthV = std::fabs(z1 - z0);
    radiusU = std::fabs(r);
  } else if (n == "Cone" || n == "Disk") {
    const bool cone = n == "Cone";
    const float h = v[0], r = v[1];
    position = [=](float u, float t) {
      const float rr = r * (1.0f - t);
      return glm::vec3(rr * std::cos(u * thetamax), rr * std::sin(u * thetamax), cone ? t * h : h);
    };
    alongV = [=](float u, float) {
      return glm::vec3(-r * std::cos(u * thetamax), -r * std::sin(u * thetamax), cone ? h : 0.0f);
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
    alongV = [=](float u, float t) {  // infinite at an apex (z = 0): smoothSurfaceDerivatives skips it
      const float z = z0 + t * (z1 - z0);
      const float dr = rmax * (z1 - z0) / (2.0f * std::sqrt(z * z1));
      return glm::vec3(dr * std::cos(u * thetamax), dr * std::sin(u * thetamax), z1 - z0);
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
    alongV = [=](float u, float) {
      const glm::vec3 d = p2 - p1;
      const float c = std::cos(u * thetamax), s = std::sin(u * thetamax);
      return glm::vec3(d.x * c - d.y * s, d.x * s + d.y * c, d.z);
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
    alongV = [=](float u, float t) {
      const float phi = phi0 + t * (phi1 - phi0), dphi = phi1 - phi0;
      return dphi * glm::vec3(-minor * std::sin(phi) * std::cos(u * thetamax),
                              -minor * std::sin(phi) * std::sin(u * thetamax), minor * std::cos(phi));
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
  const glm::mat3 linear(attr_.ctm);
  const glm::mat3 normalFromObject = glm::transpose(glm::inverse(linear));
  Mesh mesh;
  for (int j = 0; j <= nv; ++j)
    for (int i = 0; i <= nu; ++i) {
      const float u = float(i) / float(nu), t = float(j) / float(nv);
      const glm::vec3 p = position(u, t);
      mesh.P.push_back(glm::vec3(attr_.ctm * glm::vec4(p, 1.0f)));
      mesh.dPdu.push_back(linear * (thetamax * glm::vec3(-p.y, p.x, 0.0f)));
      mesh.dPdv.push_back(linear * alongV(u, t));
      glm::vec3 normal = normalFromObject * normalAt(u, t);
      const float len = glm::length(normal);
      mesh.N.push_back(len > 0.0f ? normal / len : glm::vec3(0, 0, 1));
      mesh.uv.emplace_back(u, t);
    }
  // A full sweep's last column is its first (cos and sin of 2 pi are not exactly 1 and 0): the same
  // bits, so displacement cannot open the seam, and one group for smoothSurfaceDerivatives. So is a
  // torus's last row when its tube goes all the way round.
  const size_t row = size_t(nu) + 1;
  if (std::fabs(thetamax) >= 2.0f * float(M_PI) * (1.0f - 1e-6f))
    for (size_t j = 0; j <= size_t(nv); ++j)
      mesh.P[j * row + size_t(nu)] = mesh.P[j * row], mesh.N[j * row + size_t(nu)] = mesh.N[j * row];
  if (n == "Torus" && std::fabs(v[3] - v[2]) >= 360.0f * (1.0f - 1e-6f))
    for (size_t i = 0; i < row; ++i)
      mesh.P[size_t(nv) * row + i] = mesh.P[i], mesh.N[size_t(nv) * row + i] = mesh.N[i];
  // A row collapsed to one point (a cone's or paraboloid's apex, where a hyperboloid crosses the
  // axis, a disk's centre): its copies take their mean normal. Each had its own column's normal,
  // nudged off the apex, and displaced along them the apex opened into a hole.
  for (size_t j = 0; j <= size_t(nv); ++j) {
    const glm::vec3 first = mesh.P[j * row];
    bool collapsed = true;
    glm::vec3 sum(0.0f);
    for (size_t i = 0; i < row && collapsed; ++i) {
      collapsed = mesh.P[j * row + i] == first;
      sum += mesh.N[j * row + i];
    }
    const float len = glm::length(sum);
    if (!collapsed || !(len > 1e-6f) || !std::isfinite(len)) continue;
    for (size_t i = 0; i < row; ++i) mesh.N[j * row + i] = sum / len;
  }
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const uint32_t a = uint32_t(j * (nu + 1) + i), b = a + 1, c = a + uint32_t(nu + 1), d = c + 1;
      mesh.indices.insert(mesh.indices.end(), {a, b, d, a, d, c});
    }
  applyQuadricPrimvars(vars, &mesh);
  mesh.smoothSurface = !mesh.N.empty();
  return addMesh(std::move(mesh), call.line);
}

// Reads the primitive variables N st s t Cs of a polygon or patch mesh. `counts` gives the
// expected number of values per class; an undeclared class is inferred from the value count.
// A primitive variable that is not one of the standard ones: one named like a parameter of the
// displacement shader is bound over the Displacement call's value for this primitive (RenderMan's
// rule), when it has one value for the primitive (constant, or uniform and the same on every
// face); a value varying over the primitive is not supported: a warning, and the shader's own.
bool RibParser::shaderPrimvar(const Call& call, const Param& p, const PrimvarCounts& counts) {
  const runtime::ParamInfo* info =
      attr_.displacement ? attr_.displacement->shader().findParam(p.name) : nullptr;
  if (!info || info->isOutput) {
    warnOnce(p.line, call.name + "/" + p.name,
             "'" + call.name + "': primitive variable '" + p.name +
                 "' is not supported (nor a parameter of the displacement shader); ignored");
    return true;
  }
  runtime::ParamValue value;
  if (!shaderParamValue(p.line, attr_.displacement->shader(), p, &value)) return false;
  const int components = value.type == runtime::ParamType::Matrix ? 16
                         : value.type == runtime::ParamType::Float || value.type == runtime::ParamType::Int ||
                                 value.type == runtime::ParamType::String
                             ? 1
                             : 3;
  const size_t one = size_t(std::max(info->arrayLength, 1)) * size_t(components);
  const size_t given = value.type == runtime::ParamType::String ? value.strings.size() : value.numbers.size();
  // A count that fits no storage class (or not the one declared) is a slip, an error as for the
  // standard variables, not a value that merely varies.
  {
    const std::pair<const char*, size_t> classes[] = {{"constant", 1},
                                                      {"uniform", counts.uniform},
                                                      {"varying", counts.varying},
                                                      {"vertex", counts.vertex},
                                                      {"facevarying", counts.faceVarying}};
    bool fits = false;
    for (const auto& [word, items] : classes)
      if ((p.storageClass.empty() || p.storageClass == word) && given == one * items) fits = true;
    if (!fits) {
      if (!p.storageClass.empty())
        for (const auto& [word, items] : classes)
          if (p.storageClass == word)
            return fail(p.line, "'" + call.name + "': " + p.storageClass + " '" + p.name + "' needs " +
                                    std::to_string(one * items) + (one * items == 1 ? " value" : " values") + ", got " +
                                    std::to_string(given));
      return fail(p.line, "'" + call.name + "': '" + p.name + "' has " + std::to_string(given) + " values; expected " +
                              std::to_string(one) + " (one in all), " + std::to_string(one * counts.uniform) +
                              " (per face), " + std::to_string(one * counts.varying) + " (per vertex) or " +
                              std::to_string(one * counts.faceVarying) + " (per face corner)");
    }
  }
  const bool constant = p.storageClass == "constant" || (p.storageClass.empty() && given == one);
  // Per face, vertex or face corner: bound when every item has the same value (a varying value
  // that does not vary is one value; it had been refused as "varies").
  const size_t items = given / one;
  bool same = !constant && items > 0;
  for (size_t f = 1; same && f < items; ++f)
    for (size_t i = 0; same && i < one; ++i)
      same = value.type == runtime::ParamType::String ? value.strings[f * one + i] == value.strings[i]
                                                      : value.numbers[f * one + i] == value.numbers[i];
  if (!constant && !same) {
    warnOnce(p.line, call.name + "/" + p.name,
             "'" + call.name + "': primitive variable '" + p.name + "' varies over the primitive; " +
                 "shader parameters take one value per primitive, so the Displacement call's is used");
    return true;
  }
  value.numbers.resize(std::min(value.numbers.size(), one));
  value.strings.resize(std::min(value.strings.size(), one));
  std::string error;
  runtime::ShaderInstance probe(attr_.displacement->sharedShader());
  if (!probe.bind(value, &error)) return fail(p.line, "'" + call.name + "': " + error + declareNote(p));
  primvarParams_.push_back(std::move(value));
  return true;
}

bool RibParser::readPrimvars(const Call& call, const std::vector<Param>& params,
                             const PrimvarCounts& counts, std::vector<Primvar>* out) {
  struct Known {
    const char* name;
    int components;
    const char* typeName;
  };
  static const Known known[] = {{"N", 3, "normal"}, {"st", 2, "float"}, {"s", 1, "float"},
                                {"t", 1, "float"},  {"Cs", 3, "color"}};
  for (const Param& p : params) {
    if (p.name == "P" || p.name == "Pw" || p.name == "Pz") continue;
    const Known* k = nullptr;
    for (const Known& candidate : known)
      if (p.name == candidate.name) k = &candidate;
    if (!k) {
      if (!shaderPrimvar(call, p, counts)) return false;
      continue;
    }
    Primvar v;
    v.name = p.name;
    v.components = k->components;
    if (!numbersParam(call, p, k->typeName, 0, &v.values)) return false;
    const size_t items = v.values.size() / size_t(k->components);
    const std::pair<const char*, PrimvarClass> classes[] = {
        {"vertex", PrimvarClass::Vertex},   {"varying", PrimvarClass::Varying},
        {"facevarying", PrimvarClass::FaceVarying}, {"uniform", PrimvarClass::Uniform},
        {"constant", PrimvarClass::Constant}};
    auto expected = [&](PrimvarClass c) {
      switch (c) {
        case PrimvarClass::Constant: return size_t(1);
        case PrimvarClass::Uniform: return counts.uniform;
        case PrimvarClass::Vertex: return counts.vertex;
        case PrimvarClass::Varying: return counts.varying;
        case PrimvarClass::FaceVarying: return counts.faceVarying;
      }
      return size_t(0);
    };
    bool found = false;
    if (!p.storageClass.empty()) {
      for (const auto& [word, c] : classes)
        if (p.storageClass == word) v.storage = c, found = true;
      if (!found)
        return fail(p.line, "'" + call.name + "': '" + p.name + "' has class '" +
                                p.storageClass + "', which this primitive does not take");
      if (v.values.size() != expected(v.storage) * size_t(k->components))
        return fail(p.line, "'" + call.name + "': " + p.storageClass + " '" + p.name +
                                "' needs " +
                                std::to_string(expected(v.storage) * size_t(k->components)) +
                                " numbers, got " + std::to_string(v.values.size()));
    } else if (v.values.size() % size_t(k->components) == 0) {
      // RenderMan's default for these variables is varying; other counts pick their class.
      for (PrimvarClass c : {PrimvarClass::Varying, PrimvarClass::Vertex,
                             PrimvarClass::FaceVarying, PrimvarClass::Uniform,
                             PrimvarClass::Constant})
        if (!found && items == expected(c)) v.storage = c, found = true;
    }
    if (!found)
      return fail(p.line, "'" + call.name + "': \"" + p.name + "\" has " +
                              std::to_string(v.values.size()) + " numbers; expected " +
                              std::to_string(counts.varying * size_t(k->components)) + " (one " +
                              k->typeName + " per vertex), " +
                              std::to_string(counts.uniform * size_t(k->components)) +
                              " (per face), " +
                              std::to_string(counts.faceVarying * size_t(k->components)) +
                              " (per face corner) or " + std::to_string(k->components) +
                              " (one in all)");
    if (v.name == "N")
      for (size_t i = 0; i < items; ++i)
        if (glm::length(glm::vec3(v.at(i)[0], v.at(i)[1], v.at(i)[2])) == 0.0f)
          return fail(p.line, "'" + call.name + "': zero-length normal at index " +
                                  std::to_string(i));
    out->push_back(std::move(v));
  }
  return true;
}

// PointsPolygons, PointsGeneralPolygons, Polygon, GeneralPolygon: `nloops` loops per face (the
// first the boundary, the rest holes), `nverts` points per loop, `verts` the point indices.
// Faces are triangulated by ear clipping (concave faces and holes work). Vertices are shared when
// every primitive variable is per point; uniform or facevarying ones split them per face corner.
bool RibParser::buildPolygonMesh(const Call& call, const std::vector<int>& nloops,
                                 const std::vector<int>& nverts, const std::vector<int>& verts,
                                 size_t first) {
  std::vector<Param> params;
  std::vector<float> P;
  if (!parseParams(call, first, &params) || !positions(call, params, 0, &P)) return false;
  const size_t numPoints = P.size() / 3;
  size_t loopsTotal = 0;
  for (int l : nloops) {
    if (l < 1) return fail(call.line, "'" + call.name + "': a polygon needs at least one loop");
    loopsTotal += size_t(l);
  }
  if (loopsTotal != nverts.size())
    return fail(call.line, "'" + call.name + "': nloops sum to " + std::to_string(loopsTotal) +
                               " but " + std::to_string(nverts.size()) + " loop sizes given");
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
  std::vector<Primvar> vars;
  PrimvarCounts counts{nloops.size(), numPoints, numPoints, verts.size()};
  if (!readPrimvars(call, params, counts, &vars)) return false;
  bool perCorner = false;
  for (const Primvar& v : vars)
    perCorner = perCorner || v.storage == PrimvarClass::Uniform ||
                v.storage == PrimvarClass::FaceVarying;

  const glm::mat4& m = attr_.ctm;
  const glm::mat3 normalFromObject = glm::transpose(glm::inverse(glm::mat3(m)));
  std::vector<glm::vec3> world(numPoints);
  for (size_t i = 0; i < numPoints; ++i)
    world[i] = glm::vec3(m * glm::vec4(P[3 * i], P[3 * i + 1], P[3 * i + 2], 1.0f));

  Mesh mesh;
  const Primvar *N = nullptr, *st = nullptr, *s = nullptr, *t = nullptr, *Cs = nullptr;
  for (const Primvar& v : vars) {
    if (v.name == "N") N = &v;
    if (v.name == "st") st = &v;
    if (v.name == "s") s = &v;
    if (v.name == "t") t = &v;
    if (v.name == "Cs") Cs = &v;
  }
  auto valueOf = [](const Primvar& v, size_t face, size_t point, size_t corner) {
    switch (v.storage) {
      case PrimvarClass::Constant: return v.at(0);
      case PrimvarClass::Uniform: return v.at(face);
      case PrimvarClass::FaceVarying: return v.at(corner);
      default: return v.at(point);
    }
  };
  auto addVertex = [&](size_t face, size_t point, size_t corner) {
    mesh.P.push_back(world[point]);
    // RI spec, "Polygons": the surface parameters of a polygon are its object-space (x, y), and
    // its texture coordinates equal them unless given. Shared points get the same (u, v), so a
    // shader reading u, v, s or t displaces shared edges alike.
    mesh.uv.emplace_back(P[3 * point], P[3 * point + 1]);
    if (N) {
      const float* n = valueOf(*N, face, point, corner);
      mesh.N.push_back(glm::normalize(normalFromObject * glm::vec3(n[0], n[1], n[2])));
    }
    if (st) {
      const float* v = valueOf(*st, face, point, corner);
      mesh.st.emplace_back(v[0], v[1]);
    } else if (s || t) {
      // The one not given keeps its default, (u, v), as on every other primitive.
      mesh.st.emplace_back(s ? valueOf(*s, face, point, corner)[0] : P[3 * point],
                           t ? valueOf(*t, face, point, corner)[0] : P[3 * point + 1]);
    }
    if (Cs) {
      const float* c = valueOf(*Cs, face, point, corner);
      mesh.Cs.emplace_back(c[0], c[1], c[2]);
    }
  };
  if (!perCorner)
    for (size_t i = 0; i < numPoints; ++i) addVertex(0, i, 0);

  size_t loop = 0, corner = 0;
  std::vector<std::vector<glm::vec3>> loops;
  std::vector<uint32_t> faceVertices;
  for (size_t face = 0; face < nloops.size(); ++face) {
    loops.clear();
    faceVertices.clear();
    for (int l = 0; l < nloops[face]; ++l, ++loop) {
      std::vector<glm::vec3> points;
      for (int k = 0; k < nverts[loop]; ++k, ++corner) {
        const size_t point = size_t(verts[corner]);
        points.push_back(world[point]);
        if (perCorner) {
          faceVertices.push_back(uint32_t(mesh.P.size()));
          addVertex(face, point, corner);
        } else {
          faceVertices.push_back(uint32_t(point));
        }
      }
      loops.push_back(std::move(points));
    }
    bool fanned = false;
    size_t outsideHoles = 0;
    for (uint32_t i : triangulatePolygon(loops, &fanned, &outsideHoles)) mesh.indices.push_back(faceVertices[i]);
    if (outsideHoles)
      warnOnce(call.line, "outsidehole",
               "'" + call.name + "': a hole reaches outside its polygon's boundary; the hole is ignored");
    if (fanned)
      warnOnce(call.line, "fanned",
               "'" + call.name + "': a polygon of more than " + std::to_string(kMaxEarClippingPoints) +
                   " points that is not convex is split without ear clipping (triangles may cross its "
                   "concave parts), its holes ignored; split it into smaller polygons");
  }
  mesh.givenNormals = N != nullptr;
  return addMesh(std::move(mesh), call.line);  // which keeps the winding under a mirroring transform
}

// Patch and PatchMesh: an nu x nv grid of control points (u fastest) cut into bilinear or bicubic
// patches (the current Basis and its steps), periodic or not in each direction. All patches are
// sampled on one shared grid of vertices, so neighbouring patches meet without cracks; uv spans
// the whole mesh, and st defaults to it.
bool RibParser::buildPatchMesh(const Call& call, bool bicubic, int nu, bool uPeriodic, int nv,
                               bool vPeriodic, size_t first) {
  std::vector<Param> params;
  std::vector<float> P;
  if (!parseParams(call, first, &params)) return false;
  // "Pz" (RI 3.2, Patch and PatchMesh): a height field, one z per control point, whose x and y are
  // the surface parameters u and v. The basis interpolates z; x and y are set to (u, v) after.
  const Param* heights = findParam(params, "P") || findParam(params, "Pw") ? nullptr : findParam(params, "Pz");
  if (heights) {
    std::vector<float> z;
    if (!numbersParam(call, *heights, "float", size_t(nu) * size_t(nv), &z)) return false;
    for (float h : z) P.insert(P.end(), {0.0f, 0.0f, h});
  } else if (!positions(call, params, size_t(nu) * size_t(nv), &P)) {
    return false;
  }
  const CubicBasis& ub = attr_.uBasis;
  const CubicBasis& vb = attr_.vBasis;
  auto patchCount = [bicubic](int n, bool periodic, int step) {
    if (!bicubic) return periodic ? n : n - 1;
    return periodic ? n / step : (n - 4) / step + 1;
  };
  const int uSteps = bicubic ? ub.step : 1, vSteps = bicubic ? vb.step : 1;
  const int nuPatches = patchCount(nu, uPeriodic, uSteps);
  const int nvPatches = patchCount(nv, vPeriodic, vSteps);
  const int minimum = bicubic ? 4 : 2;
  if (nu < minimum || nv < minimum || nuPatches < 1 || nvPatches < 1 ||
      (bicubic && !uPeriodic && (nu - 4) % uSteps != 0) ||
      (bicubic && !vPeriodic && (nv - 4) % vSteps != 0) ||
      (bicubic && uPeriodic && nu % uSteps != 0) || (bicubic && vPeriodic && nv % vSteps != 0))
    return fail(call.line, "'" + call.name + "': " + std::to_string(nu) + " x " +
                               std::to_string(nv) + " control points do not make whole " +
                               (bicubic ? "bicubic" : "bilinear") + " patches with steps " +
                               std::to_string(uSteps) + ", " + std::to_string(vSteps));
  const size_t nuVarying = size_t(nuPatches + (uPeriodic ? 0 : 1));
  const size_t nvVarying = size_t(nvPatches + (vPeriodic ? 0 : 1));
  std::vector<Primvar> vars;
  PrimvarCounts counts{size_t(nuPatches) * size_t(nvPatches), size_t(nu) * size_t(nv),
                       nuVarying * nvVarying, size_t(nuPatches) * size_t(nvPatches) * 4};
  if (!readPrimvars(call, params, counts, &vars)) return false;
  auto controlPoint = [&](int i, int j) {
    const size_t k = 3 * (size_t(j) * size_t(nu) + size_t(i));
    return glm::vec3(P[k], P[k + 1], P[k + 2]);
  };

  // Samples per patch edge: bilinear flat patches need none inside; curved ones are cut about
  // (displaced ? 16 : 4) edge lengths apart like the quadrics.
  const glm::mat4& m = attr_.ctm;
  const float scale = maxScale(m);
  float hull = 0.0f;
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i + 1 < nu; ++i) hull = std::max(hull, glm::length(controlPoint(i + 1, j) - controlPoint(i, j)));
  for (int j = 0; j + 1 < nv; ++j)
    for (int i = 0; i < nu; ++i) hull = std::max(hull, glm::length(controlPoint(i, j + 1) - controlPoint(i, j)));
  const float target = (attr_.displacement ? 16.0f : 4.0f) * attr_.edgeLength;
  int samples = std::clamp(int(std::ceil(hull * scale * (bicubic ? 3.0f : 1.0f) / target)),
                           bicubic ? 8 : 16, 32);
  // Control point indices and weights of one direction at parameter `local` in [0, 1] of patch
  // `patch`.
  struct Span {
    int index[4];
    float w[4], dw[4];
    int count;
    int patch;
    float local;
  };
  auto spanAt = [&](int patch, float local, int n, const CubicBasis& basis) {
    Span sp{};
    sp.patch = patch;
    sp.local = local;
    if (bicubic) {
      sp.count = 4;
      basis.weights(sp.local, sp.w);
      basis.derivativeWeights(sp.local, sp.dw);
      for (int k = 0; k < 4; ++k) sp.index[k] = (sp.patch * basis.step + k) % n;
    } else {
      sp.count = 2;
      sp.w[0] = 1.0f - sp.local, sp.w[1] = sp.local;
      sp.dw[0] = -1.0f, sp.dw[1] = 1.0f;
      sp.index[0] = sp.patch, sp.index[1] = (sp.patch + 1) % n;
    }
    return sp;
  };
  // The same at global parameter g in [0, patches]: a border belongs to the patch after it.
  auto span = [&](float g, int patches, int n, const CubicBasis& basis) {
    const int patch = std::min(int(std::floor(g)), patches - 1);
    return spanAt(patch, g - float(patch), n, basis);
  };
  auto evaluate = [&](const Span& su, const Span& sv, const float* data, int components,
                      float* out, float* du, float* dv) {
    for (int c = 0; c < components; ++c) out[c] = du[c] = dv[c] = 0.0f;
    for (int j = 0; j < sv.count; ++j)
      for (int i = 0; i < su.count; ++i) {
        const float* value =
            data + (size_t(sv.index[j]) * size_t(nu) + size_t(su.index[i])) * size_t(components);
        for (int c = 0; c < components; ++c) {
          out[c] += su.w[i] * sv.w[j] * value[c];
          du[c] += su.dw[i] * sv.w[j] * value[c];
          dv[c] += su.w[i] * sv.dw[j] * value[c];
        }
      }
  };
  auto varyingValue = [&](const Primvar& v, const Span& su, const Span& sv, float* out) {
    if (v.storage == PrimvarClass::Constant) {
      std::copy(v.at(0), v.at(0) + v.components, out);
      return;
    }
    if (v.storage == PrimvarClass::Uniform) {
      std::copy(v.at(size_t(sv.patch) * size_t(nuPatches) + size_t(su.patch)),
                v.at(size_t(sv.patch) * size_t(nuPatches) + size_t(su.patch)) + v.components, out);
      return;
    }
    if (v.storage == PrimvarClass::Vertex && bicubic) {
      float du[4], dv[4];
      evaluate(su, sv, v.values.data(), v.components, out, du, dv);
      return;
    }
    const float u = su.local, w = sv.local;
    const float* c[4];
    if (v.storage == PrimvarClass::FaceVarying) {
      const size_t base = 4 * (size_t(sv.patch) * size_t(nuPatches) + size_t(su.patch));
      for (int k = 0; k < 4; ++k) c[k] = v.at(base + size_t(k));
    } else {
      // Varying (and vertex on bilinear meshes): one value per patch corner.
      const size_t stride = v.storage == PrimvarClass::Vertex ? size_t(nu) : nuVarying;
      const size_t wrapU = v.storage == PrimvarClass::Vertex ? size_t(nu) : nuVarying;
      const size_t wrapV = v.storage == PrimvarClass::Vertex ? size_t(nv) : nvVarying;
      const size_t i0 = size_t(su.patch), i1 = (i0 + 1) % wrapU;
      const size_t j0 = size_t(sv.patch), j1 = (j0 + 1) % wrapV;
      c[0] = v.at(j0 * stride + i0), c[1] = v.at(j0 * stride + i1);
      c[2] = v.at(j1 * stride + i0), c[3] = v.at(j1 * stride + i1);
    }
    for (int k = 0; k < v.components; ++k)
      out[k] = (1 - w) * ((1 - u) * c[0][k] + u * c[1][k]) + w * ((1 - u) * c[2][k] + u * c[3][k]);
  };

  const glm::mat3 normalFromObject = glm::transpose(glm::inverse(glm::mat3(m)));
  const Primvar *st = nullptr, *s = nullptr, *t = nullptr, *Cs = nullptr, *N = nullptr;
  for (const Primvar& v : vars) {
    if (v.name == "st") st = &v;
    if (v.name == "s") s = &v;
    if (v.name == "t") t = &v;
    if (v.name == "Cs") Cs = &v;
    if (v.name == "N") N = &v;
  }
  // Uniform and facevarying values change across patch borders, which vertices shared by two
  // patches cannot hold: such meshes get vertices of their own per patch, with their positions and
  // continuous values from the shared grid (so neighbouring patches still meet bit for bit) and
  // their uniform and facevarying values from their own patch.
  auto perPatchClass = [](const Primvar* v) {
    return v && (v->storage == PrimvarClass::Uniform || v->storage == PrimvarClass::FaceVarying);
  };
  const bool perPatch = perPatchClass(st) || perPatchClass(s) || perPatchClass(t) || perPatchClass(Cs) ||
                        perPatchClass(N);
  // Two triangles per bilinear patch are exact only where the bilinear map is affine: the
  // positions a parallelogram (a flat but skewed quad is not: its isoparametric lines bend) and
  // every interpolated primvar with c00 + c11 = c10 + c01. Any other patch is sampled like a
  // curved one, or st, Cs and N would follow the diagonal instead of the patch.
  if (!bicubic) {
    auto affine = [](const float* c00, const float* c10, const float* c01, const float* c11,
                     int components) {
      for (int k = 0; k < components; ++k) {
        const float scale = std::max({std::fabs(c00[k]), std::fabs(c10[k]), std::fabs(c01[k]),
                                      std::fabs(c11[k])});
        if (!(std::fabs((c00[k] + c11[k]) - (c10[k] + c01[k])) <= 1e-5f * scale)) return false;
      }
      return true;
    };
    bool flat = true;
    for (int pv = 0; pv < nvPatches && flat; ++pv)
      for (int pu = 0; pu < nuPatches && flat; ++pu) {
        const glm::vec3 p00 = controlPoint(pu, pv), p10 = controlPoint((pu + 1) % nu, pv);
        const glm::vec3 p01 = controlPoint(pu, (pv + 1) % nv);
        const glm::vec3 p11 = controlPoint((pu + 1) % nu, (pv + 1) % nv);
        flat = affine(&p00[0], &p10[0], &p01[0], &p11[0], 3);
        const Span u0 = spanAt(pu, 0.0f, nu, ub), u1 = spanAt(pu, 1.0f, nu, ub);
        const Span v0 = spanAt(pv, 0.0f, nv, vb), v1 = spanAt(pv, 1.0f, nv, vb);
        for (const Primvar* v : {st, s, t, Cs, N}) {
          if (!flat || !v || v->storage == PrimvarClass::Constant || v->storage == PrimvarClass::Uniform)
            continue;
          float c00[16], c10[16], c01[16], c11[16];
          varyingValue(*v, u0, v0, c00), varyingValue(*v, u1, v0, c10);
          varyingValue(*v, u0, v1, c01), varyingValue(*v, u1, v1, c11);
          flat = affine(c00, c10, c01, c11, std::min(v->components, 16));
        }
      }
    if (flat) samples = 1;
  }
  const int columns = nuPatches * samples + 1, rows = nvPatches * samples + 1;
  if (size_t(columns) * size_t(rows) > (size_t(1) << 24))
    return fail(call.line, "'" + call.name + "' is too large to tessellate");

  // The values of primvars `st`, `s`, `t`, `Cs` at spans su, sv, over `stValue` (uv by default).
  auto stAt = [&](const Span& su, const Span& sv, bool discontinuous, glm::vec2& stValue) {
    float value[3];
    if (st) {
      if (perPatchClass(st) == discontinuous) varyingValue(*st, su, sv, value), stValue = glm::vec2(value[0], value[1]);
    } else {
      if (s && perPatchClass(s) == discontinuous) varyingValue(*s, su, sv, value), stValue.x = value[0];
      if (t && perPatchClass(t) == discontinuous) varyingValue(*t, su, sv, value), stValue.y = value[0];
    }
  };
  auto normalAt = [&](const Span& su, const Span& sv) {
    float value[3];
    varyingValue(*N, su, sv, value);
    return normalFromObject * glm::vec3(value[0], value[1], value[2]);
  };
  // The shared grid in world space. A periodic mesh's wrap-around copy of its first column/row
  // takes that column's position and normal bits, so the seam cannot crack.
  const size_t gridSize = size_t(columns) * size_t(rows);
  std::vector<glm::vec3> gridP(gridSize), gridN(gridSize), gridCs(Cs ? gridSize : 0);
  std::vector<glm::vec3> gridDu(gridSize), gridDv(gridSize);  // dP/du, dP/dv of the mesh's (u, v)
  std::vector<glm::vec2> gridUv(gridSize), gridSt(gridSize);
  for (int row = 0; row < rows; ++row)
    for (int col = 0; col < columns; ++col) {
      const size_t k = size_t(row) * size_t(columns) + size_t(col);
      const float gu = float(col) / float(samples), gv = float(row) / float(samples);
      const Span su = span(gu, nuPatches, nu, ub), sv = span(gv, nvPatches, nv, vb);
      const bool seamU = uPeriodic && col == columns - 1, seamV = vPeriodic && row == rows - 1;
      if (seamU || seamV) {
        const size_t source = size_t(seamV ? 0 : row) * size_t(columns) + size_t(seamU ? 0 : col);
        gridP[k] = gridP[source], gridN[k] = gridN[source];
        gridDu[k] = gridDu[source], gridDv[k] = gridDv[source];
      } else {
        glm::vec3 p, dPdu, dPdv;
        evaluate(su, sv, P.data(), 3, &p[0], &dPdu[0], &dPdv[0]);
        // Where patches meet (and across a periodic mesh's seam) the derivatives are the mean of
        // both sides': at a crease (bilinear patches, a B-spline with a corner) either side's
        // alone tilted the normal toward that side (a square tube's corner took the next face's
        // normal), and displacement pushed the crease sideways.
        const bool uJoin = col % samples == 0 && (uPeriodic ? true : col > 0 && col < columns - 1);
        const bool vJoin = row % samples == 0 && (vPeriodic ? true : row > 0 && row < rows - 1);
        if (uJoin) {
          const Span left = spanAt(su.patch > 0 ? su.patch - 1 : nuPatches - 1, 1.0f, nu, ub);
          glm::vec3 q, du, dv;
          evaluate(left, sv, P.data(), 3, &q[0], &du[0], &dv[0]);
          dPdu = 0.5f * (dPdu + du), dPdv = 0.5f * (dPdv + dv);
        }
        if (vJoin) {
          const Span below = spanAt(sv.patch > 0 ? sv.patch - 1 : nvPatches - 1, 1.0f, nv, vb);
          glm::vec3 q, du, dv;
          evaluate(su, below, P.data(), 3, &q[0], &du[0], &dv[0]);
          dPdu = 0.5f * (dPdu + du), dPdv = 0.5f * (dPdv + dv);
        }
        if (heights) {
          p.x = gu / float(nuPatches), p.y = gv / float(nvPatches);
          dPdu.x = 1.0f / float(nuPatches), dPdu.y = 0.0f;
          dPdv.x = 0.0f, dPdv.y = 1.0f / float(nvPatches);
        }
        gridP[k] = glm::vec3(m * glm::vec4(p, 1.0f));
        gridN[k] = N && !perPatchClass(N) ? normalAt(su, sv) : normalFromObject * glm::cross(dPdu, dPdv);
        // Per patch, the local parameter runs over [0, 1]; the mesh's u over 1 / nuPatches of it.
        gridDu[k] = glm::mat3(m) * (dPdu * float(nuPatches));
        gridDv[k] = glm::mat3(m) * (dPdv * float(nvPatches));
      }
      gridUv[k] = glm::vec2(gu / float(nuPatches), gv / float(nvPatches));
      gridSt[k] = gridUv[k];
      stAt(su, sv, false, gridSt[k]);
      if (Cs && !perPatchClass(Cs)) {
        float value[3];
        varyingValue(*Cs, su, sv, value);
        gridCs[k] = glm::vec3(value[0], value[1], value[2]);
      }
    }
  // Degenerate points of a surface's own normals (a pole, a row collapsed to a point: the cross
  // product vanishes) take the sum of their grid neighbours' normals, and the copies of one point
  // (within a millionth of the grid's size: the basis rounds them apart) become one point with the
  // sum of all their sums, so they move alike when displaced. Clearing every normal of the
  // primitive for one such point (as before) displaced the whole patch along facet normals, which
  // opened every edge.
  if (!N) {
    // Degenerate relative to the grid's largest normal: at a collapsed row the cross product is
    // zero only up to rounding, and such a remainder points anywhere.
    float largest = 0.0f;
    for (const glm::vec3& n : gridN)
      if (const float len = glm::length(n); std::isfinite(len)) largest = std::max(largest, len);
    auto ok = [&](const glm::vec3& n) {
      const float len = glm::length(n);
      return len > 1e-20f && len > 1e-5f * largest && std::isfinite(len);
    };
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (const glm::vec3& p : gridP) lo = glm::min(lo, p), hi = glm::max(hi, p);
    const float tolerance = 1e-6f * glm::length(hi - lo);
    struct Pole {
      glm::vec3 at, normal;
    };
    std::vector<Pole> poles;
    std::vector<std::pair<size_t, size_t>> members;  // (grid point, pole)
    for (size_t k = 0; k < gridSize; ++k) {
      if (ok(gridN[k])) continue;
      const int row = int(k / size_t(columns)), col = int(k % size_t(columns));
      glm::vec3 sum(0.0f);
      for (const auto& [dr, dc] : {std::pair{-1, 0}, {1, 0}, {0, -1}, {0, 1}}) {
        const int r = row + dr, c = col + dc;
        if (r < 0 || r >= rows || c < 0 || c >= columns) continue;
        const glm::vec3 n = gridN[size_t(r) * size_t(columns) + size_t(c)];
        if (ok(n)) sum += glm::normalize(n);
      }
      size_t pole = 0;
      while (pole < poles.size() && !(glm::length(poles[pole].at - gridP[k]) <= tolerance)) ++pole;
      if (pole == poles.size()) poles.push_back({gridP[k], glm::vec3(0.0f)});
      poles[pole].normal += sum;
      members.emplace_back(k, pole);
    }
    for (const auto& [k, pole] : members) gridP[k] = poles[pole].at, gridN[k] = poles[pole].normal;
  }
  Mesh mesh;
  bool normalsOk = true;
  // Appends grid point (row, col), with the uniform and facevarying values of patch spans su, sv.
  auto emit = [&](int row, int col, const Span& su, const Span& sv) {
    const size_t k = size_t(row) * size_t(columns) + size_t(col);
    mesh.P.push_back(gridP[k]);
    mesh.dPdu.push_back(gridDu[k]), mesh.dPdv.push_back(gridDv[k]);
    const glm::vec3 normal = perPatchClass(N) ? normalAt(su, sv) : gridN[k];
    const float len = glm::length(normal);
    if (len > 1e-20f && std::isfinite(len) && normalsOk)
      mesh.N.push_back(normal / len);
    else
      normalsOk = false;  // a degenerate point (a pole): shade with face normals instead
    mesh.uv.push_back(gridUv[k]);
    glm::vec2 stValue = gridSt[k];
    stAt(su, sv, true, stValue);
    mesh.st.push_back(stValue);
    if (Cs) {
      glm::vec3 c = gridCs[k];
      if (perPatchClass(Cs)) {
        float value[3];
        varyingValue(*Cs, su, sv, value);
        c = glm::vec3(value[0], value[1], value[2]);
      }
      mesh.Cs.push_back(c);
    }
  };
  auto quads = [&](uint32_t first, int width, int height) {
    for (int j = 0; j + 1 < height; ++j)
      for (int i = 0; i + 1 < width; ++i) {
        const uint32_t a = first + uint32_t(j * width + i), b = a + 1, c = a + uint32_t(width), d = c + 1;
        mesh.indices.insert(mesh.indices.end(), {a, b, d, a, d, c});
      }
  };
  if (!perPatch) {
    for (int row = 0; row < rows; ++row)
      for (int col = 0; col < columns; ++col)
        emit(row, col, span(float(col) / float(samples), nuPatches, nu, ub),
             span(float(row) / float(samples), nvPatches, nv, vb));
    quads(0, columns, rows);
  } else {
    for (int pv = 0; pv < nvPatches; ++pv)
      for (int pu = 0; pu < nuPatches; ++pu) {
        const auto first = uint32_t(mesh.P.size());
        for (int r = 0; r <= samples; ++r)
          for (int c = 0; c <= samples; ++c)
            emit(pv * samples + r, pu * samples + c, spanAt(pu, float(c) / float(samples), nu, ub),
                 spanAt(pv, float(r) / float(samples), nv, vb));
        quads(first, samples + 1, samples + 1);
      }
  }
  if (!normalsOk) mesh.N.clear();
  mesh.givenNormals = N != nullptr && !mesh.N.empty();
  mesh.smoothSurface = !mesh.givenNormals && !mesh.N.empty();
  return addMesh(std::move(mesh), call.line);
}

// Geometry "objmesh" "string filename" ["file.obj"]: a Wavefront OBJ file, relative to the file
// that names it.
bool RibParser::doGeometry(const Call& call) {
  std::string type;
  if (!positionalString(call, 0, &type)) return false;
  if (type != "objmesh") {
    warnOnce(call.line, "geometry/" + type, "'Geometry \"" + type + "\"' is not supported; skipped");
    return true;
  }
  std::vector<Param> params;
  if (!parseParams(call, 1, &params)) return false;
  std::string file;
  if (!stringParam(call, params, "filename", &file)) return false;
  if (file.empty()) return fail(call.line, "'Geometry \"objmesh\"' needs a \"filename\"");
  warnUnusedParams(call, params, {"filename"});
  std::string tried;
  const std::string path = findFile(file, &tried);
  if (path.empty()) return fail(call.line, "cannot open mesh '" + file + "' (tried " + tried + ")");
  Mesh object;
  std::string error, warning;
  if (!loadObjMesh(path, &object, &error, &warning)) return fail(call.line, error);
  if (!warning.empty()) {
    while (!warning.empty() && warning.back() == '\n') warning.pop_back();
    warnOnce(call.line, "objwarning/" + path, "mesh '" + path + "': " + warning);
  }
  const glm::mat4& m = attr_.ctm;
  const glm::mat3 normalFromObject = glm::transpose(glm::inverse(glm::mat3(m)));
  // A polygon mesh: (u, v) is the object-space (x, y), as for RIB polygons (OBJ texture
  // coordinates, when present, are st).
  object.uv.clear();
  for (const glm::vec3& p : object.P) object.uv.emplace_back(p.x, p.y);
  for (glm::vec3& p : object.P) p = glm::vec3(m * glm::vec4(p, 1.0f));
  for (glm::vec3& n : object.N) n = glm::normalize(normalFromObject * n);
  object.givenNormals = !object.N.empty();
  return addMesh(std::move(object), call.line);
}

// Procedural "DelayedReadArchive" ["file"] [bound]: read at once, like ReadArchive (the bound
// only serves deferred loading, which the reader does not need).
bool RibParser::doProcedural(const Call& call) {
  std::string type;
  if (!positionalString(call, 0, &type)) return false;
  if (type != "DelayedReadArchive") {
    warnOnce(call.line, "procedural/" + type,
             "'Procedural \"" + type + "\"' is not supported; skipped");
    return true;
  }
  if (call.args.size() < 2 || !call.args[1].isStringy() || call.args[1].strings.empty())
    return fail(call.line, "'Procedural \"DelayedReadArchive\"' expects [\"file\"] [bound]");
  if (call.args.size() > 2 && (!call.args[2].isNumeric() || call.args[2].numbers.size() != 6))
    return fail(call.line, "'Procedural': the bound must be 6 numbers");
  if (call.args.size() > 2) {
    const std::vector<double>& b = call.args[2].numbers;
    if (!(b[0] <= b[1] && b[2] <= b[3] && b[4] <= b[5]))
      warn(call.line, "'Procedural': the bound [xmin xmax ymin ymax zmin zmax] has a minimum above its maximum");
  }
  return readArchive(call, call.args[1].strings[0]);
}

// Runs recorded calls (an object's or an inline archive's), each in the file it came from.
bool RibParser::replay(const std::vector<RecordedCall>& calls) {
  const std::string savedFile = fileName_;
  bool ok = true;
  for (const RecordedCall& recorded : calls) {
    fileName_ = recorded.file;
    if (!execute(recorded.call)) {
      ok = false;
      break;
    }
  }
  fileName_ = savedFile;
  return ok;
}

// ObjectInstance handle: replays the calls recorded between ObjectBegin and ObjectEnd inside an
// attribute block, so the instance is placed by the transform and attributes current here.
bool RibParser::doObjectInstance(const Call& call) {
  constexpr int kMaxInstanceDepth = 32;  // an object that instances itself would recurse forever
  std::string handle;
  if (call.args.size() != 1 || !lightHandle(call.args[0], &handle))
    return fail(call.line, "'ObjectInstance' expects one handle (a number or a string)");
  const auto object = objects_.find(handle);
  if (object == objects_.end() || &object->second == recording_)
    return fail(call.line, "'ObjectInstance': no object with handle '" + handle + "'");
  if (!requireWorld(call)) return false;
  if (instanceDepth_ >= kMaxInstanceDepth)
    return fail(call.line, "'ObjectInstance' nested more than " +
                               std::to_string(kMaxInstanceDepth) +
                               " deep (does an object instance itself?)");
  const AttributeState saved = attr_;
  const size_t depth = stack_.size();
  // An instance may be the sample of an enclosing motion block; its own calls are not samples.
  const int motionLine = std::exchange(motionLine_, 0);
  ++instanceDepth_;
  const bool ok = replay(object->second);
  --instanceDepth_;
  if (ok && (stack_.size() != depth || motionLine_ != 0))
    return fail(call.line,
                "object '" + handle + "' has unbalanced attribute, transform or motion blocks");
  motionLine_ = motionLine;
  attr_ = saved;
  return ok;
}

// Option "relief": render settings carried by the scene (the command line overrides them).
bool RibParser::doReliefOption(const Call& call, const std::vector<Param>& params) {
  // A setting is given when its parameter is there, whatever its value (-1, the old "absent",
  // had passed unchecked).
  float budget = 0.0f, depth = 0.0f;
  std::string order;
  if (!floatParam(call, params, "cachebudget", &budget) ||
      !floatParam(call, params, "maxdepth", &depth) ||
      !stringParam(call, params, "order", &order))
    return false;
  if (findParam(params, "cachebudget")) {
    if (!(budget >= 1.0f && budget <= 1e15f) || budget != std::floor(budget))
      return fail(call.line, "'Option \"relief\"': 'cachebudget' must be a positive integer");
    scene_.cacheBudgetTriangles = uint64_t(budget);
  }
  if (findParam(params, "maxdepth")) {
    // The range of --max-depth: 0 (no secondary rays) to 100.
    if (!(depth >= 0.0f && depth <= 100.0f) || depth != std::floor(depth))
      return fail(call.line, "'Option \"relief\"': 'maxdepth' must be an integer from 0 to 100");
    scene_.maxDepth = int(depth);
  }
  if (findParam(params, "order")) {
    if (order != "scanline" && order != "bucket" && order != "hilbert")
      return fail(call.line, "'Option \"relief\"': 'order' must be scanline, bucket or hilbert");
    scene_.order = order;
  }
  warnUnusedParams(call, params, {"cachebudget", "maxdepth", "order"});
  return true;
}

bool RibParser::readArchive(const Call& call, const std::string& name) {
  // Nesting guard: an archive that reads itself would otherwise recurse until the stack runs out.
  constexpr int kMaxArchiveDepth = 32;
  if (archiveDepth_ >= kMaxArchiveDepth)
    return fail(call.line, "'" + call.name + "' nested more than " +
                               std::to_string(kMaxArchiveDepth) +
                               " deep (does an archive read itself?)");
  if (const auto inlined = inlineArchives_.find(name); inlined != inlineArchives_.end()) {
    // An inline archive runs where it is read, as a file would (no attribute block of its own).
    // From a copy: what it runs may define an archive of the same name again.
    const std::vector<RecordedCall> calls = inlined->second;
    ++archiveDepth_;
    const bool ok = replay(calls);
    --archiveDepth_;
    return ok;
  }
  std::string tried;
  const std::string path = findFile(name, &tried);
  if (path.empty())
    return fail(call.line, "cannot open archive '" + name + "' (tried " + tried + ")");
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(call.line, "cannot open archive '" + path + "'");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  std::string archiveText = buffer.str();
  if (std::string inflateError; !inflateIfGzipped(&archiveText, &inflateError))
    return fail(call.line, "cannot read archive '" + path + "': " + inflateError);
  std::vector<RibToken> tokens;
  SceneError tokenError;
  if (!tokenizeRib(archiveText, path, &tokens, &tokenError)) {
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
  const bool openBefore = recording_ != nullptr;
  bool ok = runCalls();
  // A block opened in this file must close in it, or it would swallow the reader's requests.
  if (ok && !openBefore && recording_)
    ok = fail(recordingLine_, "end of archive: " + unclosedRecording());
  --archiveDepth_;
  tokens_ = std::move(savedTokens);
  pos_ = savedPos;
  fileName_ = savedFile;
  return ok;
}

bool RibParser::addMesh(Mesh mesh, int line, bool wound) {
  if (mesh.indices.empty()) return true;
  // A mirroring transform flips the current coordinate system and, with it, the current
  // orientation (RI spec, "Orientation"), so a primitive keeps its side: the winding its world
  // points have after the mirror is reversed back. The winding is what one-sided culling and the
  // displacement shaders' Ng follow.
  if (!wound && glm::determinant(glm::mat3(attr_.ctm)) < 0.0f)
    for (size_t k = 0; k + 2 < mesh.indices.size(); k += 3) std::swap(mesh.indices[k + 1], mesh.indices[k + 2]);
  inputTriangles_ += mesh.numTriangles();
  if (inputTriangles_ > kMaxInputTriangles)
    return fail(line, "the scene has more than " + std::to_string(kMaxInputTriangles) + " input triangles" +
                          (instanceDepth_ + archiveDepth_ > 1
                               ? " (ObjectInstance or ReadArchive nested within each other?)"
                           : instanceDepth_ > 0
                               ? " (each ObjectInstance adds a copy of its object's triangles; quadrics are "
                                 "tessellated finely: 65,536 triangles for a whole sphere)"
                               : " (quadrics are tessellated finely: 65,536 triangles for a whole sphere)"));
  for (const glm::vec3& p : mesh.P)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      return fail(line, "geometry has non-finite coordinates after transformation");
  // Smooth surfaces with one (u, v) over the whole surface (quadrics, patches, NURBS) get shared
  // per-vertex derivatives; subdivision meshes are marked smooth after this and keep their facets'.
  if (mesh.smoothSurface)
    smoothSurfaceDerivatives(mesh);
  else
    mesh.dPdu.clear(), mesh.dPdv.clear();
  mesh.materialIndex = materialIndex();
  mesh.lights = attr_.lightsOn;
  mesh.lightsSet = true;
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

namespace {

// Standard input ("-") is named as compilers name it; its relative paths are the working
// directory's.
std::string sceneLabel(const std::string& path) { return path == "-" ? "<stdin>" : path; }

bool readSceneText(const std::string& path, std::string* text, SceneError* error) {
  if (path == "-") {
    // Standard input is read once: a scene of several frames is parsed once per frame.
    static std::optional<std::string> input;
    if (!input) {
      std::ostringstream buffer;
      buffer << std::cin.rdbuf();
      input = buffer.str();
    }
    *text = *input;
    if (std::string inflateError; !inflateIfGzipped(text, &inflateError)) {
      *error = SceneError{sceneLabel(path), 0, inflateError};
      return false;
    }
    return true;
  }
  // A device or a pipe (/dev/zero) would be read for ever.
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (!ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status) &&
      !std::filesystem::is_directory(status)) {
    *error = SceneError{path, 0, "cannot open scene file: not a regular file"};
    return false;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    *error = SceneError{path, 0, std::string("cannot open scene file: ") + std::strerror(errno)};
    return false;
  }
  if (std::filesystem::is_directory(path)) {
    *error = SceneError{path, 0, "cannot open scene file: it is a directory"};
    return false;
  }
  std::ostringstream buffer;
  buffer << in.rdbuf();
  *text = buffer.str();
  if (std::string inflateError; !inflateIfGzipped(text, &inflateError)) {
    *error = SceneError{path, 0, inflateError};
    return false;
  }
  return true;
}

}  // namespace

std::optional<Scene> readRibFile(const std::string& path, const RibReadOptions& options,
                                 SceneError* error) {
  std::string text;
  if (!readSceneText(path, &text, error)) return std::nullopt;
  return readRibString(text, sceneLabel(path), options, error);
}

std::optional<std::vector<int>> readRibFrameNumbers(const std::string& path,
                                                    const RibReadOptions& options,
                                                    SceneError* error) {
  std::string text;
  std::vector<RibToken> tokens;
  if (!readSceneText(path, &text, error) || !tokenizeRib(text, sceneLabel(path), &tokens, error))
    return std::nullopt;
  RibParser parser(sceneLabel(path), options, /*listFrames=*/true);
  std::optional<Scene> scene = parser.parse(std::move(tokens), error);
  if (!scene) return std::nullopt;
  return std::move(scene->frameNumbers);
}

}  // namespace relief
