// Type checker implementation (see typecheck.h). One pass per shader: parameters, then the body.
// Context-typed calls (noise, §6.1) receive an expected type from their parent expression.
#include "compiler/typecheck.h"

#include "compiler/prelude.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

namespace relief::compiler {

namespace {

// RSL's surface-shading globals (language.md 5 names them), which displacement shaders lack:
// their undeclared uses get a note saying why.
const std::set<std::string> kRslGlobals = {"I",  "E",  "L",  "Cl",   "Ol",    "Cs",      "Os",
                                           "Ci", "Oi", "time", "dtime", "dPdtime", "ncomps", "alpha"};

const Type kError{};
const Type kVoid{TypeKind::Void};
const Type kInt{TypeKind::Int};
const Type kFloat{TypeKind::Float};
const Type kVector{TypeKind::Vector};

bool isArithmetic(Tok op) {
  return op == Tok::Plus || op == Tok::Minus || op == Tok::Star || op == Tok::Slash;
}
Tok compoundBase(Tok op) {
  switch (op) {
    case Tok::PlusAssign: return Tok::Plus;
    case Tok::MinusAssign: return Tok::Minus;
    case Tok::StarAssign: return Tok::Star;
    case Tok::SlashAssign: return Tok::Slash;
    case Tok::PercentAssign: return Tok::Percent;
    default: return Tok::Eof;
  }
}

// Result of `a op b`, or kError when the operands do not fit (not reported here).
Type binaryResult(Tok op, Type a, Type b) {
  if (a.isArray() || b.isArray()) return kError;
  const bool am = a.kind == TypeKind::Matrix, bm = b.kind == TypeKind::Matrix;
  if (am || bm) {
    // §4.1: m*m, m/m (= m·inverse), m*f, f*m, m/f; == and != compare all elements. Also RSL's
    // f/m = f·inverse(m) (`1/m` is how RSL spells the inverse).
    const Type m{TypeKind::Matrix};
    switch (op) {
      case Tok::Star: return (am || a.isScalar()) && (bm || b.isScalar()) ? m : kError;
      case Tok::Slash: return (am || a.isScalar()) && (bm || b.isScalar()) ? m : kError;
      case Tok::EqEq:
      case Tok::NotEq: return (am || a.isScalar()) && (bm || b.isScalar()) ? kInt : kError;
      default: return kError;
    }
  }
  const bool strings = a.kind == TypeKind::String && b.kind == TypeKind::String;
  switch (op) {
    case Tok::AmpAmp:
    case Tok::PipePipe:
    case Tok::Less:
    case Tok::LessEq:
    case Tok::Greater:
    case Tok::GreaterEq: return a.isScalar() && b.isScalar() ? kInt : kError;
    case Tok::EqEq:
    case Tok::NotEq:
      if (strings) return kInt;
      if (!a.isNumeric() || !b.isNumeric()) return kError;
      if (a.isTriple() && b.isTriple() && (a.isSpatial() != b.isSpatial())) return kError;
      return kInt;
    case Tok::Dot:
      if ((a.isSpatial() && b.isSpatial()) ||
          (a.kind == TypeKind::Color && b.kind == TypeKind::Color && !a.isArray()))
        return kFloat;
      return kError;
    case Tok::Caret: return a.isSpatial() && b.isSpatial() ? kVector : kError;
    case Tok::Percent: return a.kind == TypeKind::Int && b.kind == TypeKind::Int ? kInt : kError;
    case Tok::Plus:
    case Tok::Minus:
    case Tok::Star:
    case Tok::Slash:
      if (!a.isNumeric() || !b.isNumeric()) return kError;
      if (a.isScalar() && b.isScalar())
        return a.kind == TypeKind::Int && b.kind == TypeKind::Int ? kInt : kFloat;
      if (a.isScalar()) return b;
      if (b.isScalar()) return a;
      if (a.kind == TypeKind::Color || b.kind == TypeKind::Color)
        return a.kind == b.kind ? a : kError;
      if (op == Tok::Plus || op == Tok::Minus)
        return Type(spatialSum(a.kind, b.kind, op == Tok::Minus));
      return a.kind == b.kind ? a : kVector;
    default: return kError;
  }
}

// Walks the chain §6.1 inspects (parentheses leave no node).
bool hasContextCall(const Expr& e) {
  switch (e.kind) {
    case ExprKind::Call: {
      const BuiltinInfo* b = findBuiltin(e.text);
      return b && (b->shape == BuiltinShape::Noise || b->shape == BuiltinShape::Texture ||
                   b->shape == BuiltinShape::Random || b->shape == BuiltinShape::PNoise);
    }
    // A tuple is typed by context the same way (§2.2), wherever it stands in the chain.
    case ExprKind::Tuple: return e.operands.size() == 3;
    case ExprKind::Unary: return e.op == Tok::Minus && hasContextCall(*e.operands[0]);
    case ExprKind::Conditional:
      return hasContextCall(*e.operands[1]) || hasContextCall(*e.operands[2]);
    case ExprKind::Binary:
      return isArithmetic(e.op) &&
             (hasContextCall(*e.operands[0]) || hasContextCall(*e.operands[1]));
    default: return false;
  }
}

// The expected type a context-typed operand gets from a `+ - * /` whose other operand has type
// `other`; `outer` is the parent's own expectation.
Type contextHint(Tok op, Type other, Type outer) {
  if (other.isTriple()) return (op == Tok::Plus || op == Tok::Minus) ? other : kFloat;
  return outer;
}

std::string typeList(const std::vector<ExprPtr>& args) {
  std::string out;
  for (size_t i = 0; i < args.size(); ++i) {
    if (i) out += ", ";
    out += typeName(args[i]->type);
  }
  return out;
}

bool isKnownSpace(const std::string& s) {
  return s == "current" || s == "world" || s == "common" || s == "object" || s == "shader" ||
         s == "camera";
}

class Checker;

// The expression an Index chain (`a[i]`, `v[1]`, `m[i][j]`) starts from: the variable an lvalue
// writes when it is an Identifier with a declaration.
const Expr& indexRoot(const Expr& e) {
  const Expr* base = &e;
  while (base->kind == ExprKind::Index) base = base->operands[0].get();
  return *base;
}

// -Wuninitialized (§8): a local without initializer read on some path before any assignment.
// Definite-assignment analysis over the checked AST; loop bodies may not run, `return`/`break`/
// `continue` end a path, and an `output` argument (of a user function or a setter such as
// `setxcomp`) counts as an assignment. Arrays are exempt. As in clang, writing one component or
// element (`v[1] = 2`) neither reads the variable nor leaves it partly uninitialized.
class UninitializedAnalysis {
 public:
  explicit UninitializedAnalysis(Checker& checker) : checker_(checker) {}
  void stmt(const Stmt& s);

 private:
  struct State {
    std::set<const VarDecl*> assigned;  // on every path here
    std::set<const VarDecl*> maybe;     // on some path here (for the wording of the warning)
    bool dead = false;  // the path ended: it constrains nothing at a join
  };
  static State join(const State& a, const State& b) {
    if (a.dead) return b;
    if (b.dead) return a;
    State r;
    for (const VarDecl* d : a.assigned)
      if (b.assigned.count(d)) r.assigned.insert(d);
    r.maybe = a.maybe;
    r.maybe.insert(b.maybe.begin(), b.maybe.end());
    return r;
  }
  void expr(const Expr& e);
  // Analyses a condition: the states where it is true and where it is false. `k > 0 && (r = 1)`
  // assigns r where it is true, though not where it is false.
  void cond(const Expr& e, State* whenTrue, State* whenFalse);
  void readIndices(const Expr& target);
  void assignTarget(const Expr& target);

  // A loop condition that is a nonzero literal (`while (1)`) or absent (`for (;;)`): the loop
  // is left only through break (or return).
  static bool alwaysTrue(const Expr* cond) {
    if (!cond) return true;
    return (cond->kind == ExprKind::IntLiteral && cond->intValue != 0) ||
           (cond->kind == ExprKind::FloatLiteral && cond->floatValue != 0.0f);
  }
  // Ends the innermost loop's analysis: `exit` is the state where its condition ends it. With an
  // always-true condition only its breaks leave it: what every break had assigned is assigned.
  void leaveLoop(const Expr* cond, State exit) {
    State broken = std::move(breaks_.back());
    breaks_.pop_back(), continues_.pop_back();
    if (alwaysTrue(cond)) {
      broken.maybe.insert(exit.maybe.begin(), exit.maybe.end());
      state_ = std::move(broken);
    } else {
      state_ = join(exit, broken);
    }
  }
  static State deadState() {
    State d;
    d.dead = true;
    return d;
  }

  Checker& checker_;
  State state_;
  // Per enclosing loop, innermost last: the states at its `break`s and `continue`s, joined (a dead
  // state when there are none).
  std::vector<State> breaks_, continues_;
  std::set<const VarDecl*> tracked_;  // locals declared without initializer
  std::set<const VarDecl*> warned_;
  bool silent_ = false;  // a pass that only learns which variables a loop body sets
};

class Checker {
 public:
  friend class UninitializedAnalysis;
  Checker(TranslationUnit& unit, DiagnosticsEngine& diags, const Prelude* prelude)
      : unit_(unit), diags_(diags), prelude_(prelude) {}

  void run() {
    makeGlobals();
    functionScopes_.clear();
    functionScopes_.emplace_back();
    // Shaders and file-scope functions in source order: a function is visible after its definition.
    std::vector<std::pair<uint32_t, size_t>> order;  // (parse order, index; shaders first in index space)
    for (size_t i = 0; i < unit_.shaders.size(); ++i) order.emplace_back(unit_.shaders[i]->parseOrder, i);
    for (size_t i = 0; i < unit_.functions.size(); ++i)
      order.emplace_back(unit_.functions[i]->parseOrder, unit_.shaders.size() + i);
    std::sort(order.begin(), order.end());
    std::map<std::string, const ShaderDecl*> shaderNames;
    for (const auto& [offset, index] : order) {
      if (index >= unit_.shaders.size()) {
        checkFunction(*unit_.functions[index - unit_.shaders.size()]);
        continue;
      }
      ShaderDecl& shader = *unit_.shaders[index];
      const auto [first, inserted] = shaderNames.emplace(shader.name, &shader);
      if (!inserted)
        report(DiagId::ErrDuplicateShader, shader.nameRange.begin)
            .arg(shader.name)
            .range(shader.nameRange)
            .note(DiagId::NotePreviousDefinition, first->second->nameRange.begin, {}, first->second->nameRange);
      checkShader(shader);
    }
  }

 private:
  DiagnosticsEngine::Builder report(DiagId id, SourceLoc loc) {
    if (suppress_) return DiagnosticsEngine::Builder(&scratch_, id, loc);
    return diags_.report(id, loc);
  }

  void makeGlobals() {
    struct G {
      const char* name;
      TypeKind type;
      GlobalId id;
      bool writable;
    };
    static constexpr G kGlobals[] = {
        {"P", TypeKind::Point, GlobalId::P, true},        {"N", TypeKind::Normal, GlobalId::N, true},
        {"Ng", TypeKind::Normal, GlobalId::Ng, false},    {"dPdu", TypeKind::Vector, GlobalId::dPdu, false},
        {"dPdv", TypeKind::Vector, GlobalId::dPdv, false}, {"u", TypeKind::Float, GlobalId::u, false},
        {"v", TypeKind::Float, GlobalId::v, false},       {"s", TypeKind::Float, GlobalId::s, false},
        {"t", TypeKind::Float, GlobalId::t, false},       {"du", TypeKind::Float, GlobalId::du, false},
        {"dv", TypeKind::Float, GlobalId::dv, false},     {"PI", TypeKind::Float, GlobalId::PI, false},
    };
    unit_.globals.clear();
    scopes_.clear();
    scopes_.emplace_back();
    for (const G& g : kGlobals) {
      auto d = std::make_unique<VarDecl>();
      d->name = g.name;
      d->type = Type(g.type);
      d->storage = Storage::Global;
      d->global = g.id;
      d->writable = g.writable;
      scopes_.back()[d->name] = d.get();
      unit_.globals.push_back(std::move(d));
    }
  }

  VarDecl* lookup(const std::string& name) {
    for (auto it = scopes_.rbegin(); it != scopes_.rend(); ++it) {
      auto f = it->find(name);
      if (f != it->end()) return f->second;
    }
    return nullptr;
  }

