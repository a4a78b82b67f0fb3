// Parser implementation (see parser.h). Each parse function carries its production. On a syntax
// error a function reports once and returns null; statement and top-level loops resynchronize.
#include "compiler/parser.h"

#include <algorithm>
#include <cstdint>

#include "compiler/lexer.h"

namespace relief::compiler {

namespace {

// The longest array a declaration may have (see the check in the declaration parser).
constexpr int64_t kMaxArrayLength = 65536;
// Binary operator precedence, higher binds tighter (language.md §4.1 rows 3..10); 0: not binary.
int binaryPrecedence(Tok k) {
  switch (k) {
    case Tok::Dot: return 9;
    case Tok::Star:
    case Tok::Slash:
    case Tok::Percent: return 8;
    case Tok::Caret: return 7;
    case Tok::Plus:
    case Tok::Minus: return 6;
    case Tok::Less:
    case Tok::LessEq:
    case Tok::Greater:
    case Tok::GreaterEq: return 5;
    case Tok::EqEq:
    case Tok::NotEq: return 4;
    case Tok::AmpAmp: return 3;
    case Tok::PipePipe: return 2;
    default: return 0;
  }
}
bool isAssignOp(Tok k) {
  return k == Tok::Assign || k == Tok::PlusAssign || k == Tok::MinusAssign ||
         k == Tok::StarAssign || k == Tok::SlashAssign || k == Tok::PercentAssign;
}
SourceRange join(SourceLoc b, SourceLoc e) { return {b, e}; }

}  // namespace

Parser::Parser(std::vector<Token> tokens, std::string fileName, DiagnosticsEngine& diags)
    : diags_(diags), toks_(std::move(tokens)) {
  if (toks_.empty() || !toks_.back().is(Tok::Eof)) toks_.emplace_back();
  unit_ = std::make_unique<TranslationUnit>();
  unit_->fileName = std::move(fileName);
}

Parser::Parser(const SourceManager& sm, SourceManager::FileId file, DiagnosticsEngine& diags)
    : Parser(Lexer(sm, file, diags).lexAll(), sm.name(file), diags) {}

bool Parser::accept(Tok k) {
  if (!tok().is(k)) return false;
  consume();
  return true;
}

bool Parser::expectAfterPrev(Tok k, const char* context) {
  if (accept(k)) return true;
  if (tok().is(Tok::Unknown) || stopped_ || (pos_ && prev().malformed) || cutShort()) return false;  // already reported
  const SourceLoc at = pos_ ? prev().end() : tok().loc;
  if (context)
    diags_.report(DiagId::ErrExpectedAfter, at).arg(tokDescription(k)).arg(context);
  else
    diags_.report(DiagId::ErrExpected, at).arg(tokDescription(k));
  return false;
}

bool Parser::expectClosing(Tok k, const Token& opener) {
  if (accept(k)) return true;
  if (tok().is(Tok::Unknown) || stopped_ || (pos_ && prev().malformed) || cutShort()) return false;  // already reported
  const SourceLoc at = pos_ ? prev().end() : tok().loc;
  diags_.report(DiagId::ErrExpected, at)
      .arg(tokDescription(k))
      .note(DiagId::NoteToMatch, opener.loc, {std::string(tokSpelling(opener.kind))});
  return false;
}

bool Parser::tooDeep(const char* what) {
  if (nesting_ <= kMaxNesting) return false;
  diags_.report(DiagId::ErrNestingTooDeep, tok().loc).arg(what).arg(kMaxNesting).range(tok().range());
  // Skip to the end of the file: every enclosing level would report again otherwise.
  while (!tok().is(Tok::Eof)) consume();
  stopped_ = true;
  return true;
}

// Computes the subtree height and rejects trees too tall for the recursive passes.
ExprPtr Parser::bounded(ExprPtr e) {
  if (!e) return e;
  uint32_t d = 0;
  for (const ExprPtr& c : e->operands) d = std::max(d, c->depth);
  e->depth = d + 1;
  if (e->depth <= kMaxExpressionDepth) return e;
  diags_.report(DiagId::ErrExpressionTooTall, e->opLoc).arg(kMaxExpressionDepth);
  while (!tok().is(Tok::Eof)) consume();
  stopped_ = true;
  return nullptr;
}

// After a missing ';' (already reported): if the next token starts a new line, or a declaration or
// a statement keyword follows on the same line (`float a = 1 float b = 2;`), the statement most
// likely just lacks its ';', so keep it and carry on without skipping what follows (skipping to the
// next ';' lost `b`, and its uses were reported as undeclared).
bool Parser::missingSemiAtLineEnd() const {
  if (tok().atLineStart || tok().is(Tok::RBrace) || startsDeclaration()) return true;
  switch (tok().kind) {
    case Tok::KwIf:
    case Tok::KwFor:
    case Tok::KwWhile:
    case Tok::KwDo:
    case Tok::KwReturn:
    case Tok::KwBreak:
    case Tok::KwContinue: return true;
    default: return false;
  }
}

void Parser::errorExpectedExpression() {
  if (tok().is(Tok::Unknown) || stopped_ || cutShort()) return;
  if (tok().is(Tok::ReservedWord) || tok().is(Tok::ShaderKindWord))
    diags_.report(DiagId::ErrReservedWord, tok().loc).arg(tok().text).range(tok().range());
  else
    diags_.report(DiagId::ErrExpectedExpression, tok().loc).range(tok().range());
}

// Skips to just after the next ';' at this nesting level, or to (not past) a '}' closing the
// current block or a top-level keyword; nested braces are skipped whole.
void Parser::syncStatement() {
  int depth = 0;
  while (!tok().is(Tok::Eof)) {
    if (tok().is(Tok::LBrace)) {
      ++depth;
    } else if (tok().is(Tok::RBrace)) {
      if (depth == 0) return;
      --depth;
      if (depth == 0) {
        consume();
        return;
      }
    } else if (tok().is(Tok::Semi) && depth == 0) {
      consume();
      return;
    } else if (atShaderHeader()) {
      return;
    }
    consume();
  }
}

// Inside a body, a shader keyword ends it (a '}' is missing) only where it starts a shader, as
// in `surface plastic(`; elsewhere (`float light = 1;`) it is a misused reserved word, reported
// by whoever expected an identifier or expression, and the body goes on.
bool Parser::atShaderHeader() const {
  return (tok().is(Tok::KwDisplacement) || tok().is(Tok::ShaderKindWord)) && peek().is(Tok::Identifier);
}

// Skips to the next shader keyword or to a line that starts a function definition.
void Parser::syncTopLevel() {
  while (!tok().is(Tok::Eof) && !tok().is(Tok::KwDisplacement) && !tok().is(Tok::ShaderKindWord)) {
    if (tok().atLineStart && (isTypeKeyword(tok().kind) || tok().is(Tok::KwVoid)) &&
        peek().is(Tok::Identifier) && peek(2).is(Tok::LParen))
      return;
    consume();
  }
}

bool Parser::isTypeKeyword(Tok k) const {
  switch (k) {
    case Tok::KwFloat:
    case Tok::KwInt:
    case Tok::KwPoint:
    case Tok::KwVector:
    case Tok::KwNormal:
    case Tok::KwColor:
    case Tok::KwMatrix:
    case Tok::KwString: return true;
    default: return false;
  }
}

TypeKind Parser::typeOf(Tok k) const {
  switch (k) {
    case Tok::KwFloat: return TypeKind::Float;
    case Tok::KwInt: return TypeKind::Int;
    case Tok::KwPoint: return TypeKind::Point;
    case Tok::KwVector: return TypeKind::Vector;
    case Tok::KwNormal: return TypeKind::Normal;
    case Tok::KwColor: return TypeKind::Color;
    case Tok::KwMatrix: return TypeKind::Matrix;
    case Tok::KwString: return TypeKind::String;
    case Tok::KwVoid: return TypeKind::Void;
    default: return TypeKind::Error;
  }
}

// The type keyword a misspelt word most likely meant (at most two edits, and fewer than the word
// has letters to spare), or "".
std::string Parser::closestTypeName(std::string_view word) {
  static constexpr std::string_view kTypes[] = {"float", "int", "point", "vector", "normal",
                                                "color", "string", "matrix", "void"};
  auto distance = [](std::string_view a, std::string_view b) {
    // Optimal string alignment: insertions, deletions, substitutions and adjacent swaps.
    std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
    for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
    for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
    for (size_t i = 1; i <= a.size(); ++i)
      for (size_t j = 1; j <= b.size(); ++j) {
        d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] != b[j - 1])});
        if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
          d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    return d[a.size()][b.size()];
  };
  // Ties go to the longer shared prefix: a typo rarely hits the first letters ("pint" is "point"
  // more likely than "int").
  auto prefix = [](std::string_view a, std::string_view b) {
    size_t n = 0;
    while (n < a.size() && n < b.size() && a[n] == b[n]) ++n;
    return n;
  };
  std::string best;
  size_t bestDistance = 3, bestPrefix = 0;
  for (std::string_view type : kTypes) {
    const size_t dist = distance(word, type), shared = prefix(word, type);
    if (dist > 2 || dist >= type.size() - 1) continue;
    if (dist < bestDistance || (dist == bestDistance && shared > bestPrefix))
      best = std::string(type), bestDistance = dist, bestPrefix = shared;
  }
  return best;
}

