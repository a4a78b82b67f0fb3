// Recursive-descent parser with precedence climbing for .disp files (language.md §3, §4). Reports
// syntax errors and resynchronizes at ';', '}' or a top-level keyword, so one run reports several.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "compiler/ast.h"
#include "compiler/diagnostics.h"
#include "compiler/source_manager.h"
#include "compiler/token.h"

namespace relief::compiler {

// Bounds that keep the recursive passes (parser, type checker, codegen) within the stack on
// hostile input: nested parentheses/blocks, and the height of expression trees built by loops.
// Long operator chains (`a + b + ... + z`, generated code) parse iteratively but make tall trees,
// so their bound is higher; compiles run on a 256 MiB stack (compiler.cpp), where a level costs
// a few KiB even in a sanitizer build.
inline constexpr int kMaxNesting = 256;
inline constexpr uint32_t kMaxExpressionDepth = 16384;
// `else if` links being parsed at once; they do not count as nesting.
inline constexpr int kMaxElseChain = 4096;

class Parser {
 public:
  // Parses already preprocessed tokens (ending with Eof).
  Parser(std::vector<Token> tokens, std::string fileName, DiagnosticsEngine& diags);
  // Lexes `file` itself, without preprocessing (tests).
  Parser(const SourceManager& sm, SourceManager::FileId file, DiagnosticsEngine& diags);
  std::unique_ptr<TranslationUnit> parseTranslationUnit();
  // Parses a single expression (tests); null after an error.
  ExprPtr parseStandaloneExpression();

 private:
  const Token& tok() const { return toks_[pos_]; }
  const Token& peek(size_t n = 1) const { return toks_[std::min(pos_ + n, toks_.size() - 1)]; }
  const Token& prev() const { return toks_[pos_ ? pos_ - 1 : 0]; }
  Token consume() { return toks_[pos_ < toks_.size() - 1 ? pos_++ : pos_]; }
  bool accept(Tok k);
  // At an end of file that an unterminated comment or macro call brought early (the Eof token is
  // then `malformed`): that error is the one to read, not what the parser misses after it.
  bool cutShort() const { return tok().is(Tok::Eof) && tok().malformed; }
  // Reports "expected X" one column past the previous token (missing closers and ';').
  bool expectAfterPrev(Tok k, const char* context = nullptr);
  bool expectClosing(Tok k, const Token& opener);
  void errorExpectedExpression();
  bool missingSemiAtLineEnd() const;
  void syncStatement();
  void skipBadCharacters();
  bool atShaderHeader() const;
  void syncTopLevel();
  bool isTypeKeyword(Tok k) const;
  bool startsDeclaration() const;
  static std::string closestTypeName(std::string_view word);
  // Whether tokens [from, to) include text the lexer already rejected (a dropped character, a
  // string that swallowed the rest of its line): code the parser never saw.
  bool lexedBadly(size_t from, size_t to) const;
  TypeKind typeOf(Tok k) const;

  void parseShader();
  std::unique_ptr<FunctionDecl> parseFunction();
  StmtPtr parseExtern();
  bool parseFormals(std::vector<std::unique_ptr<VarDecl>>& params);
  bool keywordAfterComma(Storage storage) const;
  bool parseDeclarators(std::vector<std::unique_ptr<VarDecl>>& out, Type type, bool isOutput,
                        bool isUniform, Storage storage);

  StmtPtr parseStatement();
  StmtPtr parseBlock();
  StmtPtr parseDeclaration();
  StmtPtr parseIf();
  StmtPtr parseWhile();
  StmtPtr parseDoWhile();
  StmtPtr parseFor();
  StmtPtr parseReturn();

  ExprPtr parseExpression();
  ExprPtr parseAssignment();
  ExprPtr parseConditional();
  ExprPtr parseBinary(int minPrec);
  ExprPtr parseUnary();
  ExprPtr parsePostfix();
  ExprPtr parsePrimary();
  ExprPtr parseConstructor();
  bool parseArguments(std::vector<ExprPtr>& args, const Token& open);

  DiagnosticsEngine& diags_;
  std::vector<Token> toks_;
  size_t pos_ = 0;
  size_t unaryMinusOperand_ = SIZE_MAX;  // token position right after the latest unary minus
  std::unique_ptr<TranslationUnit> unit_;
  bool recovering_ = false;  // a statement was kept despite an error: resync after it
  int nesting_ = 0;          // recursion depth of statements and unary expressions
  int elseChain_ = 0;        // `else if` links being parsed (kMaxElseChain)
  bool stopped_ = false;     // gave up on the file (nesting limit): report nothing more
  bool tooDeep(const char* what);
  ExprPtr bounded(ExprPtr e);
};

}  // namespace relief::compiler
