// Lexer unit tests: token kinds, values, source ranges and lexical errors (language.md §1).
#include <gtest/gtest.h>

#include "compiler/diagnostics.h"
#include "compiler/lexer.h"
#include "compiler/source_manager.h"

namespace relief::compiler {
namespace {

struct Lexed {
  SourceManager sm;
  DiagnosticsEngine diags;
  std::vector<Token> tokens;
  std::vector<std::string> messages;  // "line:col: message"
};

std::unique_ptr<Lexed> lex(const std::string& text) {
  auto r = std::make_unique<Lexed>();
  const auto id = r->sm.addBuffer("l.disp", text);
  r->tokens = Lexer(r->sm, id, r->diags).lexAll();
  for (const Diagnostic& d : r->diags.sorted()) {
    const PresumedLoc p = r->sm.presumed(d.loc);
    r->messages.push_back(std::to_string(p.line) + ":" + std::to_string(p.column) + ": " + d.message);
  }
  return r;
}

std::vector<Tok> kinds(const Lexed& l) {
  std::vector<Tok> out;
  for (const Token& t : l.tokens) out.push_back(t.kind);
  return out;
}

TEST(LexerTest, KeywordsIdentifiersAndPunctuators) {
  auto l = lex("displacement foo(float Km = 1; point P2) { P += N ^ dPdu . v; x != y && !z || a <= b; }");
  EXPECT_TRUE(l->messages.empty());
  const std::vector<Tok> expected = {
      Tok::KwDisplacement, Tok::Identifier, Tok::LParen,    Tok::KwFloat,   Tok::Identifier, Tok::Assign,
      Tok::IntLiteral,     Tok::Semi,       Tok::KwPoint,   Tok::Identifier, Tok::RParen,    Tok::LBrace,
      Tok::Identifier,     Tok::PlusAssign, Tok::Identifier, Tok::Caret,    Tok::Identifier, Tok::Dot,
      Tok::Identifier,     Tok::Semi,       Tok::Identifier, Tok::NotEq,    Tok::Identifier, Tok::AmpAmp,
      Tok::Bang,           Tok::Identifier, Tok::PipePipe,  Tok::Identifier, Tok::LessEq,   Tok::Identifier,
      Tok::Semi,           Tok::RBrace,     Tok::Eof};
  EXPECT_EQ(kinds(*l), expected);
}

// A UTF-8 byte-order mark at the start (as Windows editors save) is skipped; elsewhere U+FEFF is
// an invalid character like any other.
TEST(LexerTest, ByteOrderMarkAtTheStartIsSkipped) {
  auto l = lex("\xEF\xBB\xBF" "float x;");
  EXPECT_TRUE(l->messages.empty());
  EXPECT_EQ(kinds(*l), (std::vector<Tok>{Tok::KwFloat, Tok::Identifier, Tok::Semi, Tok::Eof}));
  EXPECT_EQ(lex("float \xEF\xBB\xBF" "x;")->messages.size(), 1u);
}

TEST(LexerTest, NumbersAndTheDotRule) {
  auto l = lex("1 1.0 1. .5 1e3 2.5e-3 0x1F a.5 7ex");
  ASSERT_TRUE(l->messages.empty());
  const auto& t = l->tokens;
  EXPECT_EQ(t[0].kind, Tok::IntLiteral);
  EXPECT_EQ(t[0].intValue, 1);
  EXPECT_EQ(t[1].kind, Tok::FloatLiteral);
  EXPECT_EQ(t[2].kind, Tok::FloatLiteral);
  EXPECT_FLOAT_EQ(t[2].floatValue, 1.0f);
  EXPECT_FLOAT_EQ(t[3].floatValue, 0.5f);
  EXPECT_FLOAT_EQ(t[4].floatValue, 1000.0f);
  EXPECT_FLOAT_EQ(t[5].floatValue, 0.0025f);
  EXPECT_EQ(t[6].intValue, 31);
  // `a.5` is `a` `.5`.
  EXPECT_EQ(t[7].kind, Tok::Identifier);
  EXPECT_EQ(t[8].kind, Tok::FloatLiteral);
  EXPECT_FLOAT_EQ(t[8].floatValue, 0.5f);
  // `7ex` is the number 7 followed by the identifier ex (the parser reports it).
  EXPECT_EQ(t[9].kind, Tok::IntLiteral);
  EXPECT_EQ(t[10].kind, Tok::Identifier);
  // An exponent without digits is an invalid literal, one error at the lexer.
  auto bad = lex("1e; 2e+ 3");
  ASSERT_EQ(bad->messages.size(), 2u);
  EXPECT_EQ(bad->messages[0], "1:1: invalid numeric literal '1e'");
  EXPECT_EQ(bad->messages[1], "1:5: invalid numeric literal '2e+'");
}

TEST(LexerTest, IntegerOverflowIsAnError) {
  auto l = lex("\n  4294967296 2147483647");
  ASSERT_EQ(l->messages.size(), 1u);
  EXPECT_EQ(l->messages[0], "2:3: integer literal is too large to be represented in 32 bits");
  EXPECT_EQ(l->tokens[1].intValue, 2147483647);
}

TEST(LexerTest, TokensCarryRanges) {
  auto l = lex("  foo\n\tbar_2 ");
  const Token& bar = l->tokens[1];
  EXPECT_EQ(bar.text, "bar_2");
  const PresumedLoc p = l->sm.presumed(bar.loc);
  EXPECT_EQ(p.line, 2u);
  EXPECT_EQ(p.column, 2u);  // a tab counts one column
  EXPECT_EQ(bar.range().end.offset - bar.range().begin.offset, 5u);
}

TEST(LexerTest, StringsAndEscapes) {
  auto l = lex(R"("a\tb\"c\\" "bad\q")");
  ASSERT_EQ(l->messages.size(), 1u);
  EXPECT_EQ(l->messages[0], "1:17: unknown escape sequence '\\q'");
  EXPECT_EQ(Lexer::stringValue(l->tokens[0]), "a\tb\"c\\");
}

TEST(LexerTest, UnterminatedStringIsReportedAtTheQuote) {
  auto l = lex("x = \"abc\ny");
  ASSERT_EQ(l->messages.size(), 1u);
  EXPECT_EQ(l->messages[0], "1:5: missing terminating '\"' character");
  EXPECT_EQ(l->tokens.back().kind, Tok::Eof);
  EXPECT_EQ(l->tokens[l->tokens.size() - 2].text, "y");
}

TEST(LexerTest, CommentsAndUnterminatedComment) {
  auto ok = lex("a // line\n/* block\n * still */ b");
  EXPECT_TRUE(ok->messages.empty());
  ASSERT_EQ(ok->tokens.size(), 3u);
  EXPECT_EQ(ok->tokens[1].text, "b");

  auto bad = lex("a\n  /* never closed");
  ASSERT_EQ(bad->messages.size(), 1u);
  EXPECT_EQ(bad->messages[0], "2:3: unterminated /* comment");
}

TEST(LexerTest, BadCharactersAreReportedAndSkipped) {
  auto l = lex("a @ b $ c");
  ASSERT_EQ(l->messages.size(), 2u);
  EXPECT_EQ(l->messages[0], "1:3: invalid character '@' in source");
  EXPECT_EQ(l->messages[1], "1:7: invalid character '$' in source");
  EXPECT_EQ(l->tokens[2].text, "b");

  // A non-ASCII character is one error naming its code point; a byte that is not UTF-8 is named
  // by its value, so messages stay valid UTF-8.
  auto u = lex("caf\xC3\xA9 \xF0\x9F\x98\x80 x\xE9 \xC3");
  ASSERT_EQ(u->messages.size(), 4u);
  EXPECT_EQ(u->messages[0], "1:4: invalid character '\xC3\xA9' (U+00E9) in source");
  EXPECT_EQ(u->messages[1], "1:7: invalid character '\xF0\x9F\x98\x80' (U+1F600) in source");
  EXPECT_EQ(u->messages[2], "1:13: invalid byte 0xE9 in source (not UTF-8)");
  EXPECT_EQ(u->messages[3], "1:15: invalid byte 0xC3 in source (not UTF-8)");
  EXPECT_EQ(u->tokens[0].text, "caf");
  EXPECT_EQ(u->tokens[1].text, "\xC3\xA9");
}

TEST(LexerTest, ReservedWordsAndShaderKinds) {
  auto l = lex("gather surface illuminance light volume");
  EXPECT_EQ(l->tokens[0].kind, Tok::ReservedWord);
  EXPECT_EQ(l->tokens[1].kind, Tok::ShaderKindWord);
  EXPECT_EQ(l->tokens[2].kind, Tok::ReservedWord);
  EXPECT_EQ(l->tokens[3].kind, Tok::ShaderKindWord);
}

TEST(LexerTest, CrLfAndCrLineEndings) {
  auto l = lex("a\r\nb\rc");
  EXPECT_EQ(l->sm.presumed(l->tokens[1].loc).line, 2u);
  EXPECT_EQ(l->sm.presumed(l->tokens[2].loc).line, 3u);
  EXPECT_EQ(l->sm.presumed(l->tokens[2].loc).column, 1u);
}

TEST(LexerTest, BackslashNewlineSplicesLines) {
  // A splice joins lines before tokenizing (§1.1), even inside a token; locations stay physical.
  auto l = lex("fo\\\no = \\\r\n\"a\\\nb\" +\n  @ x");
  ASSERT_EQ(l->messages.size(), 1u);
  EXPECT_EQ(l->messages[0], "5:3: invalid character '@' in source");
  EXPECT_EQ(l->tokens[0].kind, Tok::Identifier);
  EXPECT_EQ(l->tokens[0].text, "foo");
  EXPECT_EQ(l->sm.presumed(l->tokens[1].loc).line, 2u);
  EXPECT_EQ(l->sm.presumed(l->tokens[1].loc).column, 3u);
  EXPECT_EQ(Lexer::stringValue(l->tokens[2]), "ab");
  EXPECT_FALSE(l->tokens[2].atLineStart);  // still the logical line of `fo\`
  EXPECT_EQ(l->sm.presumed(l->tokens[3].loc).line, 4u);
  EXPECT_TRUE(l->tokens[4].atLineStart);
  EXPECT_EQ(l->tokens[5].text, "x");
  EXPECT_EQ(l->sm.presumed(l->tokens[5].loc).column, 5u);
  // A backslash not followed by a line end is still an invalid character.
  auto bad = lex("a \\ b");
  ASSERT_EQ(bad->messages.size(), 1u);
  EXPECT_EQ(bad->messages[0], "1:3: invalid character '\\' in source");
}

}  // namespace
}  // namespace relief::compiler