bool Parser::lexedBadly(size_t from, size_t to) const {
  for (size_t i = from; i < to && i < toks_.size(); ++i)
    if (toks_[i].is(Tok::Unknown) || toks_[i].malformed) return true;
  return false;
}

bool Parser::startsDeclaration() const {
  if (tok().is(Tok::KwUniform) || tok().is(Tok::KwVarying)) return true;
  return isTypeKeyword(tok().kind) && peek().is(Tok::Identifier);
}

// file := { shader | function }
// Characters the lexer reported (Tok::Unknown) where a statement or declaration would start are
// dropped: the lexer has resumed after them (language.md §1), so the parser must too. Taken as the
// start of a broken statement, one at a line's end made the parser skip the whole next line.
void Parser::skipBadCharacters() {
  while (tok().is(Tok::Unknown)) consume();
}

std::unique_ptr<TranslationUnit> Parser::parseTranslationUnit() {
  while (skipBadCharacters(), !tok().is(Tok::Eof)) {
    if (tok().is(Tok::KwDisplacement)) {
      parseShader();
    } else if (tok().is(Tok::Semi)) {
      consume();  // `float f() { ... };`: an empty declaration, as C++ and RSL compilers take it
    } else if (tok().is(Tok::ShaderKindWord)) {
      diags_.report(DiagId::ErrOnlyDisplacement, tok().loc).arg(tok().text).range(tok().range());
      consume();
      syncTopLevel();
    } else if ((isTypeKeyword(tok().kind) || tok().is(Tok::KwVoid)) && peek().is(Tok::Identifier) &&
               peek(2).is(Tok::LParen)) {
      if (auto f = parseFunction()) {
        f->parseOrder = uint32_t(unit_->shaders.size() + unit_->functions.size());
        unit_->functions.push_back(std::move(f));
      }
    } else {
      diags_.report(DiagId::ErrExpectedTopLevel, tok().loc).range(tok().range());
      consume();
      syncTopLevel();
    }
  }
  return std::move(unit_);
}

