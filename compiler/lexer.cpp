// Lexer implementation (see lexer.h). Columns are byte offsets, so tabs need no special casing.
#include "compiler/lexer.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <unordered_map>

#include "compiler/utf8.h"

namespace relief::compiler {

std::string_view tokSpelling(Tok kind) {
  switch (kind) {
#define RELIEF_TOK_CASE(Name, Spelling) \
  case Tok::Name: return Spelling;
    RELIEF_PUNCTUATORS(RELIEF_TOK_CASE)
#define RELIEF_KW_CASE(Name, Spelling) \
  case Tok::Kw##Name: return Spelling;
    RELIEF_KEYWORDS(RELIEF_KW_CASE)
#undef RELIEF_TOK_CASE
#undef RELIEF_KW_CASE
    default: return {};
  }
}

std::string tokDescription(Tok kind) {
  switch (kind) {
    case Tok::Eof: return "end of file";
    case Tok::Identifier: return "identifier";
    case Tok::IntLiteral:
    case Tok::FloatLiteral: return "number";
    case Tok::StringLiteral: return "string literal";
    case Tok::ReservedWord:
    case Tok::ShaderKindWord: return "reserved word";
    case Tok::Unknown: return "invalid character";
    case Tok::Hash: return "'#'";
    default: return "'" + std::string(tokSpelling(kind)) + "'";
  }
}

namespace {
const std::unordered_map<std::string_view, Tok>& keywordTable() {
  static const std::unordered_map<std::string_view, Tok> table = [] {
    std::unordered_map<std::string_view, Tok> t;
#define RELIEF_KW_ENTRY(Name, Spelling) t.emplace(Spelling, Tok::Kw##Name);
    RELIEF_KEYWORDS(RELIEF_KW_ENTRY)
#undef RELIEF_KW_ENTRY
    for (const char* w : {"gather", "illuminance", "illuminate", "solar", "struct", "transformation"})
      t.emplace(w, Tok::ReservedWord);
    for (const char* w : {"surface", "light", "volume", "imager"}) t.emplace(w, Tok::ShaderKindWord);
    return t;
  }();
  return table;
}
bool isIdentStart(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_'; }
bool isDigit(char c) { return c >= '0' && c <= '9'; }
bool isIdentChar(char c) { return isIdentStart(c) || isDigit(c); }

std::string hex(uint32_t value, int digits) {
  static const char* kDigits = "0123456789ABCDEF";
  std::string out(size_t(digits), '0');
  for (int i = digits - 1; i >= 0; --i, value >>= 4) out[size_t(i)] = kDigits[value & 15];
  return out;
}
}  // namespace

Lexer::Lexer(const SourceManager& sm, SourceManager::FileId file, DiagnosticsEngine& diags)
    : sm_(sm), file_(file), diags_(diags) {
  const std::string_view text = sm.splicedText(file);
  spliced_ = text.data() != sm.text(file).data();
  begin_ = text.data();
  cur_ = begin_;
  end_ = begin_ + text.size();
  base_ = sm.startOf(file);
  // A UTF-8 byte-order mark (Windows editors) starts no token; columns still count from the file's
  // first byte.
  if (text.substr(0, 3) == "\xEF\xBB\xBF") cur_ += 3;
}

void Lexer::skipWhitespaceAndComments() {
  while (cur_ < end_) {
    const char c = *cur_;
    if (c == '\n' || c == '\r') {
      atLineStart_ = true;
      ++cur_;
    } else if (c == ' ' || c == '\t' || c == '\f' || c == '\v') {
      ++cur_;
    } else if (c == '/' && cur_ + 1 < end_ && cur_[1] == '/') {
      while (cur_ < end_ && *cur_ != '\n' && *cur_ != '\r') ++cur_;
    } else if (c == '/' && cur_ + 1 < end_ && cur_[1] == '*') {
      const char* start = cur_;
      cur_ += 2;
      while (cur_ + 1 < end_ && !(cur_[0] == '*' && cur_[1] == '/')) ++cur_;
      if (cur_ + 1 >= end_) {
        sink().report(DiagId::ErrUnterminatedComment, locOf(start));
        cur_ = end_;
        cutShort_ = true;
        return;
      }
      cur_ += 2;
    } else {
      return;
    }
  }
}

Token Lexer::make(Tok kind, const char* start) {
  Token t;
  t.kind = kind;
  t.loc = locOf(start);
  t.length = locOf(cur_).offset - t.loc.offset;
  t.text = std::string_view(start, cur_ - start);
  t.atLineStart = atLineStart_;
  atLineStart_ = false;
  return t;
}

Token Lexer::lexNumber(const char* start) {
  // Hex integers.
  if (cur_[0] == '0' && cur_ + 1 < end_ && (cur_[1] == 'x' || cur_[1] == 'X')) {
    cur_ += 2;
    while (cur_ < end_ && std::isxdigit(static_cast<unsigned char>(*cur_))) ++cur_;
    Token t = make(Tok::IntLiteral, start);
    if (t.text.size() == 2) {
      sink().report(DiagId::ErrBadNumber, t.loc).arg(t.text).range(t.range());
      return t;
    }
    const unsigned long long v = std::strtoull(std::string(t.text.substr(2)).c_str(), nullptr, 16);
    if (t.text.size() > 10 || v > 0xffffffffULL)
      sink().report(DiagId::ErrIntegerTooLarge, t.loc).range(t.range());
    else
      t.intValue = int32_t(uint32_t(v));
    return t;
  }
  bool isFloat = false;
  while (cur_ < end_ && isDigit(*cur_)) ++cur_;
  if (cur_ < end_ && *cur_ == '.') {
    isFloat = true;
    ++cur_;
    while (cur_ < end_ && isDigit(*cur_)) ++cur_;
  }
  if (cur_ < end_ && (*cur_ == 'e' || *cur_ == 'E')) {
    const char* save = cur_;
    ++cur_;
    if (cur_ < end_ && (*cur_ == '+' || *cur_ == '-')) ++cur_;
    if (cur_ < end_ && isDigit(*cur_)) {
      isFloat = true;
      while (cur_ < end_ && isDigit(*cur_)) ++cur_;
    } else if (cur_ < end_ && (std::isalpha(static_cast<unsigned char>(*cur_)) || *cur_ == '_')) {
      cur_ = save;  // "2ex": the number 2, then an identifier; the parser complains
    } else {
      // "1e", "1e+": an exponent without digits, one error here rather than a confusing one at
      // the parser (C calls it an invalid pp-number too).
      Token t = make(Tok::FloatLiteral, start);
      sink().report(DiagId::ErrBadNumber, t.loc).arg(t.text).range(t.range());
      t.floatValue = std::strtof(std::string(t.text).c_str(), nullptr);
      t.malformed = true;
      return t;
    }
  }
  Token t = make(isFloat ? Tok::FloatLiteral : Tok::IntLiteral, start);
  const std::string text(t.text);
  if (isFloat) {
    errno = 0;
    t.floatValue = std::strtof(text.c_str(), nullptr);
    // Out of float's range the literal silently becomes infinity or zero: say so, as clang does
    // (a denormal result is representable and passes).
    if (errno == ERANGE) {
      if (std::isinf(t.floatValue))
        sink().report(DiagId::WarnLiteralTooLarge, t.loc).range(t.range());
      else if (t.floatValue == 0.0f)
        sink().report(DiagId::WarnLiteralTooSmall, t.loc).range(t.range());
    }
  } else {
    errno = 0;
    const unsigned long long v = std::strtoull(text.c_str(), nullptr, 10);
    if (errno == ERANGE || v > 0x7fffffffULL) {
      // 2147483648 is allowed only as the operand of unary minus; keep it simple and accept the
      // value with wrap-around so that -2147483648 works.
      if (errno != ERANGE && v == 0x80000000ULL)
        t.intValue = INT32_MIN;
      else
        sink().report(DiagId::ErrIntegerTooLarge, t.loc).range(t.range());
    } else {
      t.intValue = int32_t(v);
    }
  }
  return t;
}

Token Lexer::lexString(const char* start) {
  ++cur_;  // opening quote
  while (cur_ < end_ && *cur_ != '"' && *cur_ != '\n' && *cur_ != '\r') {
    if (*cur_ == '\\') {
      if (cur_ + 1 < end_ && std::strchr("nt\\\"", cur_[1]) && cur_[1] != '\0') {
        cur_ += 2;
        continue;
      }
      if (cur_ + 1 < end_ && cur_[1] != '\n' && cur_[1] != '\r')
        sink().report(DiagId::ErrBadEscape, locOf(cur_))
            .arg(std::string_view(cur_ + 1, 1))
            .range({locOf(cur_), locOf(cur_ + 2)});
      ++cur_;
      if (cur_ < end_ && *cur_ != '\n' && *cur_ != '\r') ++cur_;
      continue;
    }
    ++cur_;
  }
  if (cur_ >= end_ || *cur_ != '"') {
    sink().report(DiagId::ErrUnterminatedString, locOf(start));
    Token t = make(Tok::StringLiteral, start);
    t.malformed = true;
    return t;
  }
  ++cur_;
  return make(Tok::StringLiteral, start);
}

std::string Lexer::stringValue(const Token& token) {
  std::string out;
  std::string_view t = token.text;
  if (!t.empty() && t.front() == '"') t.remove_prefix(1);
  if (!t.empty() && t.back() == '"') t.remove_suffix(1);
  for (size_t i = 0; i < t.size(); ++i) {
    if (t[i] == '\\' && i + 1 < t.size()) {
      const char e = t[++i];
      out += e == 'n' ? '\n' : e == 't' ? '\t' : e;
    } else {
      out += t[i];
    }
  }
  return out;
}

Token Lexer::next() {
  for (;;) {
    skipWhitespaceAndComments();
    const char* start = cur_;
    if (cur_ >= end_) {
      Token eof = make(Tok::Eof, start);
      eof.malformed = cutShort_;  // the file ended inside a comment
      return eof;
    }
    const char c = *cur_;
    if (isIdentStart(c)) {
      while (cur_ < end_ && isIdentChar(*cur_)) ++cur_;
      const std::string_view word(start, cur_ - start);
      const auto& kw = keywordTable();
      auto it = kw.find(word);
      return make(it == kw.end() ? Tok::Identifier : it->second, start);
    }
    if (isDigit(c) || (c == '.' && cur_ + 1 < end_ && isDigit(cur_[1]))) return lexNumber(start);
    if (c == '"') return lexString(start);
    if (c == '#') {
      // A directive at the start of a line, else `#`/`##` in a macro body; the preprocessor
      // reports any other use.
      ++cur_;
      return make(Tok::Hash, start);
    }
    auto two = [&](char second) { return cur_ + 1 < end_ && cur_[1] == second; };
    Tok kind = Tok::Eof;
    int len = 1;
    switch (c) {
      case '(': kind = Tok::LParen; break;
      case ')': kind = Tok::RParen; break;
      case '{': kind = Tok::LBrace; break;
      case '}': kind = Tok::RBrace; break;
      case '[': kind = Tok::LBracket; break;
      case ']': kind = Tok::RBracket; break;
      case ';': kind = Tok::Semi; break;
      case ',': kind = Tok::Comma; break;
      case '.': kind = Tok::Dot; break;
      case '?': kind = Tok::Question; break;
      case ':': kind = Tok::Colon; break;
      case '^': kind = Tok::Caret; break;
      case '+':
        kind = two('+') ? (len = 2, Tok::PlusPlus) : two('=') ? (len = 2, Tok::PlusAssign) : Tok::Plus;
        break;
      case '-':
        kind = two('-') ? (len = 2, Tok::MinusMinus)
               : two('=') ? (len = 2, Tok::MinusAssign)
                          : Tok::Minus;
        break;
      case '*': kind = two('=') ? (len = 2, Tok::StarAssign) : Tok::Star; break;
      case '/': kind = two('=') ? (len = 2, Tok::SlashAssign) : Tok::Slash; break;
      case '%': kind = two('=') ? (len = 2, Tok::PercentAssign) : Tok::Percent; break;
      case '!': kind = two('=') ? (len = 2, Tok::NotEq) : Tok::Bang; break;
      case '<': kind = two('=') ? (len = 2, Tok::LessEq) : Tok::Less; break;
      case '>': kind = two('=') ? (len = 2, Tok::GreaterEq) : Tok::Greater; break;
      case '=': kind = two('=') ? (len = 2, Tok::EqEq) : Tok::Assign; break;
      case '&':
        if (two('&')) kind = Tok::AmpAmp, len = 2;
        break;
      case '|':
        if (two('|')) kind = Tok::PipePipe, len = 2;
        break;
      default: break;
    }
    if (kind == Tok::Eof) {
      // Any other character: report at it and resume after it. A non-ASCII one is a whole UTF-8
      // sequence (one error, its code point named), else a single byte that is not UTF-8.
      uint32_t cp = 0;
      if (static_cast<unsigned char>(c) < 0x80) {
        // A control character (NUL, ESC, ...) is named, not echoed: it would garble the terminal.
        const auto byte = static_cast<unsigned char>(c);
        char shown[8];
        if (byte < 0x20 || byte == 0x7f)
          std::snprintf(shown, sizeof shown, "\\x%02x", byte);
        else
          shown[0] = char(byte), shown[1] = 0;
        sink().report(DiagId::ErrBadCharacter, locOf(start)).arg(std::string_view(shown));
      } else if (const int n = utf8Sequence(start, end_, &cp)) {
        sink().report(DiagId::ErrBadCodePoint, locOf(start))
            .arg(std::string_view(start, size_t(n)))
            .arg(hex(cp, cp > 0xFFFFF ? 6 : cp > 0xFFFF ? 5 : 4));
        len = n;
      } else {
        sink().report(DiagId::ErrBadByte, locOf(start)).arg(hex(static_cast<unsigned char>(c), 2));
      }
      cur_ += len;
      return make(Tok::Unknown, start);
    }
    cur_ += len;
    return make(kind, start);
  }
}

std::vector<Token> Lexer::lexAll() {
  std::vector<Token> out;
  for (;;) {
    out.push_back(next());
    if (out.back().is(Tok::Eof)) return out;
  }
}

}  // namespace relief::compiler
