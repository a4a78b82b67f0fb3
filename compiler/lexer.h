// Lexer of .disp source (language.md §1): comments, identifiers/keywords, numbers, strings,
// punctuators. Reports lexical errors to the diagnostics engine and keeps going.
#pragma once

#include <string>
#include <vector>

#include "compiler/diagnostics.h"
#include "compiler/source_manager.h"
#include "compiler/token.h"

namespace relief::compiler {

class Lexer {
 public:
  Lexer(const SourceManager& sm, SourceManager::FileId file, DiagnosticsEngine& diags);
  Token next();
  // Lexes the whole buffer; the last token is Eof.
  std::vector<Token> lexAll();
  // Decoded contents of a string literal token (escapes resolved; bad escapes already reported).
  static std::string stringValue(const Token& token);
  // While quiet, lexical errors are not reported (groups skipped by #if).
  void setQuiet(bool quiet) { quiet_ = quiet; }

 private:
  void skipWhitespaceAndComments();
  Token make(Tok kind, const char* start);
  Token lexNumber(const char* start);
  Token lexString(const char* start);
  // Locations are physical: past a backslash-newline the lexer's text runs ahead of the file's.
  SourceLoc locOf(const char* p) const {
    const uint32_t offset = uint32_t(p - begin_);
    return base_.advanced(spliced_ ? sm_.physicalOffset(file_, offset) : offset);
  }

  const SourceManager& sm_;
  SourceManager::FileId file_;
  bool cutShort_ = false;  // an unterminated comment ran to the end of the file
  bool spliced_ = false;  // the text had backslash-newlines, removed before lexing (§1.1)
  DiagnosticsEngine& diags_;
  const char* begin_;
  const char* cur_;
  const char* end_;
  SourceLoc base_;
  bool atLineStart_ = true;
  bool quiet_ = false;
  DiagnosticsEngine quietSink_;
  DiagnosticsEngine& sink() { return quiet_ ? quietSink_ : diags_; }
};

}  // namespace relief::compiler