// function := (type | "void") IDENT "(" [formals] ")" block
std::unique_ptr<FunctionDecl> Parser::parseFunction() {
  auto f = std::make_unique<FunctionDecl>();
  const Token type = consume();
  f->begin = type.loc;
  f->returnType = Type(typeOf(type.kind));
  const Token name = consume();
  f->name = std::string(name.text);
  f->nameRange = name.range();
  const Token open = consume();  // callers checked it is '('
  if (!tok().is(Tok::RParen) && !parseFormals(f->params)) {
    while (!tok().is(Tok::Eof) && !tok().is(Tok::LBrace) && !tok().is(Tok::KwDisplacement)) consume();
    if (tok().is(Tok::LBrace)) parseBlock();
    return nullptr;
  }
  if (!expectClosing(Tok::RParen, open)) {
    while (!tok().is(Tok::Eof) && !tok().is(Tok::LBrace) && !tok().is(Tok::KwDisplacement)) consume();
  }
  if (!tok().is(Tok::LBrace)) {
    expectAfterPrev(Tok::LBrace);
    // A prototype (`float f(float x);`) ends here: the ';' is its, not a new top-level error.
    if (tok().is(Tok::Semi) && !f->name.empty()) consume();
    return nullptr;
  }
  const unsigned errorsBefore = diags_.numErrors();
  const size_t firstToken = pos_;
  f->body = parseBlock();
  f->bodyHadErrors = diags_.numErrors() != errorsBefore || lexedBadly(firstToken, pos_) || cutShort();
  return f;
}

// extern := "extern" ["uniform"|"varying"] type IDENT ["[" [int-const] "]"] { "," IDENT ["[" [int-const] "]"] } ";"
StmtPtr Parser::parseExtern() {
  const Token kw = consume();
  auto s = std::make_unique<Stmt>(StmtKind::Extern, kw.range());
  if (!accept(Tok::KwUniform)) accept(Tok::KwVarying);
  if (!isTypeKeyword(tok().kind)) {
    diags_.report(DiagId::ErrExpectedType, tok().loc).range(tok().range());
    return nullptr;
  }
  const Type type(typeOf(consume().kind));
  for (;;) {
    if (!tok().is(Tok::Identifier)) {
      diags_.report(DiagId::ErrExpected, tok().loc).arg("identifier").range(tok().range());
      return nullptr;
    }
    const Token name = consume();
    auto d = std::make_unique<VarDecl>();
    d->name = std::string(name.text);
    d->nameRange = name.range();
    d->type = type;
    // An enclosing array: "name[n]", or "name[]" for whatever length it has.
    if (tok().is(Tok::LBracket)) {
      const Token open = consume();
      d->type.arrayLength = -1;
      if (!accept(Tok::RBracket)) {
        ExprPtr length = parseConditional();
        if (!length || !expectClosing(Tok::RBracket, open)) return nullptr;
        int64_t n = 0;
        if (!foldIntConstant(*length, &n) || n <= 0 || n > kMaxArrayLength) {
          diags_.report(DiagId::ErrArrayLength, length->range.begin).range(length->range);
          d->type = Type(TypeKind::Error);
        } else {
          d->type.arrayLength = int(n);
        }
      }
    }
    s->decls.push_back(std::move(d));
    if (!accept(Tok::Comma)) break;
  }
  if (!expectAfterPrev(Tok::Semi, "extern declaration")) return nullptr;
  s->range.end = prev().end();
  return s;
}

// shader := "displacement" IDENT "(" [formals] ")" block
void Parser::parseShader() {
  const unsigned errorsBefore = diags_.numErrors();
  const size_t firstToken = pos_;
  auto shader = std::make_unique<ShaderDecl>();
  shader->keywordLoc = consume().loc;
  if (!tok().is(Tok::Identifier)) {
    diags_.report(DiagId::ErrExpectedAfter, pos_ ? prev().end() : tok().loc)
        .arg("shader name")
        .arg("'displacement'");
    syncTopLevel();
    return;
  }
  const Token name = consume();
  shader->name = std::string(name.text);
  shader->nameRange = name.range();
  if (!tok().is(Tok::LParen)) {
    expectAfterPrev(Tok::LParen, "shader name");
    syncTopLevel();
    return;
  }
  const Token open = consume();
  if (!tok().is(Tok::RParen)) {
    if (!parseFormals(shader->params)) {
      // Skip to the body so its errors are still found.
      while (!tok().is(Tok::Eof) && !tok().is(Tok::LBrace) && !tok().is(Tok::KwDisplacement))
        consume();
      if (!tok().is(Tok::LBrace)) return;
      shader->body = parseBlock();
      return;  // not added: the signature is broken
    }
  }
  if (!expectClosing(Tok::RParen, open)) {
    while (!tok().is(Tok::Eof) && !tok().is(Tok::LBrace) && !tok().is(Tok::KwDisplacement))
      consume();
  }
  if (!tok().is(Tok::LBrace)) {
    expectAfterPrev(Tok::LBrace);
    syncTopLevel();
    return;
  }
  shader->body = parseBlock();
  shader->hadSyntaxErrors = diags_.numErrors() != errorsBefore || lexedBadly(firstToken, pos_) || cutShort();
  shader->parseOrder = uint32_t(unit_->shaders.size() + unit_->functions.size());
  unit_->shaders.push_back(std::move(shader));
}