  void pushScope() {
    scopes_.emplace_back();
    scopeDecls_.emplace_back();
    functionScopes_.emplace_back();
  }
  void popScope() {
    // -Wunused-variable / -Wunused-parameter, in declaration order for stable output.
    for (VarDecl* d : scopeDecls_.back()) {
      if (d->reads != 0 || skipUnusedWarnings_) continue;
      if (d->invalid || (d->init && d->init->type.isError())) continue;  // already diagnosed
      if (d->storage == Storage::Local)
        report(DiagId::WarnUnusedVariable, d->nameRange.begin).arg(d->name).range(d->nameRange);
      else if (d->storage == Storage::Parameter && !d->isOutput)
        report(DiagId::WarnUnusedParameter, d->nameRange.begin).arg(d->name).range(d->nameRange);
    }
    scopes_.pop_back();
    scopeDecls_.pop_back();
    functionScopes_.pop_back();
  }

  void declare(VarDecl& d) {
    auto& scope = scopes_.back();
    auto it = scope.find(d.name);
    if (it != scope.end()) {
      report(DiagId::ErrRedeclaration, d.nameRange.begin)
          .arg(d.name)
          .range(d.nameRange)
          .note(DiagId::NotePreviousDeclaration, it->second->nameRange.begin, {}, it->second->nameRange);
      return;
    }
    if (VarDecl* outer = lookup(d.name)) {
      const char* what = outer->storage == Storage::Global      ? "the global"
                         : outer->storage == Storage::Parameter ? "the parameter"
                                                                : "the local variable";
      report(DiagId::WarnShadow, d.nameRange.begin).arg(what).arg(d.name).range(d.nameRange);
    }
    scope[d.name] = &d;
    scopeDecls_.back().push_back(&d);
  }

  void checkShader(ShaderDecl& shader) {
    // After syntax errors in it, parts of the shader are missing: "unused" or "uninitialized"
    // would be a guess, not a finding. Other definitions in the file are judged as usual.
    skipUnusedWarnings_ = shader.hadSyntaxErrors;
    const unsigned errorsBefore = diags_.numHardErrors();
    shader_ = &shader;
    inlineCost_ = 0;
    inlineReported_ = false;
    undeclaredReported_.clear();
    pushScope();
    for (auto& p : shader.params) {
      p->storage = Storage::Parameter;
      if (p->type.arrayLength < 0) {
        report(DiagId::ErrUnsizedArray, p->nameRange.begin).range(p->nameRange);
      } else if (!p->init) {
        report(DiagId::ErrMissingDefault, p->nameRange.begin).arg(p->name).range(p->nameRange);
      } else {
        const unsigned errorsBefore = diags_.numHardErrors();
        initializing_ = p.get();
        checkInit(*p);
        initializing_ = nullptr;
        if (!p->init->type.isError()) {
          bool atShadingTime = false;
          if (const Expr* bad = firstNonConstant(*p->init, atShadingTime))
            report(DiagId::ErrNonConstantDefault, bad->range.begin).range(bad->range);
          p->defaultAtShadingTime = atShadingTime;
        }
        if (diags_.numHardErrors() != errorsBefore) p->invalid = true;
      }
      declare(*p);
    }
    loopDepth_ = 0;
    if (shader.body) {
      checkBlockContents(*shader.body);
      if (!shader.hadSyntaxErrors && diags_.numHardErrors() == errorsBefore)
        UninitializedAnalysis(*this).stmt(*shader.body);
    }
    popScope();
    shader_ = nullptr;
  }

  // A sub-expression that makes a default non-constant, or null. Coordinate spaces (RSL's
  // `point center = point "shader" (0, 0, 0)`) and other parameters are allowed: `atShadingTime`
  // says the default reads them, so that it is evaluated with the batch's spaces and the bound
  // values (codegen).
  const Expr* firstNonConstant(const Expr& e, bool& atShadingTime) {
    switch (e.kind) {
      case ExprKind::Identifier:
        if (e.decl && e.decl->storage == Storage::Parameter) {
          // A default that reads another parameter follows that parameter's bound value, so it
          // is evaluated at shading time too.
          atShadingTime |= !e.decl->invalid;
          return nullptr;
        }
        if (e.decl && e.decl->global == GlobalId::PI) return nullptr;
        return &e;
      case ExprKind::Assign:
      case ExprKind::PreIncDec:
      case ExprKind::PostIncDec: return &e;
      case ExprKind::Construct:
        // Components given in a named space, and matrix("from", "to"), read the transforms.
        if (!e.operands.empty() && e.operands[0]->type.kind == TypeKind::String &&
            e.constructType != TypeKind::Color)
          atShadingTime = true;
        break;
      case ExprKind::Call:
        // Library functions are pure math over their arguments unless they read globals.
        if (e.function && e.function->isLibrary && !e.function->readsVarying) break;
        if (!e.builtin) return &e;
        switch (e.builtin->shape) {
          case BuiltinShape::Transform:  // reads the batch's spaces (unless given a matrix)
            if (e.operands.empty() || e.operands[0]->type.kind != TypeKind::Matrix) atShadingTime = true;
            break;
          case BuiltinShape::Deriv:
          case BuiltinShape::CalcNormal:
          case BuiltinShape::Texture:
          case BuiltinShape::Random: return &e;
          case BuiltinShape::Printf:
          case BuiltinShape::StringFn:
          case BuiltinShape::DerivRatio:
          case BuiltinShape::Setcomp:
          case BuiltinShape::SetXyz:
          case BuiltinShape::Displace: return &e;
          default: break;
        }
        break;
      default: break;
    }
    for (const ExprPtr& c : e.operands)
      if (const Expr* bad = firstNonConstant(*c, atShadingTime)) return bad;
    return nullptr;
  }

  void checkBlockContents(Stmt& block) {
    bool terminated = false;
    bool warned = false;
    for (StmtPtr& s : block.stmts) {
      if (terminated && !warned && s->kind != StmtKind::Empty) {
        report(DiagId::WarnUnreachable, s->range.begin).range(s->range);
        warned = true;
      }
      checkStmt(*s);
      // A break/continue outside a loop is an error, not a jump: what follows still runs.
      if (s->kind == StmtKind::Return ||
          ((s->kind == StmtKind::Break || s->kind == StmtKind::Continue) && loopDepth_ > 0))
        terminated = true;
    }
  }

  void checkCondition(Expr& e) {
    const Type t = checkExpr(e, kError);
    if (t.isError()) return;
    if (!t.isScalar())
      report(DiagId::ErrBadCondition, e.range.begin).arg(typeName(t)).range(e.range);
  }

  void checkInit(VarDecl& d) {
    if (d.type.arrayLength < 0 && d.storage != Storage::Parameter)
      report(DiagId::ErrUnsizedArray, d.nameRange.begin).range(d.nameRange);
    if (d.init->kind == ExprKind::InitList) {
      Expr& list = *d.init;
      if (!d.type.isArray()) {
        // A variable whose type is already in error (a bad array length, an unknown type name)
        // says nothing more about its list, only about the elements' own mistakes.
        if (!d.type.isError()) report(DiagId::ErrInitListNotArray, list.range.begin).range(list.range);
        else
          for (const ExprPtr& x : list.operands) checkExpr(*x, kError);
        list.type = kError;
        return;
      }
      const Type element = d.type.element();
      // Expr starts out varying; a list is varying only if one of its elements is.
      list.isVarying = false;
      for (size_t i = 0; i < list.operands.size(); ++i) {
        Expr& x = *list.operands[i];
        const Type t = checkExpr(x, element);
        list.isVarying |= x.isVarying;
        if (d.type.arrayLength > 0 && int(i) == d.type.arrayLength)
          report(DiagId::ErrTooManyInitializers, x.range.begin).arg(d.type.arrayLength).range(x.range);
        checkConversion(x, t, element, DiagId::ErrIncompatibleInit);
      }
      list.type = d.type;
      return;
    }
    const Type t = checkExpr(*d.init, d.type);
    checkConversion(*d.init, t, d.type, DiagId::ErrIncompatibleInit);
  }

  void checkConversion(const Expr& value, Type from, Type to, DiagId error) {
    if (from.isError() || to.isError()) return;
    if (from.kind == TypeKind::Void) {
      report(DiagId::ErrVoidValue, value.range.begin).range(value.range);
      return;
    }
    switch (conversion(from, to)) {
      case Conversion::None:
        if (error == DiagId::ErrIncompatibleAssign)
          report(error, value.range.begin).arg(typeName(to)).arg(typeName(from)).range(value.range);
        else
          report(error, value.range.begin).arg(typeName(to)).arg(typeName(from)).range(value.range);
        break;
      case Conversion::Narrowing: warnNarrowing(value); break;
      default: break;
    }
  }

  void checkStmt(Stmt& s) {
    switch (s.kind) {
      case StmtKind::Block:
        pushScope();
        checkBlockContents(s);
        popScope();
        break;
      case StmtKind::Decl:
        for (auto& d : s.decls) {
          d->storage = Storage::Local;
          if (d->type.arrayLength < 0 && !d->init)
            report(DiagId::ErrUnsizedArray, d->nameRange.begin).range(d->nameRange);
          if (d->init) {
            // Only real errors make the variable invalid: a warning promoted by -Werror leaves it
            // a variable like any other (still reported if unused).
            const unsigned errorsBefore = diags_.numHardErrors();
            suppress_ += s.unterminated;
            initializing_ = d.get();
            checkInit(*d);
            initializing_ = nullptr;
            if (d->isUniform && d->init->isVarying && !d->init->type.isError())
              report(DiagId::ErrUniformFromVarying, d->init->range.begin).arg(d->name).range(d->init->range);
            suppress_ -= s.unterminated;
            if (diags_.numHardErrors() != errorsBefore || s.unterminated) d->invalid = true;
          }
          declare(*d);
        }
        break;
      case StmtKind::ExprStmt: {
        Expr& e = *s.expr;
        suppress_ += s.unterminated;
        const Type t = checkExpr(e, kError);
        suppress_ -= s.unterminated;
        const bool effect = e.kind == ExprKind::Assign || e.kind == ExprKind::PreIncDec ||
                            e.kind == ExprKind::PostIncDec || e.kind == ExprKind::Call;
        if (!effect && !t.isError() && !s.unterminated) report(DiagId::ErrUnusedResult, e.range.begin).range(e.range);
        break;
      }
      case StmtKind::If:
        checkCondition(*s.cond);
        checkScoped(*s.then);
        if (s.otherwise) checkScoped(*s.otherwise);
        break;
      case StmtKind::While:
      case StmtKind::DoWhile:
        checkCondition(*s.cond);
        ++loopDepth_;
        checkScoped(*s.body);
        --loopDepth_;
        break;
      case StmtKind::For:
        pushScope();
        if (s.init) checkStmt(*s.init);
        if (s.cond) checkCondition(*s.cond);
        if (s.step) checkExpr(*s.step, kError);
        ++loopDepth_;
        checkScoped(*s.body);
        --loopDepth_;
        popScope();
        break;
      case StmtKind::Break:
      case StmtKind::Continue:
        if (loopDepth_ == 0)
          report(DiagId::ErrBreakOutsideLoop, s.keywordLoc)
              .arg(s.kind == StmtKind::Break ? "break" : "continue")
              .range({s.keywordLoc, s.keywordLoc.advanced(s.kind == StmtKind::Break ? 5 : 8)});
        else if (s.levels > loopDepth_)
          report(DiagId::ErrBreakTooDeep, s.keywordLoc)
              .arg(s.kind == StmtKind::Break ? "break" : "continue")
              .arg(std::to_string(s.levels))
              .arg(std::to_string(loopDepth_))
              .range(s.range);
        break;
      case StmtKind::Return: {
        const SourceRange kw{s.keywordLoc, s.keywordLoc.advanced(6)};
        if (!function_) {
          if (s.expr) {
            checkExpr(*s.expr, kError);
            report(DiagId::ErrReturnValueInShader, s.keywordLoc).range(s.expr->range);
          }
        } else if (function_->returnType.kind == TypeKind::Void) {
          if (s.expr) {
            checkExpr(*s.expr, kError);
            report(DiagId::ErrReturnVoidValue, s.keywordLoc).arg(function_->name).range(s.expr->range);
          }
        } else if (!s.expr) {
          report(DiagId::ErrReturnMissingValue, s.keywordLoc).arg(function_->name).range(kw);
        } else {
          const Type t = checkExpr(*s.expr, function_->returnType);
          if (requireValue(*s.expr, t)) {
            const Conversion c = conversion(t, function_->returnType);
            if (c == Conversion::None)
              report(DiagId::ErrIncompatibleReturn, s.expr->range.begin)
                  .arg(typeName(t))
                  .arg(typeName(function_->returnType))
                  .range(s.expr->range);
            else if (c == Conversion::Narrowing)
              warnNarrowing(*s.expr);
          }
        }
        break;
      }
      case StmtKind::FunctionDef: checkFunction(*s.function); break;
      case StmtKind::Extern:
        for (auto& d : s.decls) {
          VarDecl* target = nullptr;
          if (!outerScopes_.empty()) {
            // The nearest enclosing function's variables first, then those of the functions
            // around it: lexical scope, so a function nested two deep reaches the shader's locals
            // without the one between declaring them too.
            // Each level's first scope is the globals' (see checkFunction): they come last.
            for (auto level = outerScopes_.rbegin(); level != outerScopes_.rend() && !target; ++level)
              for (auto it = (*level)->rbegin(); it + 1 < (*level)->rend() && !target; ++it) {
                auto f = it->find(d->name);
                if (f != it->end()) target = f->second;
              }
            if (!target && !outerScopes_.front()->empty()) {
              auto f = outerScopes_.front()->front().find(d->name);
              if (f != outerScopes_.front()->front().end()) target = f->second;
            }
          } else {
            target = lookup(d->name);
          }
          if (!target) {
            // `extern float time;` (RSL functions declare the globals they use): why it is missing.
            auto r = report(DiagId::ErrExternUnknown, d->nameRange.begin);
            r.arg(d->name).range(d->nameRange);
            if (kRslGlobals.count(d->name)) r.note(DiagId::NoteRslGlobal, d->nameRange.begin, {d->name}, d->nameRange);
            // Declared here as a variable in error, so its uses raise nothing more.
            d->invalid = true;
            scopes_.back()[d->name] = d.get();
            continue;
          }
          // "name[]" takes the enclosing array's length.
          if (d->type.arrayLength == -1 && target->type.isArray() && target->type.kind == d->type.kind)
            d->type = target->type;
          if (!(target->type == d->type)) {
            report(DiagId::ErrExternType, d->nameRange.begin)
                .arg(d->name)
                .arg(typeName(d->type))
                .arg(typeName(target->type))
                .range(d->nameRange);
            // Declared here in error, so its uses raise nothing more; the outer variable was meant
            // to be used, so it is not reported as unused either.
            d->invalid = true;
            d->type = kError;
            ++target->reads;
            scopes_.back()[d->name] = d.get();
            continue;
          }
          d->externTarget = target;
          scopes_.back()[d->name] = target;  // by reference: the same variable
          if (target->storage != Storage::Global && !target->isUniform) noteVaryingSource();
        }
        break;
      case StmtKind::Empty: break;
    }
  }

