// The RIB scene reader: tokenizes and parses the RenderMan subset Relief understands and builds an
// immutable Scene. Depended on by tools/relief and the renderer tests; shaders come in through a
// runtime::ShaderProvider so this file never sees the compiler.
#pragma once

#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "renderer/scene.h"
#include "runtime/shader.h"

namespace relief {

// A scene problem located in its source. The reader never prints errors; the caller does (as
// `file:line: error: message`) and renders nothing.
struct SceneError {
  std::string file;
  int line = 0;  // 0: no line (e.g. the file could not be opened)
  std::string message;

  std::string format() const;
};

struct RibReadOptions {
  // Resolves `Displacement "name"`. Null: any Displacement call is an error.
  runtime::ShaderProvider* shaders = nullptr;
  // The shader search path before any `Option "searchpath"`, and what `@` expands to there.
  std::vector<std::string> defaultShaderPath;
  // The texture search path before any `Option "searchpath" "string texture"` (what `@` means
  // there); it is also Scene::texturePath when the scene sets none.
  std::vector<std::string> defaultTexturePath;
  // Receives `file:line: warning: message` lines; null drops them.
  std::ostream* warnings = nullptr;
  // Which `FrameBegin` block to read, counted from 0 in file order. The scene is made of the calls
  // outside frame blocks plus that block; the other blocks are only checked for balance, since
  // FrameEnd restores what their calls set (RenderMan). A file without FrameBegin is frame 0.
  int frame = 0;
  // The image's name comes from elsewhere (relief -o): the main Display's file name is not used,
  // so it gets no warning about its missing extension (an added "+" display still does).
  bool mainDisplayReplaced = false;
};

// One RIB token. Requests are bare words; everything else is an argument.
struct RibToken {
  enum class Kind { Request, Number, String, OpenBracket, CloseBracket, End };
  Kind kind = Kind::End;
  std::string text;   // request name or string contents (escapes resolved)
  double number = 0;  // Kind::Number
  int line = 0;
};

// Splits RIB text into tokens. Returns false with *error set (line, message) on malformed input:
// an unterminated string, a bad number or a stray character. The final token is always Kind::End.
bool tokenizeRib(std::string_view text, const std::string& fileName, std::vector<RibToken>* tokens,
                 SceneError* error);

// Reads a RIB file. On failure returns nullopt and fills *error.
std::optional<Scene> readRibFile(const std::string& path, const RibReadOptions& options,
                                 SceneError* error);

// Reads RIB text; `fileName` names it in messages and its directory anchors relative search paths.
std::optional<Scene> readRibString(std::string_view text, const std::string& fileName,
                                   const RibReadOptions& options, SceneError* error);

// The n of each `FrameBegin n` block of a RIB file, in file order; empty when it has none (it is
// one frame). Runs the calls outside frame blocks, which may fail, and skips every block, so it
// costs little more than tokenizing when the frames hold the scene. On failure returns nullopt.
std::optional<std::vector<int>> readRibFrameNumbers(const std::string& path,
                                                    const RibReadOptions& options,
                                                    SceneError* error);

// A GLM (column-major, column-vector) transform as the shader ABI wants it: row-major with row
// vectors, p' = p * M. The two layouts of the same matrix coincide element for element.
void toRlfMatrix(const glm::mat4& m, float out[16]);

}  // namespace relief