// formals := group { (";" | ",") group } [";"]
// group   := ["output"] ["uniform"|"varying"] type decltor { "," decltor }
bool Parser::parseFormals(std::vector<std::unique_ptr<VarDecl>>& params) {
  for (;;) {
    const bool isOutput = accept(Tok::KwOutput);
    bool isUniform = false;
    if (tok().is(Tok::KwUniform)) {
      isUniform = true;
      consume();
    } else {
      accept(Tok::KwVarying);
    }
    if (!isTypeKeyword(tok().kind)) {
      diags_.report(DiagId::ErrExpectedType, tok().loc).range(tok().range());
      return false;
    }
    const Type type(typeOf(consume().kind));
    if (!parseDeclarators(params, type, isOutput, isUniform, Storage::Parameter)) return false;
    if (recovering_) {
      recovering_ = false;
      return false;
    }
    if (tok().is(Tok::Semi)) {
      consume();
      if (tok().is(Tok::RParen)) return true;
      continue;
    }
    if (tok().is(Tok::Comma)) {  // `, type` starts a new group (OSL style)
      consume();
      continue;
    }
    return true;
  }
}

// decltor := IDENT ["[" [int-const] "]"] ["=" init]; a ',' followed by an identifier continues.
// After a declarator's comma, a keyword where the next name belongs (in a local declaration,
// where a comma cannot start anything else).
bool Parser::keywordAfterComma(Storage storage) const {
  return storage == Storage::Local &&
         (peek().kind >= Tok::KwBreak || peek().is(Tok::ReservedWord) || peek().is(Tok::ShaderKindWord));
}

bool Parser::parseDeclarators(std::vector<std::unique_ptr<VarDecl>>& out, Type type, bool isOutput,
                              bool isUniform, Storage storage) {
  for (;;) {
    if (!tok().is(Tok::Identifier)) {
      if (tok().is(Tok::ReservedWord) || tok().is(Tok::ShaderKindWord))
        diags_.report(DiagId::ErrReservedWord, tok().loc).arg(tok().text).range(tok().range());
      else if (tok().kind >= Tok::KwBreak)
        diags_.report(DiagId::ErrKeywordAsName, tok().loc).arg(std::string(tok().text)).range(tok().range());
      else
        diags_.report(DiagId::ErrExpected, tok().loc).arg("identifier").range(tok().range());
      if (out.empty()) return false;
      // The declarators before the bad one stay declared, so their uses raise no more errors.
      recovering_ = true;
      return true;
    }
    const Token name = consume();
    auto decl = std::make_unique<VarDecl>();
    decl->name = std::string(name.text);
    decl->nameRange = name.range();
    decl->type = type;
    decl->isOutput = isOutput;
    decl->isUniform = isUniform;
    decl->storage = storage;
    if (tok().is(Tok::LBracket)) {
      // "[" [int-const] "]": an integer constant expression (after macro expansion), like C's.
      const Token open = consume();
      if (accept(Tok::RBracket)) {
        decl->type.arrayLength = -1;
      } else {
        ExprPtr length = parseConditional();
        if (!length || !expectClosing(Tok::RBracket, open)) return false;
        int64_t n = 0;
        if (!foldIntConstant(*length, &n) || n <= 0) {
          diags_.report(DiagId::ErrArrayLength, length->range.begin).range(length->range);
          n = 0;
        }
        // A bound on the stack the generated code takes per array (each component and derivative
        // lane is an alloca of its own); zeroing, copies and parameter loads are loops, so the
        // length costs the compile nothing (65536 elements: 0.03 s).
        if (n > kMaxArrayLength) {
          diags_.report(DiagId::ErrArrayTooLong, length->range.begin)
              .arg(std::to_string(n))
              .arg(std::to_string(kMaxArrayLength))
              .range(length->range);
          n = 0;
        }
        // A bad length still declares the variable, with the error type, so that its uses raise
        // no further errors.
        if (n > 0)
          decl->type.arrayLength = int(n);
        else
          decl->type = Type(TypeKind::Error);
      }
    }
    if (accept(Tok::Assign)) {
      if (tok().is(Tok::LBrace)) {
        // init := "{" expr { "," expr } "}"
        const Token open = consume();
        auto list = std::make_unique<Expr>(ExprKind::InitList, open.range());
        if (!tok().is(Tok::RBrace)) {
          for (;;) {
            ExprPtr element = parseAssignment();
            if (!element) return false;
            list->operands.push_back(std::move(element));
            if (!accept(Tok::Comma)) break;
          }
        }
        if (!expectClosing(Tok::RBrace, open)) return false;
        list->range.end = prev().end();
        decl->init = std::move(list);
        out.push_back(std::move(decl));
        if (tok().is(Tok::Comma) && (peek().is(Tok::Identifier) || keywordAfterComma(storage))) {
          consume();
          continue;
        }
        return true;
      }
      decl->init = parseAssignment();
      if (!decl->init) {
        // Keep the variable declared so later uses do not cascade into more errors.
        decl->invalid = true;
        out.push_back(std::move(decl));
        recovering_ = true;
        return true;
      }
    }
    out.push_back(std::move(decl));
    if (tok().is(Tok::Comma) && peek().is(Tok::Identifier)) {
      consume();
      continue;
    }
    // `float a = 1, color = 2;`: a keyword as the next name, said at the keyword.
    if (tok().is(Tok::Comma) && keywordAfterComma(storage)) {
      consume();
      continue;
    }
    return true;
  }
}