  // A statement in its own scope (if/loop bodies that are not blocks still scope declarations).
  void checkScoped(Stmt& s) {
    if (s.kind == StmtKind::Block) {
      checkStmt(s);
      return;
    }
    pushScope();
    checkStmt(s);
    popScope();
  }

  Type probe(Expr& e) {
    ++suppress_;
    ++contextFloat_;
    const Type t = checkExpr(e, kError);
    --contextFloat_;
    --suppress_;
    return t;
  }

  Type set(Expr& e, Type t) {
    e.type = t;
    return t;
  }

  // Reports use of a void value once; returns false if `t` is not a value.
  bool requireValue(const Expr& e, Type t) {
    if (t.kind != TypeKind::Void) return !t.isError();
    report(DiagId::ErrVoidValue, e.range.begin).range(e.range);
    return false;
  }

  Type checkExpr(Expr& e, Type expected) {
    e.isVarying = false;
    if (!suppress_) ++inlineCost_;
    switch (e.kind) {
      case ExprKind::IntLiteral: return set(e, kInt);
      case ExprKind::FloatLiteral: return set(e, kFloat);
      case ExprKind::StringLiteral: return set(e, Type(TypeKind::String));
      case ExprKind::Identifier: {
        VarDecl* d = lookup(e.text);
        e.decl = d;
        if (!d) {
          if (!suppress_ && initializing_ && initializing_->name == e.text)
            report(DiagId::ErrOwnInitializer, e.range.begin).arg(e.text).range(e.opRange);
          else if (!suppress_ && undeclaredReported_.insert(e.text).second) {
            // RSL's surface-shading globals (language.md 5 names them): say why they are missing.
            auto r = report(DiagId::ErrUndeclared, e.range.begin);
            r.arg(e.text).range(e.opRange);
            if (kRslGlobals.count(e.text)) r.note(DiagId::NoteRslGlobal, e.range.begin, {e.text}, e.opRange);
          }
          return set(e, kError);
        }
        ++d->reads;
        const bool varyingGlobal = d->storage == Storage::Global && d->global != GlobalId::PI;
        if (varyingGlobal) noteVaryingSource();
        e.isVarying = varyingGlobal || (d->storage == Storage::Local && !d->isUniform);
        return set(e, d->type);
      }
      case ExprKind::Unary: {
        Expr& a = *e.operands[0];
        const Type t = checkExpr(a, e.op == Tok::Minus ? expected : kError);
        e.isVarying = a.isVarying;
        if (!requireValue(a, t)) return set(e, kError);
        if (e.op == Tok::Bang) {
          if (t.isScalar()) return set(e, kInt);
        } else if (t.isNumeric()) {
          return set(e, t);
        }
        report(DiagId::ErrInvalidUnaryOperand, e.opLoc).arg(typeName(t)).range(a.range);
        return set(e, kError);
      }
      case ExprKind::PreIncDec:
      case ExprKind::PostIncDec: {
        Expr& a = *e.operands[0];
        const Type t = checkExpr(a, kError);
        e.isVarying = a.isVarying;
        if (t.isError()) return set(e, kError);
        if (!t.isScalar()) {
          report(DiagId::ErrIncDecOperand, e.opLoc).arg(typeName(t)).range(a.range);
          return set(e, kError);
        }
        if (!checkAssignable(a, e.opLoc, e.opRange)) return set(e, kError);
        return set(e, t);
      }
      case ExprKind::Binary: return checkBinary(e, expected);
      case ExprKind::Assign: return checkAssign(e);
      case ExprKind::Conditional: {
        checkCondition(*e.operands[0]);
        const Type a = checkExpr(*e.operands[1], expected);
        const Type b = checkExpr(*e.operands[2], expected);
        e.isVarying = e.operands[0]->isVarying || e.operands[1]->isVarying || e.operands[2]->isVarying;
        if (!requireValue(*e.operands[1], a) || !requireValue(*e.operands[2], b) ||
            e.operands[0]->type.isError())
          return set(e, kError);
        Type r = kError;
        if (a == b)
          r = a;
        else if (a.kind != TypeKind::String && b.kind != TypeKind::String)
          r = binaryResult(Tok::Plus, a, b);
        if (a.isArray() || b.isArray()) {
          // Arrays are not values (§2): "incompatible 'float[2]' and 'float[2]'" would puzzle.
          report(DiagId::ErrConditionalArray, e.opLoc)
              .arg(typeName(a.isArray() ? a : b))
              .range(e.operands[1]->range)
              .range(e.operands[2]->range);
          return set(e, kError);
        }
        if (r.isError() || r.isArray()) {
          report(DiagId::ErrConditionalOperands, e.opLoc)
              .arg(typeName(a))
              .arg(typeName(b))
              .range(e.operands[1]->range)
              .range(e.operands[2]->range);
          return set(e, kError);
        }
        return set(e, r);
      }
      case ExprKind::Call: return checkCall(e, expected);
      case ExprKind::Construct: return checkConstruct(e);
      case ExprKind::Index: {
        Expr& base = *e.operands[0];
        Expr& index = *e.operands[1];
        const bool matrixRowAllowed = matrixRowOk_;
        matrixRowOk_ = base.kind == ExprKind::Index;
        const Type bt = checkExpr(base, kError);
        matrixRowOk_ = false;
        const Type it = checkExpr(index, kError);
        e.isVarying = base.isVarying || index.isVarying;
        if (bt.isError() || it.isError()) return set(e, kError);
        if (bt.isArray()) {
          if (!intIndex(e.operands[1], it)) return set(e, kError);
          if (bt.arrayLength > 0 && badConstantIndex(*e.operands[1], bt.arrayLength, bt)) return set(e, kError);
          return set(e, bt.element());
        }
        if (bt.kind == TypeKind::Matrix) {
          // m[i][j]: the inner index yields a row that only a second index may consume.
          if (!intIndex(e.operands[1], it)) return set(e, kError);
          if (badConstantIndex(*e.operands[1], 4, bt)) return set(e, kError);
          if (base.matrixRow) return set(e, kFloat);
          if (!matrixRowAllowed) {
            report(DiagId::ErrMatrixRow, e.range.begin).range(e.range);
            return set(e, kError);
          }
          e.matrixRow = true;
          return set(e, bt);
        }
        if (!bt.isTriple()) {
          report(DiagId::ErrNotIndexable, e.opLoc).arg(typeName(bt)).range(base.range);
          return set(e, kError);
        }
        if (!intIndex(e.operands[1], it)) return set(e, kError);
        if (badConstantIndex(*e.operands[1], 3, bt)) return set(e, kError);
        return set(e, kFloat);
      }
      case ExprKind::InitList:
        // Only valid as an array initializer, where checkInit handles it.
        report(DiagId::ErrInitListNotArray, e.range.begin).range(e.range);
        return set(e, kError);
      case ExprKind::Tuple: {
        bool ok = true;
        for (ExprPtr& c : e.operands) {
          const Type t = checkExpr(*c, kError);
          e.isVarying |= c->isVarying;
          if (!requireValue(*c, t)) {
            ok = false;
          } else if (!t.isScalar()) {
            report(DiagId::ErrIncompatibleArg, c->range.begin).arg(typeName(t)).arg("float").range(c->range);
            ok = false;
          }
        }
        if (!ok) return set(e, kError);
        if (e.operands.size() == 16) return set(e, Type(TypeKind::Matrix));
        if (e.operands.size() != 3) {
          report(DiagId::ErrUnsupported, e.range.begin)
              .arg("a tuple of " + std::to_string(e.operands.size()) + " elements")
              .range(e.range);
          return set(e, kError);
        }
        if (expected.isTriple()) return set(e, expected);
        // Judged as the other operand of a context-typed call (probe): its kind is not known
        // yet, so it must not decide the call's (`noise(P) + (1, 2, 3)` takes the outer type).
        if (contextFloat_) return set(e, kFloat);
        return set(e, Type(TypeKind::Point));
      }
    }
    return set(e, kError);
  }

  // A constant index (a literal, possibly negated) outside [0, limit) is an error at the index (§6.3);
  // other indices are clamped at run time.
  static bool constantInt(const Expr& e, int64_t* value) {
    if (e.kind == ExprKind::IntLiteral) {
      *value = e.intValue;
      return true;
    }
    if (e.kind == ExprKind::Unary && (e.op == Tok::Minus || e.op == Tok::Plus) &&
        e.operands[0]->kind == ExprKind::IntLiteral) {
      *value = e.op == Tok::Minus ? -int64_t(e.operands[0]->intValue) : e.operands[0]->intValue;
      return true;
    }
    // A float literal index, truncated by the cast intIndex put in front of it (`a[3.5]` is a[3]).
    if (e.kind == ExprKind::Construct && e.isCast && e.constructType == TypeKind::Int && e.operands.size() == 1) {
      const Expr& f = *e.operands[0];
      const bool negated = f.kind == ExprKind::Unary && f.op == Tok::Minus;
      const Expr& lit = negated ? *f.operands[0] : f;
      if (lit.kind != ExprKind::FloatLiteral || !(std::fabs(lit.floatValue) < 1e9f)) return false;
      *value = int64_t(negated ? -lit.floatValue : lit.floatValue);
      return true;
    }
    return false;
  }
  bool badConstantIndex(const Expr& index, int limit, Type t) {
    int64_t k = 0;
    if (!constantInt(index, &k) || (k >= 0 && k < limit)) return false;
    report(DiagId::ErrIndexRange, index.range.begin).arg(static_cast<long long>(k)).arg(typeName(t)).range(index.range);
    return true;
  }

