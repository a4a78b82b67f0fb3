// The preprocessor (language.md §1.1): #include, object- and function-like #define, #undef,
// conditionals, #error, #pragma once. Works on tokens; expanded tokens keep the location of the
// macro use, so diagnostics point into the original files. No LLVM here.
#pragma once

#include <memory>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "compiler/diagnostics.h"
#include "compiler/lexer.h"
#include "compiler/source_manager.h"
#include "compiler/token.h"

namespace relief::compiler {

struct PreprocessorOptions {
  std::vector<std::string> includeDirs;                      // -I, searched in order
  std::vector<std::pair<std::string, std::string>> defines;  // -D NAME=value
  std::string builtinIncludeDir;                             // searched last (stdlib/)
};

// Nesting limit of #include (language.md §1.1).
inline constexpr int kMaxIncludeDepth = 64;
// Tokens one file may expand to: far above real shaders, far below exhausting memory.
inline constexpr size_t kMaxExpandedTokens = size_t(1) << 22;

class Preprocessor {
 public:
  Preprocessor(SourceManager& sm, DiagnosticsEngine& diags, PreprocessorOptions options);
  ~Preprocessor();
  // The token stream of `file` after preprocessing, ending with Eof.
  std::vector<Token> run(SourceManager::FileId file);
  // A fatal problem (an include not found, a runaway macro) cut the tokens short: parsing them
  // would only report the cut.
  bool stopped() const { return fatal_; }

 private:
  struct Macro {
    bool functionLike = false;
    std::vector<std::string> params;
    std::vector<Token> body;
    SourceLoc loc;
  };
  struct Conditional {
    SourceLoc loc;     // the #if/#ifdef/#ifndef
    bool parentActive;
    bool active;       // this group's tokens are kept
    bool taken;        // some group of this chain was active
    bool sawElse;
  };
  struct Source {
    std::unique_ptr<Lexer> lexer;
    SourceManager::FileId file;
    std::string dir;
    std::vector<Conditional> conditionals;
    Token lookahead;
    bool hasLookahead = false;
  };

  Token nextRaw();
  void pushBack(const Token& t);
  std::vector<Token> directiveLine();
  bool active() const;
  void directive(const Token& hash);
  void include(const Token& name, const std::vector<Token>& line);
  void defineMacro(const std::vector<Token>& line);
  bool evaluateCondition(const Token& directiveName, const std::vector<Token>& line);
  void definePredefined(const std::string& name, const std::string& value, const char* origin);

  // Expands `input` (rescanning results); `more` may pull further tokens for a function-like
  // macro whose '(' follows in the source.
  void expand(std::vector<Token> input, std::vector<Token>& out, const std::set<std::string>& disabled,
              bool fromSource);
  // The arguments of the call of macro `name` whose '(' is next; `end` gets where its ')' ends.
  bool collectArguments(std::vector<Token>& input, size_t& pos, bool fromSource,
                        std::vector<std::vector<Token>>& args, const Token& name, SourceLoc* end);
  Token synthesize(const std::string& text, const Token& at);
  std::vector<Token> paste(std::vector<Token> toks, const Token& at);
  static bool isPaste(const std::vector<Token>& body, size_t i);
  static std::string spelling(const std::vector<Token>& tokens);

  SourceManager& sm_;
  DiagnosticsEngine& diags_;
  PreprocessorOptions options_;
  std::vector<Source> stack_;
  std::unordered_map<std::string, Macro> macros_;
  std::set<std::string> onceFiles_;
  bool fatal_ = false;
  bool cutShort_ = false;  // an unterminated macro call or comment ended the main file early
  int expansionDepth_ = 0;
  std::string outermost_;  // the macro used in the source whose expansion is under way
  bool inCondition_ = false;  // expanding an #if line: `defined`'s operand is not expanded
};

}  // namespace relief::compiler