// stmt := block | decl ";" | expr ";" | ";" | if | while | do | for | break | continue | return
StmtPtr Parser::parseStatement() {
  struct Guard {
    int& n;
    ~Guard() { --n; }
  } guard{++nesting_};
  if (tooDeep("statements")) return nullptr;
  skipBadCharacters();
  const Token& t = tok();
  switch (t.kind) {
    case Tok::LBrace: return parseBlock();
    case Tok::KwIf: return parseIf();
    case Tok::KwWhile: return parseWhile();
    case Tok::KwDo: return parseDoWhile();
    case Tok::KwFor: return parseFor();
    case Tok::KwReturn: return parseReturn();
    case Tok::KwBreak:
    case Tok::KwContinue: {
      const Token kw = consume();
      auto s = std::make_unique<Stmt>(kw.is(Tok::KwBreak) ? StmtKind::Break : StmtKind::Continue,
                                      kw.range());
      // RSL's `break n` / `continue n`: the n-th enclosing loop (n a positive integer literal).
      if (tok().is(Tok::IntLiteral)) {
        const Token n = consume();
        if (n.intValue < 1)
          diags_.report(DiagId::ErrBreakLevel, n.loc).arg(kw.is(Tok::KwBreak) ? "break" : "continue").range(n.range());
        s->levels = std::max(1, n.intValue);
        s->range.end = n.end();
      }
      if (!expectAfterPrev(Tok::Semi, kw.is(Tok::KwBreak) ? "'break'" : "'continue'") &&
          !missingSemiAtLineEnd())
        recovering_ = true;
      return s;
    }
    case Tok::Semi: {
      const Token semi = consume();
      return std::make_unique<Stmt>(StmtKind::Empty, semi.range());
    }
    case Tok::KwExtern: return parseExtern();
    default: break;
  }
  if ((isTypeKeyword(t.kind) || t.is(Tok::KwVoid)) && peek().is(Tok::Identifier) && peek(2).is(Tok::LParen)) {
    const SourceLoc start = t.loc;
    auto f = parseFunction();
    if (!f) return nullptr;
    auto s = std::make_unique<Stmt>(StmtKind::FunctionDef, SourceRange{start, prev().end()});
    s->function = std::move(f);
    return s;
  }
  // `float color = 1;`: a keyword where the variable's name belongs. Said at the keyword, not as
  // "expected expression" further on.
  if (isTypeKeyword(t.kind) &&
      (peek().kind >= Tok::KwBreak || peek().is(Tok::ReservedWord) || peek().is(Tok::ShaderKindWord)) &&
      (peek(2).is(Tok::Assign) || peek(2).is(Tok::Semi) || peek(2).is(Tok::Comma) || peek(2).is(Tok::LBracket))) {
    const Token& name = peek();
    const bool reserved = name.is(Tok::ReservedWord) || name.is(Tok::ShaderKindWord);
    diags_.report(reserved ? DiagId::ErrReservedWord : DiagId::ErrKeywordAsName, name.loc)
        .arg(std::string(name.text))
        .range(name.range());
    recovering_ = true;
    return nullptr;
  }
  // `void x;`: only functions are void.
  if (t.is(Tok::KwVoid) && peek().is(Tok::Identifier) && !peek(2).is(Tok::LParen)) {
    diags_.report(DiagId::ErrVoidVariable, t.loc).arg(std::string(peek().text)).range(t.range());
    recovering_ = true;
    return nullptr;
  }
  // `flaot h = 1;`: an unknown word where a type belongs. The variable is still declared, with the
  // error type, so that its uses say nothing more (one error, not three).
  if (t.is(Tok::Identifier) && peek().is(Tok::Identifier) &&
      (peek(2).is(Tok::Assign) || peek(2).is(Tok::Semi) || peek(2).is(Tok::Comma) ||
       peek(2).is(Tok::LBracket))) {
    const std::string suggestion = closestTypeName(t.text);
    diags_.report(DiagId::ErrUnknownTypeName, t.loc)
        .arg(std::string(t.text))
        .arg(suggestion.empty() ? std::string() : "; did you mean '" + suggestion + "'?")
        .range(t.range());
    const Token typeWord = consume();
    auto s = std::make_unique<Stmt>(StmtKind::Decl, typeWord.range());
    if (!parseDeclarators(s->decls, Type(TypeKind::Error), false, false, Storage::Local)) return nullptr;
    if (!expectAfterPrev(Tok::Semi, "declaration") && !missingSemiAtLineEnd()) recovering_ = s->unterminated = true;
    s->range.end = prev().end();
    return s;
  }
  if (startsDeclaration()) {
    const size_t firstToken = pos_;
    auto s = parseDeclaration();
    if (!s) return nullptr;
    if (recovering_) return s;
    // Without its ';' the declaration is still complete: keep it, resync unless at a line end.
    if (!expectAfterPrev(Tok::Semi, "declaration") && !missingSemiAtLineEnd()) recovering_ = s->unterminated = true;
    if (lexedBadly(firstToken, pos_)) s->unterminated = true;  // as for expression statements below
    s->range.end = prev().end();
    return s;
  }
  const SourceLoc start = t.loc;
  const size_t firstToken = pos_;
  ExprPtr e = parseExpression();
  if (!e) return nullptr;
  const bool unterminated = !expectAfterPrev(Tok::Semi, "expression") && !missingSemiAtLineEnd();
  if (unterminated) recovering_ = true;
  auto s = std::make_unique<Stmt>(StmtKind::ExprStmt, join(start, prev().end()));
  s->expr = std::move(e);
  // A token the lexer reported (an unterminated string took the rest of its line) makes the
  // statement a syntax error already reported: nothing more is said of it.
  s->unterminated = unterminated || lexedBadly(firstToken, pos_);
  return s;
}

// block := "{" { stmt } "}"
StmtPtr Parser::parseBlock() {
  const Token open = consume();
  auto block = std::make_unique<Stmt>(StmtKind::Block, open.range());
  while (skipBadCharacters(), !tok().is(Tok::RBrace) && !tok().is(Tok::Eof) && !atShaderHeader()) {
    const size_t before = pos_;
    recovering_ = false;
    StmtPtr s = parseStatement();
    if (s) {
      block->stmts.push_back(std::move(s));
      if (recovering_) syncStatement();
    } else {
      syncStatement();
      if (pos_ == before) consume();  // always make progress
    }
  }
  expectClosing(Tok::RBrace, open);
  block->range.end = prev().end();
  return block;
}

