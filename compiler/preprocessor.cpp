// Preprocessor implementation (see preprocessor.h). Directives are recognized from Tok::Hash at
// the start of a line and end at the next token that starts a line.
#include "compiler/preprocessor.h"

#include <algorithm>
#include <filesystem>

namespace relief::compiler {

namespace {

std::string tokenText(const Token& t) { return std::string(t.text); }

// Source text between two physical locations, with its backslash-newlines removed (§1.1).
std::string withoutSplices(const char* begin, const char* end) {
  std::string out;
  for (const char* p = begin; p < end; ++p) {
    if (*p == '\\' && p + 1 < end && (p[1] == '\n' || p[1] == '\r')) {
      p += (p[1] == '\r' && p + 2 < end && p[2] == '\n') ? 2 : 1;
      continue;
    }
    out += *p;
  }
  return out;
}

// The key of `#pragma once`: the canonical path, or the path as given where the file system
// cannot say (a name too long to resolve, a scratch buffer), rather than an exception.
std::string onceKey(const std::string& path) {
  std::error_code ec;
  std::filesystem::path canonical = std::filesystem::weakly_canonical(path, ec);
  return ec ? path : canonical.string();
}

bool isIdentifierLike(const Token& t) {
  // Keywords can be directive names (#if, #else) and macro names.
  return t.is(Tok::Identifier) || (t.kind >= Tok::KwBreak);
}

// Integer expressions of #if/#elif: precedence climbing over already expanded tokens.
class ConditionParser {
 public:
  explicit ConditionParser(const std::vector<Token>& toks) : toks_(toks) {}
  bool parse(int64_t* value) {
    if (!expr(1, value)) return false;
    return pos_ == toks_.size();
  }
  // Whether an evaluated operand divided by zero (as in C, `0 && 1 / 0` does not).
  bool dividedByZero() const { return dividedByZero_; }

 private:
  static int precedence(Tok k) {
    switch (k) {
      case Tok::PipePipe: return 1;
      case Tok::AmpAmp: return 2;
      case Tok::EqEq:
      case Tok::NotEq: return 3;
      case Tok::Less:
      case Tok::LessEq:
      case Tok::Greater:
      case Tok::GreaterEq: return 4;
      case Tok::Plus:
      case Tok::Minus: return 5;
      case Tok::Star:
      case Tok::Slash:
      case Tok::Percent: return 6;
      default: return 0;
    }
  }
  bool primary(int64_t* v) {
    if (pos_ >= toks_.size()) return false;
    const Token& t = toks_[pos_++];
    switch (t.kind) {
      case Tok::IntLiteral: *v = t.intValue; return true;
      case Tok::Minus:
      case Tok::Plus:
      case Tok::Bang: {
        int64_t x;
        if (!primary(&x)) return false;
        *v = t.is(Tok::Minus) ? int64_t(0 - uint64_t(x)) : t.is(Tok::Bang) ? !x : x;
        return true;
      }
      case Tok::LParen:
        if (!expr(1, v)) return false;
        return pos_ < toks_.size() && toks_[pos_++].is(Tok::RParen);
      default: return false;
    }
  }
  bool expr(int minPrec, int64_t* v) {
    if (!primary(v)) return false;
    while (pos_ < toks_.size()) {
      const Tok op = toks_[pos_].kind;
      const int prec = precedence(op);
      if (op == Tok::Question && minPrec <= 1) {
        ++pos_;
        int64_t a, b;
        const bool first = *v != 0;
        skip_ += !first;
        const bool okA = expr(1, &a);
        skip_ -= !first;
        if (!okA || pos_ >= toks_.size() || !toks_[pos_++].is(Tok::Colon)) return false;
        skip_ += first;
        const bool okB = expr(1, &b);
        skip_ -= first;
        if (!okB) return false;
        *v = first ? a : b;
        continue;
      }
      if (prec == 0 || prec < minPrec) return true;
      ++pos_;
      int64_t r;
      const bool unevaluated = (op == Tok::AmpAmp && *v == 0) || (op == Tok::PipePipe && *v != 0);
      skip_ += unevaluated;
      const bool ok = expr(prec + 1, &r);
      skip_ -= unevaluated;
      if (!ok) return false;
      if ((op == Tok::Slash || op == Tok::Percent) && r == 0 && skip_ == 0) dividedByZero_ = true;
      // Wrapping arithmetic: an overflowing #if must not be undefined behaviour in the compiler.
      auto wrap = [](uint64_t x) { return int64_t(x); };
      switch (op) {
        case Tok::PipePipe: *v = *v || r; break;
        case Tok::AmpAmp: *v = *v && r; break;
        case Tok::EqEq: *v = *v == r; break;
        case Tok::NotEq: *v = *v != r; break;
        case Tok::Less: *v = *v < r; break;
        case Tok::LessEq: *v = *v <= r; break;
        case Tok::Greater: *v = *v > r; break;
        case Tok::GreaterEq: *v = *v >= r; break;
        case Tok::Plus: *v = wrap(uint64_t(*v) + uint64_t(r)); break;
        case Tok::Minus: *v = wrap(uint64_t(*v) - uint64_t(r)); break;
        case Tok::Star: *v = wrap(uint64_t(*v) * uint64_t(r)); break;
        case Tok::Slash: *v = r == 0 ? 0 : r == -1 ? wrap(0 - uint64_t(*v)) : *v / r; break;
        case Tok::Percent: *v = r == 0 || r == -1 ? 0 : *v % r; break;
        default: return false;
      }
    }
    return true;
  }

