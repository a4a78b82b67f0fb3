// Text dump of the syntax tree (tests, `reliefc --emit-ast`): one node per line, children indented;
// and the folding of integer constant expressions, which the parser (array lengths) and the type
// checker (-Winteger-division) share.
#include "compiler/ast.h"

namespace relief::compiler {

namespace {
void pad(std::ostream& out, int indent) {
  for (int i = 0; i < indent; ++i) out << "  ";
}
std::string typeSuffix(const Type& t) {
  return t.isError() ? std::string() : " : " + typeName(t);
}
void dumpDecl(std::ostream& out, const VarDecl& d, int indent, const char* what) {
  pad(out, indent);
  out << what << ' ';
  if (d.isOutput) out << "output ";
  if (d.isUniform) out << "uniform ";
  out << typeName(d.type) << ' ' << d.name << '\n';
  if (d.init) dump(out, *d.init, indent + 1);
}
}  // namespace

void dump(std::ostream& out, const Expr& e, int indent) {
  pad(out, indent);
  switch (e.kind) {
    case ExprKind::IntLiteral: out << "IntLiteral " << e.intValue; break;
    case ExprKind::FloatLiteral: out << "FloatLiteral " << e.floatValue; break;
    case ExprKind::StringLiteral: out << "StringLiteral \"" << e.text << '"'; break;
    case ExprKind::Identifier: out << "Identifier " << e.text; break;
    case ExprKind::Unary: out << "Unary " << tokSpelling(e.op); break;
    case ExprKind::PreIncDec: out << "PreIncDec " << tokSpelling(e.op); break;
    case ExprKind::PostIncDec: out << "PostIncDec " << tokSpelling(e.op); break;
    case ExprKind::Binary: out << "Binary " << tokSpelling(e.op); break;
    case ExprKind::Assign: out << "Assign " << tokSpelling(e.op); break;
    case ExprKind::Conditional: out << "Conditional"; break;
    case ExprKind::Call: out << "Call " << e.text; break;
    case ExprKind::Construct:
      out << (e.isCast ? "Cast " : "Construct ") << typeName(Type(e.constructType));
      if (!e.text.empty()) out << " \"" << e.text << '"';
      break;
    case ExprKind::Index: out << "Index"; break;
    case ExprKind::Tuple: out << "Tuple"; break;
    case ExprKind::InitList: out << "InitList"; break;
  }
  out << typeSuffix(e.type) << '\n';
  for (const ExprPtr& c : e.operands) dump(out, *c, indent + 1);
}

void dump(std::ostream& out, const Stmt& s, int indent) {
  pad(out, indent);
  switch (s.kind) {
    case StmtKind::Block:
      out << "Block\n";
      for (const StmtPtr& c : s.stmts) dump(out, *c, indent + 1);
      return;
    case StmtKind::Decl:
      out << "Decl\n";
      for (const auto& d : s.decls) dumpDecl(out, *d, indent + 1, "Var");
      return;
    case StmtKind::ExprStmt: out << "ExprStmt\n"; break;
    case StmtKind::If: out << "If\n"; break;
    case StmtKind::While: out << "While\n"; break;
    case StmtKind::DoWhile: out << "DoWhile\n"; break;
    case StmtKind::For: out << "For\n"; break;
    case StmtKind::Break: out << "Break\n"; return;
    case StmtKind::Continue: out << "Continue\n"; return;
    case StmtKind::Return: out << "Return\n"; break;
    case StmtKind::Empty: out << "Empty\n"; return;
    case StmtKind::FunctionDef:
      out << "FunctionDef\n";
      dump(out, *s.function, indent + 1);
      return;
    case StmtKind::Extern:
      out << "Extern\n";
      for (const auto& d : s.decls) dumpDecl(out, *d, indent + 1, "Var");
      return;
  }
  if (s.init) dump(out, *s.init, indent + 1);
  if (s.cond && s.kind != StmtKind::DoWhile) dump(out, *s.cond, indent + 1);
  if (s.expr) dump(out, *s.expr, indent + 1);
  if (s.step) dump(out, *s.step, indent + 1);
  if (s.then) dump(out, *s.then, indent + 1);
  if (s.otherwise) {
    pad(out, indent);
    out << "Else\n";
    dump(out, *s.otherwise, indent + 1);
  }
  if (s.body) dump(out, *s.body, indent + 1);
  if (s.cond && s.kind == StmtKind::DoWhile) dump(out, *s.cond, indent + 1);
}

void dump(std::ostream& out, const FunctionDecl& f, int indent) {
  pad(out, indent);
  out << "Function " << typeName(f.returnType) << ' ' << f.name << '\n';
  for (const auto& p : f.params) dumpDecl(out, *p, indent + 1, "Param");
  if (f.body) dump(out, *f.body, indent + 1);
}

void dump(std::ostream& out, const TranslationUnit& unit) {
  for (const auto& f : unit.functions) dump(out, *f);
  for (const auto& sh : unit.shaders) {
    out << "Shader " << sh->name << '\n';
    for (const auto& p : sh->params) dumpDecl(out, *p, 1, "Param");
    if (sh->body) dump(out, *sh->body, 1);
  }
}

bool foldIntConstant(const Expr& e, int64_t* value) {
  int64_t a = 0, b = 0;
  switch (e.kind) {
    case ExprKind::IntLiteral: *value = e.intValue; return true;
    case ExprKind::Unary:
      if ((e.op != Tok::Minus && e.op != Tok::Plus) || !foldIntConstant(*e.operands[0], &a)) return false;
      *value = e.op == Tok::Minus ? -a : a;
      break;
    case ExprKind::Binary:
      if (!foldIntConstant(*e.operands[0], &a) || !foldIntConstant(*e.operands[1], &b)) return false;
      switch (e.op) {
        case Tok::Plus: *value = a + b; break;
        case Tok::Minus: *value = a - b; break;
        case Tok::Star: *value = a * b; break;
        case Tok::Slash: *value = b ? a / b : 0; break;  // int division by 0 is 0 (§4.1)
        case Tok::Percent: *value = b ? a % b : 0; break;
        default: return false;
      }
      break;
    default: return false;
  }
  return *value >= INT32_MIN && *value <= INT32_MAX;
}
}  // namespace relief::compiler