// decl := ["uniform"|"varying"] type decltor { "," decltor }
StmtPtr Parser::parseDeclaration() {
  const SourceLoc start = tok().loc;
  bool isUniform = false;
  if (tok().is(Tok::KwUniform)) {
    isUniform = true;
    consume();
  } else {
    accept(Tok::KwVarying);
  }
  if (!isTypeKeyword(tok().kind)) {
    diags_.report(DiagId::ErrExpectedType, tok().loc).range(tok().range());
    return nullptr;
  }
  const Type type(typeOf(consume().kind));
  auto s = std::make_unique<Stmt>(StmtKind::Decl, join(start, prev().end()));
  if (!parseDeclarators(s->decls, type, false, isUniform, Storage::Local)) return nullptr;
  s->range.end = prev().end();
  return s;
}

// if := "if" "(" expr ")" stmt ["else" stmt]
StmtPtr Parser::parseIf() {
  const Token kw = consume();
  auto s = std::make_unique<Stmt>(StmtKind::If, kw.range());
  if (!tok().is(Tok::LParen)) {
    expectAfterPrev(Tok::LParen, "'if'");
    return nullptr;
  }
  const Token open = consume();
  s->cond = parseExpression();
  if (!s->cond) return nullptr;
  if (!expectClosing(Tok::RParen, open) && !tok().is(Tok::LBrace)) return nullptr;
  s->then = parseStatement();
  if (!s->then) return nullptr;
  if (accept(Tok::KwElse)) {
    // An `else if` continues a chain rather than nesting a level: long chains of cases are
    // common, and only the chain's length is bounded (the later passes recurse along it).
    if (tok().is(Tok::KwIf)) {
      if (elseChain_ >= kMaxElseChain) {
        diags_.report(DiagId::ErrElseChainTooLong, tok().loc).arg(kMaxElseChain).range(tok().range());
        while (!tok().is(Tok::Eof)) consume();  // every enclosing link would report again
        stopped_ = true;
        return nullptr;
      }
      ++elseChain_;
      s->otherwise = parseIf();
      --elseChain_;
    } else {
      s->otherwise = parseStatement();
    }
    if (!s->otherwise) return nullptr;
  }
  s->range.end = prev().end();
  return s;
}

// while := "while" "(" expr ")" stmt
StmtPtr Parser::parseWhile() {
  const Token kw = consume();
  auto s = std::make_unique<Stmt>(StmtKind::While, kw.range());
  if (!tok().is(Tok::LParen)) {
    expectAfterPrev(Tok::LParen, "'while'");
    return nullptr;
  }
  const Token open = consume();
  s->cond = parseExpression();
  if (!s->cond) return nullptr;
  if (!expectClosing(Tok::RParen, open) && !tok().is(Tok::LBrace)) return nullptr;
  s->body = parseStatement();
  if (!s->body) return nullptr;
  s->range.end = prev().end();
  return s;
}

// do := "do" stmt "while" "(" expr ")" ";"
StmtPtr Parser::parseDoWhile() {
  const Token kw = consume();
  auto s = std::make_unique<Stmt>(StmtKind::DoWhile, kw.range());
  s->body = parseStatement();
  if (!s->body) return nullptr;
  if (!tok().is(Tok::KwWhile)) {
    expectAfterPrev(Tok::KwWhile, "'do' statement");
    return nullptr;
  }
  consume();
  if (!tok().is(Tok::LParen)) {
    expectAfterPrev(Tok::LParen, "'while'");
    return nullptr;
  }
  const Token open = consume();
  s->cond = parseExpression();
  if (!s->cond || !expectClosing(Tok::RParen, open)) return nullptr;
  if (!expectAfterPrev(Tok::Semi, "do/while loop")) return nullptr;
  s->range.end = prev().end();
  return s;
}

// for := "for" "(" (decl | [expr]) ";" [expr] ";" [expr] ")" stmt
StmtPtr Parser::parseFor() {
  const Token kw = consume();
  auto s = std::make_unique<Stmt>(StmtKind::For, kw.range());
  if (!tok().is(Tok::LParen)) {
    expectAfterPrev(Tok::LParen, "'for'");
    return nullptr;
  }
  const Token open = consume();
  // A header in error (`for (a = 0, b = 10; ...)`: there is no comma operator) is reported once:
  // the rest of it is skipped to its ')', and the body is parsed for its own errors and dropped,
  // rather than the header's remains being read as statements.
  auto abandon = [&]() -> StmtPtr {
    if (stopped_) return nullptr;
    int depth = 0;
    while (!tok().is(Tok::Eof) && !tok().is(Tok::LBrace) && !tok().is(Tok::RBrace) && !atShaderHeader()) {
      if (tok().is(Tok::LParen)) ++depth;
      if (tok().is(Tok::RParen) && depth-- == 0) break;
      consume();
    }
    if (!accept(Tok::RParen)) return nullptr;
    if (!parseStatement()) recovering_ = true;
    auto empty = std::make_unique<Stmt>(StmtKind::Block, kw.range());
    empty->range.end = prev().end();
    return empty;
  };
  if (startsDeclaration()) {
    s->init = parseDeclaration();
    if (!s->init) return abandon();
  } else if (!tok().is(Tok::Semi)) {
    const SourceLoc start = tok().loc;
    ExprPtr e = parseExpression();
    if (!e) return abandon();
    s->init = std::make_unique<Stmt>(StmtKind::ExprStmt, join(start, prev().end()));
    s->init->expr = std::move(e);
  }
  if (!expectAfterPrev(Tok::Semi)) return abandon();
  if (!tok().is(Tok::Semi)) {
    s->cond = parseExpression();
    if (!s->cond) return abandon();
  }
  if (!expectAfterPrev(Tok::Semi)) return abandon();
  if (!tok().is(Tok::RParen)) {
    s->step = parseExpression();
    if (!s->step) return abandon();
  }
  if (!expectClosing(Tok::RParen, open)) return abandon();
  s->body = parseStatement();
  if (!s->body) return nullptr;
  s->range.end = prev().end();
  return s;
}

