// The syntax tree: nodes own their children through unique_ptr; the type checker annotates them in
// place (types, resolved declarations, builtins). dump() prints a stable text form for tests and
// `reliefc --emit-ast`.
#pragma once

#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "compiler/builtins.h"
#include "compiler/source_manager.h"
#include "compiler/token.h"
#include "compiler/types.h"

namespace relief::compiler {

struct VarDecl;
struct Stmt;
struct Expr;
struct FunctionDecl;
using ExprPtr = std::unique_ptr<Expr>;
using StmtPtr = std::unique_ptr<Stmt>;

enum class ExprKind : uint8_t {
  IntLiteral,     // intValue
  FloatLiteral,   // floatValue
  StringLiteral,  // text (decoded)
  Identifier,     // text; sema: decl
  Unary,          // op (Minus, Plus, Bang), operands[0]
  PreIncDec,      // op (PlusPlus, MinusMinus), operands[0]
  PostIncDec,     // op, operands[0]
  Binary,         // op, operands[0..1]
  Assign,         // op (Assign or a compound), operands[0] = target, [1] = value
  Conditional,    // operands[0] ? [1] : [2]
  Call,           // text = callee, operands = arguments; sema: builtin
  Construct,      // constructType(operands) / cast; text = space literal (may be empty)
  Index,          // operands[0][operands[1]]
  Tuple,          // (a, b, c)
  InitList,       // { a, b, ... }: array initializers only
};

struct Expr {
  ExprKind kind;
  SourceRange range;  // whole expression
  SourceLoc opLoc;    // operator / callee name / type keyword: where diagnostics point
  SourceRange opRange;
  Tok op = Tok::Eof;
  int32_t intValue = 0;
  float floatValue = 0;
  std::string text;
  TypeKind constructType = TypeKind::Error;
  bool isCast = false;  // (T) e or prefix T e: numeric conversion
  // RSL's T "space" (…) or T "space" e, the space written before the operands (for a matrix it
  // means what the RI spec says: current→space, then the given matrix; see codegen).
  bool spaceOutside = false;
  uint32_t depth = 1;   // height of this subtree (the parser bounds it; later passes recurse)
  std::vector<ExprPtr> operands;

  // Filled in by the type checker.
  Type type;
  VarDecl* decl = nullptr;
  const BuiltinInfo* builtin = nullptr;
  const FunctionDecl* function = nullptr;  // a resolved user function call
  bool isVarying = true;
  bool matrixRow = false;  // the inner `m[i]` of `m[i][j]` (only valid as that)

  Expr(ExprKind k, SourceRange r) : kind(k), range(r), opLoc(r.begin) {}
};

enum class Storage : uint8_t { Global, Parameter, Local };

// Globals of §5 in the order codegen loads them.
enum class GlobalId : uint8_t { P, N, Ng, dPdu, dPdv, u, v, s, t, du, dv, PI, Count };

struct VarDecl {
  std::string name;
  SourceRange nameRange;
  Type type;
  ExprPtr init;
  Storage storage = Storage::Local;
  GlobalId global = GlobalId::Count;
  bool isOutput = false;
  bool isUniform = false;  // explicitly declared uniform
  bool writable = true;
  bool invalid = false;  // its initializer failed to parse or check: declared, never diagnosed again
  VarDecl* externTarget = nullptr;  // `extern` declarations: the variable they refer to

