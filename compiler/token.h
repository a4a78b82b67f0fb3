// Token kinds and tokens of the .disp language (language.md §1). Tokens carry their source range.
#pragma once

#include <cstdint>
#include <string_view>

#include "compiler/source_manager.h"

namespace relief::compiler {

// X-macro lists so names and spellings stay in one place.
#define RELIEF_KEYWORDS(K)                                                                       \
  K(Break, "break") K(Color, "color") K(Continue, "continue") K(Displacement, "displacement")     \
  K(Do, "do") K(Else, "else") K(Extern, "extern") K(Float, "float") K(For, "for") K(If, "if")    \
  K(Int, "int") K(Matrix, "matrix") K(Normal, "normal") K(Output, "output") K(Point, "point")     \
  K(Return, "return") K(String, "string") K(Uniform, "uniform") K(Varying, "varying")            \
  K(Vector, "vector") K(Void, "void") K(While, "while")

#define RELIEF_PUNCTUATORS(P)                                                                    \
  P(LParen, "(") P(RParen, ")") P(LBrace, "{") P(RBrace, "}") P(LBracket, "[") P(RBracket, "]")   \
  P(Semi, ";") P(Comma, ",") P(Dot, ".") P(Question, "?") P(Colon, ":") P(Plus, "+")             \
  P(Minus, "-") P(Star, "*") P(Slash, "/") P(Percent, "%") P(Caret, "^") P(Bang, "!")            \
  P(Less, "<") P(LessEq, "<=") P(Greater, ">") P(GreaterEq, ">=") P(EqEq, "==") P(NotEq, "!=")   \
  P(AmpAmp, "&&") P(PipePipe, "||") P(Assign, "=") P(PlusAssign, "+=") P(MinusAssign, "-=")      \
  P(StarAssign, "*=") P(SlashAssign, "/=") P(PercentAssign, "%=") P(PlusPlus, "++")              \
  P(MinusMinus, "--")

enum class Tok : uint8_t {
  Eof,
  Identifier,
  IntLiteral,
  FloatLiteral,
  StringLiteral,
  ReservedWord,  // gather, illuminance, ...: never an identifier
  ShaderKindWord,  // surface, light, volume, imager: a shader kind we do not support
  Unknown,  // a character the lexer already reported; the parser stays silent about it
  Hash,     // '#' at the start of a line: a preprocessor directive follows
#define RELIEF_TOK_ENUM(Name, Spelling) Name,
  RELIEF_PUNCTUATORS(RELIEF_TOK_ENUM)
#define RELIEF_KW_ENUM(Name, Spelling) Kw##Name,
  RELIEF_KEYWORDS(RELIEF_KW_ENUM)
#undef RELIEF_TOK_ENUM
#undef RELIEF_KW_ENUM
};

// How a token kind is described in "expected X" messages: 'spelling' or a class name.
std::string_view tokSpelling(Tok kind);
std::string tokDescription(Tok kind);

struct Token {
  Tok kind = Tok::Eof;
  SourceLoc loc;
  uint32_t length = 0;
  std::string_view text;  // view into the SourceManager's buffer
  // Literal values (valid for the literal kinds).
  int32_t intValue = 0;
  float floatValue = 0;
  bool atLineStart = false;
  // Already reported by the lexer (an unterminated string swallowed the rest of its line): what
  // the parser expected after it is not reported again.
  bool malformed = false;
  // A macro name met while that macro was being expanded: it is never expanded again, wherever
  // rescanning takes it (C's "painted blue" tokens; `#define w w + 1` then `ID(w)` is `w + 1`).
  bool noExpand = false;
  // An empty macro argument beside `##` (C's placemarker): pasting with it gives the other
  // operand; what is left of it after pasting is dropped.
  bool placemarker = false;
  // A macro argument's token in its macro's replacement: it keeps its own location (where an
  // error in the argument is), while the macro's own tokens sit at the use (language.md §1.1).
  bool fromArgument = false;
  // The last token of a macro's replacement ends where the use ends (after the call's ')'), so
  // what is missing after it ("expected ';'") is reported there, not inside the call.
  SourceLoc endLoc;

  bool is(Tok k) const { return kind == k; }
  SourceRange range() const { return {loc, loc.advanced(length)}; }
  SourceLoc end() const { return endLoc.isValid() ? endLoc : loc.advanced(length); }
};

}  // namespace relief::compiler