// return := "return" [expr] ";"
StmtPtr Parser::parseReturn() {
  const Token kw = consume();
  auto s = std::make_unique<Stmt>(StmtKind::Return, kw.range());
  if (!tok().is(Tok::Semi)) {
    s->expr = parseExpression();
    if (!s->expr) return nullptr;
  }
  // Kept without its ';', so that the function still counts as returning here.
  if (!expectAfterPrev(Tok::Semi, "return statement") && !missingSemiAtLineEnd()) recovering_ = true;
  s->range.end = prev().end();
  return s;
}

ExprPtr Parser::parseStandaloneExpression() {
  ExprPtr e = parseExpression();
  if (e && !tok().is(Tok::Eof)) {
    diags_.report(DiagId::ErrUnexpectedToken, tok().loc).arg(tokDescription(tok().kind));
    return nullptr;
  }
  return e;
}

ExprPtr Parser::parseExpression() { return parseAssignment(); }

// assign := cond [("=" | "+=" | "-=" | "*=" | "/=" | "%=") assign]
ExprPtr Parser::parseAssignment() {
  ExprPtr lhs = parseConditional();
  if (!lhs || !isAssignOp(tok().kind)) return lhs;
  const Token op = consume();
  ExprPtr rhs = parseAssignment();
  if (!rhs) return nullptr;
  auto e = std::make_unique<Expr>(ExprKind::Assign, join(lhs->range.begin, rhs->range.end));
  e->op = op.kind;
  e->opLoc = op.loc;
  e->opRange = op.range();
  e->operands.push_back(std::move(lhs));
  e->operands.push_back(std::move(rhs));
  return bounded(std::move(e));
}

// cond := binary ["?" expr ":" cond]
ExprPtr Parser::parseConditional() {
  ExprPtr c = parseBinary(1);
  if (!c || !tok().is(Tok::Question)) return c;
  const Token q = consume();
  ExprPtr a = parseExpression();
  if (!a) return nullptr;
  if (!tok().is(Tok::Colon)) {
    diags_.report(DiagId::ErrExpected, prev().end())
        .arg("':'")
        .note(DiagId::NoteToMatch, q.loc, {"?"});
    return nullptr;
  }
  consume();
  ExprPtr b = parseConditional();
  if (!b) return nullptr;
  auto e = std::make_unique<Expr>(ExprKind::Conditional, join(c->range.begin, b->range.end));
  e->opLoc = q.loc;
  e->opRange = q.range();
  e->operands.push_back(std::move(c));
  e->operands.push_back(std::move(a));
  e->operands.push_back(std::move(b));
  return bounded(std::move(e));
}

// binary := unary { binop unary }, by precedence climbing (all binary operators are left-assoc.)
ExprPtr Parser::parseBinary(int minPrec) {
  ExprPtr lhs = parseUnary();
  if (!lhs) return nullptr;
  for (;;) {
    const int prec = binaryPrecedence(tok().kind);
    if (prec == 0 || prec < minPrec) return lhs;
    const Token op = consume();
    ExprPtr rhs = parseBinary(prec + 1);
    if (!rhs) return nullptr;
    auto e = std::make_unique<Expr>(ExprKind::Binary, join(lhs->range.begin, rhs->range.end));
    e->op = op.kind;
    e->opLoc = op.loc;
    e->opRange = op.range();
    e->operands.push_back(std::move(lhs));
    e->operands.push_back(std::move(rhs));
    lhs = bounded(std::move(e));
    if (!lhs) return nullptr;
  }
}

// unary := ("-" | "+" | "!" | "++" | "--") unary | "(" type ")" unary | type unary | postfix
ExprPtr Parser::parseUnary() {
  struct Guard {
    int& n;
    ~Guard() { --n; }
  } guard{++nesting_};
  if (tooDeep("expressions")) return nullptr;
  const Token t = tok();
  if (t.is(Tok::Minus) || t.is(Tok::Plus) || t.is(Tok::Bang) || t.is(Tok::PlusPlus) ||
      t.is(Tok::MinusMinus)) {
    if (t.is(Tok::Minus)) unaryMinusOperand_ = pos_ + 1;
    consume();
    ExprPtr operand = parseUnary();
    if (!operand) return nullptr;
    const bool incDec = t.is(Tok::PlusPlus) || t.is(Tok::MinusMinus);
    auto e = std::make_unique<Expr>(incDec ? ExprKind::PreIncDec : ExprKind::Unary,
                                    join(t.loc, operand->range.end));
    e->op = t.kind;
    e->opLoc = t.loc;
    e->opRange = t.range();
    e->operands.push_back(std::move(operand));
    return bounded(std::move(e));
  }
  if (t.is(Tok::LParen) && isTypeKeyword(peek().kind) && peek(2).is(Tok::RParen)) {
    consume();
    const Token type = consume();
    consume();
    ExprPtr operand = parseUnary();
    if (!operand) return nullptr;
    auto e = std::make_unique<Expr>(ExprKind::Construct, join(t.loc, operand->range.end));
    e->constructType = typeOf(type.kind);
    e->isCast = true;
    e->opLoc = t.loc;
    e->opRange = join(t.loc, type.end().advanced(1));
    e->operands.push_back(std::move(operand));
    return bounded(std::move(e));
  }
  return parsePostfix();
}