  Type checkBinary(Expr& e, Type expected) {
    Expr& l = *e.operands[0];
    Expr& r = *e.operands[1];
    Type tl, tr;
    // A tuple beside a triple is that triple's kind whatever the operator: it cannot be the float
    // a noise call becomes under `*` or `/` (`Ct * (0.3, 0.59, 0.11)`).
    auto hint = [&](const Expr& operand, Type other) {
      return operand.kind == ExprKind::Tuple && other.isTriple() ? other : contextHint(e.op, other, expected);
    };
    if (isArithmetic(e.op)) {
      const bool cl = hasContextCall(l);
      const bool cr = hasContextCall(r);
      if (cl && cr) {
        const Type pl = probe(l);
        const Type pr = probe(r);
        tl = checkExpr(l, hint(l, pr));
        tr = checkExpr(r, hint(r, pl));
      } else if (cl) {
        tr = checkExpr(r, kError);
        tl = checkExpr(l, hint(l, tr));
      } else {
        tl = checkExpr(l, kError);
        tr = checkExpr(r, hint(r, tl));
      }
    } else if ((e.op == Tok::EqEq || e.op == Tok::NotEq) && l.kind == ExprKind::Tuple) {
      tr = checkExpr(r, kError);  // `(0, 0, 0) != Ct`: the tuple takes Ct's kind
      tl = checkExpr(l, tr.isTriple() ? tr : kError);
    } else if (e.op == Tok::EqEq || e.op == Tok::NotEq) {
      tl = checkExpr(l, kError);
      tr = checkExpr(r, r.kind == ExprKind::Tuple && tl.isTriple() ? tl : kError);
    } else {
      tl = checkExpr(l, kError);
      tr = checkExpr(r, kError);
    }
    e.isVarying = l.isVarying || r.isVarying;
    const bool lv = requireValue(l, tl);
    const bool rv = requireValue(r, tr);
    if (!lv || !rv) return set(e, kError);
    const Type t = binaryResult(e.op, tl, tr);
    if (t.isError()) {
      report(DiagId::ErrInvalidBinaryOperands, e.opLoc)
          .arg(typeName(tl))
          .arg(typeName(tr))
          .range(l.range)
          .range(r.range);
    }
    // `1/2` is 0 here as in C, where RSL (whose numbers are all floats) gives 0.5: a shader
    // brought over from RSL would silently lose the term. So would `-1/2`, `(N + 1)/2` with a
    // macro N, or `1/(1 + 1)`: any division of integer constant expressions that is inexact.
    int64_t lc = 0, rc = 0;
    if (e.op == Tok::Slash && t.kind == TypeKind::Int && foldIntConstant(l, &lc) && foldIntConstant(r, &rc) && rc != 0 && lc % rc != 0) {
      const bool literals = l.kind == ExprKind::IntLiteral && r.kind == ExprKind::IntLiteral;
      report(DiagId::WarnIntegerDivision, e.opLoc)
          .arg(std::to_string(lc / rc))
          .arg(literals ? std::to_string(lc) + ".0/" + std::to_string(rc)
                        : "a float operand (a divisor of " + std::to_string(rc) + ".0)")
          .range(l.range)
          .range(r.range);
    }
    return set(e, t);
  }

  // An index must be an int (§4.1). RSL has no int type and indexes with floats (`float i; …
  // a[i]`), so a float index is accepted as an implicit conversion (§2.1): it truncates, with
  // -Wnarrowing, through an int cast put in front of it. Anything else is an error.
  bool intIndex(ExprPtr& index, const Type& it) {
    if (it.kind == TypeKind::Int) return true;
    if (it.kind != TypeKind::Float) {
      report(DiagId::ErrIndexNotInt, index->range.begin).arg(typeName(it)).range(index->range);
      return false;
    }
    // A silent probe (suppress_) checks this tree again for real: the cast and the warning are
    // the real pass's, or the warning would be lost with the probe's reports.
    if (suppress_) return true;
    warnNarrowing(*index);
    auto cast = std::make_unique<Expr>(ExprKind::Construct, index->range);
    cast->constructType = TypeKind::Int;
    cast->isCast = true;
    cast->opLoc = index->range.begin;
    cast->opRange = index->range;
    cast->isVarying = index->isVarying;
    cast->operands.push_back(std::move(index));
    set(*cast, kInt);
    index = std::move(cast);
    return true;
  }

  // Checks that `target` may be written; marks P/N writes for the host contract.
  // `surfaceNormal`: the value written is the displaced surface's own normal (isSurfaceNormal),
  // so a write of N does not make the shader's normal its own (ShaderDecl::ownNormal).
  bool checkAssignable(Expr& target, SourceLoc opLoc, SourceRange opRange, bool surfaceNormal = false) {
    const Expr& base = indexRoot(target);
    if (base.kind != ExprKind::Identifier) {
      report(DiagId::ErrNotAssignable, opLoc).range(opRange).range(target.range);
      return false;
    }
    VarDecl* d = base.decl;
    if (!d) return false;
    if (!d->writable) {
      report(DiagId::ErrReadOnly, opLoc).arg(d->name).range(opRange).range(target.range);
      return false;
    }
    d->written = true;
    if (d->storage == Storage::Global) {
      const bool n = d->global == GlobalId::N;
      markWrites(d->global == GlobalId::P, n, n && !surfaceNormal);
    }
    return true;
  }

  // Records writes of P/N: on the function being checked (propagated at its calls), else the shader.
  // `ownN`: the N written may differ from the displaced surface's normal (ShaderDecl::ownNormal).
  void markWrites(bool p, bool n, bool ownN) {
    if (function_) {
      function_->writesP |= p;
      function_->writesN |= n;
      function_->writesOwnN |= ownN;
    } else if (shader_) {
      shader_->assignsP |= p;
      shader_->assignsN |= n;
      shader_->ownNormal |= ownN;
    }
  }

  // `calculatenormal(P)` or `normalize(calculatenormal(P))` of the global P: the displaced
  // surface's own normal, which the renderer's micro-triangles already have.
  static bool isSurfaceNormal(const Expr& e) {
    if (e.kind != ExprKind::Call || e.operands.size() != 1) return false;
    const Expr& a = *e.operands[0];
    if (e.text == "normalize") return isSurfaceNormal(a);
    return e.text == "calculatenormal" && a.kind == ExprKind::Identifier && a.decl &&
           a.decl->storage == Storage::Global && a.decl->global == GlobalId::P;
  }

  Type checkAssign(Expr& e) {
    Expr& target = *e.operands[0];
    Expr& value = *e.operands[1];
    const Type tt = checkExpr(target, kError);
    // A plain assignment does not read its target, nor the variable whose element or component
    // it sets (`a[0] = 1`, `v[1] = 2`); its index expressions still count as reads.
    VarDecl* written = nullptr;
    if (const Expr& root = indexRoot(target); e.op == Tok::Assign && root.kind == ExprKind::Identifier && root.decl)
      --(written = root.decl)->reads;
    const Tok base = compoundBase(e.op);
    // (A tuple takes the target's kind under any operator, `Ct *= (0.3, 0.59, 0.11)`, as in checkBinary.)
    const Type tv = checkExpr(value, base == Tok::Eof || (value.kind == ExprKind::Tuple && tt.isTriple())
                                         ? tt
                                         : contextHint(base, tt, tt));
    e.isVarying = value.isVarying;
    if (tt.isError()) return set(e, kError);
    const bool surfaceNormal = e.op == Tok::Assign && target.kind == ExprKind::Identifier && isSurfaceNormal(value);
    if (!checkAssignable(target, e.opLoc, e.opRange, surfaceNormal)) {
      if (written) ++written->reads;  // already an error: no "unused" on top of it
      return set(e, kError);
    }
    if (!requireValue(value, tv)) return set(e, kError);
    Type result = tv;
    if (base != Tok::Eof) {
      result = binaryResult(base, tt, tv);
      if (result.isError()) {
        report(DiagId::ErrInvalidBinaryOperands, e.opLoc)
            .arg(typeName(tt))
            .arg(typeName(tv))
            .range(target.range)
            .range(value.range);
        return set(e, kError);
      }
    }
    if (conversion(result, tt) == Conversion::None) {
      report(DiagId::ErrIncompatibleAssign, value.range.begin)
          .arg(typeName(tt))
          .arg(typeName(result))
          .range(value.range);
      return set(e, kError);
    }
    if (conversion(result, tt) == Conversion::Narrowing) warnNarrowing(value);
    checkUniformTarget(target, value);
    return set(e, tt);
  }

  // The one uniform check of §2: an explicitly uniform variable (or element of one) written with a
  // varying value, by assignment or as an `output`/setcomp argument.
  void checkUniformTarget(const Expr& target, const Expr& value) { checkUniformTarget(target, value.isVarying, value.range); }
  void checkUniformTarget(const Expr& target, bool varying, SourceRange at) {
    const Expr* base = &indexRoot(target);
    if (varying && base->kind == ExprKind::Identifier && base->decl && base->decl->isUniform)
      report(DiagId::ErrUniformFromVarying, at.begin).arg(base->decl->name).range(at);
  }

  // Marks the function being checked as varying whatever its arguments (FunctionDecl::readsVarying).
  void noteVaryingSource() {
    if (function_) function_->readsVarying = true;
  }

  Type checkConstruct(Expr& e) {
    const Type target(e.constructType);
    std::vector<ExprPtr>& args = e.operands;
    const Type hint = args.size() == 1 ? target : kError;
    bool ok = true;
    for (ExprPtr& a : args) {
      const Type t = checkExpr(*a, hint);
      e.isVarying |= a->isVarying;
      if (!requireValue(*a, t)) ok = false;
    }
    if (!ok) return set(e, kError);
    auto bad = [&] {
      report(DiagId::ErrBadConstructor, e.opLoc).arg(typeName(target)).arg(typeList(args)).range(e.opRange);
      return set(e, kError);
    };
    if (target.kind == TypeKind::Float || target.kind == TypeKind::Int) {
      if (args.size() != 1 || !args[0]->type.isScalar()) return bad();
      return set(e, target);
    }
    if (target.kind == TypeKind::Matrix) return checkMatrixConstruct(e, bad);
    if (!target.isTriple()) {
      report(DiagId::ErrUnsupported, e.opLoc).arg("'" + typeName(target) + "' constructor").range(e.opRange);
      return set(e, kError);
    }
    size_t first = 0;
    if (!args.empty() && args[0]->type.kind == TypeKind::String) {
      const Expr& space = *args[0];
      // A non-literal name is looked up at run time (identity and a warning if unknown, §2.3).
      const bool known = space.kind != ExprKind::StringLiteral ||
                         (target.kind == TypeKind::Color ? space.text == "rgb" : isKnownSpace(space.text));
      if (!known) {
        report(target.kind == TypeKind::Color ? DiagId::ErrUnknownColorSpace : DiagId::ErrUnknownSpace,
               space.range.begin)
            .arg(space.text)
            .range(space.range);
        return set(e, kError);
      }
      e.text = space.text;
      first = 1;
    }
    const size_t n = args.size() - first;
    if (n == 1 && args[first]->type.isNumeric()) return set(e, target);
    if (n == 3 && args[first]->type.isScalar() && args[first + 1]->type.isScalar() &&
        args[first + 2]->type.isScalar())
      return set(e, target);
    return bad();
  }

  // matrix(f), matrix(m), matrix(m00, ..., m33), matrix("from", "to"), matrix("space", f),
  // matrix("space", m00, ..., m33) (§2.2).
  template <class Bad>
  Type checkMatrixConstruct(Expr& e, Bad bad) {
    std::vector<ExprPtr>& args = e.operands;
    size_t first = 0;
    while (first < args.size() && first < 2 && args[first]->type.kind == TypeKind::String) {
      const Expr& space = *args[first];
      if (space.kind == ExprKind::StringLiteral && !isKnownSpace(space.text)) {
        report(DiagId::ErrUnknownSpace, space.range.begin).arg(space.text).range(space.range);
        return set(e, kError);
      }
      ++first;
    }
    const size_t n = args.size() - first;
    if (first == 2) return n == 0 ? set(e, Type(TypeKind::Matrix)) : bad();
    bool scalars = true;
    for (size_t i = first; i < args.size(); ++i) scalars &= args[i]->type.isScalar();
    if ((n == 1 || n == 16) && scalars) return set(e, Type(TypeKind::Matrix));
    if (n == 1 && first == 0 && args[0]->type == Type(TypeKind::Matrix)) return set(e, Type(TypeKind::Matrix));
    return bad();
  }

  const std::vector<FunctionDecl*>* lookupFunctions(const std::string& name) const {
    for (auto it = functionScopes_.rbegin(); it != functionScopes_.rend(); ++it) {
      auto f = it->find(name);
      if (f != it->end()) return &f->second;
    }
    return nullptr;
  }

  static bool sameParameters(const FunctionDecl& a, const FunctionDecl& b) {
    if (a.params.size() != b.params.size()) return false;
    for (size_t i = 0; i < a.params.size(); ++i)
      if (!(a.params[i]->type == b.params[i]->type)) return false;
    return true;
  }

  // True if control can reach the end of `s` (loops may exit; `if` without `else` falls through).
  static bool canFallThrough(const Stmt& s) {
    switch (s.kind) {
      case StmtKind::Return: return false;
      case StmtKind::Block:
        for (const StmtPtr& c : s.stmts)
          if (!canFallThrough(*c)) return false;
        return true;
      case StmtKind::If: return !s.otherwise || canFallThrough(*s.then) || canFallThrough(*s.otherwise);
      default: return true;
    }
  }