  const std::vector<Token>& toks_;
  size_t pos_ = 0;
  int skip_ = 0;  // > 0 inside an operand the value does not depend on
  bool dividedByZero_ = false;
};

}  // namespace

Preprocessor::Preprocessor(SourceManager& sm, DiagnosticsEngine& diags, PreprocessorOptions options)
    : sm_(sm), diags_(diags), options_(std::move(options)) {}

Preprocessor::~Preprocessor() = default;

void Preprocessor::definePredefined(const std::string& name, const std::string& value, const char* origin) {
  // Written out as the directive it stands for, in a buffer named like clang's ("<built-in>",
  // "<command line>"), so a note pointing at the definition has a line to show.
  const auto id = sm_.addBuffer(origin, "#define " + name + " " + value);
  std::vector<Token> toks = Lexer(sm_, id, diags_).lexAll();
  toks.pop_back();  // Eof
  Macro m;
  if (toks.size() >= 3) {
    m.loc = toks[2].loc;
    m.body.assign(toks.begin() + 3, toks.end());
  }
  macros_[name] = std::move(m);
}

std::vector<Token> Preprocessor::run(SourceManager::FileId file) {
  // Spelt as in <math.h> (glibc) where it has them, so a shader that copies those lines (the
  // RenderMan Companion's do) redefines them identically, without a warning.
  static const std::pair<const char*, const char*> kPredefined[] = {
      {"__DISP__", "1"},
      {"M_PI", "3.14159265358979323846"},
      {"M_PI_2", "1.57079632679489661923"},
      {"M_2PI", "6.28318530717958647692"},
      {"M_E", "2.7182818284590452354"},
      {"M_SQRT2", "1.41421356237309504880"},
  };
  for (const auto& [name, value] : kPredefined) definePredefined(name, value, "<built-in>");
  for (const auto& [name, value] : options_.defines)
    definePredefined(name, value, "<command line>");  // -D X= is empty; reliefc turns -D X into X=1

  Source main;
  main.lexer = std::make_unique<Lexer>(sm_, file, diags_);
  main.file = file;
  main.dir = std::filesystem::path(sm_.name(file)).parent_path().string();
  stack_.push_back(std::move(main));

  std::vector<Token> out;
  while (!stack_.empty() && !fatal_) {
    Token t = nextRaw();
    if (t.is(Tok::Eof)) {
      if (stack_.size() == 1 && t.malformed) cutShort_ = true;
      for (const Conditional& c : stack_.back().conditionals)
        diags_.report(DiagId::ErrUnterminatedConditional, c.loc);
      stack_.pop_back();
      continue;
    }
    if (t.is(Tok::Hash) && t.atLineStart) {
      directive(t);
      continue;
    }
    if (!active()) continue;
    const size_t before = out.size();
    if (t.is(Tok::Identifier) && (macros_.count(tokenText(t)) || t.text == "__LINE__" || t.text == "__FILE__"))
      expand({t}, out, {}, true);
    else
      out.push_back(t);
    // `#` outside directives and macro operators is an error at that character (§1).
    for (size_t i = before; i < out.size(); ++i) {
      if (!out[i].is(Tok::Hash)) continue;
      diags_.report(DiagId::ErrBadCharacter, out[i].loc).arg("#");
      out[i].kind = Tok::Unknown;
    }
  }
  Token eof;
  eof.kind = Tok::Eof;
  eof.loc = sm_.startOf(file).advanced(uint32_t(sm_.text(file).size()));
  eof.atLineStart = true;
  eof.malformed = cutShort_;  // the parser does not report what it misses at an early end
  out.push_back(eof);
  return out;
}

bool Preprocessor::active() const {
  if (stack_.empty()) return true;
  const auto& conds = stack_.back().conditionals;
  return conds.empty() || conds.back().active;
}

Token Preprocessor::nextRaw() {
  Source& s = stack_.back();
  if (s.hasLookahead) {
    s.hasLookahead = false;
    return s.lookahead;
  }
  s.lexer->setQuiet(!active());
  return s.lexer->next();
}

void Preprocessor::pushBack(const Token& t) {
  Source& s = stack_.back();
  s.lookahead = t;
  s.hasLookahead = true;
}

std::vector<Token> Preprocessor::directiveLine() {
  std::vector<Token> line;
  for (;;) {
    Token t = nextRaw();
    if (t.is(Tok::Eof) || t.atLineStart) {
      pushBack(t);
      return line;
    }
    line.push_back(t);
  }
}

void Preprocessor::directive(const Token& hash) {
  std::vector<Token> line = directiveLine();
  if (line.empty()) return;  // the null directive
  const Token& name = line[0];
  const std::string n = tokenText(name);
  auto& conds = stack_.back().conditionals;
  if (n == "if" || n == "ifdef" || n == "ifndef") {
    const bool parent = active();
    const bool value = parent && evaluateCondition(name, line);
    conds.push_back({hash.loc, parent, value, value, false});
    return;
  }
  if (n == "elif" || n == "else" || n == "endif") {
    if (conds.empty()) {
      diags_.report(DiagId::ErrStrayConditional, name.loc).arg(n).range(name.range());
      return;
    }
    Conditional& c = conds.back();
    if (n == "endif") {
      conds.pop_back();
      return;
    }
    if (c.sawElse) {
      diags_.report(DiagId::ErrElseAfterElse, name.loc).arg(n).range(name.range());
      return;
    }
    if (n == "else") {
      c.sawElse = true;
      c.active = c.parentActive && !c.taken;
      c.taken = true;
    } else {
      c.active = c.parentActive && !c.taken && evaluateCondition(name, line);
      c.taken |= c.active;
    }
    return;
  }
  if (!active()) return;  // other directives in skipped groups are ignored
  if (n == "include") {
    include(name, line);
  } else if (n == "define") {
    defineMacro(line);
  } else if (n == "undef") {
    if (line.size() < 2 || !isIdentifierLike(line[1]))
      diags_.report(DiagId::ErrMacroName, line.size() < 2 ? name.end() : line[1].loc);
    else
      macros_.erase(tokenText(line[1]));
  } else if (n == "error") {
    std::string text;
    if (line.size() > 1) {
      const char* b = sm_.character(line[1].loc);
      const char* e = sm_.character(line.back().end());
      text = withoutSplices(b, e);
    }
    diags_.report(DiagId::ErrUserError, hash.loc).arg(text.empty() ? "#error" : text);
  } else if (n == "pragma") {
    if (line.size() > 1 && line[1].text == "once")
      onceFiles_.insert(onceKey(sm_.name(stack_.back().file)));
    // Unknown pragmas are ignored (§1.1).
  } else {
    diags_.report(DiagId::ErrUnknownDirective, name.loc).arg(n).range(name.range());
  }
}

void Preprocessor::include(const Token& name, const std::vector<Token>& line) {
  std::string file;
  bool angled = false;
  const Token* nameTok = line.size() > 1 ? &line[1] : nullptr;
  if (nameTok && nameTok->is(Tok::StringLiteral)) {
    file = Lexer::stringValue(*nameTok);
  } else if (nameTok && nameTok->is(Tok::Less)) {
    size_t close = 2;
    while (close < line.size() && !line[close].is(Tok::Greater)) ++close;
    if (close < line.size()) {
      angled = true;
      file = withoutSplices(sm_.character(nameTok->end()), sm_.character(line[close].loc));
    }
  }
  if (file.empty()) {
    diags_.report(DiagId::ErrIncludeSyntax, nameTok ? nameTok->loc : name.end());
    return;
  }
  if (stack_.size() > size_t(kMaxIncludeDepth)) {
    diags_.report(DiagId::ErrIncludeDepth, nameTok->loc).arg(kMaxIncludeDepth).range(nameTok->range());
    // A file including itself: everything it defines would be redefined at every level.
    fatal_ = true;
    return;
  }
  std::vector<std::string> dirs;
  if (!angled) dirs.push_back(stack_.back().dir);
  for (const std::string& d : options_.includeDirs) dirs.push_back(d);
  if (!options_.builtinIncludeDir.empty()) dirs.push_back(options_.builtinIncludeDir);
  std::string found, notRegular;
  bool builtin = false;
  for (size_t k = 0; k < dirs.size(); ++k) {
    const std::string& d = dirs[k];
    const std::filesystem::path candidate = d.empty() ? std::filesystem::path(file) : std::filesystem::path(d) / file;
    std::error_code ec;
    if (std::filesystem::is_regular_file(candidate, ec)) {
      found = candidate.string();
      builtin = !options_.builtinIncludeDir.empty() && k + 1 == dirs.size();
      break;
    }
    if (notRegular.empty() && std::filesystem::exists(candidate, ec)) notRegular = candidate.string();
  }
  // The built-in directory's files are the prelude, compiled with every shader (prelude.cpp):
  // including one adds nothing, and including its text again would redefine every function in it.
  if (builtin && std::filesystem::path(found).extension() == ".disp") return;
  if (found.empty() && !notRegular.empty()) {
    // A directory or a device by that name: "not found" would send the user looking elsewhere.
    diags_.report(DiagId::FatalIncludeUnreadable, nameTok->loc).arg(file).arg("'" + notRegular + "' is not a regular file")
        .range(nameTok->range());
    fatal_ = true;
    return;
  }
  if (found.empty()) {
    diags_.report(DiagId::FatalIncludeNotFound, nameTok->loc).arg(file).range(nameTok->range());
    fatal_ = true;  // compilation stops: later errors would only be noise
    return;
  }
  if (onceFiles_.count(onceKey(found))) return;
  SourceManager::FileId id;
  std::string error;
  if (!sm_.addFile(found, &id, &error, name.loc)) {
    diags_.report(DiagId::FatalIncludeUnreadable, nameTok->loc).arg(file).arg(error).range(nameTok->range());
    fatal_ = true;
    return;
  }
  Source s;
  s.lexer = std::make_unique<Lexer>(sm_, id, diags_);
  s.file = id;
  s.dir = std::filesystem::path(found).parent_path().string();
  stack_.push_back(std::move(s));
}

// `##`: two adjacent '#' tokens.
bool Preprocessor::isPaste(const std::vector<Token>& body, size_t i) {
  return i + 1 < body.size() && body[i].is(Tok::Hash) && body[i + 1].is(Tok::Hash) &&
         body[i + 1].loc == body[i].end();
}

Token Preprocessor::synthesize(const std::string& text, const Token& at) {
  const auto id = sm_.addBuffer("<scratch>", text);
  std::vector<Token> toks = Lexer(sm_, id, diags_).lexAll();
  Token r = toks.size() == 2 ? toks[0] : Token{};
  if (toks.size() != 2) {
    diags_.report(DiagId::ErrBadPaste, at.loc).arg(text).range(at.range());
    r.kind = Tok::Unknown;
    r.text = sm_.text(id);
  }
  r.loc = at.loc;
  r.length = at.length;
  return r;
}

// Joins the tokens around each `##` into one token (§1.1 SHOULD).
std::vector<Token> Preprocessor::paste(std::vector<Token> toks, const Token& at) {
  std::vector<Token> out;
  for (size_t i = 0; i < toks.size(); ++i) {
    if (isPaste(toks, i) && !out.empty() && i + 2 < toks.size()) {
      const Token left = out.back();
      const Token& right = toks[i + 2];
      if (left.placemarker) out.back() = right;
      else if (!right.placemarker) out.back() = synthesize(std::string(left.text) + std::string(right.text), at);
      i += 2;
      continue;
    }
    out.push_back(toks[i]);
  }
  std::erase_if(out, [](const Token& t) { return t.placemarker; });
  return out;
}

std::string Preprocessor::spelling(const std::vector<Token>& tokens) {
  std::string out;
  for (const Token& t : tokens) {
    if (!out.empty()) out += ' ';
    out += t.text;
  }
  return out;
}

void Preprocessor::defineMacro(const std::vector<Token>& line) {
  if (line.size() < 2 || !isIdentifierLike(line[1])) {
    diags_.report(DiagId::ErrMacroName, line.size() < 2 ? line[0].end() : line[1].loc);
    return;
  }
  const Token& name = line[1];
  Macro m;
  m.loc = name.loc;
  size_t bodyStart = 2;
  // Function-like only when '(' touches the name.
  if (line.size() > 2 && line[2].is(Tok::LParen) && line[2].loc == name.end()) {
    m.functionLike = true;
    size_t i = 3;
    bool ok = false;
    if (i < line.size() && line[i].is(Tok::RParen)) {
      ok = true;
      ++i;
    } else {
      while (i < line.size() && line[i].is(Tok::Identifier)) {
        if (std::find(m.params.begin(), m.params.end(), line[i].text) != m.params.end()) {
          diags_.report(DiagId::ErrMacroDuplicateParam, line[i].loc).arg(line[i].text).range(line[i].range());
          return;
        }
        m.params.emplace_back(line[i].text);
        ++i;
        if (i < line.size() && line[i].is(Tok::Comma)) {
          ++i;
          continue;
        }
        if (i < line.size() && line[i].is(Tok::RParen)) {
          ok = true;
          ++i;
        }
        break;
      }
    }
    if (!ok) {
      diags_.report(DiagId::ErrMacroParams, i < line.size() ? line[i].loc : line.back().end());
      return;
    }
    bodyStart = i;
  }
  m.body.assign(line.begin() + long(bodyStart), line.end());
  // The operators' misuses are errors at the definition, as in C (a use would only say "invalid
  // character '#'", at the use, and once per expansion).
  const size_t n = m.body.size();
  if (n >= 2 && (isPaste(m.body, 0) || isPaste(m.body, n - 2))) {
    const Token& at = isPaste(m.body, 0) ? m.body[0] : m.body[n - 2];
    diags_.report(DiagId::ErrPasteAtEnd, at.loc).range({at.loc, at.loc.advanced(2)});
    return;
  }
  for (size_t i = 0; m.functionLike && i < n; ++i) {
    if (isPaste(m.body, i)) {
      ++i;
      continue;
    }
    if (!m.body[i].is(Tok::Hash)) continue;
    const bool param = i + 1 < n && m.body[i + 1].is(Tok::Identifier) &&
                       std::find(m.params.begin(), m.params.end(), m.body[i + 1].text) != m.params.end();
    if (!param) {
      diags_.report(DiagId::ErrStringizeNotParam, m.body[i].loc).range(m.body[i].range());
      return;
    }
  }
  const std::string key = tokenText(name);
  auto it = macros_.find(key);
  if (it != macros_.end() && (spelling(it->second.body) != spelling(m.body) || it->second.params != m.params ||
                              it->second.functionLike != m.functionLike))
    diags_.report(DiagId::WarnMacroRedefined, name.loc)
        .arg(key)
        .range(name.range())
        .note(DiagId::NotePreviousDefinition, it->second.loc);
  macros_[key] = std::move(m);
}

bool Preprocessor::evaluateCondition(const Token& directiveName, const std::vector<Token>& line) {
  const std::string n = tokenText(directiveName);
  if (n == "ifdef" || n == "ifndef") {
    if (line.size() < 2 || !isIdentifierLike(line[1])) {
      diags_.report(DiagId::ErrMacroName, line.size() < 2 ? directiveName.end() : line[1].loc);
      return false;
    }
    const bool defined = macros_.count(tokenText(line[1])) != 0;
    return n == "ifdef" ? defined : !defined;
  }
  // `defined X` / `defined(X)` first, then macro expansion, then unknown identifiers are 0.
  static const char kOne[] = "1";
  static const char kZero[] = "0";
  auto literal = [&](bool value, const Token& at) {
    Token t = at;
    t.kind = Tok::IntLiteral;
    t.intValue = value ? 1 : 0;
    t.text = value ? kOne : kZero;
    return t;
  };
  // Replaces each `defined X` / `defined ( X )` of `in` from `first` on by 1 or 0; false at a
  // `defined` without a name.
  auto resolveDefined = [&](const std::vector<Token>& in, size_t first, std::vector<Token>* out) {
    for (size_t i = first; i < in.size(); ++i) {
      if (in[i].is(Tok::Identifier) && in[i].text == "defined") {
        size_t j = i + 1;
        const bool paren = j < in.size() && in[j].is(Tok::LParen);
        if (paren) ++j;
        if (j < in.size() && isIdentifierLike(in[j]) && (!paren || (j + 1 < in.size() && in[j + 1].is(Tok::RParen)))) {
          out->push_back(literal(macros_.count(tokenText(in[j])) != 0, in[i]));
          i = paren ? j + 1 : j;
          continue;
        }
        return false;
      }
      out->push_back(in[i]);
    }
    return true;
  };
  std::vector<Token> pre, expanded, resolved;
  if (!resolveDefined(line, 1, &pre)) {
    diags_.report(DiagId::ErrIfExpression, directiveName.loc).arg(n).range(directiveName.range());
    return false;
  }
  inCondition_ = true;
  expand(pre, expanded, {}, false);
  inCondition_ = false;
  // Again for those that macros produced (`#define HAS_A defined(A)`), as GNU cpp evaluates them;
  // a malformed one is the same error.
  if (!resolveDefined(expanded, 0, &resolved)) {
    diags_.report(DiagId::ErrIfExpression, directiveName.loc).arg(n).range(directiveName.range());
    return false;
  }
  expanded = std::move(resolved);
  for (Token& t : expanded)
    if (isIdentifierLike(t)) t = literal(false, t);
  int64_t value = 0;
  ConditionParser parser(expanded);
  if (expanded.empty() || !parser.parse(&value)) {
    diags_.report(DiagId::ErrIfExpression, directiveName.loc).arg(n).range(directiveName.range());
    return false;
  }
  if (parser.dividedByZero()) {
    diags_.report(DiagId::ErrIfDivisionByZero, directiveName.loc).arg(n).range(directiveName.range());
    return false;
  }
  return value != 0;
}

bool Preprocessor::collectArguments(std::vector<Token>& input, size_t& pos, bool fromSource,
                                    std::vector<std::vector<Token>>& args, const Token& name, SourceLoc* end) {
  auto next = [&](Token* t) {
    if (pos < input.size()) {
      *t = input[pos++];
      return true;
    }
    if (!fromSource) return false;
    *t = nextRaw();
    return !t->is(Tok::Eof);
  };
  Token t;
  next(&t);  // '('
  args.emplace_back();
  int depth = 0;
  for (;;) {
    if (!next(&t)) {
      diags_.report(DiagId::ErrUnterminatedMacroCall, name.loc).arg(name.text).range(name.range());
      if (fromSource) cutShort_ = true;
      return false;
    }
    if (t.is(Tok::LParen)) {
      ++depth;
    } else if (t.is(Tok::RParen)) {
      if (depth == 0) {
        *end = t.end();
        return true;
      }
      --depth;
    } else if (t.is(Tok::Comma) && depth == 0) {
      args.emplace_back();
      continue;
    }
    args.back().push_back(t);
  }
}

void Preprocessor::expand(std::vector<Token> input, std::vector<Token>& out, const std::set<std::string>& disabled,
                          bool fromSource) {
  struct Guard {
    int& n;
    ~Guard() { --n; }
  } guard{++expansionDepth_};
  if (expansionDepth_ > 200) {
    if (!input.empty())
      diags_.report(DiagId::ErrMacroNestingTooDeep, input.front().loc)
          .arg(outermost_.empty() ? input.front().text : outermost_);
    fatal_ = true;
    return;
  }
  size_t pos = 0;
  while (pos < input.size() && !fatal_) {
    const Token t = input[pos++];
    if (out.size() > kMaxExpandedTokens) {
      // Exponential macro definitions (#define A B B, #define B C C, ...) would exhaust memory.
      diags_.report(DiagId::ErrMacroNestingTooDeep, t.loc).arg(outermost_.empty() ? t.text : outermost_);
      fatal_ = true;
      return;
    }
    std::string name = t.is(Tok::Identifier) && !t.noExpand ? tokenText(t) : std::string();
    // In an #if, the operand of a `defined` that a macro produced is a name, not a macro call
    // (GNU cpp's reading of what C leaves undefined).
    const size_t n = out.size();
    if (inCondition_ && !name.empty() &&
        ((n >= 1 && out[n - 1].is(Tok::Identifier) && out[n - 1].text == "defined") ||
         (n >= 2 && out[n - 1].is(Tok::LParen) && out[n - 2].is(Tok::Identifier) && out[n - 2].text == "defined")))
      name.clear();
    auto it = name.empty() ? macros_.end() : macros_.find(name);
    if ((name == "__LINE__" || name == "__FILE__") && it == macros_.end()) {
      // C's predefined pair, at the use (a macro's tokens sit at its use, so inside one too).
      const PresumedLoc at = sm_.presumed(t.loc);
      std::string text = std::to_string(at.line);
      if (name == "__FILE__") {
        text = "\"";
        for (char c : at.file) text += c == '"' || c == '\\' ? std::string("\\") + c : std::string(1, c);
        text += '"';
      }
      out.push_back(synthesize(text, t));
      continue;
    }
    if (it == macros_.end() || disabled.count(name)) {
      out.push_back(t);
      if (it != macros_.end()) out.back().noExpand = true;
      continue;
    }
    if (expansionDepth_ == 1) outermost_ = name;  // what a "too deep" error names
    const Macro m = it->second;  // a copy: expansion never redefines, but keep it simple and safe
    std::vector<Token> replacement;
    SourceLoc useEnd = t.end();  // after the name, or after the call's ')'
    if (!m.functionLike) {
      replacement = paste(m.body, t);
    } else {
      bool invoked = pos < input.size() && input[pos].is(Tok::LParen);
      if (!invoked && pos >= input.size() && fromSource) {
        // As in C, white space including line breaks may separate the name from its '('.
        const Token peek = nextRaw();
        if (peek.is(Tok::LParen)) {
          input.push_back(peek);
          invoked = true;
        } else {
          pushBack(peek);
        }
      }
      if (!invoked) {
        out.push_back(t);  // a function-like macro name without arguments is just a name
        continue;
      }
      std::vector<std::vector<Token>> args;
      if (!collectArguments(input, pos, fromSource, args, t, &useEnd)) continue;
      if (m.params.empty() && args.size() == 1 && args[0].empty()) args.clear();
      if (args.size() != m.params.size()) {
        diags_.report(DiagId::ErrMacroArgs, t.loc)
            .arg(name)
            .arg(static_cast<long long>(m.params.size()))
            .arg(static_cast<long long>(args.size()))
            .range(t.range());
        // In its place, a token the parser knows is reported: no "expected expression" after it.
        Token bad = t;
        bad.kind = Tok::Unknown;
        bad.malformed = true;
        out.push_back(bad);
        continue;
      }
      auto paramIndex = [&](const Token& b) {
        size_t k = 0;
        while (k < m.params.size() && !(b.is(Tok::Identifier) && b.text == m.params[k])) ++k;
        return k;
      };
      for (size_t bi = 0; bi < m.body.size(); ++bi) {
        const Token& b = m.body[bi];
        // `# param`: the argument's spelling as a string literal.
        if (b.is(Tok::Hash) && !isPaste(m.body, bi) && !(bi >= 1 && isPaste(m.body, bi - 1)) &&
            bi + 1 < m.body.size() &&
            paramIndex(m.body[bi + 1]) < m.params.size()) {
          std::string text = "\"";
          for (char c : spelling(args[paramIndex(m.body[bi + 1])])) {
            if (c == '"' || c == '\\') text += '\\';
            text += c;
          }
          replacement.push_back(synthesize(text + "\"", t));
          ++bi;
          continue;
        }
        const size_t k = paramIndex(b);
        if (k == m.params.size()) {
          replacement.push_back(b);
          continue;
        }
        // Operands of ## use the argument unexpanded.
        const bool pasted = (bi >= 2 && isPaste(m.body, bi - 2)) || isPaste(m.body, bi + 1);
        if (pasted) {
          if (args[k].empty()) {
            Token mark = b;
            mark.kind = Tok::Unknown;
            mark.placemarker = true;
            replacement.push_back(mark);
          }
          replacement.insert(replacement.end(), args[k].begin(), args[k].end());
          continue;
        }
        std::vector<Token> arg;
        expand(args[k], arg, disabled, false);
        for (Token& a : arg) a.fromArgument = true;
        replacement.insert(replacement.end(), arg.begin(), arg.end());
      }
    }
    replacement = paste(std::move(replacement), t);
    // A replacement ending in a function-like macro name takes its arguments from what follows
    // (`#define G F` then `G(1, 2)`): move that parenthesized group behind it before rescanning.
    if (!replacement.empty() && replacement.back().is(Tok::Identifier)) {
      auto last = macros_.find(tokenText(replacement.back()));
      if (!replacement.back().noExpand && last != macros_.end() && last->second.functionLike && !disabled.count(last->first) &&
          last->first != name) {
        std::vector<Token> group;
        int depth = 0;
        auto take = [&](const Token& tk) {
          group.push_back(tk);
          if (tk.is(Tok::LParen)) ++depth;
          if (tk.is(Tok::RParen)) --depth;
        };
        if (pos < input.size() && input[pos].is(Tok::LParen)) {
          do take(input[pos++]);
          while (depth > 0 && pos < input.size());
        } else if (pos >= input.size() && fromSource) {
          Token peek = nextRaw();
          if (peek.is(Tok::LParen)) {
            take(peek);
            while (depth > 0) {
              peek = nextRaw();
              if (peek.is(Tok::Eof)) {
                pushBack(peek);
                break;
              }
              take(peek);
            }
          } else {
            pushBack(peek);
          }
        }
        for (Token& g : group) g.loc = t.loc, g.length = t.length;
        replacement.insert(replacement.end(), group.begin(), group.end());
      }
    }
    // Expanded tokens sit at the macro use (§1.1), but for an argument's, which stay where the
    // argument is written (as clang has it: an error in an argument of a call spanning lines is
    // on the argument's line); the last ends where the use does.
    for (Token& r : replacement) {
      if (!r.fromArgument) {
        r.loc = t.loc;
        r.length = t.length;
        r.endLoc = {};
      }
      r.atLineStart = false;
    }
    if (!replacement.empty()) {
      replacement.front().atLineStart = t.atLineStart;
      replacement.back().endLoc = useEnd;
    }
    std::set<std::string> inner = disabled;
    inner.insert(name);
    expand(std::move(replacement), out, inner, false);
  }
}

}  // namespace relief::compiler