// postfix := primary { "[" expr "]" | "++" | "--" }
ExprPtr Parser::parsePostfix() {
  ExprPtr e = parsePrimary();
  if (!e) return nullptr;
  for (;;) {
    if (tok().is(Tok::LBracket)) {
      const Token open = consume();
      ExprPtr index = parseExpression();
      if (!index) return nullptr;
      if (!expectClosing(Tok::RBracket, open)) return nullptr;
      auto ix = std::make_unique<Expr>(ExprKind::Index, join(e->range.begin, prev().end()));
      ix->opLoc = open.loc;
      ix->opRange = open.range();
      ix->operands.push_back(std::move(e));
      ix->operands.push_back(std::move(index));
      e = bounded(std::move(ix));
      if (!e) return nullptr;
    } else if (tok().is(Tok::PlusPlus) || tok().is(Tok::MinusMinus)) {
      const Token op = consume();
      auto inc = std::make_unique<Expr>(ExprKind::PostIncDec, join(e->range.begin, op.end()));
      inc->op = op.kind;
      inc->opLoc = op.loc;
      inc->opRange = op.range();
      inc->operands.push_back(std::move(e));
      e = bounded(std::move(inc));
      if (!e) return nullptr;
    } else {
      return e;
    }
  }
}

bool Parser::parseArguments(std::vector<ExprPtr>& args, const Token& open) {
  if (accept(Tok::RParen)) return true;
  for (;;) {
    ExprPtr a = parseAssignment();
    if (!a) return false;
    args.push_back(std::move(a));
    if (accept(Tok::Comma)) continue;
    return expectClosing(Tok::RParen, open);
  }
}

// constructor := type ["space-string"] "(" args ")" | type ["space-string"] unary
//                (prefix cast, e.g. float noise(P); RSL's matrix "shader" 1)
ExprPtr Parser::parseConstructor() {
  const Token type = consume();
  auto e = std::make_unique<Expr>(ExprKind::Construct, type.range());
  e->constructType = typeOf(type.kind);
  e->opLoc = type.loc;
  e->opRange = type.range();
  // A string after the type names a space (a string operand of a cast would be an error anyway).
  if (tok().is(Tok::StringLiteral) && !peek().is(Tok::Semi) && !peek().is(Tok::Comma) &&
      !peek().is(Tok::RParen)) {
    const Token space = consume();
    auto lit = std::make_unique<Expr>(ExprKind::StringLiteral, space.range());
    lit->text = Lexer::stringValue(space);
    e->operands.push_back(std::move(lit));
    e->spaceOutside = true;
  }
  if (tok().is(Tok::LParen)) {
    const Token open = consume();
    if (!parseArguments(e->operands, open)) return nullptr;
    e->range.end = prev().end();
    return bounded(std::move(e));
  }
  ExprPtr operand = parseUnary();
  if (!operand) return nullptr;
  e->isCast = !e->spaceOutside;  // with a space it is the constructor T("space", operand)
  e->range.end = operand->range.end;
  e->operands.push_back(std::move(operand));
  return bounded(std::move(e));
}

// primary := number | string | IDENT | IDENT "(" args ")" | "(" expr ")" | "(" expr "," ... ")"
//          | constructor
ExprPtr Parser::parsePrimary() {
  const Token t = tok();
  switch (t.kind) {
    case Tok::IntLiteral: {
      consume();
      // 2147483648 (the lexer's INT_MIN) fits only as the operand of a unary minus, as in C.
      if (t.intValue == INT32_MIN && !t.text.starts_with("0x") && !t.text.starts_with("0X") &&
          unaryMinusOperand_ != pos_ - 1)
        diags_.report(DiagId::ErrIntegerTooLarge, t.loc).range(t.range());
      auto e = std::make_unique<Expr>(ExprKind::IntLiteral, t.range());
      e->intValue = t.intValue;
      return e;
    }
    case Tok::FloatLiteral: {
      consume();
      auto e = std::make_unique<Expr>(ExprKind::FloatLiteral, t.range());
      e->floatValue = t.floatValue;
      return e;
    }
    case Tok::StringLiteral: {
      consume();
      auto e = std::make_unique<Expr>(ExprKind::StringLiteral, t.range());
      e->text = Lexer::stringValue(t);
      return e;
    }
    case Tok::Identifier: {
      consume();
      if (tok().is(Tok::LParen)) {
        const Token open = consume();
        auto e = std::make_unique<Expr>(ExprKind::Call, t.range());
        e->text = std::string(t.text);
        e->opRange = t.range();
        if (!parseArguments(e->operands, open)) return nullptr;
        e->range.end = prev().end();
        return bounded(std::move(e));
      }
      auto e = std::make_unique<Expr>(ExprKind::Identifier, t.range());
      e->text = std::string(t.text);
      e->opRange = t.range();
      return e;
    }
    case Tok::LParen: {
      const Token open = consume();
      const bool macroAroundArgument = !open.fromArgument && tok().fromArgument;
      ExprPtr first = parseExpression();
      if (!first) return nullptr;
      if (tok().is(Tok::Comma)) {
        auto tuple = std::make_unique<Expr>(ExprKind::Tuple, open.range());
        tuple->operands.push_back(std::move(first));
        while (accept(Tok::Comma)) {
          ExprPtr next = parseAssignment();
          if (!next) return nullptr;
          tuple->operands.push_back(std::move(next));
        }
        if (!expectClosing(Tok::RParen, open)) return nullptr;
        tuple->range.end = prev().end();
        return bounded(std::move(tuple));
      }
      // A missing ')' right before ';' is most likely just that: keep the expression.
      if (!expectClosing(Tok::RParen, open) && !tok().is(Tok::Semi)) return nullptr;
      // Parentheses leave no node; widen the range so carets cover them (unless a macro's
      // parentheses hold an argument written elsewhere: its own place says more).
      if (!macroAroundArgument) first->range = join(open.loc, prev().end());
      return first;
    }
    default:
      if (isTypeKeyword(t.kind)) return parseConstructor();
      errorExpectedExpression();
      return nullptr;
  }
}

}  // namespace relief::compiler