  void checkFunction(FunctionDecl& f) {
    // As in checkShader; a function nested in a shader with syntax errors keeps the shader's flag.
    const bool savedSkipUnused = skipUnusedWarnings_;
    skipUnusedWarnings_ = (function_ || shader_ ? savedSkipUnused : false) || f.bodyHadErrors;
    const unsigned errorsBefore = diags_.numHardErrors();
    // Registered before its body is checked, so a recursive call resolves and is reported.
    const std::vector<FunctionDecl*>* visible = lookupFunctions(f.name);
    auto& overloads = functionScopes_.back()[f.name];
    bool redefinition = false;
    for (FunctionDecl* other : overloads) {
      if (!sameParameters(*other, f)) continue;
      report(DiagId::ErrFunctionRedefinition, f.nameRange.begin)
          .arg(f.name)
          .range(f.nameRange)
          .note(DiagId::NotePreviousDeclaration, other->nameRange.begin, {}, other->nameRange);
      redefinition = true;
    }
    if (!visible && (findBuiltin(f.name) || (prelude_ && prelude_->find(f.name))))
      report(DiagId::WarnShadowFunction, f.nameRange.begin).arg(f.name).range(f.nameRange);
    if (!redefinition) overloads.push_back(&f);

    // Variables: globals and its own; enclosing locals only through `extern`.
    auto savedScopes = std::move(scopes_);
    auto savedDecls = std::move(scopeDecls_);
    scopes_.clear();
    scopeDecls_.clear();
    scopes_.push_back(savedScopes.front());
    scopeDecls_.emplace_back();
    outerScopes_.push_back(&savedScopes);
    FunctionDecl* savedFunction = function_;
    const int savedLoopDepth = loopDepth_;
    auto savedUndeclared = std::move(undeclaredReported_);
    undeclaredReported_.clear();
    function_ = &f;
    loopDepth_ = 0;
    functionStack_.push_back(&f);
    const uint64_t savedCost = inlineCost_;
    inlineCost_ = 0;

    pushScope();
    for (auto& p : f.params) {
      p->storage = Storage::Parameter;
      p->writable = p->isOutput;
      if (p->init) {
        report(DiagId::ErrFunctionParamDefault, p->init->range.begin).range(p->init->range);
        p->init.reset();
      }
      declare(*p);
    }
    if (f.body) {
      checkBlockContents(*f.body);
      if (!skipUnusedWarnings_ && diags_.numHardErrors() == errorsBefore)
        UninitializedAnalysis(*this).stmt(*f.body);
      if (f.returnType.kind != TypeKind::Void && !f.bodyHadErrors && canFallThrough(*f.body))
        report(DiagId::ErrMissingReturn, SourceLoc{f.body->range.end.offset - 1}).arg(f.name);
    }
    popScope();

    functionStack_.pop_back();
    f.inlineCost = inlineCost_;
    inlineCost_ = savedCost;
    function_ = savedFunction;
    loopDepth_ = savedLoopDepth;
    undeclaredReported_ = std::move(savedUndeclared);
    skipUnusedWarnings_ = savedSkipUnused;
    outerScopes_.pop_back();
    scopes_ = std::move(savedScopes);
    scopeDecls_ = std::move(savedDecls);
  }

  // Lvalues (§4.1): a variable, an array element, a triple's `v[i]` or a matrix's `m[i][j]`, so
  // an Index chain down to a variable (whether that is writable is checkAssignable's business).
  static bool isLvalue(const Expr& e) {
    const Expr& base = indexRoot(e);
    return base.kind == ExprKind::Identifier && base.decl;
  }

  // An output argument is the parameter's own type, or any array of its element type for an
  // unsized `T a[]` parameter (§2.1).
  static bool outputArgumentFits(Type argument, Type parameter) {
    if (parameter.arrayLength == -1) return argument.isArray() && argument.kind == parameter.kind;
    return argument == parameter;
  }

  // Overload resolution (§6): exact match, then int→float-only conversions, then the unique
  // candidate with the fewest conversions.
  // Library candidates are reported like built-ins: at the callee, without notes into stdlib/.
  Type checkUserCall(Expr& e, const std::vector<FunctionDecl*>& candidates, bool library) {
    std::vector<ExprPtr>& args = e.operands;
    struct Viable {
      FunctionDecl* f;
      int conversions;
      bool intToFloatOnly;
    };
    std::vector<Viable> viable;
    for (FunctionDecl* f : candidates) {
      if (f->params.size() != args.size()) continue;
      Viable v{f, 0, true};
      bool ok = true;
      for (size_t i = 0; i < args.size() && ok; ++i) {
        const VarDecl& p = *f->params[i];
        const Expr& a = *args[i];
        if (p.isOutput) {
          ok = isLvalue(a) && outputArgumentFits(a.type, p.type);
          continue;
        }
        switch (conversion(a.type, p.type)) {
          case Conversion::None: ok = false; break;
          case Conversion::Identity: break;
          case Conversion::Implicit:
            ++v.conversions;
            v.intToFloatOnly &= a.type.kind == TypeKind::Int && p.type.kind == TypeKind::Float;
            break;
          case Conversion::Narrowing:
            ++v.conversions;
            v.intToFloatOnly = false;
            break;
        }
      }
      if (ok) viable.push_back(v);
    }
    if (viable.empty()) {
      if (!library && candidates.size() == 1 && candidates[0]->params.size() == args.size()) {
        // Non-overloaded: point at the offending argument.
        const FunctionDecl& f = *candidates[0];
        for (size_t i = 0; i < args.size(); ++i) {
          const VarDecl& p = *f.params[i];
          const Expr& a = *args[i];
          if (p.isOutput && !(isLvalue(a) && outputArgumentFits(a.type, p.type))) {
            report(DiagId::ErrOutputArgument, a.range.begin).arg(p.name).arg(typeName(p.type)).range(a.range);
            break;
          }
          if (!p.isOutput && conversion(a.type, p.type) == Conversion::None) {
            report(DiagId::ErrIncompatibleArg, a.range.begin).arg(typeName(a.type)).arg(typeName(p.type)).range(a.range);
            break;
          }
        }
      } else {
        // The shader's own candidates are shown, with their argument counts where those differ.
        auto builder = report(DiagId::ErrNoMatchingCall, e.range.begin);
        builder.arg(e.text).arg(typeList(args)).range(e.opRange);
        auto count = [](size_t n) { return std::to_string(n) + (n == 1 ? " argument" : " arguments"); };
        for (const FunctionDecl* f : candidates) {
          if (f->isLibrary) continue;
          if (f->params.size() != args.size())
            builder.note(DiagId::NoteCandidateArgCount, f->nameRange.begin, {count(f->params.size()), std::to_string(args.size())},
                         f->nameRange);
          else
            builder.note(DiagId::NoteCandidate, f->nameRange.begin, {}, f->nameRange);
        }
      }
      return set(e, kError);
    }
    const Viable* best = nullptr;
    auto pick = [&](auto pred) -> int {
      int n = 0;
      for (const Viable& v : viable)
        if (pred(v)) {
          if (!n) best = &v;
          ++n;
        }
      return n;
    };
    // §6: an exact match; else, among the candidates needing only int->float conversions (or,
    // if there are none, among all), the one with the fewest conversions.
    int n = pick([](const Viable& v) { return v.conversions == 0; });
    if (n == 0) {
      const bool intToFloatTier =
          std::any_of(viable.begin(), viable.end(), [](const Viable& v) { return v.intToFloatOnly; });
      auto inTier = [&](const Viable& v) { return !intToFloatTier || v.intToFloatOnly; };
      int fewest = INT32_MAX;
      for (const Viable& v : viable)
        if (inTier(v)) fewest = std::min(fewest, v.conversions);
      n = pick([&](const Viable& v) { return inTier(v) && v.conversions == fewest; });
    }
    if (n != 1) {
      auto builder = report(DiagId::ErrAmbiguousCall, e.range.begin);
      builder.arg(e.text).range(e.opRange);
      for (const Viable& v : viable)
        if (!v.f->isLibrary) builder.note(DiagId::NoteCandidate, v.f->nameRange.begin, {}, v.f->nameRange);
      return set(e, kError);
    }
    FunctionDecl* f = best->f;
    if (std::find(functionStack_.begin(), functionStack_.end(), f) != functionStack_.end()) {
      report(DiagId::ErrRecursiveCall, e.range.begin).arg(e.text).range(e.opRange);
      return set(e, kError);
    }
    // A call is uniform when its arguments are and the function reads nothing varying (§2).
    e.isVarying = f->readsVarying;
    for (const ExprPtr& a : args) e.isVarying |= a->isVarying;
    if (f->readsVarying) noteVaryingSource();
    for (size_t i = 0; i < args.size(); ++i) {
      const VarDecl& p = *f->params[i];
      Expr& a = *args[i];
      if (p.isOutput) {
        if (!checkAssignable(a, a.range.begin, a.range)) return set(e, kError);
        checkUniformTarget(a, e.isVarying, a.range);  // the function's result may land in it
      } else if (conversion(a.type, p.type) == Conversion::Narrowing) {
        warnNarrowing(a);
      }
    }
    markWrites(f->writesP, f->writesN, f->writesOwnN);
    // Inlining recurses through a chain of calls: a chain thousands of functions long would
    // overflow the compiler's stack (16,000 did) long before its code passed the size limit.
    if (function_ && !suppress_) function_->callDepth = std::max(function_->callDepth, f->callDepth + 1);
    if (f->callDepth + 1 > kMaxCallDepth) {
      // Always an error (a silent probe's pass must not let the real one through); reported once.
      if (!suppress_ && !callDepthReported_) {
        callDepthReported_ = true;
        report(DiagId::ErrCallChainTooDeep, e.range.begin).arg(e.text).arg(static_cast<long long>(kMaxCallDepth)).range(e.opRange);
      }
      return set(e, kError);
    }
    // User functions are inlined at every call: bound the code a call chain may expand to. Only
    // the shader's own body is generated, so a function's cost is an error only where the shader
    // (or a function it calls) calls it: a library of functions never called costs nothing.
    inlineCost_ = std::min<uint64_t>(inlineCost_ + std::min<uint64_t>(f->inlineCost, 1ull << 40), 1ull << 40);
    if (inlineCost_ > kMaxInlineCost && !functionStack_.empty() && function_ && !function_->overLimitCallee) {
      function_->overLimitCall = e.opRange;
      function_->overLimitCallee = f;
    }
    if (inlineCost_ > kMaxInlineCost && !inlineReported_ && functionStack_.empty()) {
      inlineReported_ = true;
      // The deepest function whose own body passes the limit: where the growth is.
      const FunctionDecl* grows = f->overLimitCallee ? f : nullptr;
      while (grows && grows->overLimitCallee->overLimitCallee) grows = grows->overLimitCallee;
      auto builder = report(DiagId::ErrInlineTooLarge, e.range.begin);
      builder.arg(e.text).arg(static_cast<long long>(kMaxInlineCost)).range(e.opRange);
      if (grows)
        builder.note(DiagId::NoteInlineGrowth, grows->overLimitCall.begin,
                     {grows->name, grows->overLimitCallee->name}, grows->overLimitCall);
      return set(e, kError);
    }
    e.function = f;
    return set(e, f->returnType);
  }