  // Filled in by the type checker.
  unsigned reads = 0;
  bool written = false;
  // A shader parameter whose default reads coordinate spaces (`point "shader" (0, 0, 0)`) or
  // another parameter: evaluated at shading time, with the batch's spaces and the parameters'
  // values, unless the host binds the parameter itself.
  bool defaultAtShadingTime = false;
};

enum class StmtKind : uint8_t {
  Block,     // stmts
  Decl,      // decls
  ExprStmt,  // expr
  If,        // cond, then, otherwise
  While,     // cond, body
  DoWhile,   // body, cond
  For,       // init (Decl/ExprStmt/null), cond (may be null), step (may be null), body
  Break,
  Continue,
  Return,  // expr (may be null)
  Empty,
  FunctionDef,  // function (a nested function definition)
  Extern,       // decls: the names it imports (type as declared; sema: externTarget)
};

struct Stmt {
  StmtKind kind;
  SourceRange range;
  SourceLoc keywordLoc;
  std::vector<StmtPtr> stmts;
  std::vector<std::unique_ptr<VarDecl>> decls;
  ExprPtr expr;
  ExprPtr cond;
  ExprPtr step;
  StmtPtr init;
  StmtPtr then;
  StmtPtr otherwise;
  StmtPtr body;
  std::unique_ptr<FunctionDecl> function;
  int levels = 1;  // break/continue: RSL's `break n` leaves the n-th enclosing loop
  // A declaration or expression that stopped short of its ';' mid-line (`float g = a.5;` is
  // `a` `.5`): its expressions are what the parser made of a syntax error, so they are checked
  // without diagnostics (language.md §8: one error per mistake).
  bool unterminated = false;

  Stmt(StmtKind k, SourceRange r) : kind(k), range(r), keywordLoc(r.begin) {}
};

struct ShaderDecl {
  uint32_t parseOrder = 0;  // position among top-level definitions (functions precede their use)
  std::string name;
  SourceLoc keywordLoc;
  SourceRange nameRange;
  std::vector<std::unique_ptr<VarDecl>> params;
  StmtPtr body;
  bool hadSyntaxErrors = false;  // parts may be missing: no unused/uninitialized warnings for it

  // Filled in by the type checker: host contract of §5 (append N = normalize(calculatenormal(P))).
  bool assignsP = false;
  bool assignsN = false;
  // Some write of N may leave it other than the displaced surface's own normal (a bump: anything
  // but `N = calculatenormal(P)` or `N = normalize(calculatenormal(P))`, or displace()).
  bool ownNormal = false;
};

// function := (type | "void") IDENT "(" [formals] ")" block
struct FunctionDecl {
  uint32_t parseOrder = 0;
  Type returnType;
  std::string name;
  SourceLoc begin;
  SourceRange nameRange;
  std::vector<std::unique_ptr<VarDecl>> params;
  StmtPtr body;

  // Filled in by the type checker: what a call may write (propagates the §5 host contract).
  bool writesP = false;
  bool writesN = false;
  bool writesOwnN = false;  // as ShaderDecl::ownNormal
  // Its calls are varying whatever the arguments (§2): it reads a global other than PI or an
  // enclosing variable, or uses a varying-only built-in, itself or through its callees.
  bool readsVarying = false;
  // Defined in stdlib/ (prelude.h): shared by all compilations, its locations are not the user's.
  bool isLibrary = false;
  bool bodyHadErrors = false;  // parse errors in the body: its paths are not judged (no follow-ons)
  // Expression nodes a call expands to once inlined (its body plus its callees', transitively).
  uint64_t inlineCost = 0;
  // The call in its body (and its callee) that first took inlineCost past the compiler's limit:
  // where a too-large expansion is explained.
  SourceRange overLimitCall;
  const FunctionDecl* overLimitCallee = nullptr;
  // The longest chain of user-function calls from its body, itself counted: code generation
  // inlines through it recursively, so it is bounded (TypeChecker::kMaxCallDepth).
  uint32_t callDepth = 1;
};

struct TranslationUnit {
  std::string fileName;
  std::vector<std::unique_ptr<ShaderDecl>> shaders;
  // File-scope functions; with shaders, checked in source order (functions precede their use).
  std::vector<std::unique_ptr<FunctionDecl>> functions;
  // The §5 globals, created by the type checker; identifiers resolve to these.
  std::vector<std::unique_ptr<VarDecl>> globals;
};

void dump(std::ostream& out, const TranslationUnit& unit);
void dump(std::ostream& out, const FunctionDecl& f, int indent = 0);
void dump(std::ostream& out, const Expr& e, int indent = 0);
void dump(std::ostream& out, const Stmt& s, int indent = 0);

// The value of an integer constant expression (int literals under + - * / % and unary - +, as
// after macro expansion `N * 2 + 1`, division by 0 giving 0 as §4.1 says); false for anything
// else or a result outside int.
bool foldIntConstant(const Expr& e, int64_t* value);

}  // namespace relief::compiler