  Type checkCall(Expr& e, Type expected) {
    // A user function hides every library overload of its name (§3); library functions written in
    // the language (the prelude) come next, then those built into the compiler.
    const std::vector<FunctionDecl*>* fns = lookupFunctions(e.text);
    const bool library = !fns && prelude_ && (fns = prelude_->find(e.text));
    if (fns) {
      const FunctionDecl* single = fns->size() == 1 ? (*fns)[0] : nullptr;
      bool ok = true;
      for (size_t i = 0; i < e.operands.size(); ++i) {
        Expr& a = *e.operands[i];
        const Type hint = single && i < single->params.size() ? single->params[i]->type : kError;
        const Type t = checkExpr(a, hint);
        if (!requireValue(a, t)) ok = false;
      }
      if (!ok) return set(e, kError);
      return checkUserCall(e, *fns, library);
    }
    const BuiltinInfo* b = findBuiltin(e.text);
    e.builtin = b;
    if (b && b->shape == BuiltinShape::Texture && !e.operands.empty() && e.operands[0]->kind == ExprKind::Index &&
        !e.operands[0]->operands.empty()) {
      // RSL channel selection: texture(file[i], ...) means texture(file, ..., "firstchannel", i).
      Expr& index = *e.operands[0];
      ++suppress_;
      const Type baseType = checkExpr(*index.operands[0], kError);
      --suppress_;
      if (baseType.kind == TypeKind::String && !baseType.isArray()) {
        ExprPtr base = std::move(index.operands[0]);
        ExprPtr channel = std::move(index.operands[1]);
        // A channel index is an index like any other (§6.3): an int, or a float that truncates
        // with -Wnarrowing (RSL has only floats, so `texture(name[ch], ...)` with a float
        // parameter is how RSL shaders select channels). checkTexture warns for the option.
        ++suppress_;
        const Type channelType = checkExpr(*channel, kError);
        --suppress_;
        if (!channelType.isError() && channelType.kind != TypeKind::Int && channelType.kind != TypeKind::Float) {
          report(DiagId::ErrIndexNotInt, channel->range.begin).arg(typeName(channelType)).range(channel->range);
          return set(e, kError);
        }
        auto name = std::make_unique<Expr>(ExprKind::StringLiteral, channel->range);
        name->text = "firstchannel";
        e.operands[0] = std::move(base);
        e.operands.push_back(std::move(name));
        e.operands.push_back(std::move(channel));
      }
    }
    std::vector<ExprPtr>& args = e.operands;
    bool ok = true;
    for (ExprPtr& a : args) {
      const Type t = checkExpr(*a, kError);
      e.isVarying |= a->isVarying;
      if (!requireValue(*a, t)) ok = false;
    }
    // Tuples among the arguments take the kind of the first other triple argument, or else the
    // expected one (`mix(Ct, (1, 0.5, 0.25), s)`, `color c = mix((0, 0, 0), (1, 1, 1), s)`): they
    // were points, which a color argument does not match.
    if (ok) {
      Type kind = kError;
      for (const ExprPtr& a : args)
        if (a->kind != ExprKind::Tuple && a->type.isTriple() && !a->type.isArray()) {
          kind = a->type;
          break;
        }
      // (Not for transforms: which transform applies follows the argument's kind, not the result's.)
      if (kind.isError() && expected.isTriple() && !expected.isArray() && b && b->shape != BuiltinShape::Transform)
        kind = expected;
      if (!kind.isError())
        for (ExprPtr& a : args)
          if (a->kind == ExprKind::Tuple && a->type.isTriple()) a->type = Type(kind.kind);
    }
    if (!b) {
      // Once per body, as undeclared variables: the first call says it.
      if (!suppress_ && undeclaredReported_.insert(e.text + "()").second) {
        // RSL built-ins of surface and light shading, or of the renderer's state.
        static const std::set<std::string> kRslFunctions = {
            "environment", "shadow",   "depth",       "textureinfo", "attribute",  "option",
            "rendererinfo", "incident", "opposite",    "lightsource", "surface",    "atmosphere",
            "trace",       "transmission", "occlusion", "indirectdiffuse", "gather", "diffuse",
            "specular",    "specularbrdf", "ambient",  "phong",       "fresnel",    "bake3d",
            "texture3d",   "ctransform", "match",     "shadername",  "bump",       "illuminance"};
        auto r = report(DiagId::ErrUndeclaredFunction, e.range.begin);
        r.arg(e.text).range(e.opRange);
        if (kRslFunctions.count(e.text)) r.note(DiagId::NoteRslFunction, e.range.begin, {e.text}, e.opRange);
      }
      return set(e, kError);
    }
    if (!ok) return set(e, kError);
    if (b->shape == BuiltinShape::Texture) return checkTexture(e, expected);
    if (b->shape == BuiltinShape::Spline) return checkSpline(e);
    const Type r = callResult(*b, args, expected);
    if (r.isError()) {
      report(DiagId::ErrNoMatchingCall, e.range.begin).arg(e.text).arg(typeList(args)).range(e.opRange);
      return set(e, kError);
    }
    switch (b->shape) {
      case BuiltinShape::Deriv:
      case BuiltinShape::CalcNormal:
      case BuiltinShape::Filterwidth:
      case BuiltinShape::Filterstep:
      case BuiltinShape::DerivRatio:
        e.isVarying = true;
        noteVaryingSource();
        break;
      case BuiltinShape::Displace:
        markWrites(true, true, false);  // N = normalize(calculatenormal(P))
        noteVaryingSource();  // it reads P and N
        break;
      case BuiltinShape::Printf:
        if (args[0]->kind == ExprKind::StringLiteral) checkFormat(*args[0], args);
        break;
      case BuiltinShape::StringFn:
        if (b->id == BuiltinId::Format && args[0]->kind == ExprKind::StringLiteral) checkFormat(*args[0], args);
        break;
      case BuiltinShape::Random:
        e.isVarying = true;
        noteVaryingSource();
        break;
      case BuiltinShape::Arraylength:
        e.isVarying = false;  // the length is the declaration's, whatever the elements hold
        break;
      case BuiltinShape::Comp: {
        const bool m = args[0]->type.kind == TypeKind::Matrix;
        if (badConstantIndex(*args[1], m ? 4 : 3, args[0]->type) || (m && badConstantIndex(*args[2], 4, args[0]->type)))
          return set(e, kError);
        warnNarrowIndices(args, m ? 3 : 2);
        break;
      }
      case BuiltinShape::Setcomp:
      case BuiltinShape::SetXyz:
        if (b->shape == BuiltinShape::Setcomp) {
          const bool m = args[0]->type.kind == TypeKind::Matrix;
          if (badConstantIndex(*args[1], m ? 4 : 3, args[0]->type) || (m && badConstantIndex(*args[2], 4, args[0]->type)))
            return set(e, kError);
          warnNarrowIndices(args, m ? 3 : 2);
        }
        // The first argument is an output: it must be a writable variable or component.
        if (!checkAssignable(*args[0], args[0]->range.begin, args[0]->range)) return set(e, kError);
        checkUniformTarget(*args[0], e.isVarying, args.back()->range);
        break;
      default: break;
    }
    const size_t numSpaces = b->shape == BuiltinShape::Displace && args.size() == 2 ? 1
                             : b->shape == BuiltinShape::Transform &&
                                       args[0]->type.kind == TypeKind::String ? args.size() - 1
                                                                                   : 0;
    for (size_t i = 0; i < numSpaces; ++i) {
      const Expr& space = *args[i];
      if (space.kind == ExprKind::StringLiteral && !isKnownSpace(space.text)) {
        report(DiagId::ErrUnknownSpace, space.range.begin).arg(space.text).range(space.range);
        return set(e, kError);
      }
    }
    return set(e, r);
  }

  // -Wnarrowing for a float value converted to int. A constant with a whole value (`int n = 3.0`,
  // `a[1.0]`, an RSL `octaves` of 4) loses nothing, as clang does not warn on it either.
  void warnNarrowing(const Expr& value) {
    const Expr* e = &value;
    while (e->kind == ExprKind::Unary && (e->op == Tok::Minus || e->op == Tok::Plus) && e->operands.size() == 1)
      e = e->operands[0].get();
    if (e->kind == ExprKind::FloatLiteral && std::trunc(e->floatValue) == e->floatValue &&
        std::fabs(e->floatValue) < 2147483648.0f)
      return;
    report(DiagId::WarnNarrowing, value.range.begin).range(value.range);
  }

  // comp/setcomp: arguments 1..end-1 are int indices; a float one truncates (§2.1).
  void warnNarrowIndices(const std::vector<ExprPtr>& args, size_t end) {
    for (size_t i = 1; i < end; ++i)
      if (args[i]->type.kind == TypeKind::Float) warnNarrowing(*args[i]);
  }

  // Where the decoded character `index` of a string literal sits in the source, when the
  // literal's spelling is plain enough to tell (else at the opening quote).
  static SourceRange literalCharRange(const Expr& literal, size_t index, size_t length) {
    auto spelled = [&](size_t end) {
      size_t n = 0;
      for (size_t k = 0; k < end; ++k) n += std::string("\n\t\\\"").find(literal.text[k]) != std::string::npos ? 2 : 1;
      return n;
    };
    const uint32_t width = literal.range.end.offset - literal.range.begin.offset;
    if (width != spelled(literal.text.size()) + 2) return literal.range;  // a macro, a splice, ...
    const SourceLoc at = literal.range.begin.advanced(uint32_t(1 + spelled(index)));
    return {at, at.advanced(uint32_t(spelled(index + length) - spelled(index)))};  // "\n" is 2 wide
  }

  // A conversion character as the message shows it: escapes as they are written, so a message
  // stays on its line.
  static std::string shownCharacter(char c) {
    switch (c) {
      case '\n': return "\\n";
      case '\t': return "\\t";
      case '\\': return "\\\\";
      case '"': return "\\\"";
      default: break;
    }
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", static_cast<unsigned char>(c));
      return hex;
    }
    return std::string(1, c);
  }

  // -Wformat: a literal printf format against its arguments (§6.8).
  void checkFormat(const Expr& format, const std::vector<ExprPtr>& args) {
    const std::string& f = format.text;
    size_t arg = 1, conversions = 0;
    for (size_t i = 0; i < f.size(); ++i) {
      if (f[i] != '%') continue;
      if (i + 1 < f.size() && f[i + 1] == '%') {
        ++i;
        continue;
      }
      const size_t start = i;
      size_t j = i + 1;
      while (j < f.size() && std::string("-+ #0123456789.").find(f[j]) != std::string::npos) ++j;
      if (j >= f.size()) {
        // A '%' (and flags) with no conversion ends the format: printed verbatim at run time.
        const SourceRange r = literalCharRange(format, start, j - start);
        report(DiagId::WarnFormatInvalid, r.begin).arg("").range(r);
        break;
      }
      const char conv = f[j];
      i = j;
      ++conversions;
      if (std::string("difgespcm").find(conv) == std::string::npos) {
        // The run time prints such a conversion verbatim (and skips its argument).
        const SourceRange r = literalCharRange(format, start, j + 1 - start);
        report(DiagId::WarnFormatInvalid, r.begin).arg(shownCharacter(conv)).range(r);
      }
      if (arg >= args.size()) continue;
      const Expr& a = *args[arg++];
      const char* want = nullptr;
      bool ok = true;
      if (conv == 's') {
        want = "a string";
        ok = a.type.kind == TypeKind::String;
      } else if (conv == 'd' || conv == 'i') {
        want = "an int";
        ok = a.type.kind == TypeKind::Int;
      } else if (conv == 'f' || conv == 'g' || conv == 'e') {
        want = "a number";
        ok = a.type.isNumeric() || a.type.kind == TypeKind::Matrix;
      } else if (conv == 'p') {  // RSL's point, color and matrix conversions
        want = "a point, vector or normal";
        ok = a.type.isSpatial();
      } else if (conv == 'c') {
        want = "a color";
        ok = a.type.isTriple() && a.type.kind == TypeKind::Color;  // as %p wants the spatial types
      } else if (conv == 'm') {
        want = "a matrix";
        ok = a.type.kind == TypeKind::Matrix && !a.type.isArray();
      } else {
        continue;
      }
      if (!ok)
        report(DiagId::WarnFormatType, a.range.begin)
            .arg(std::string(1, conv))
            .arg(want)
            .arg(typeName(a.type))
            .range(a.range);
    }
    if (conversions != args.size() - 1)
      report(DiagId::WarnFormatCount, format.range.begin)
          .arg(static_cast<long long>(conversions))
          .arg(static_cast<long long>(args.size() - 1))
          .range(format.range);
  }

  // spline([basis,] x, knots...) (§6.6): T binds to the knots; a literal basis checks the count.
  // A basis held in a string variable is chosen at run time (codegen falls back to catmull-rom
  // for a name it does not know), so only the minimum of every basis, 4 knots, is checked here.
  Type checkSpline(Expr& e) {
    std::vector<ExprPtr>& args = e.operands;
    size_t first = 0;
    std::string basis = "catmull-rom";
    bool runtimeBasis = false;
    auto noMatch = [&] {
      report(DiagId::ErrNoMatchingCall, e.range.begin).arg(e.text).arg(typeList(args)).range(e.opRange);
      return set(e, kError);
    };
    if (!args.empty() && args[0]->type.kind == TypeKind::String) {
      runtimeBasis = args[0]->kind != ExprKind::StringLiteral;
      if (!runtimeBasis) basis = args[0]->text;
      first = 1;
    }
    static const std::set<std::string> kBases = {"catmull-rom", "bspline", "linear", "constant", "bezier", "hermite"};
    if (!kBases.count(basis)) {
      report(DiagId::ErrSplineBasis, args[0]->range.begin).arg(basis).range(args[0]->range);
      return set(e, kError);
    }
    if (args.size() < first + 2 || !args[first]->type.isScalar()) return noMatch();
    Type knotType;
    int count = 0;
    if (args.size() == first + 2 && args[first + 1]->type.isArray()) {
      knotType = args[first + 1]->type.element();
      count = args[first + 1]->type.arrayLength;
      if (!(knotType.isScalar() || knotType.isTriple())) return noMatch();
      if (knotType.kind == TypeKind::Int) knotType = kFloat;
    } else {
      knotType = kFloat;
      for (size_t i = first + 1; i < args.size(); ++i)
        if (args[i]->type.isTriple()) {
          knotType = args[i]->type;
          break;
        }
      for (size_t i = first + 1; i < args.size(); ++i)
        if (args[i]->type.isArray() || conversion(args[i]->type, knotType) == Conversion::None) return noMatch();
      count = int(args.size() - first - 1);
    }
    // An unsized array parameter's length is known only where the function is inlined: codegen
    // checks it there, counting a misfit as a run-time spline problem.
    if (count == -1) return set(e, knotType);
    if (runtimeBasis && count < 4) {
      report(DiagId::ErrSplineKnotsAnyBasis, e.range.begin).arg(count).range(e.opRange);
      return set(e, kError);
    }
    const bool ok = runtimeBasis           ? true
                    : basis == "bezier"  ? count >= 4 && (count - 1) % 3 == 0
                    : basis == "hermite" ? count >= 4 && count % 2 == 0
                                         : count >= 4;
    if (!ok) {
      report(DiagId::ErrSplineKnots, e.range.begin).arg(basis).arg(count).range(e.opRange);
      return set(e, kError);
    }
    return set(e, knotType);
  }

  // texture(string file[, float s, float t][, "option", value ...]) (§6.7), context-typed.
  Type checkTexture(Expr& e, Type expected) {
    std::vector<ExprPtr>& args = e.operands;
    if (args.empty() || args[0]->type.kind != TypeKind::String) {
      report(DiagId::ErrNoMatchingCall, e.range.begin).arg(e.text).arg(typeList(args)).range(e.opRange);
      return set(e, kError);
    }
    size_t first = 1;
    if (args.size() >= 3 && args[1]->type.isScalar() && args[2]->type.isScalar()) first = 3;
    // RSL's four-point form names the corners of the area to filter: a clearer error than "option
    // names must be string literals" at its third coordinate.
    if (first == 3 && args.size() >= 9) {
      bool fourPoints = true;
      for (size_t i = 3; i < 9; ++i) fourPoints &= args[i]->type.isScalar() && args[i]->kind != ExprKind::StringLiteral;
      if (fourPoints) {
        report(DiagId::ErrTextureFourPoints, args[3]->range.begin).range(args[3]->range).range(args[8]->range);
        return set(e, kError);
      }
    }
    if ((args.size() - first) % 2 != 0) {
      report(DiagId::ErrNoMatchingCall, e.range.begin).arg(e.text).arg(typeList(args)).range(e.opRange);
      return set(e, kError);
    }
    // Every option is checked, so that one compile reports each bad one.
    bool bad = false;
    for (size_t i = first; i < args.size(); i += 2) {
      const Expr& name = *args[i];
      const Expr& value = *args[i + 1];
      if (name.kind != ExprKind::StringLiteral) {
        report(DiagId::ErrTextureOptionName, name.range.begin).range(name.range);
        bad = true;
        continue;
      }
      static const std::set<std::string> kFloat = {"blur", "sblur", "tblur", "width", "swidth", "twidth",
                                                   "fill", "samples", "lerp"};
      static const std::set<std::string> kString = {"wrap", "swrap", "twrap", "filter"};
      const char* want = nullptr;
      bool fitsValue = false;
      if (kFloat.count(name.text)) {
        want = "float";
        fitsValue = value.type.isScalar();
      } else if (kString.count(name.text)) {
        want = "string";
        fitsValue = value.type.kind == TypeKind::String;
      } else if (name.text == "firstchannel") {
        want = "int";
        fitsValue = value.type.isScalar();
        // A float converts as it would to an int parameter (§2.1).
        if (value.type.kind == TypeKind::Float) warnNarrowing(value);
        // A constant negative channel is an error, as a constant negative index is (§6.3); one
        // computed at run time reads the fill value, as a channel the file lacks does.
        const bool negated = value.kind == ExprKind::Unary && value.op == Tok::Minus;
        const Expr& literal = negated ? *value.operands[0] : value;
        const double magnitude = literal.kind == ExprKind::IntLiteral     ? double(literal.intValue)
                                 : literal.kind == ExprKind::FloatLiteral ? std::trunc(double(literal.floatValue))
                                                                          : 0.0;
        if (negated && magnitude > 0.0) {
          report(DiagId::ErrTextureChannel, value.range.begin).arg(static_cast<long long>(-magnitude)).range(value.range);
          bad = true;
          continue;
        }
      } else if (name.text == "missingcolor") {
        want = "color";
        fitsValue = value.type.kind == TypeKind::Color || value.type.isScalar();
      } else {
        report(DiagId::ErrTextureOption, name.range.begin).arg(name.text).range(name.range);
        bad = true;
        continue;
      }
      static const std::set<std::string> kWrap = {"default", "black", "clamp", "periodic", "mirror"};
      if (fitsValue && name.text.find("wrap") != std::string::npos && value.kind == ExprKind::StringLiteral &&
          !kWrap.count(value.text)) {
        report(DiagId::ErrTextureWrap, value.range.begin).arg(value.text).range(value.range);
        bad = true;
        continue;
      }
      if (!fitsValue) {
        report(DiagId::ErrTextureOptionType, name.range.begin)
            .arg(name.text)
            .arg(want)
            .arg(typeName(value.type))
            .range(name.range)
            .range(value.range);
        bad = true;
      }
    }
    if (bad) return set(e, kError);
    if (first == 1) {
      // Without coordinates, texture reads the globals s and t.
      e.isVarying = true;
      noteVaryingSource();
    }
    // float|color (§6.7): a triple context asks for the three channels, which are a color; a
    // spatial context then needs a cast (`vector(texture(...))`), as color↔spatial always does.
    if (contextFloat_) return set(e, kFloat);
    return set(e, expected.isTriple() ? Type(TypeKind::Color) : kFloat);
  }

  // The §6 "T" binding: first triple argument, else int when `allowInt` and all are int, else float.
  static Type bindT(const std::vector<ExprPtr>& args, bool allowInt) {
    for (const ExprPtr& a : args)
      if (a->type.isTriple()) return a->type;
    if (allowInt) {
      bool allInt = true;
      for (const ExprPtr& a : args) allInt &= a->type.kind == TypeKind::Int;
      if (allInt) return kInt;
    }
    return kFloat;
  }
  static bool fits(const Expr& a, Type t) { return conversion(a.type, t) != Conversion::None; }
  static bool allFit(const std::vector<ExprPtr>& args, Type t, size_t from = 0, size_t to = SIZE_MAX) {
    for (size_t i = from; i < args.size() && i < to; ++i)
      if (!fits(*args[i], t) || args[i]->type.isArray() || args[i]->type.kind == TypeKind::String)
        return false;
    return true;
  }

  Type callResult(const BuiltinInfo& b, const std::vector<ExprPtr>& args, Type expected) {
    const size_t n = args.size();
    auto allNumeric = [&] {
      for (const ExprPtr& a : args)
        if (!a->type.isNumeric()) return false;
      return true;
    };
    const bool matrixFirst = n > 0 && args[0]->type == Type(TypeKind::Matrix);
    if (!allNumeric() && b.shape != BuiltinShape::Displace && b.shape != BuiltinShape::Transform &&
        b.shape != BuiltinShape::Filterstep && b.shape != BuiltinShape::Arraylength &&
        b.shape != BuiltinShape::Printf && b.shape != BuiltinShape::StringFn &&
        !(matrixFirst && (b.shape == BuiltinShape::Comp || b.shape == BuiltinShape::Setcomp ||
                          b.shape == BuiltinShape::MatrixFn)))
      return kError;
    switch (b.shape) {
      case BuiltinShape::UnaryT: {
        if (b.id == BuiltinId::Atan && n == 2) {
          const Type t = bindT(args, false);
          return allFit(args, t) ? t : kError;
        }
        if (b.id == BuiltinId::Log && n == 2) {
          const Type t = bindT(args, false);
          return fits(*args[0], t) && args[1]->type.isScalar() ? t : kError;
        }
        if (n != 1) return kError;
        // §6.2: of these only abs has an int form (sign(-3) is -1.0, as in RSL).
        return bindT(args, b.id == BuiltinId::Abs);
      }
      case BuiltinShape::BinaryT: {
        if (n != 2) return kError;
        const Type t = bindT(args, false);  // §6.2: mod has no int form (mod(7, 4) is 3.0)
        return allFit(args, t) ? t : kError;
      }
      case BuiltinShape::PowT: {
        if (n != 2) return kError;
        const Type t = bindT(args, false);
        return fits(*args[0], t) && (fits(*args[1], t) || args[1]->type.isScalar()) ? t : kError;
      }
      case BuiltinShape::MinMax: {
        if (n < 2) return kError;
        const Type t = bindT(args, true);
        return allFit(args, t) ? t : kError;
      }
      case BuiltinShape::Clamp:
      case BuiltinShape::Smoothstep: {
        if (n != 3) return kError;
        const Type t = bindT(args, b.shape == BuiltinShape::Clamp);
        return allFit(args, t) ? t : kError;
      }
      case BuiltinShape::Mix: {
        if (n != 3) return kError;
        const Type t = bindT(args, false);
        return allFit(args, t, 0, 2) && (fits(*args[2], t) || args[2]->type.isScalar()) ? t : kError;
      }
      case BuiltinShape::Dot:
        if (n != 2) return kError;
        return binaryResult(Tok::Dot, args[0]->type, args[1]->type);
      case BuiltinShape::Cross:
        return n == 2 && args[0]->type.isSpatial() && args[1]->type.isSpatial() ? kVector : kError;
      case BuiltinShape::Length:
      case BuiltinShape::Component: return n == 1 && args[0]->type.isSpatial() ? kFloat : kError;
      case BuiltinShape::Normalize: return n == 1 && args[0]->type.isSpatial() ? args[0]->type : kError;
      case BuiltinShape::CalcNormal: return n == 1 && args[0]->type.isSpatial() ? kVector : kError;
      // Indices are `int`; a float converts as §2.1 says (truncated, -Wnarrowing at the call).
      case BuiltinShape::Comp:
        if (matrixFirst) return n == 3 && args[1]->type.isScalar() && args[2]->type.isScalar() ? kFloat : kError;
        return n == 2 && args[0]->type.isTriple() && args[1]->type.isScalar() ? kFloat : kError;
      case BuiltinShape::Setcomp:
        if (matrixFirst)
          return n == 4 && args[1]->type.isScalar() && args[2]->type.isScalar() && args[3]->type.isScalar() ? kVoid
                                                                                                             : kError;
        return n == 3 && args[0]->type.isTriple() && args[1]->type.isScalar() && args[2]->type.isScalar() ? kVoid
                                                                                                          : kError;
      case BuiltinShape::SetXyz: return n == 2 && args[0]->type.isSpatial() && args[1]->type.isScalar() ? kVoid : kError;
      case BuiltinShape::DerivRatio:
        if (n != 2 || !args[1]->type.isScalar()) return kError;
        if (args[0]->type.isScalar()) return kFloat;
        return args[0]->type.isSpatial() ? kVector : kError;
      case BuiltinShape::Random:
        if (n != 0) return kError;
        if (contextFloat_) return kFloat;
        return expected.isTriple() || expected.kind == TypeKind::Float ? expected.element() : kFloat;
      case BuiltinShape::Deriv: {
        if (n != 1) return kError;
        const Type t = args[0]->type;
        if (t.isScalar()) return kFloat;
        return t.kind == TypeKind::Color ? t : kVector;
      }
      case BuiltinShape::Noise: {
        if (n < 1 || n > 2) return kError;
        if (!(args[0]->type.isScalar() || args[0]->type.isSpatial())) return kError;
        if (n == 2 && !args[1]->type.isScalar()) return kError;
        if (contextFloat_) return kFloat;
        return expected.isTriple() || expected.kind == TypeKind::Float ? expected.element() : kFloat;
      }
      case BuiltinShape::Displace:
        if (n == 1 && (args[0]->type.isSpatial() || args[0]->type.isScalar())) return kVoid;
        if (n == 2 && args[0]->type.kind == TypeKind::String && args[1]->type.isScalar()) return kVoid;
        return kError;
      case BuiltinShape::MatrixFn:
        if (n != 1 || !matrixFirst) return kError;
        return b.id == BuiltinId::Determinant ? kFloat : Type(TypeKind::Matrix);
      case BuiltinShape::StringFn: {
        if (n < 1 || args[0]->type.kind != TypeKind::String) return kError;
        for (const ExprPtr& a : args) {
          if (a->type.isArray()) return kError;
          if (b.id == BuiltinId::Concat && a->type.kind != TypeKind::String) return kError;
        }
        return Type(TypeKind::String);
      }
      case BuiltinShape::FloatPred: return n == 1 && args[0]->type.isScalar() ? kInt : kError;
      case BuiltinShape::Transform: {
        if (n == 2 && matrixFirst) {
          const Type p = args[1]->type;
          if (!p.isSpatial()) return kError;
          if (b.id == BuiltinId::Vtransform) return kVector;
          if (b.id == BuiltinId::Ntransform) return Type(TypeKind::Normal);
          return p;
        }
        if (n != 2 && n != 3) return kError;
        for (size_t i = 0; i + 1 < n; ++i)
          if (args[i]->type.kind != TypeKind::String) return kError;
        const Type p = args[n - 1]->type;
        if (!p.isSpatial()) return kError;
        if (b.id == BuiltinId::Vtransform) return kVector;
        if (b.id == BuiltinId::Ntransform) return Type(TypeKind::Normal);
        return p;
      }
      case BuiltinShape::Filterwidth:
        if (n != 1) return kError;
        if (args[0]->type.isScalar()) return kFloat;
        return args[0]->type.isSpatial() ? kVector : kError;
      case BuiltinShape::Filterstep: {
        // (e, x[, x2]) then RSL's name/value pairs: "width" (a float) and "filter" (a name,
        // accepted and ignored as texture() does: the step is always box-filtered).
        auto scalar = [&](size_t i) { return args[i]->type.isScalar(); };
        if (n < 2 || !scalar(0) || !scalar(1)) return kError;
        const size_t first = n >= 3 && scalar(2) ? 3 : 2;
        if ((n - first) % 2 != 0) return kError;
        for (size_t i = first; i < n; i += 2) {
          if (args[i]->kind != ExprKind::StringLiteral) return kError;
          const bool ok = (args[i]->text == "width" && scalar(i + 1)) ||
                          (args[i]->text == "filter" && args[i + 1]->type.kind == TypeKind::String);
          if (!ok) return kError;
        }
        return kFloat;
      }
      case BuiltinShape::Texture:  // checkTexture
      case BuiltinShape::Spline: return kError;  // checkSpline
      case BuiltinShape::Printf: {
        if (n < 1 || args[0]->type.kind != TypeKind::String) return kError;
        for (const ExprPtr& a : args)
          if (a->type.isArray()) return kError;
        return kVoid;
      }
      case BuiltinShape::Arraylength: return n == 1 && args[0]->type.isArray() ? kInt : kError;
      case BuiltinShape::PNoise: {
        auto scalar = [&](size_t i) { return args[i]->type.isScalar(); };
        auto spatial = [&](size_t i) { return args[i]->type.isSpatial(); };
        const bool ok = (n == 2 && scalar(0) && scalar(1)) ||
                        (n == 4 && scalar(0) && scalar(1) && scalar(2) && scalar(3)) ||
                        (n == 2 && spatial(0) && spatial(1)) ||
                        (n == 4 && spatial(0) && scalar(1) && spatial(2) && scalar(3));
        if (!ok) return kError;
        if (contextFloat_) return kFloat;
        return expected.isTriple() || expected.kind == TypeKind::Float ? expected.element() : kFloat;
      }
    }
    return kError;
  }

  TranslationUnit& unit_;
  DiagnosticsEngine& diags_;
  const Prelude* prelude_;
  DiagnosticsEngine scratch_;
  std::vector<std::unordered_map<std::string, VarDecl*>> scopes_;
  std::vector<std::vector<VarDecl*>> scopeDecls_;
  std::set<std::string> undeclaredReported_;
  // The variable whose initializer is being checked: its name is not in scope yet (C scoping
  // would make it read itself, uninitialized), so a use of it gets its own message.
  const VarDecl* initializing_ = nullptr;
  ShaderDecl* shader_ = nullptr;
  FunctionDecl* function_ = nullptr;
  std::vector<FunctionDecl*> functionStack_;
  std::vector<std::unordered_map<std::string, std::vector<FunctionDecl*>>> functionScopes_;
  // While checking a nested function: the enclosing variable scopes, for `extern`.
  std::vector<const std::vector<std::unordered_map<std::string, VarDecl*>>*> outerScopes_;
  int loopDepth_ = 0;
  int suppress_ = 0;
  int contextFloat_ = 0;
  bool matrixRowOk_ = false;  // the expression being checked is the base of an Index
  bool skipUnusedWarnings_ = false;
  uint64_t inlineCost_ = 0;  // expression nodes of the shader or function being checked, inlined
  bool inlineReported_ = false;
  // Inlining budget per shader or function: far above real shaders, far below what exhausts
  // memory or compile time (each call of a function copies its body).
  static constexpr uint64_t kMaxInlineCost = 200000;
  static constexpr uint32_t kMaxCallDepth = 1000;
  bool callDepthReported_ = false;
};

}  // namespace

// The indices of a written lvalue (`a[i][j] = x`) are read; its variable is not.
void UninitializedAnalysis::readIndices(const Expr& target) {
  for (const Expr* t = &target; t->kind == ExprKind::Index; t = t->operands[0].get()) expr(*t->operands[1]);
}

void UninitializedAnalysis::assignTarget(const Expr& target) {
  const Expr* base = &indexRoot(target);
  if (base->kind == ExprKind::Identifier && base->decl) {
    state_.assigned.insert(base->decl);
    state_.maybe.insert(base->decl);
  }
}

void UninitializedAnalysis::expr(const Expr& e) {
  switch (e.kind) {
    case ExprKind::Identifier:
      if (e.decl && tracked_.count(e.decl) && !state_.assigned.count(e.decl) && !state_.dead && !silent_ &&
          warned_.insert(e.decl).second)
        checker_.report(state_.maybe.count(e.decl) ? DiagId::WarnMaybeUninitialized : DiagId::WarnUninitialized,
                        e.range.begin)
            .arg(e.decl->name)
            .range(e.opRange);
      return;
    case ExprKind::Assign: {
      const Expr& target = *e.operands[0];
      // Compound assignment reads the target; plain assignment only its indices.
      if (e.op != Tok::Assign)
        expr(target);
      else
        readIndices(target);
      expr(*e.operands[1]);
      assignTarget(target);
      return;
    }
    case ExprKind::Binary:
      if (e.op == Tok::AmpAmp || e.op == Tok::PipePipe) {
        State t, f;
        cond(e, &t, &f);  // the right operand may not run
        state_ = join(t, f);
        return;
      }
      break;
    case ExprKind::Conditional: {
      State t, f;
      cond(*e.operands[0], &t, &f);
      state_ = std::move(t);
      expr(*e.operands[1]);
      const State a = state_;
      state_ = std::move(f);
      expr(*e.operands[2]);
      state_ = join(a, state_);
      return;
    }
    case ExprKind::Call: {
      // All arguments are evaluated before the call writes its output arguments.
      std::vector<const Expr*> written;
      for (size_t i = 0; i < e.operands.size(); ++i) {
        const bool isOutput = e.function && i < e.function->params.size() && e.function->params[i]->isOutput;
        const bool isSetter = e.builtin && i == 0 &&
                              (e.builtin->shape == BuiltinShape::Setcomp || e.builtin->shape == BuiltinShape::SetXyz);
        if (isOutput || isSetter) {
          readIndices(*e.operands[i]);
          written.push_back(e.operands[i].get());
        } else {
          expr(*e.operands[i]);
        }
      }
      for (const Expr* w : written) assignTarget(*w);
      return;
    }
    default: break;
  }
  for (const ExprPtr& c : e.operands) expr(*c);
}

void UninitializedAnalysis::cond(const Expr& e, State* whenTrue, State* whenFalse) {
  const bool andOr = e.kind == ExprKind::Binary && (e.op == Tok::AmpAmp || e.op == Tok::PipePipe);
  if (andOr) {
    const bool isAnd = e.op == Tok::AmpAmp;
    State leftTrue, leftFalse, rightTrue, rightFalse;
    cond(*e.operands[0], &leftTrue, &leftFalse);
    // The right operand runs where the left one did not decide the result.
    state_ = isAnd ? leftTrue : leftFalse;
    cond(*e.operands[1], &rightTrue, &rightFalse);
    if (isAnd) {
      *whenTrue = std::move(rightTrue);
      *whenFalse = join(leftFalse, rightFalse);
    } else {
      *whenTrue = join(leftTrue, rightTrue);
      *whenFalse = std::move(rightFalse);
    }
    // What the right operand may set, it may have set on either outcome.
    whenTrue->maybe.insert(rightFalse.maybe.begin(), rightFalse.maybe.end());
    whenTrue->maybe.insert(rightTrue.maybe.begin(), rightTrue.maybe.end());
    whenFalse->maybe.insert(whenTrue->maybe.begin(), whenTrue->maybe.end());
    whenTrue->maybe.insert(whenFalse->maybe.begin(), whenFalse->maybe.end());
    return;
  }
  if (e.kind == ExprKind::Unary && e.op == Tok::Bang) {
    cond(*e.operands[0], whenFalse, whenTrue);
    return;
  }
  expr(e);
  *whenTrue = state_;
  *whenFalse = state_;
}

void UninitializedAnalysis::stmt(const Stmt& s) {
  switch (s.kind) {
    case StmtKind::Block:
      for (const StmtPtr& c : s.stmts) stmt(*c);
      return;
    case StmtKind::Decl:
      for (const auto& d : s.decls) {
        if (d->init) {
          expr(*d->init);
          state_.assigned.insert(d.get());
          state_.maybe.insert(d.get());
        } else if (!d->type.isArray()) {
          tracked_.insert(d.get());
          state_.assigned.erase(d.get());
          state_.maybe.erase(d.get());
        }
      }
      return;
    case StmtKind::ExprStmt: expr(*s.expr); return;
    case StmtKind::If: {
      State t, f;
      cond(*s.cond, &t, &f);
      state_ = std::move(t);
      stmt(*s.then);
      const State a = state_;
      state_ = std::move(f);
      if (s.otherwise) stmt(*s.otherwise);
      state_ = join(a, state_);
      return;
    }
    case StmtKind::While:
    case StmtKind::For: {
      if (s.init) stmt(*s.init);
      // A variable the body sets may hold a value from the previous iteration wherever the body
      // reads it: "may be", not "is", uninitialized there.
      // A silent first pass finds them (loops inside it skip their own, so nesting costs a
      // pass per level, not a power of two).
      if (!silent_) {
        const State before = state_;
        silent_ = true;
        breaks_.push_back(deadState()), continues_.push_back(deadState());
        stmt(*s.body);
        if (s.step) expr(*s.step);
        breaks_.pop_back(), continues_.pop_back();
        silent_ = false;
        std::set<const VarDecl*> setByBody = std::move(state_.maybe);
        state_ = before;
        state_.maybe.insert(setByBody.begin(), setByBody.end());
      }
      State saved = state_;  // where the loop ends: its condition false
      if (s.cond) {
        State t;
        cond(*s.cond, &t, &saved);
        state_ = std::move(t);
      }
      breaks_.push_back(deadState()), continues_.push_back(deadState());
      stmt(*s.body);
      state_ = join(state_, continues_.back());
      if (s.step) expr(*s.step);
      saved.maybe.insert(state_.maybe.begin(), state_.maybe.end());  // ...or may
      leaveLoop(s.cond.get(), std::move(saved));  // the body may not run
      return;
    }
    case StmtKind::DoWhile: {
      // The body runs at least once; the loop is left where the condition is false (reached at
      // the end of the body or by continue) or by break.
      breaks_.push_back(deadState()), continues_.push_back(deadState());
      stmt(*s.body);
      state_ = join(state_, continues_.back());
      State whenFalse = state_;
      if (!state_.dead) {
        State t;
        cond(*s.cond, &t, &whenFalse);
      }
      leaveLoop(s.cond.get(), std::move(whenFalse));
      return;
    }
    case StmtKind::Return:
      if (s.expr) expr(*s.expr);
      state_.dead = true;
      return;
    case StmtKind::Break:
    case StmtKind::Continue: {
      std::vector<State>& targets = s.kind == StmtKind::Break ? breaks_ : continues_;
      if (size_t(s.levels) <= targets.size()) {
        State& target = targets[targets.size() - size_t(s.levels)];
        target = join(target, state_);
      }
      state_.dead = true;
      return;
    }
    case StmtKind::Empty:
    case StmtKind::FunctionDef:  // analyzed when the function itself is checked
    case StmtKind::Extern: return;
  }
}

bool typeCheck(TranslationUnit& unit, DiagnosticsEngine& diags, const Prelude* prelude) {
  const unsigned before = diags.numErrors();
  Checker(unit, diags, prelude).run();
  return diags.numErrors() == before;
}

}  // namespace relief::compiler
