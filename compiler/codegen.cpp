// Codegen implementation (see codegen.h). Values are handled per component as dual numbers; a null
// derivative lane means an exact zero, so uniform arithmetic costs nothing extra and LLVM's DCE
// removes derivative lanes nobody reads.
#include "compiler/codegen.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <map>

#include <llvm/IR/Constants.h>
#include <llvm/IR/DerivedTypes.h>
#include <llvm/IR/Function.h>
#include <llvm/IR/IRBuilder.h>
#include <llvm/IR/Intrinsics.h>
#include <llvm/IR/LLVMContext.h>
#include <llvm/IR/Module.h>
#include <llvm/IR/Verifier.h>

#include "runtime/abi.h"
#include "runtime/builtins_space.h"
#include "runtime/builtins_texture.h"

namespace relief::compiler {

namespace {

using llvm::Value;

struct Dual {
  Value* v = nullptr;
  Value* du = nullptr;  // null: zero
  Value* dv = nullptr;
};

struct Slot;

// A typed value: ints and strings use c[0].v only; floats c[0]; triples c[0..2]; matrices
// c[0..15] (row-major, no derivative lanes). Arrays are not SSA values: `array` names the storage
// holding them (copied element-wise when stored).
struct Val {
  Type type;
  Dual c[16];
  const Slot* array = nullptr;
};

// Which derivative lanes of variables get storage. A lane alloca exists only where some store may put
// a non-zero derivative in it: otherwise its loads would be opaque zeros that the optimiser may not
// fold (0 * x is not 0 for x = inf), and uniform data such as parameters would pay for dual
// arithmetic. Lanes are numbered in the deterministic order codegen creates them; generateModule
// reruns codegen with `allocate` = the previous run's `live` until the two agree.
struct LanePlan {
  std::vector<char> allocate;  // by lane number; empty: every lane
  std::vector<char> live;      // filled by the run: a non-zero derivative was stored
  bool dropped = false;        // a non-zero derivative met an unallocated lane: rerun with every lane
  uint32_t count = 0;          // lanes the run numbered
  bool allocates(uint32_t lane) const { return allocate.empty() || (lane < allocate.size() && allocate[lane]); }
  bool isLive(uint32_t lane) const { return lane < live.size() && live[lane]; }
};

// Storage of a variable: one alloca per component and lane ([N x T] allocas for arrays). A null
// lane alloca holds an exact zero (see LanePlan).
struct Slot {
  Type type;
  llvm::AllocaInst* v[16] = {};
  llvm::AllocaInst* du[16] = {};
  llvm::AllocaInst* dv[16] = {};
};

int numComponents(Type t) { return t.isTriple() ? 3 : t.kind == TypeKind::Matrix && !t.isArray() ? 16 : 1; }
int elementComponents(Type t) { return numComponents(t.element()); }

runtime::ParamType paramTypeOf(TypeKind k) {
  switch (k) {
    case TypeKind::Int: return runtime::ParamType::Int;
    case TypeKind::Point: return runtime::ParamType::Point;
    case TypeKind::Vector: return runtime::ParamType::Vector;
    case TypeKind::Normal: return runtime::ParamType::Normal;
    case TypeKind::Color: return runtime::ParamType::Color;
    case TypeKind::String: return runtime::ParamType::String;
    case TypeKind::Matrix: return runtime::ParamType::Matrix;
    default: return runtime::ParamType::Float;
  }
}

class ShaderCodegen {
 public:
  ShaderCodegen(llvm::Module& module, const ShaderDecl& shader, uint32_t loopLimit, LanePlan& lanes)
      : ctx_(module.getContext()), module_(module), shader_(shader), b_(ctx_), loopLimit_(loopLimit), lanes_(lanes) {
    f32_ = llvm::Type::getFloatTy(ctx_);
    i32_ = llvm::Type::getInt32Ty(ctx_);
    i64_ = llvm::Type::getInt64Ty(ctx_);
    i8_ = llvm::Type::getInt8Ty(ctx_);
    ptr_ = llvm::PointerType::get(ctx_, 0);
  }

  ShaderLayout generate() {
    ShaderLayout layout;
    layout.name = shader_.name;
    layout.ownNormal = shader_.ownNormal;
    layout.entrySymbol = "rlf_shader_" + shader_.name;
    layout.defaultsSymbol = "rlf_defaults_" + shader_.name;
    layoutParams(layout);
    emitDefaults(layout);
    emitEntry(layout);
    return layout;
  }

 private:
  // ---- Parameter block layout (runtime/shader.h): 4-byte scalars, strings 8-byte aligned.
  void layoutParams(ShaderLayout& layout) {
    uint32_t offset = 0;
    for (const auto& p : shader_.params) {
      runtime::ParamInfo info;
      info.name = p->name;
      info.type = paramTypeOf(p->type.kind);
      info.isOutput = p->isOutput;
      const uint32_t count = p->type.arrayLength > 0 ? uint32_t(p->type.arrayLength) : 1;
      info.arrayLength = p->type.arrayLength > 0 ? p->type.arrayLength : 0;
      if (p->type.kind == TypeKind::String) {
        offset = (offset + 7) & ~7u;
        info.offset = offset;
        offset += 8 * count;
      } else {
        info.offset = offset;
        offset += 4 * uint32_t(elementComponents(p->type)) * count;
      }
      paramOffsets_[p.get()] = info.offset;
      layout.params.push_back(std::move(info));
    }
    // The "bound" flags of defaults evaluated at shading time (VarDecl::defaultAtShadingTime).
    offset = (offset + 3) & ~3u;
    for (size_t i = 0; i < shader_.params.size(); ++i) {
      if (!shader_.params[i]->defaultAtShadingTime) continue;
      layout.params[i].boundFlagOffset = int32_t(offset);
      boundFlagOffsets_[shader_.params[i].get()] = offset;
      offset += 4;
    }
    layout.blockSize = (offset + 7) & ~7u;
  }

  // ---- Small IR helpers.
  Value* cf(float x) { return llvm::ConstantFP::get(f32_, x); }
  Value* ci(int32_t x) { return llvm::ConstantInt::get(i32_, uint32_t(x), true); }
  Value* bytePtr(Value* base, uint64_t offset) {
    return b_.CreateConstInBoundsGEP1_64(i8_, base, offset);
  }
  Value* loadPtrField(Value* base, size_t offset) { return b_.CreateLoad(ptr_, bytePtr(base, offset)); }
  llvm::AllocaInst* entryAlloca(llvm::Type* t, const char* name = "") {
    llvm::IRBuilder<> eb(&fn_->getEntryBlock(), fn_->getEntryBlock().begin());
    return eb.CreateAlloca(t, nullptr, name);
  }
  Value* intrinsic(llvm::Intrinsic::ID id, std::initializer_list<Value*> args) {
    llvm::Function* f = llvm::Intrinsic::getDeclaration(&module_, id, {f32_});
    return b_.CreateCall(f, llvm::ArrayRef<Value*>(args.begin(), args.size()));
  }
  Value* libcall(const char* name, std::initializer_list<Value*> args) {
    std::vector<llvm::Type*> params(args.size(), f32_);
    llvm::FunctionCallee f = module_.getOrInsertFunction(name, llvm::FunctionType::get(f32_, params, false));
    if (auto* fn = llvm::dyn_cast<llvm::Function>(f.getCallee())) {
      fn->setDoesNotThrow();
      fn->setWillReturn();
      fn->setDoesNotAccessMemory();
    }
    return b_.CreateCall(f, llvm::ArrayRef<Value*>(args.begin(), args.size()));
  }
  llvm::BasicBlock* newBlock(const char* name) { return llvm::BasicBlock::Create(ctx_, name, fn_); }
  // After a terminator, later statements go to a fresh unreachable block LLVM deletes.
  void startDeadBlock() { b_.SetInsertPoint(newBlock("dead")); }
  bool terminated() { return b_.GetInsertBlock()->getTerminator() != nullptr; }

  // ---- Dual arithmetic. Lanes are combined symbolically when one side is zero.
  Value* lAdd(Value* a, Value* b) { return !a ? b : !b ? a : b_.CreateFAdd(a, b); }
  Value* lSub(Value* a, Value* b) { return !b ? a : !a ? b_.CreateFNeg(b) : b_.CreateFSub(a, b); }
  Value* lMul(Value* lane, Value* k) { return lane ? b_.CreateFMul(lane, k) : nullptr; }
  Value* lSel(Value* c, Value* a, Value* b) {
    if (!a && !b) return nullptr;
    return b_.CreateSelect(c, a ? a : cf(0), b ? b : cf(0));
  }
  Dual dconst(float x) { return {cf(x), nullptr, nullptr}; }
  Dual dadd(Dual a, Dual b) { return {b_.CreateFAdd(a.v, b.v), lAdd(a.du, b.du), lAdd(a.dv, b.dv)}; }
  Dual dsub(Dual a, Dual b) { return {b_.CreateFSub(a.v, b.v), lSub(a.du, b.du), lSub(a.dv, b.dv)}; }
  Dual dneg(Dual a) { return {b_.CreateFNeg(a.v), a.du ? b_.CreateFNeg(a.du) : nullptr, a.dv ? b_.CreateFNeg(a.dv) : nullptr}; }
  Dual dmul(Dual a, Dual b) {
    return {b_.CreateFMul(a.v, b.v), lAdd(lMul(a.du, b.v), lMul(b.du, a.v)),
            lAdd(lMul(a.dv, b.v), lMul(b.dv, a.v))};
  }
  // Division by zero yields 0 (§4.1), derivatives included.
  Dual ddiv(Dual a, Dual b) {
    Value* zero = b_.CreateFCmpOEQ(b.v, cf(0));
    Value* safeB = b_.CreateSelect(zero, cf(1), b.v);
    Value* q = b_.CreateFDiv(a.v, safeB);
    Dual r;
    r.v = b_.CreateSelect(zero, cf(0), q);
    // The lanes share one reciprocal: divisions are the slowest arithmetic there is. A denormal
    // divisor's reciprocal would overflow (and 0 * inf is NaN), so the lanes use FLT_MIN in its
    // place: a finite, if approximate, derivative of an already degenerate quotient.
    Value* recip = nullptr;
    auto lane = [&](Value* da, Value* db) -> Value* {
      if (!da && !db) return nullptr;
      Value* num = lSub(da, lMul(db, q));
      if (!recip) {
        Value* tiny = b_.CreateFCmpOLT(intrinsic(llvm::Intrinsic::fabs, {safeB}), cf(1.17549435e-38f));
        Value* lb = b_.CreateSelect(tiny, intrinsic(llvm::Intrinsic::copysign, {cf(1.17549435e-38f), safeB}), safeB);
        recip = b_.CreateFDiv(cf(1), lb);
      }
      return b_.CreateSelect(zero, cf(0), b_.CreateFMul(num ? num : cf(0), recip));
    };
    r.du = lane(a.du, b.du);
    r.dv = lane(a.dv, b.dv);
    return r;
  }
  // f(x) with derivative f'(x): chain rule.
  Dual chain(Value* fx, Value* dfx, Dual x) { return {fx, lMul(x.du, dfx), lMul(x.dv, dfx)}; }
  Dual dselect(Value* c, Dual a, Dual b) {
    return {b_.CreateSelect(c, a.v, b.v), lSel(c, a.du, b.du), lSel(c, a.dv, b.dv)};
  }
  Dual dsqrtSafe(Dual x) {
    Value* neg = b_.CreateFCmpOLT(x.v, cf(0));
    Value* s = b_.CreateSelect(neg, cf(0), intrinsic(llvm::Intrinsic::sqrt, {b_.CreateSelect(neg, cf(0), x.v)}));
    Value* pos = b_.CreateFCmpOGT(s, cf(0));
    Value* d = b_.CreateSelect(pos, b_.CreateFDiv(cf(0.5f), b_.CreateSelect(pos, s, cf(1))), cf(0));
    return chain(s, d, x);
  }
  Dual dfloorLike(llvm::Intrinsic::ID id, Dual x) { return {intrinsic(id, {x.v}), nullptr, nullptr}; }
  Dual dmin(Dual a, Dual b) { return dselect(b_.CreateFCmpOLT(b.v, a.v), b, a); }
  Dual dmax(Dual a, Dual b) { return dselect(b_.CreateFCmpOGT(b.v, a.v), b, a); }
  Dual dlogSafe(Dual x, float scale) {
    // log(x <= 0) = log(FLT_MIN) (§6.2); scale turns ln into log2/log10.
    Value* pos = b_.CreateFCmpOGT(x.v, cf(0));
    Value* safe = b_.CreateSelect(pos, x.v, cf(1.17549435e-38f));
    Value* l = b_.CreateFMul(intrinsic(llvm::Intrinsic::log, {safe}), cf(scale));
    Value* d = b_.CreateSelect(pos, b_.CreateFDiv(cf(scale), safe), cf(0));
    return chain(l, d, x);
  }
  Dual dpowSafe(Dual a, Dual e) {
    // Negative base with a non-integer exponent gives 0 (§6.2).
    Value* isInt = b_.CreateFCmpOEQ(intrinsic(llvm::Intrinsic::floor, {e.v}), e.v);
    Value* bad = b_.CreateAnd(b_.CreateFCmpOLT(a.v, cf(0)), b_.CreateNot(isInt));
    Value* p = b_.CreateSelect(bad, cf(0), intrinsic(llvm::Intrinsic::pow, {a.v, e.v}));
    Dual r{p, nullptr, nullptr};
    if (a.du || a.dv) {
      // d/da a^e = e * a^(e-1)
      Value* k = b_.CreateSelect(bad, cf(0), b_.CreateFMul(e.v, intrinsic(llvm::Intrinsic::pow, {a.v, b_.CreateFSub(e.v, cf(1))})));
      Value* finite = b_.CreateFCmpOLT(intrinsic(llvm::Intrinsic::fabs, {k}), cf(INFINITY));
      k = b_.CreateSelect(finite, k, cf(0));
      r.du = lMul(a.du, k);
      r.dv = lMul(a.dv, k);
    }
    if (e.du || e.dv) {
      Value* pos = b_.CreateFCmpOGT(a.v, cf(0));
      Value* k = b_.CreateSelect(pos, b_.CreateFMul(p, intrinsic(llvm::Intrinsic::log, {b_.CreateSelect(pos, a.v, cf(1))})), cf(0));
      r.du = lAdd(r.du, lMul(e.du, k));
      r.dv = lAdd(r.dv, lMul(e.dv, k));
    }
    return r;
  }
  Dual dabs(Dual x) {
    Value* neg = b_.CreateFCmpOLT(x.v, cf(0));
    return dselect(neg, dneg(x), x);
  }
  Dual dclamp01(Dual x) { return dmin(dmax(x, dconst(0)), dconst(1)); }

  // ---- Triples.
  Val splat(Type t, Dual d) {
    Val r;
    r.type = t;
    if (t.kind == TypeKind::Matrix) {
      // A scalar becomes a matrix's diagonal (§2.1).
      for (int k = 0; k < 16; ++k) r.c[k] = k % 5 == 0 ? Dual{d.v, nullptr, nullptr} : dconst(0);
      return r;
    }
    for (int k = 0; k < 3; ++k) r.c[k] = d;
    return r;
  }
  Val makeTriple(Type t, Dual x, Dual y, Dual z) {
    Val r;
    r.type = t;
    r.c[0] = x;
    r.c[1] = y;
    r.c[2] = z;
    return r;
  }
  Val makeFloat(Dual d) {
    Val r;
    r.type = Type(TypeKind::Float);
    r.c[0] = d;
    return r;
  }
  Val makeInt(Value* v) {
    Val r;
    r.type = Type(TypeKind::Int);
    r.c[0].v = v;
    return r;
  }
  Dual dot3(const Val& a, const Val& b) {
    return dadd(dadd(dmul(a.c[0], b.c[0]), dmul(a.c[1], b.c[1])), dmul(a.c[2], b.c[2]));
  }
  Val cross3(const Val& a, const Val& b) {
    return makeTriple(Type(TypeKind::Vector), dsub(dmul(a.c[1], b.c[2]), dmul(a.c[2], b.c[1])),
                      dsub(dmul(a.c[2], b.c[0]), dmul(a.c[0], b.c[2])),
                      dsub(dmul(a.c[0], b.c[1]), dmul(a.c[1], b.c[0])));
  }
  // A power of two bringing a triple whose largest component lies beyond 2^60 or below 2^-60
  // near 1, so that its squared length neither overflows nor underflows; 1 in between, where
  // results keep their bits (scaling by a power of two is exact). Without it the normal of a
  // surface 1e9 units across, a cross product of 1e19, normalized to zero.
  Value* tripleScale(const Val& a) {
    Value* m = nullptr;
    for (int k = 0; k < 3; ++k) {
      Value* c = intrinsic(llvm::Intrinsic::fabs, {a.c[k].v});
      m = m ? intrinsic(llvm::Intrinsic::maxnum, {m, c}) : c;
    }
    Value* big = b_.CreateFCmpOGT(m, cf(0x1p60f));
    Value* small = b_.CreateFCmpOLT(m, cf(0x1p-60f));
    return b_.CreateSelect(big, cf(0x1p-100f), b_.CreateSelect(small, cf(0x1p100f), cf(1)));
  }
  Val scaled(const Val& a, Value* s) {
    Val r = a;
    for (int k = 0; k < numComponents(a.type); ++k) {
      auto mul = [&](Value* x) -> Value* { return x ? b_.CreateFMul(x, s) : nullptr; };
      r.c[k] = {mul(a.c[k].v), mul(a.c[k].du), mul(a.c[k].dv)};
    }
    return r;
  }
  Dual length3(const Val& a) {
    Value* s = tripleScale(a);
    const Dual len = dsqrtSafe(dot3(scaled(a, s), scaled(a, s)));
    Value* back = b_.CreateFDiv(cf(1), s);  // exact: s is a power of two
    auto mul = [&](Value* x) -> Value* { return x ? b_.CreateFMul(x, back) : nullptr; };
    return {mul(len.v), mul(len.du), mul(len.dv)};
  }
  Val normalize3(const Val& unscaled) {
    // One reciprocal r of the length for the three components and their lanes, by the quotient
    // rule d(a/len) = (da - (a/len) dlen) r, which needs no r² (that overflows for lengths below
    // 2^-64). A zero vector stays zero, lanes included. a/len is the same for a scaled a.
    const Val a = scaled(unscaled, tripleScale(unscaled));
    const Dual len = dsqrtSafe(dot3(a, a));
    Value* zero = b_.CreateFCmpOEQ(len.v, cf(0));
    Value* r = b_.CreateSelect(zero, cf(0), b_.CreateFDiv(cf(1), b_.CreateSelect(zero, cf(1), len.v)));
    Val n;
    n.type = a.type;
    for (int k = 0; k < 3; ++k) {
      Value* q = b_.CreateFMul(a.c[k].v, r);
      auto lane = [&](Value* da, Value* dlen) -> Value* {
        if (!da && !dlen) return nullptr;
        Value* num = lSub(da, lMul(dlen, q));
        return b_.CreateSelect(zero, cf(0), b_.CreateFMul(num ? num : cf(0), r));
      };
      n.c[k] = {q, lane(a.c[k].du, len.du), lane(a.c[k].dv, len.dv)};
    }
    return n;
  }
  template <typename F>
  Val map(Type t, const Val& a, F f) {
    Val r;
    r.type = t;
    for (int k = 0; k < numComponents(t); ++k) r.c[k] = f(a.c[k]);
    return r;
  }
  template <typename F>
  Val map2(Type t, const Val& a, const Val& b, F f) {
    Val r;
    r.type = t;
    for (int k = 0; k < numComponents(t); ++k) r.c[k] = f(a.c[k], b.c[k]);
    return r;
  }
  Val derivOf(const Val& a, bool wrtU) {
    Val r;
    r.type = a.type.isScalar() ? Type(TypeKind::Float) : a.type.kind == TypeKind::Color ? a.type : Type(TypeKind::Vector);
    for (int k = 0; k < numComponents(a.type); ++k) {
      Value* lane = wrtU ? a.c[k].du : a.c[k].dv;
      r.c[k] = {lane ? lane : cf(0), nullptr, nullptr};
    }
    return r;
  }
  // calculatenormal(p) = o * (Du(p) ^ Dv(p)); o orients the undisplaced normal like Ng.
  Val calculateNormal(const Val& p) {
    Val n = cross3(derivOf(p, true), derivOf(p, false));
    for (int k = 0; k < 3; ++k) n.c[k] = {b_.CreateFMul(n.c[k].v, orientation_), nullptr, nullptr};
    return n;
  }

  // ---- Conversions (§2.1). Sema has already accepted every conversion requested here.
  Value* floatToIntSafe(Value* f) {
    Value* inRange = b_.CreateFCmpOLT(intrinsic(llvm::Intrinsic::fabs, {f}), cf(2147483520.0f));
    return b_.CreateSelect(inRange, b_.CreateFPToSI(b_.CreateSelect(inRange, f, cf(0)), i32_), ci(0));
  }
  Val toFloatScalar(const Val& a) {
    if (a.type.kind == TypeKind::Int) return makeFloat({b_.CreateSIToFP(a.c[0].v, f32_), nullptr, nullptr});
    Val r = a;
    r.type = Type(TypeKind::Float);
    return r;
  }
  Val convert(const Val& a, Type to) {
    if (a.type == to || to.isError() || a.type.isArray()) return a;
    if (to.kind == TypeKind::Int) {
      if (a.type.kind == TypeKind::Int) return a;
      return makeInt(floatToIntSafe(a.c[0].v));
    }
    if (to.kind == TypeKind::Float) return toFloatScalar(a);
    if (to.isTriple() || to.kind == TypeKind::Matrix) {
      if (a.type.isScalar()) return splat(to, toFloatScalar(a).c[0]);
      Val r = a;
      r.type = to;
      return r;
    }
    return a;
  }

  // ---- Variables.
  Slot& slotFor(const VarDecl* d) {
    // The prelude was checked with §5 globals of its own: they are the same variables.
    if (d->storage == Storage::Global && globals_[size_t(d->global)]) d = globals_[size_t(d->global)];
    auto it = slots_.find(d);
    if (it != slots_.end()) return it->second;
    Slot s;
    s.type = d->type;
    llvm::Type* t = d->type.kind == TypeKind::Int ? i32_ : d->type.kind == TypeKind::String ? ptr_ : f32_;
    // Matrices carry no derivatives (§6.4 differentiates floats and triples).
    const bool hasLanes = t == f32_ && d->type.kind != TypeKind::Matrix;
    if (d->type.isArray()) t = llvm::ArrayType::get(t, uint64_t(std::max(d->type.arrayLength, 1)));
    llvm::Type* lane = d->type.isArray() ? t : f32_;
    for (int k = 0; k < elementComponents(d->type); ++k) {
      s.v[k] = entryAlloca(t, d->name.c_str());
      if (hasLanes) {
        s.du[k] = laneAlloca(lane);
        s.dv[k] = laneAlloca(lane);
      }
    }
    return slots_.emplace(d, s).first->second;
  }
  llvm::AllocaInst* laneAlloca(llvm::Type* t) {
    const uint32_t id = lanes_.count++;
    if (!lanes_.allocates(id)) return nullptr;
    llvm::AllocaInst* a = entryAlloca(t);
    laneIds_[a] = id;
    return a;
  }
  // Stores one derivative lane (null: zero) into a lane alloca, which may be absent.
  void storeLane(llvm::AllocaInst* slot, Value* index, Value* lane) {
    // A lane stored back into the scalar it was loaded from (`h = h + 1` copies h's derivatives)
    // does not make it live: a lane that only ever receives zeros and its own value is zero, and
    // pruning it also spares the optimiser a chain of copies it resolves in quadratic time
    // (PromoteMemToReg: 8,000 such statements took 0.5 s, 32,000 took 19 s).
    const bool selfCopy = !index && lane && llvm::isa<llvm::LoadInst>(lane) &&
                          llvm::cast<llvm::LoadInst>(lane)->getPointerOperand() == slot;
    const bool nonZero = lane && !selfCopy &&
                         !(llvm::isa<llvm::ConstantFP>(lane) && llvm::cast<llvm::ConstantFP>(lane)->isZero());
    if (!slot) {
      if (nonZero) lanes_.dropped = true;
      return;
    }
    if (nonZero) {
      const uint32_t id = laneIds_.at(slot);
      if (lanes_.live.size() <= id) lanes_.live.resize(id + 1, 0);
      lanes_.live[id] = 1;
    }
    b_.CreateStore(lane ? lane : cf(0), index ? elementPtr(slot, index) : slot);
  }
  Value* loadLane(llvm::AllocaInst* slot, Value* index) {
    if (!slot) return nullptr;
    return b_.CreateLoad(f32_, index ? elementPtr(slot, index) : slot);
  }

  // ---- Arrays: element access with run-time indices clamped into range (§6.3).
  // Emits body(i) for i in [0, n): unrolled for short arrays, as one loop for long ones, whose
  // straight-line copies the optimiser handles in quadratic time (copying a 4096-element array
  // took 3 s to compile, 16384 over two minutes).
  template <typename F>
  void forEachElement(int n, F&& body) {
    if (n <= 16) {
      for (int i = 0; i < n; ++i) body(ci(i));
      return;
    }
    llvm::BasicBlock* before = b_.GetInsertBlock();
    llvm::BasicBlock* loop = newBlock("elements");
    llvm::BasicBlock* done = newBlock("elements.done");
    b_.CreateBr(loop);
    b_.SetInsertPoint(loop);
    llvm::PHINode* i = b_.CreatePHI(i32_, 2);
    i->addIncoming(ci(0), before);
    body(static_cast<Value*>(i));
    Value* next = b_.CreateAdd(i, ci(1));
    i->addIncoming(next, b_.GetInsertBlock());
    b_.CreateCondBr(b_.CreateICmpSLT(next, ci(n)), loop, done);
    b_.SetInsertPoint(done);
  }
  Value* elementPtr(llvm::AllocaInst* a, Value* index) {
    return b_.CreateInBoundsGEP(a->getAllocatedType(), a, {llvm::ConstantInt::get(i64_, 0), b_.CreateSExt(index, i64_)});
  }
  Value* clampIndex(Value* index, int length) {
    if (auto* k = llvm::dyn_cast<llvm::ConstantInt>(index)) {
      // The type checker rejects a constant index out of a sized array; through an unsized
      // parameter the length is known only here, inlined, and the clamp is reported at run time.
      const int64_t at = k->getSExtValue();
      if ((at < 0 || at > length - 1) && indexClamped_)
        b_.CreateStore(b_.CreateAdd(b_.CreateLoad(i32_, indexClamped_), ci(1)), indexClamped_);
      return ci(int32_t(std::clamp<int64_t>(at, 0, length - 1)));
    }
    Value* low = b_.CreateICmpSLT(index, ci(0));
    Value* high = b_.CreateICmpSGT(index, ci(length - 1));
    if (indexClamped_) {
      Value* out = b_.CreateZExt(b_.CreateOr(low, high), i32_);
      b_.CreateStore(b_.CreateAdd(b_.CreateLoad(i32_, indexClamped_), out), indexClamped_);
    }
    return b_.CreateSelect(low, ci(0), b_.CreateSelect(high, ci(length - 1), index));
  }
  Val loadElement(const Slot& s, Value* index) {
    Val r;
    r.type = s.type.element();
    llvm::Type* et = s.type.kind == TypeKind::Int ? i32_ : s.type.kind == TypeKind::String ? ptr_ : f32_;
    for (int k = 0; k < elementComponents(s.type); ++k) {
      r.c[k].v = b_.CreateLoad(et, elementPtr(s.v[k], index));
      r.c[k].du = loadLane(s.du[k], index);
      r.c[k].dv = loadLane(s.dv[k], index);
    }
    return r;
  }
  void storeElement(const Slot& s, Value* index, const Val& a) {
    const bool lanes = s.type.kind != TypeKind::Matrix;  // as in store()
    for (int k = 0; k < elementComponents(s.type); ++k) {
      b_.CreateStore(a.c[k].v, elementPtr(s.v[k], index));
      if (!lanes) continue;
      storeLane(s.du[k], index, a.c[k].du);
      storeLane(s.dv[k], index, a.c[k].dv);
    }
  }
  // Zero-fills `s`, then stores the initializer list (sema bounded its length).
  void initArray(const Slot& s, const Expr* list) {
    if (s.type.kind == TypeKind::String) {
      const Val empty = zeroOf(s.type.element());
      forEachElement(s.type.arrayLength, [&](Value* i) { storeElement(s, i, empty); });
    } else {
      // Numbers are zero as all-zero bits: one memset per component and lane. Element by element,
      // a 4096-element array took the optimiser 3 s and 8192 took 32 s.
      for (int k = 0; k < 16; ++k)
        for (llvm::AllocaInst* a : {s.v[k], s.du[k], s.dv[k]})
          if (a)
            b_.CreateMemSet(a, llvm::ConstantInt::get(llvm::Type::getInt8Ty(ctx_), 0),
                            module_.getDataLayout().getTypeAllocSize(a->getAllocatedType()), a->getAlign());
    }
    if (!list) return;
    const size_t n = std::min(list->operands.size(), size_t(std::max(s.type.arrayLength, 0)));
    if (s.type.kind != TypeKind::String && n > 16 && initTable(s, list, n)) return;
    for (size_t i = 0; i < n; ++i)
      storeElement(s, ci(int32_t(i)), convert(gen(*list->operands[i]), s.type.element()));
  }
  // Numbers, signed numbers and tuples of them: what a table's initializer is made of. They have no
  // effects and read no variable, so they may all be generated before any is stored.
  static bool literalTable(const Expr& e) {
    switch (e.kind) {
      case ExprKind::IntLiteral:
      case ExprKind::FloatLiteral: return true;
      case ExprKind::Unary: return e.op != Tok::Bang && literalTable(*e.operands[0]);
      case ExprKind::Tuple:
        for (const auto& o : e.operands)
          if (!literalTable(*o)) return false;
        return true;
      default: return false;
    }
  }
  // A table of constants is copied from a constant global, one memcpy per component, as clang
  // does: element by element, the optimiser's InstCombine revisits the array for every store
  // (4,000 elements took 1.3 s to compile, 8,000 took 7 s). False (nothing emitted) otherwise.
  bool initTable(const Slot& s, const Expr* list, size_t n) {
    for (size_t i = 0; i < n; ++i)
      if (!literalTable(*list->operands[i])) return false;
    std::vector<Val> values;
    values.reserve(n);
    for (size_t i = 0; i < n; ++i) {
      values.push_back(convert(gen(*list->operands[i]), s.type.element()));
      auto zero = [](Value* lane) {
        return !lane || (llvm::isa<llvm::Constant>(lane) && llvm::cast<llvm::Constant>(lane)->isNullValue());
      };
      for (int k = 0; k < elementComponents(s.type); ++k) {
        const Dual& d = values.back().c[k];
        if (!llvm::isa<llvm::Constant>(d.v) || !zero(d.du) || !zero(d.dv)) {
          // Not folded after all: store what was generated, in order (it had no effects).
          for (size_t j = 0; j < values.size(); ++j) storeElement(s, ci(int32_t(j)), values[j]);
          for (size_t j = values.size(); j < n; ++j)
            storeElement(s, ci(int32_t(j)), convert(gen(*list->operands[j]), s.type.element()));
          return true;
        }
      }
    }
    const llvm::DataLayout& layout = module_.getDataLayout();
    for (int k = 0; k < elementComponents(s.type); ++k) {
      llvm::AllocaInst* a = s.v[k];
      auto* arrayType = llvm::cast<llvm::ArrayType>(a->getAllocatedType());
      std::vector<llvm::Constant*> elements(arrayType->getNumElements(),
                                            llvm::Constant::getNullValue(arrayType->getElementType()));
      for (size_t i = 0; i < n && i < elements.size(); ++i) elements[i] = llvm::cast<llvm::Constant>(values[i].c[k].v);
      auto* table = new llvm::GlobalVariable(module_, arrayType, /*isConstant=*/true, llvm::GlobalValue::PrivateLinkage,
                                             llvm::ConstantArray::get(arrayType, elements), "table");
      table->setUnnamedAddr(llvm::GlobalValue::UnnamedAddr::Global);
      table->setAlignment(a->getAlign());
      b_.CreateMemCpy(a, a->getAlign(), table, a->getAlign(), layout.getTypeAllocSize(arrayType));
    }
    return true;
  }
  // Initializes an array variable from its initializer: a list, another array, or nothing.
  void initArrayFrom(const Slot& s, const Expr* init) {
    if (init && init->kind != ExprKind::InitList) {
      store(s, gen(*init));
      return;
    }
    initArray(s, init);
  }
  Val load(const Slot& s) {
    Val r;
    r.type = s.type;
    if (s.type.isArray()) {
      r.array = &s;
      return r;
    }
    for (int k = 0; k < numComponents(s.type); ++k) {
      r.c[k].v = b_.CreateLoad(s.v[k]->getAllocatedType(), s.v[k]);
      r.c[k].du = loadLane(s.du[k], nullptr);
      r.c[k].dv = loadLane(s.dv[k], nullptr);
    }
    return r;
  }
  void store(const Slot& s, const Val& a) {
    if (s.type.isArray()) {
      if (!a.array || a.array == &s) return;
      const Slot& from = *a.array;
      forEachElement(std::min(s.type.arrayLength, from.type.arrayLength),
                     [&](Value* i) { storeElement(s, i, loadElement(from, i)); });
      return;
    }
    // Matrices carry no derivatives (docs/language.md): a matrix built from varying values (`q * k`)
    // drops them here by design, which is no lost lane.
    const bool lanes = s.type.kind != TypeKind::Matrix;
    for (int k = 0; k < numComponents(s.type); ++k) {
      b_.CreateStore(a.c[k].v, s.v[k]);
      if (!lanes) continue;
      storeLane(s.du[k], nullptr, a.c[k].du);
      storeLane(s.dv[k], nullptr, a.c[k].dv);
    }
  }
  // The global PI, as both the defaults function and the entry bind it.
  Val piValue() { return makeFloat(dconst(3.14159265358979f)); }
  Val zeroOf(Type t) {
    if (t.kind == TypeKind::Int) return makeInt(ci(0));
    if (t.kind == TypeKind::String) {
      Val r;
      r.type = t;
      r.c[0].v = b_.CreateGlobalStringPtr("", "str");
      return r;
    }
    return splat(t, dconst(0));
  }

  // ---- Parameters.
  // Array parameters: consecutive elements in the block.
  void loadParamArray(const VarDecl& p, Value* block, const Slot& s) {
    const uint32_t off = paramOffsets_.at(&p);
    const uint32_t size = p.type.kind == TypeKind::String ? 8 : 4 * uint32_t(elementComponents(p.type));
    forEachElement(p.type.arrayLength, [&](Value* i) {
      Val e;
      e.type = p.type.element();
      Value* at = elementBytes(block, off, size, i);
      if (p.type.kind == TypeKind::String)
        e.c[0].v = b_.CreateLoad(ptr_, at);
      else if (p.type.kind == TypeKind::Int)
        e.c[0].v = b_.CreateLoad(i32_, at);
      else
        for (int k = 0; k < elementComponents(p.type); ++k)
          e.c[k] = {b_.CreateLoad(f32_, bytePtr(at, 4 * uint64_t(k))), nullptr, nullptr};
      storeElement(s, i, e);
    });
  }
  // The address of element `i` of an array parameter at `off` in the block, elements `size` apart.
  Value* elementBytes(Value* block, uint32_t off, uint32_t size, Value* i) {
    Value* bytes = b_.CreateAdd(llvm::ConstantInt::get(i64_, off),
                                b_.CreateMul(b_.CreateSExt(i, i64_), llvm::ConstantInt::get(i64_, size)));
    return b_.CreateInBoundsGEP(i8_, block, bytes);
  }
  void storeParamArray(const VarDecl& p, Value* block, const Slot& s) {
    const uint32_t off = paramOffsets_.at(&p);
    const uint32_t size = p.type.kind == TypeKind::String ? 8 : 4 * uint32_t(elementComponents(p.type));
    forEachElement(p.type.arrayLength, [&](Value* i) {
      const Val e = loadElement(s, i);
      Value* at = elementBytes(block, off, size, i);
      for (int k = 0; k < elementComponents(p.type); ++k) b_.CreateStore(e.c[k].v, bytePtr(at, 4 * uint64_t(k)));
    });
  }

  Val loadParam(const VarDecl& p, Value* block) {
    const uint32_t off = paramOffsets_.at(&p);
    Val r;
    r.type = p.type;
    if (p.type.kind == TypeKind::String) {
      r.c[0].v = b_.CreateLoad(ptr_, bytePtr(block, off));
    } else if (p.type.kind == TypeKind::Int) {
      r.c[0].v = b_.CreateLoad(i32_, bytePtr(block, off));
    } else {
      for (int k = 0; k < numComponents(p.type); ++k)
        r.c[k] = {b_.CreateLoad(f32_, bytePtr(block, off + 4 * k)), nullptr, nullptr};
    }
    return r;
  }
  void storeParam(const VarDecl& p, Value* block, const Val& a) {
    const uint32_t off = paramOffsets_.at(&p);
    for (int k = 0; k < numComponents(p.type); ++k) b_.CreateStore(a.c[k].v, bytePtr(block, off + 4 * k));
  }

  // void defaults(void* block): evaluates each default (which may use earlier parameters).
  void emitDefaults(const ShaderLayout& layout) {
    auto* fty = llvm::FunctionType::get(llvm::Type::getVoidTy(ctx_), {ptr_}, false);
    fn_ = llvm::Function::Create(fty, llvm::Function::ExternalLinkage, layout.defaultsSymbol, module_);
    b_.SetInsertPoint(llvm::BasicBlock::Create(ctx_, "entry", fn_));
    Value* block = fn_->getArg(0);
    orientation_ = cf(1);
    slots_.clear();
    boundValues_.clear();
    gradient_ = cellInput_ = nullptr;
    textureErrors_ = nullptr;
    services_ = nullptr;
    randomInputs_ = randomOrdinal_ = nullptr;
    indexClamped_ = unknownSpace_ = splineBasisProblems_ = nullptr;
    // Defaults that read coordinate spaces see identity transforms here (the values reflection
    // reports); the entry evaluates them again with the batch's spaces (emitEntry). Per point, as
    // the parameters are loaded: a default that loops (fBm) then costs its loop at every point.
    {
      auto* spacesType = llvm::ArrayType::get(f32_, sizeof(RlfSpaces) / sizeof(float));
      llvm::AllocaInst* identitySpaces = entryAlloca(spacesType, "spaces.identity");
      for (unsigned i = 0; i < sizeof(RlfSpaces) / sizeof(float); ++i)
        b_.CreateStore(cf(i % 16 % 5 == 0 ? 1.0f : 0.0f), b_.CreateConstInBoundsGEP2_32(spacesType, identitySpaces, 0, i));
      spaces_ = identitySpaces;
    }
    unknownSpace_ = nullptr;
    // The globals a default reads here: PI is PI (a default using only it and constants is not
    // evaluated again at shading time); the geometric ones read zero, a value only reflection
    // reports, since defaults that read them are evaluated again per point (emitEntry).
    for (size_t g = 0; g < size_t(GlobalId::Count); ++g)
      if (const VarDecl* d = globals_[g])
        store(slotFor(d), GlobalId(g) == GlobalId::PI ? piValue() : zeroOf(d->type));
    // Defaults may call library functions with loops (fBm): they count like the entry's, and
    // past the limit the remaining defaults stay zero.
    loopCounter_ = entryAlloca(i32_, "iterations");
    b_.CreateStore(ci(0), loopCounter_);
    abortBlock_ = newBlock("defaults.abort");
    {
      llvm::IRBuilderBase::InsertPointGuard guard(b_);
      b_.SetInsertPoint(abortBlock_);
      b_.CreateRetVoid();
    }
    for (const auto& p : shader_.params) {
      if (p->type.isArray()) {
        const Slot& s = slotFor(p.get());
        initArrayFrom(s, p->init.get());
        storeParamArray(*p, block, s);
        continue;
      }
      Val v = p->init ? convert(gen(*p->init), p->type) : zeroOf(p->type);
      store(slotFor(p.get()), v);
      storeParam(*p, block, v);
    }
    b_.CreateRetVoid();
  }

  // ---- The batch entry.
  void emitEntry(const ShaderLayout& layout) {
    auto* fty = llvm::FunctionType::get(llvm::Type::getVoidTy(ctx_), {ptr_, ptr_, ptr_}, false);
    fn_ = llvm::Function::Create(fty, llvm::Function::ExternalLinkage, layout.entrySymbol, module_);
    fn_->setDoesNotThrow();
    Value* batch = fn_->getArg(0);
    Value* params = fn_->getArg(1);
    Value* status = fn_->getArg(2);
    llvm::BasicBlock* entry = llvm::BasicBlock::Create(ctx_, "entry", fn_);
    b_.SetInsertPoint(entry);
    slots_.clear();
    boundValues_.clear();
    gradient_ = cellInput_ = nullptr;

    // Absent seed arrays read this constant: a global, not an alloca, so that SROA does not turn the
    // per-point pointer selects into branches.
    zeroCell_ = module_.getGlobalVariable("rlf.zero", true);
    if (!zeroCell_)
      zeroCell_ = new llvm::GlobalVariable(module_, f32_, true, llvm::GlobalValue::PrivateLinkage, llvm::ConstantFP::get(f32_, 0.0), "rlf.zero");
    nonFinite_ = entryAlloca(i32_, "nonfinite");
    badNormals_ = entryAlloca(i32_, "badnormals");
    loopLimitHits_ = entryAlloca(i32_, "looplimit");
    loopCounter_ = entryAlloca(i32_, "iterations");
    textureErrors_ = entryAlloca(i32_, "textureerrors");
    randomInputs_ = entryAlloca(llvm::ArrayType::get(f32_, 5), "randominputs");
    randomOrdinal_ = entryAlloca(i32_, "randomordinal");
    indexClamped_ = entryAlloca(i32_, "indexclamped");
    b_.CreateStore(ci(0), indexClamped_);
    unknownSpace_ = entryAlloca(i32_, "unknownspace");
    b_.CreateStore(ci(0), unknownSpace_);
    splineBasisProblems_ = entryAlloca(i32_, "splinebasis");
    b_.CreateStore(ci(0), splineBasisProblems_);
    b_.CreateStore(ci(0), nonFinite_);
    b_.CreateStore(ci(0), badNormals_);
    b_.CreateStore(ci(0), loopLimitHits_);
    b_.CreateStore(ci(0), textureErrors_);
    llvm::AllocaInst* index = entryAlloca(i64_, "i");
    b_.CreateStore(llvm::ConstantInt::get(i64_, 0), index);
    Value* count = b_.CreateZExt(b_.CreateLoad(i32_, bytePtr(batch, offsetof(RlfShadingBatch, count))), i64_);

    // Field pointers, loaded once per batch.
    auto field = [&](size_t off) { return loadPtrField(batch, off); };
    auto triple = [&](size_t off) {
      return std::array<Value*, 3>{field(off), field(off + sizeof(float*)), field(off + 2 * sizeof(float*))};
    };
    const auto P = triple(offsetof(RlfShadingBatch, P));
    const auto N = triple(offsetof(RlfShadingBatch, N));
    const auto Ng = triple(offsetof(RlfShadingBatch, Ng));
    const auto dPdu = triple(offsetof(RlfShadingBatch, dPdu));
    const auto dPdv = triple(offsetof(RlfShadingBatch, dPdv));
    const auto dNdu = triple(offsetof(RlfShadingBatch, dNdu));
    const auto dNdv = triple(offsetof(RlfShadingBatch, dNdv));
    const auto Pout = triple(offsetof(RlfShadingBatch, Pout));
    const auto Nout = triple(offsetof(RlfShadingBatch, Nout));
    Value* uPtr = field(offsetof(RlfShadingBatch, u));
    Value* vPtr = field(offsetof(RlfShadingBatch, v));
    Value* sPtr = field(offsetof(RlfShadingBatch, s));
    Value* tPtr = field(offsetof(RlfShadingBatch, t));
    Value* duPtr = field(offsetof(RlfShadingBatch, du));
    Value* dvPtr = field(offsetof(RlfShadingBatch, dv));
    Value* dsduPtr = field(offsetof(RlfShadingBatch, dsdu));
    Value* dsdvPtr = field(offsetof(RlfShadingBatch, dsdv));
    Value* dtduPtr = field(offsetof(RlfShadingBatch, dtdu));
    Value* dtdvPtr = field(offsetof(RlfShadingBatch, dtdv));
    spaces_ = field(offsetof(RlfShadingBatch, spaces));
    services_ = field(offsetof(RlfShadingBatch, services));
    Value* dNduPresent = b_.CreateIsNotNull(dNdu[0]);
    Value* dNdvPresent = b_.CreateIsNotNull(dNdv[0]);

    llvm::BasicBlock* header = newBlock("point.header");
    llvm::BasicBlock* body = newBlock("point.body");
    llvm::BasicBlock* exitPoint = newBlock("point.exit");
    llvm::BasicBlock* abortPoint = newBlock("point.abort");
    llvm::BasicBlock* latch = newBlock("point.latch");
    llvm::BasicBlock* done = newBlock("done");
    b_.CreateBr(header);

    b_.SetInsertPoint(header);
    Value* i = b_.CreateLoad(i64_, index, "i");
    b_.CreateCondBr(b_.CreateICmpULT(i, count), body, done);

    b_.SetInsertPoint(body);
    auto at = [&](Value* base) { return b_.CreateInBoundsGEP(f32_, base, i); };
    auto loadAt = [&](Value* base) -> Value* { return b_.CreateLoad(f32_, at(base)); };
    // A nullable seed array reads as zero when absent (no load from null).
    auto loadOpt = [&](Value* base, Value* present) -> Value* {
      return b_.CreateLoad(f32_, b_.CreateSelect(present, at(base), zeroCell_));
    };
    auto loadTriple = [&](const std::array<Value*, 3>& a) {
      return std::array<Value*, 3>{loadAt(a[0]), loadAt(a[1]), loadAt(a[2])};
    };
    const auto pIn = loadTriple(P);
    const auto nIn = loadTriple(N);
    const auto ngIn = loadTriple(Ng);
    const auto dpduIn = loadTriple(dPdu);
    const auto dpdvIn = loadTriple(dPdv);
    auto global = [&](GlobalId g) -> const VarDecl* { return globals_[size_t(g)]; };
    {
      Val p;
      p.type = Type(TypeKind::Point);
      Val n;
      n.type = Type(TypeKind::Normal);
      Val ng, dpdu, dpdv;
      ng.type = Type(TypeKind::Normal);
      dpdu.type = dpdv.type = Type(TypeKind::Vector);
      for (int k = 0; k < 3; ++k) {
        p.c[k] = {pIn[k], dpduIn[k], dpdvIn[k]};
        n.c[k] = {nIn[k], loadOpt(dNdu[k], dNduPresent), loadOpt(dNdv[k], dNdvPresent)};
        ng.c[k] = {ngIn[k], nullptr, nullptr};
        dpdu.c[k] = {dpduIn[k], nullptr, nullptr};
        dpdv.c[k] = {dpdvIn[k], nullptr, nullptr};
      }
      store(slotFor(global(GlobalId::P)), p);
      store(slotFor(global(GlobalId::N)), n);
      store(slotFor(global(GlobalId::Ng)), ng);
      store(slotFor(global(GlobalId::dPdu)), dpdu);
      store(slotFor(global(GlobalId::dPdv)), dpdv);
      store(slotFor(global(GlobalId::u)), makeFloat({loadAt(uPtr), cf(1), nullptr}));
      store(slotFor(global(GlobalId::v)), makeFloat({loadAt(vPtr), nullptr, cf(1)}));
      store(slotFor(global(GlobalId::s)),
            makeFloat({loadAt(sPtr), loadOpt(dsduPtr, b_.CreateIsNotNull(dsduPtr)),
                       loadOpt(dsdvPtr, b_.CreateIsNotNull(dsdvPtr))}));
      store(slotFor(global(GlobalId::t)),
            makeFloat({loadAt(tPtr), loadOpt(dtduPtr, b_.CreateIsNotNull(dtduPtr)),
                       loadOpt(dtdvPtr, b_.CreateIsNotNull(dtdvPtr))}));
      store(slotFor(global(GlobalId::du)), makeFloat({loadAt(duPtr), nullptr, nullptr}));
      store(slotFor(global(GlobalId::dv)), makeFloat({loadAt(dvPtr), nullptr, nullptr}));
      store(slotFor(global(GlobalId::PI)), piValue());
      // Orientation of calculatenormal: the undisplaced dPdu ^ dPdv must face like Ng.
      Val geo = cross3(dpdu, dpdv);
      // Where the surface's own parameterization degenerates (a sphere's pole), calculatenormal
      // is zero through no fault of the shader: such points are not counted as bad normals.
      regularFrame_ = b_.CreateFCmpONE(dot3(geo, geo).v, cf(0));
      Value* facing = dot3(geo, ng).v;
      orientation_ = b_.CreateSelect(b_.CreateFCmpOLT(facing, cf(0)), cf(-1), cf(1));
    }
    // Defaults evaluated below (defaultAtShadingTime) may loop (fBm): their iterations
    // count like the body's, and past the limit the point aborts as the body's would.
    abortBlock_ = abortPoint;
    b_.CreateStore(ci(0), loopCounter_);
    for (const auto& prm : shader_.params) {
      if (prm->type.isArray())
        loadParamArray(*prm, params, slotFor(prm.get()));
      else
        store(slotFor(prm.get()), loadParam(*prm, params));
      if (prm->defaultAtShadingTime) {
        // Not bound by the host: the default again, now with this batch's coordinate spaces and
        // the values of the parameters before it, which it may read.
        Value* bound = b_.CreateLoad(i32_, bytePtr(params, boundFlagOffsets_.at(prm.get())));
        llvm::BasicBlock* evalB = newBlock("param.default");
        llvm::BasicBlock* doneB = newBlock("param.ready");
        b_.CreateCondBr(b_.CreateICmpEQ(bound, ci(0)), evalB, doneB);
        b_.SetInsertPoint(evalB);
        if (prm->type.isArray())
          initArrayFrom(slotFor(prm.get()), prm->init.get());
        else
          store(slotFor(prm.get()), convert(gen(*prm->init), prm->type));
        b_.CreateBr(doneB);
        b_.SetInsertPoint(doneB);
      }
    }
    b_.CreateStore(ci(0), loopCounter_);
    {
      Value* in[5] = {pIn[0], pIn[1], pIn[2], load(slotFor(global(GlobalId::u))).c[0].v,
                      load(slotFor(global(GlobalId::v))).c[0].v};
      for (unsigned k = 0; k < 5; ++k)
        b_.CreateStore(in[k], b_.CreateConstInBoundsGEP2_32(randomInputs_->getAllocatedType(), randomInputs_, 0, k));
      b_.CreateStore(ci(0), randomOrdinal_);
    }

    exitBlock_ = exitPoint;
    abortBlock_ = abortPoint;
    if (shader_.body) genStmt(*shader_.body);
    if (!terminated()) b_.CreateBr(exitPoint);
    if (usesStrings_) {
      // Strings built by format()/concat() live for one shading point.
      llvm::IRBuilderBase::InsertPointGuard guard(b_);
      b_.SetInsertPoint(body, body->getFirstInsertionPt());
      llvm::FunctionCallee fnc = module_.getOrInsertFunction("rlf_strings_reset", llvm::FunctionType::get(llvm::Type::getVoidTy(ctx_), false));
      if (auto* fn = llvm::dyn_cast<llvm::Function>(fnc.getCallee())) fn->setDoesNotThrow();
      b_.CreateCall(fnc);
    }

    // Host contract (§5): P assigned but N never → N = normalize(calculatenormal(P)).
    b_.SetInsertPoint(exitPoint);
    const Slot& pSlot = slotFor(global(GlobalId::P));
    const Slot& nSlot = slotFor(global(GlobalId::N));
    Val pOut = load(pSlot);
    Val nOut = load(nSlot);
    if (shader_.assignsP && !shader_.assignsN) nOut = normalize3(calculateNormal(pOut));
    auto finite3 = [&](const Val& a) {
      Value* ok = nullptr;
      for (int k = 0; k < 3; ++k) {
        Value* f = b_.CreateFCmpOLT(intrinsic(llvm::Intrinsic::fabs, {a.c[k].v}), cf(INFINITY));
        ok = ok ? b_.CreateAnd(ok, f) : f;
      }
      return ok;
    };
    // Non-finite P: the undisplaced point and input normal; non-finite or zero N: the input normal,
    // which hosts replace by the displaced surface's own (§7). Counted apart: only the first
    // leaves the point undisplaced.
    Value* pOk = finite3(pOut);
    Value* nFinite = finite3(nOut);
    Value* nNonZero = b_.CreateFCmpONE(dot3(nOut, nOut).v, cf(0));
    Value* nOk = b_.CreateAnd(nFinite, nNonZero);
    Value* allOk = b_.CreateAnd(pOk, nOk);
    Value* nBad = b_.CreateAnd(pOk, b_.CreateNot(b_.CreateAnd(nFinite, b_.CreateOr(nNonZero, b_.CreateNot(regularFrame_)))));
    for (int k = 0; k < 3; ++k) {
      b_.CreateStore(b_.CreateSelect(pOk, pOut.c[k].v, pIn[k]), at(Pout[k]));
      b_.CreateStore(b_.CreateSelect(allOk, nOut.c[k].v, nIn[k]), at(Nout[k]));
    }
    Value* nf = b_.CreateLoad(i32_, nonFinite_);
    b_.CreateStore(b_.CreateAdd(nf, b_.CreateZExt(b_.CreateNot(pOk), i32_)), nonFinite_);
    Value* bn = b_.CreateLoad(i32_, badNormals_);
    b_.CreateStore(b_.CreateAdd(bn, b_.CreateZExt(nBad, i32_)), badNormals_);
    b_.CreateBr(latch);

    // Loop limit exceeded: outputs revert to the inputs (§7).
    b_.SetInsertPoint(abortPoint);
    for (int k = 0; k < 3; ++k) {
      b_.CreateStore(pIn[k], at(Pout[k]));
      b_.CreateStore(nIn[k], at(Nout[k]));
    }
    b_.CreateStore(b_.CreateAdd(b_.CreateLoad(i32_, loopLimitHits_), ci(1)), loopLimitHits_);
    b_.CreateBr(latch);

    b_.SetInsertPoint(latch);
    b_.CreateStore(b_.CreateAdd(i, llvm::ConstantInt::get(i64_, 1)), index);
    b_.CreateBr(header);

    b_.SetInsertPoint(done);
    auto bump = [&](size_t off, llvm::AllocaInst* local) {
      Value* p = bytePtr(status, off);
      b_.CreateStore(b_.CreateAdd(b_.CreateLoad(i32_, p), b_.CreateLoad(i32_, local)), p);
    };
    bump(offsetof(RlfStatus, nonFinite), nonFinite_);
    bump(offsetof(RlfStatus, badNormal), badNormals_);
    bump(offsetof(RlfStatus, loopLimit), loopLimitHits_);
    bump(offsetof(RlfStatus, textureErrors), textureErrors_);
    bump(offsetof(RlfStatus, indexClamped), indexClamped_);
    bump(offsetof(RlfStatus, unknownSpace), unknownSpace_);
    bump(offsetof(RlfStatus, splineBasis), splineBasisProblems_);
    b_.CreateRetVoid();
  }

 public:
  void setGlobals(const TranslationUnit& unit) {
    for (const auto& g : unit.globals) globals_[size_t(g->global)] = g.get();
  }

 private:
  // ---- Statements.
  void genScoped(const Stmt& s) { genStmt(s); }

  void genStmt(const Stmt& s) {
    if (terminated()) startDeadBlock();
    switch (s.kind) {
      case StmtKind::Block:
        for (const StmtPtr& c : s.stmts) genStmt(*c);
        break;
      case StmtKind::Decl:
        for (const auto& d : s.decls) {
          const Slot& slot = slotFor(d.get());
          // Locals are zero-initialized (§4) and re-initialized each time the declaration runs.
          if (d->type.isArray())
            initArrayFrom(slot, d->init.get());
          else
            store(slot, d->init ? convert(gen(*d->init), d->type) : zeroOf(d->type));
        }
        break;
      case StmtKind::ExprStmt: gen(*s.expr); break;
      case StmtKind::If: {
        Value* c = truth(gen(*s.cond));
        llvm::BasicBlock* thenB = newBlock("if.then");
        llvm::BasicBlock* elseB = s.otherwise ? newBlock("if.else") : nullptr;
        llvm::BasicBlock* endB = newBlock("if.end");
        b_.CreateCondBr(c, thenB, elseB ? elseB : endB);
        b_.SetInsertPoint(thenB);
        genStmt(*s.then);
        if (!terminated()) b_.CreateBr(endB);
        if (elseB) {
          b_.SetInsertPoint(elseB);
          genStmt(*s.otherwise);
          if (!terminated()) b_.CreateBr(endB);
        }
        b_.SetInsertPoint(endB);
        break;
      }
      case StmtKind::While:
      case StmtKind::DoWhile:
      case StmtKind::For: genLoop(s); break;
      case StmtKind::Break:
        b_.CreateBr(loops_[loops_.size() - size_t(s.levels)].breakTarget);
        break;
      case StmtKind::Continue:
        b_.CreateBr(loops_[loops_.size() - size_t(s.levels)].continueTarget);
        break;
      case StmtKind::Return:
        if (returns_.empty()) {
          b_.CreateBr(exitBlock_);
        } else {
          const ReturnTarget r = returns_.back();  // a copy: gen() below may push more targets
          if (s.expr && r.slot) store(*r.slot, convert(gen(*s.expr), r.type));
          b_.CreateBr(r.block);
        }
        break;
      case StmtKind::Empty:
      case StmtKind::FunctionDef:  // inlined at each call
      case StmtKind::Extern: break;  // identifiers already resolve to the enclosing variable
    }
  }

  // Loops count iterations against loopLimit_ (kLoopIterationLimit unless configured) on every back edge.
  void genLoop(const Stmt& s) {
    if (s.kind == StmtKind::For && s.init) genStmt(*s.init);
    llvm::BasicBlock* condB = newBlock("loop.cond");
    llvm::BasicBlock* bodyB = newBlock("loop.body");
    llvm::BasicBlock* stepB = newBlock("loop.step");
    llvm::BasicBlock* endB = newBlock("loop.end");
    b_.CreateBr(s.kind == StmtKind::DoWhile ? bodyB : condB);

    b_.SetInsertPoint(condB);
    if (s.cond)
      b_.CreateCondBr(truth(gen(*s.cond)), bodyB, endB);
    else
      b_.CreateBr(bodyB);

    b_.SetInsertPoint(bodyB);
    loops_.push_back({endB, stepB});
    genStmt(*s.body);
    loops_.pop_back();
    if (!terminated()) b_.CreateBr(stepB);

    b_.SetInsertPoint(stepB);
    if (s.step) gen(*s.step);
    Value* n = b_.CreateAdd(b_.CreateLoad(i32_, loopCounter_), ci(1));
    b_.CreateStore(n, loopCounter_);
    b_.CreateCondBr(b_.CreateICmpUGT(n, ci(int32_t(std::min<uint32_t>(loopLimit_, INT32_MAX)))), abortBlock_, condB);

    b_.SetInsertPoint(endB);
  }

  Value* truth(const Val& a) {
    if (a.type.kind == TypeKind::Int) return b_.CreateICmpNE(a.c[0].v, ci(0));
    return b_.CreateFCmpUNE(a.c[0].v, cf(0));
  }
  Val boolToInt(Value* c) { return makeInt(b_.CreateZExt(c, i32_)); }

  // ---- Expressions.
  Val gen(const Expr& e) {
    switch (e.kind) {
      case ExprKind::IntLiteral: return makeInt(ci(e.intValue));
      case ExprKind::FloatLiteral: return makeFloat(dconst(e.floatValue));
      case ExprKind::StringLiteral: {
        Val r;
        r.type = Type(TypeKind::String);
        r.c[0].v = b_.CreateGlobalStringPtr(e.text, "str");
        return r;
      }
      case ExprKind::Identifier:
        if (const auto bound = boundValues_.find(e.decl); bound != boundValues_.end()) return bound->second;
        return load(slotFor(e.decl));
      case ExprKind::Unary: {
        Val a = gen(*e.operands[0]);
        if (e.op == Tok::Bang) return boolToInt(b_.CreateNot(truth(a)));
        if (e.op == Tok::Plus) return a;
        if (a.type.kind == TypeKind::Int) return makeInt(b_.CreateSub(ci(0), a.c[0].v));
        return map(a.type, a, [&](Dual d) { return dneg(d); });
      }
      case ExprKind::PreIncDec:
      case ExprKind::PostIncDec: {
        // The lvalue's index expressions run once (`k[i++]++` steps i once).
        const Expr& target = *e.operands[0];
        const Place place = resolvePlace(target);
        Val old = readPlace(place);
        Val nv = old;
        const bool inc = e.op == Tok::PlusPlus;
        if (old.type.kind == TypeKind::Int)
          nv.c[0].v = inc ? b_.CreateAdd(old.c[0].v, ci(1)) : b_.CreateSub(old.c[0].v, ci(1));
        else
          nv.c[0].v = inc ? b_.CreateFAdd(old.c[0].v, cf(1)) : b_.CreateFSub(old.c[0].v, cf(1));
        writePlace(place, convert(nv, target.type));
        return e.kind == ExprKind::PreIncDec ? nv : old;
      }
      case ExprKind::Binary: return genBinary(e);
      case ExprKind::Assign: {
        const Expr& target = *e.operands[0];
        if (e.op != Tok::Assign) {
          // a op= b is a = a op b with `a` evaluated once (§4.1): its place (index expressions)
          // first, then b, as the operands of `a op b` run left to right.
          Tok base = e.op == Tok::PlusAssign    ? Tok::Plus
                     : e.op == Tok::MinusAssign ? Tok::Minus
                     : e.op == Tok::StarAssign  ? Tok::Star
                     : e.op == Tok::SlashAssign ? Tok::Slash
                                                : Tok::Percent;
          const Place place = resolvePlace(target);
          const Val old = readPlace(place);
          const Val value = convert(arith(base, old, gen(*e.operands[1])), target.type);
          writePlace(place, value);
          return value;
        }
        Val value = gen(*e.operands[1]);
        value = convert(value, target.type);
        assignTo(target, value);
        return value;
      }
      case ExprKind::Conditional: {
        Value* c = truth(gen(*e.operands[0]));
        llvm::BasicBlock* aB = newBlock("cond.true");
        llvm::BasicBlock* bB = newBlock("cond.false");
        llvm::BasicBlock* endB = newBlock("cond.end");
        temps_.push_back(std::make_unique<VarDecl>());
        temps_.back()->name = "cond";
        temps_.back()->type = e.type;
        const Slot& slot = slotFor(temps_.back().get());
        b_.CreateCondBr(c, aB, bB);
        b_.SetInsertPoint(aB);
        store(slot, convert(gen(*e.operands[1]), e.type));
        b_.CreateBr(endB);
        b_.SetInsertPoint(bB);
        store(slot, convert(gen(*e.operands[2]), e.type));
        b_.CreateBr(endB);
        b_.SetInsertPoint(endB);
        return load(slot);
      }
      case ExprKind::Call: return genCall(e);
      case ExprKind::Construct: return genConstruct(e);
      case ExprKind::Index: {
        if (e.operands[0]->matrixRow) {
          const Expr& row = *e.operands[0];
          const Val m = gen(*row.operands[0]);
          return makeFloat(matrixElementAt(m, gen(*row.operands[1]).c[0].v, gen(*e.operands[1]).c[0].v));
        }
        Val base = gen(*e.operands[0]);
        Val index = gen(*e.operands[1]);
        if (base.array) return loadElement(*base.array, clampIndex(index.c[0].v, base.array->type.arrayLength));
        return makeFloat(component(base, index.c[0].v));
      }
      case ExprKind::InitList: return zeroOf(Type(TypeKind::Float));  // handled by initArray
      case ExprKind::Tuple: {
        if (e.type.kind == TypeKind::Matrix) {
          Val m;
          m.type = e.type;
          for (int k = 0; k < 16; ++k) m.c[k] = {toFloatScalar(gen(*e.operands[size_t(k)])).c[0].v, nullptr, nullptr};
          return m;
        }
        Val x = toFloatScalar(gen(*e.operands[0]));
        Val y = toFloatScalar(gen(*e.operands[1]));
        Val z = toFloatScalar(gen(*e.operands[2]));
        return makeTriple(e.type, x.c[0], y.c[0], z.c[0]);
      }
    }
    return zeroOf(Type(TypeKind::Float));
  }

  // Run-time component index, clamped into 0..2.
  Dual component(const Val& base, Value* index) {
    if (auto* k = llvm::dyn_cast<llvm::ConstantInt>(index)) {
      const int64_t i = std::clamp<int64_t>(k->getSExtValue(), 0, 2);
      return base.c[i];
    }
    Dual r = base.c[2];
    r = dselect(b_.CreateICmpEQ(index, ci(1)), base.c[1], r);
    r = dselect(b_.CreateICmpSLE(index, ci(0)), base.c[0], r);
    return r;
  }

  void assignTo(const Expr& target, const Val& value) {
    if (target.kind == ExprKind::Identifier) {
      store(slotFor(target.decl), convert(value, target.decl->type));
      return;
    }
    const Expr& baseExpr = *target.operands[0];
    if (baseExpr.type.isArray()) {
      // a[i] = x
      const Val arr = gen(baseExpr);
      const Val idx = gen(*target.operands[1]);
      storeElement(*arr.array, clampIndex(idx.c[0].v, arr.array->type.arrayLength),
                   convert(value, baseExpr.type.element()));
      return;
    }
    if (baseExpr.matrixRow) {
      // m[i][j] = x
      const Expr& mExpr = *baseExpr.operands[0];
      Val m = gen(mExpr);
      setMatrixElement(m, gen(*baseExpr.operands[1]).c[0].v, gen(*target.operands[1]).c[0].v,
                       toFloatScalar(value).c[0]);
      assignTo(mExpr, m);
      return;
    }
    // v[i] = x, where v is a variable or an array element (a[i][j] = x)
    Val base = gen(baseExpr);
    Val idx = gen(*target.operands[1]);
    const Dual x = toFloatScalar(value).c[0];
    Value* index = idx.c[0].v;
    for (int k = 0; k < 3; ++k) {
      Value* hit = k == 0   ? b_.CreateICmpSLE(index, ci(0))
                   : k == 1 ? b_.CreateICmpEQ(index, ci(1))
                            : b_.CreateICmpSGE(index, ci(2));
      base.c[k] = dselect(hit, x, base.c[k]);
    }
    assignTo(baseExpr, base);
  }

  // An lvalue (§4.1) whose indices have been evaluated once: the variable's storage, the array
  // element (clamped), then the component of a triple or the element of a matrix (row * 4 + col).
  // An `output` argument that is not a plain variable is read through it before the call and
  // written back after, with each index expression run once.
  struct Place {
    const Slot* slot = nullptr;
    Value* element = nullptr;  // array index, or null
    Value* part = nullptr;     // component (triple) or row * 4 + col (matrix), or null
  };
  Place resolvePlace(const Expr& e) {
    std::vector<const Expr*> indices;
    const Expr* base = &e;
    while (base->kind == ExprKind::Index) {
      indices.push_back(base->operands[1].get());
      base = base->operands[0].get();
    }
    std::reverse(indices.begin(), indices.end());
    std::vector<Value*> values;
    for (const Expr* i : indices) values.push_back(gen(*i).c[0].v);
    Place place;
    place.slot = &slotFor(base->decl);
    size_t k = 0;
    if (place.slot->type.isArray() && k < values.size())
      place.element = clampIndex(values[k++], place.slot->type.arrayLength);
    if (place.slot->type.kind == TypeKind::Matrix && k + 1 < values.size())
      place.part = matrixIndex(values[k], values[k + 1]);
    else if (k < values.size())
      place.part = values[k];
    return place;
  }
  Val readPlace(const Place& place) {
    const Val whole = place.element ? loadElement(*place.slot, place.element) : load(*place.slot);
    if (!place.part) return whole;
    if (whole.type.kind == TypeKind::Matrix) return makeFloat(matrixElementAt(whole, place.part));
    return makeFloat(component(whole, place.part));
  }
  void writePlace(const Place& place, const Val& value) {
    Val whole = value;
    if (place.part) {
      whole = place.element ? loadElement(*place.slot, place.element) : load(*place.slot);
      const Dual x = toFloatScalar(value).c[0];
      if (whole.type.kind == TypeKind::Matrix) {
        setMatrixElement(whole, place.part, x);
      } else {
        for (int k = 0; k < 3; ++k) {
          Value* hit = k == 0   ? b_.CreateICmpSLE(place.part, ci(0))
                       : k == 1 ? b_.CreateICmpEQ(place.part, ci(1))
                                : b_.CreateICmpSGE(place.part, ci(2));
          whole.c[k] = dselect(hit, x, whole.c[k]);
        }
      }
    }
    if (place.element)
      storeElement(*place.slot, place.element, convert(whole, place.slot->type.element()));
    else
      store(*place.slot, convert(whole, place.slot->type));
  }

  Val arith(Tok op, const Val& a0, const Val& b0) {
    if (a0.type.kind == TypeKind::Matrix || b0.type.kind == TypeKind::Matrix) return matrixArith(op, a0, b0);
    const Type rt = resultType(op, a0.type, b0.type);
    if (rt.kind == TypeKind::Int) {
      Value* a = a0.c[0].v;
      Value* b = b0.c[0].v;
      switch (op) {
        case Tok::Plus: return makeInt(b_.CreateAdd(a, b));
        case Tok::Minus: return makeInt(b_.CreateSub(a, b));
        case Tok::Star: return makeInt(b_.CreateMul(a, b));
        default: {
          // Division or remainder by 0 is 0; INT_MIN / -1 wraps instead of trapping.
          Value* zero = b_.CreateICmpEQ(b, ci(0));
          Value* overflow = b_.CreateAnd(b_.CreateICmpEQ(a, ci(INT32_MIN)), b_.CreateICmpEQ(b, ci(-1)));
          Value* safeB = b_.CreateSelect(b_.CreateOr(zero, overflow), ci(1), b);
          Value* q = op == Tok::Slash ? b_.CreateSDiv(a, safeB) : b_.CreateSRem(a, safeB);
          if (op == Tok::Percent) q = b_.CreateSelect(overflow, ci(0), q);
          return makeInt(b_.CreateSelect(zero, ci(0), q));
        }
      }
    }
    const Val a = convert(a0, rt);
    const Val b = convert(b0, rt);
    switch (op) {
      case Tok::Plus: return map2(rt, a, b, [&](Dual x, Dual y) { return dadd(x, y); });
      case Tok::Minus: return map2(rt, a, b, [&](Dual x, Dual y) { return dsub(x, y); });
      case Tok::Star: return map2(rt, a, b, [&](Dual x, Dual y) { return dmul(x, y); });
      default: return map2(rt, a, b, [&](Dual x, Dual y) { return ddiv(x, y); });
    }
  }

  // Mirrors the type checker's arithmetic typing for values whose types are already checked.
  static Type resultType(Tok op, Type a, Type b) {
    if (a.isScalar() && b.isScalar())
      return a.kind == TypeKind::Int && b.kind == TypeKind::Int ? Type(TypeKind::Int) : Type(TypeKind::Float);
    if (a.isScalar()) return b;
    if (b.isScalar()) return a;
    if (a.kind == TypeKind::Color) return a;
    if (op == Tok::Plus || op == Tok::Minus) return Type(spatialSum(a.kind, b.kind, op == Tok::Minus));
    return a.kind == b.kind ? a : Type(TypeKind::Vector);
  }

  Val genBinary(const Expr& e) {
    if (e.op == Tok::AmpAmp || e.op == Tok::PipePipe) {
      // Short-circuit: the right operand runs only when needed.
      Value* l = truth(gen(*e.operands[0]));
      llvm::BasicBlock* from = b_.GetInsertBlock();
      llvm::BasicBlock* rhsB = newBlock("logic.rhs");
      llvm::BasicBlock* endB = newBlock("logic.end");
      if (e.op == Tok::AmpAmp)
        b_.CreateCondBr(l, rhsB, endB);
      else
        b_.CreateCondBr(l, endB, rhsB);
      b_.SetInsertPoint(rhsB);
      Value* r = truth(gen(*e.operands[1]));
      llvm::BasicBlock* rhsEnd = b_.GetInsertBlock();
      b_.CreateBr(endB);
      b_.SetInsertPoint(endB);
      llvm::PHINode* phi = b_.CreatePHI(b_.getInt1Ty(), 2);
      phi->addIncoming(e.op == Tok::AmpAmp ? b_.getFalse() : b_.getTrue(), from);
      phi->addIncoming(r, rhsEnd);
      return boolToInt(phi);
    }
    Val a = gen(*e.operands[0]);
    Val b = gen(*e.operands[1]);
    switch (e.op) {
      case Tok::Plus:
      case Tok::Minus:
      case Tok::Star:
      case Tok::Slash:
      case Tok::Percent: return arith(e.op, a, b);
      case Tok::Dot: return makeFloat(dot3(a, b));
      case Tok::Caret: return cross3(a, b);
      case Tok::Less:
      case Tok::LessEq:
      case Tok::Greater:
      case Tok::GreaterEq: {
        if (a.type.kind == TypeKind::Int && b.type.kind == TypeKind::Int) {
          const auto pred = e.op == Tok::Less     ? llvm::CmpInst::ICMP_SLT
                            : e.op == Tok::LessEq ? llvm::CmpInst::ICMP_SLE
                            : e.op == Tok::Greater ? llvm::CmpInst::ICMP_SGT
                                                   : llvm::CmpInst::ICMP_SGE;
          return boolToInt(b_.CreateICmp(pred, a.c[0].v, b.c[0].v));
        }
        const auto pred = e.op == Tok::Less     ? llvm::CmpInst::FCMP_OLT
                          : e.op == Tok::LessEq ? llvm::CmpInst::FCMP_OLE
                          : e.op == Tok::Greater ? llvm::CmpInst::FCMP_OGT
                                                 : llvm::CmpInst::FCMP_OGE;
        return boolToInt(b_.CreateFCmp(pred, toFloatScalar(a).c[0].v, toFloatScalar(b).c[0].v));
      }
      case Tok::EqEq:
      case Tok::NotEq: {
        Value* eq = nullptr;
        if (a.type.kind == TypeKind::String) {
          llvm::FunctionCallee strcmpFn = module_.getOrInsertFunction(
              "strcmp", llvm::FunctionType::get(i32_, {ptr_, ptr_}, false));
          eq = b_.CreateICmpEQ(b_.CreateCall(strcmpFn, {a.c[0].v, b.c[0].v}), ci(0));
        } else if (a.type.kind == TypeKind::Int && b.type.kind == TypeKind::Int) {
          eq = b_.CreateICmpEQ(a.c[0].v, b.c[0].v);
        } else {
          const Type t = a.type.isTriple() || a.type.kind == TypeKind::Matrix   ? a.type
                         : b.type.isTriple() || b.type.kind == TypeKind::Matrix ? b.type
                                                                                : Type(TypeKind::Float);
          const Val x = convert(a, t);
          const Val y = convert(b, t);
          for (int k = 0; k < numComponents(t); ++k) {
            Value* ck = b_.CreateFCmpOEQ(x.c[k].v, y.c[k].v);
            eq = eq ? b_.CreateAnd(eq, ck) : ck;
          }
        }
        return boolToInt(e.op == Tok::EqEq ? eq : b_.CreateNot(eq));
      }
      default: return zeroOf(Type(TypeKind::Float));
    }
  }

  // ---- Coordinate spaces: row vectors, p' = p * M (abi.h). M is read from batch->spaces.
  Value* matrixElement(Value* matrix, int index) { return b_.CreateLoad(f32_, bytePtr(matrix, 4 * size_t(index))); }
  Val transformBy(const Val& a, size_t matrixOffset, size_t inverseOffset, int kind) {
    return transformBy(a, bytePtr(spaces_, matrixOffset), bytePtr(spaces_, inverseOffset), kind);
  }
  // kind: 0 point (w = 1), 1 vector (w = 0), 2 normal (uses the inverse, transposed).
  Val transformBy(const Val& a, Value* matrixOffset, Value* inverseOffset, int kind) {
    Val r;
    r.type = a.type;
    for (int j = 0; j < 3; ++j) {
      Dual acc = dconst(0);
      for (int i = 0; i < 3; ++i) {
        Value* m = kind == 2 ? matrixElement(inverseOffset, j * 4 + i) : matrixElement(matrixOffset, i * 4 + j);
        acc = dadd(acc, dmul(a.c[i], {m, nullptr, nullptr}));
      }
      if (kind == 0) acc = dadd(acc, {matrixElement(matrixOffset, 12 + j), nullptr, nullptr});
      r.c[j] = acc;
    }
    return r;
  }
  // A space named by a run-time string: both matrices from rlf_space_matrices (§2.3).
  std::pair<Value*, Value*> dynamicSpace(Value* name) {
    auto* m16 = llvm::ArrayType::get(f32_, 16);
    llvm::AllocaInst* toCurrentM = entryAlloca(m16, "space.to");
    llvm::AllocaInst* fromCurrentM = entryAlloca(m16, "space.from");
    llvm::FunctionCallee fnc = module_.getOrInsertFunction(
        "rlf_space_matrices", llvm::FunctionType::get(i32_, {ptr_, ptr_, ptr_, ptr_}, false));
    if (auto* fn = llvm::dyn_cast<llvm::Function>(fnc.getCallee())) fn->setDoesNotThrow();
    Value* spaces = spaces_ ? spaces_ : llvm::ConstantPointerNull::get(ptr_);
    Value* ok = b_.CreateCall(fnc, {spaces, name, toCurrentM, fromCurrentM});
    if (unknownSpace_) {
      Value* bad = b_.CreateZExt(b_.CreateICmpEQ(ok, ci(0)), i32_);
      b_.CreateStore(b_.CreateAdd(b_.CreateLoad(i32_, unknownSpace_), bad), unknownSpace_);
    }
    return {toCurrentM, fromCurrentM};
  }
  static int transformKind(const Val& a) {
    return a.type.kind == TypeKind::Point ? 0 : a.type.kind == TypeKind::Normal ? 2 : 1;
  }
  // From the space named by `spaceExpr` (a literal or a run-time string `name`) to current.
  Val toCurrentNamed(const Val& a, const Expr& spaceExpr, Value* name) {
    if (spaceExpr.kind == ExprKind::StringLiteral) return toCurrent(a, spaceExpr.text);
    const auto [to, from] = dynamicSpace(name);
    return transformBy(a, to, from, transformKind(a));
  }
  Val fromCurrentNamed(const Val& a, const Expr& spaceExpr, Value* name) {
    if (spaceExpr.kind == ExprKind::StringLiteral) return fromCurrent(a, spaceExpr.text);
    const auto [to, from] = dynamicSpace(name);
    return transformBy(a, from, to, transformKind(a));
  }

  // From `space` to current.
  Val toCurrent(const Val& a, const std::string& space) {
    const int kind = a.type.kind == TypeKind::Point ? 0 : a.type.kind == TypeKind::Normal ? 2 : 1;
    if (space == "object")
      return transformBy(a, offsetof(RlfSpaces, currentFromObject), offsetof(RlfSpaces, objectFromCurrent), kind);
    if (space == "shader")
      return transformBy(a, offsetof(RlfSpaces, currentFromShader), offsetof(RlfSpaces, shaderFromCurrent), kind);
    if (space == "camera")
      return transformBy(a, offsetof(RlfSpaces, currentFromCamera), offsetof(RlfSpaces, cameraFromCurrent), kind);
    return a;
  }
  // From current to `space`.
  Val fromCurrent(const Val& a, const std::string& space) {
    const int kind = a.type.kind == TypeKind::Point ? 0 : a.type.kind == TypeKind::Normal ? 2 : 1;
    if (space == "object")
      return transformBy(a, offsetof(RlfSpaces, objectFromCurrent), offsetof(RlfSpaces, currentFromObject), kind);
    if (space == "shader")
      return transformBy(a, offsetof(RlfSpaces, shaderFromCurrent), offsetof(RlfSpaces, currentFromShader), kind);
    if (space == "camera")
      return transformBy(a, offsetof(RlfSpaces, cameraFromCurrent), offsetof(RlfSpaces, currentFromCamera), kind);
    return a;
  }

  // ---- Matrices (§2.2, §4.1, §6.3): 16 scalars, row-major, row vectors.
  Val makeMatrix() {
    Val m;
    m.type = Type(TypeKind::Matrix);
    for (int k = 0; k < 16; ++k) m.c[k] = dconst(0);
    return m;
  }
  Val identity() { return splat(Type(TypeKind::Matrix), dconst(1)); }
  Val loadMatrix(Value* ptr) {
    Val m = makeMatrix();
    for (int k = 0; k < 16; ++k) m.c[k] = {matrixElement(ptr, k), nullptr, nullptr};
    return m;
  }
  Val matmul(const Val& a, const Val& b) {
    Val r = makeMatrix();
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        Dual acc = dmul(a.c[i * 4], b.c[j]);
        for (int k = 1; k < 4; ++k) acc = dadd(acc, dmul(a.c[i * 4 + k], b.c[k * 4 + j]));
        r.c[i * 4 + j] = acc;
      }
    return r;
  }
  Val transposed(const Val& a) {
    Val r = makeMatrix();
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) r.c[i * 4 + j] = a.c[j * 4 + i];
    return r;
  }
  // Cofactor expansion through the 2x2 minors of the top and bottom row pairs.
  struct Minors {
    Dual s[6], c[6], det;
  };
  Minors minors(const Val& m) {
    auto a = [&](int i, int j) { return m.c[i * 4 + j]; };
    auto d2 = [&](Dual p, Dual q, Dual r, Dual t) { return dsub(dmul(p, q), dmul(r, t)); };
    Minors r;
    r.s[0] = d2(a(0, 0), a(1, 1), a(1, 0), a(0, 1));
    r.s[1] = d2(a(0, 0), a(1, 2), a(1, 0), a(0, 2));
    r.s[2] = d2(a(0, 0), a(1, 3), a(1, 0), a(0, 3));
    r.s[3] = d2(a(0, 1), a(1, 2), a(1, 1), a(0, 2));
    r.s[4] = d2(a(0, 1), a(1, 3), a(1, 1), a(0, 3));
    r.s[5] = d2(a(0, 2), a(1, 3), a(1, 2), a(0, 3));
    r.c[5] = d2(a(2, 2), a(3, 3), a(3, 2), a(2, 3));
    r.c[4] = d2(a(2, 1), a(3, 3), a(3, 1), a(2, 3));
    r.c[3] = d2(a(2, 1), a(3, 2), a(3, 1), a(2, 2));
    r.c[2] = d2(a(2, 0), a(3, 3), a(3, 0), a(2, 3));
    r.c[1] = d2(a(2, 0), a(3, 2), a(3, 0), a(2, 2));
    r.c[0] = d2(a(2, 0), a(3, 1), a(3, 0), a(2, 1));
    r.det = dadd(dadd(dsub(dmul(r.s[0], r.c[5]), dmul(r.s[1], r.c[4])), dadd(dmul(r.s[2], r.c[3]), dmul(r.s[3], r.c[2]))),
                 dsub(dmul(r.s[5], r.c[0]), dmul(r.s[4], r.c[1])));
    return r;
  }
  Dual determinant(const Val& m) { return minors(m).det; }
  // Singular matrices (determinant 0) invert to zero: ddiv's ÷0 is 0.
  Val inverse(const Val& m) {
    const Minors n = minors(m);
    auto a = [&](int i, int j) { return m.c[i * 4 + j]; };
    auto t3 = [&](Dual x0, Dual y0, Dual x1, Dual y1, Dual x2, Dual y2) {
      return dadd(dsub(dmul(x0, y0), dmul(x1, y1)), dmul(x2, y2));
    };
    const Dual* s = n.s;
    const Dual* c = n.c;
    Dual r[16] = {
        t3(a(1, 1), c[5], a(1, 2), c[4], a(1, 3), c[3]),  dneg(t3(a(0, 1), c[5], a(0, 2), c[4], a(0, 3), c[3])),
        t3(a(3, 1), s[5], a(3, 2), s[4], a(3, 3), s[3]),  dneg(t3(a(2, 1), s[5], a(2, 2), s[4], a(2, 3), s[3])),
        dneg(t3(a(1, 0), c[5], a(1, 2), c[2], a(1, 3), c[1])), t3(a(0, 0), c[5], a(0, 2), c[2], a(0, 3), c[1]),
        dneg(t3(a(3, 0), s[5], a(3, 2), s[2], a(3, 3), s[1])), t3(a(2, 0), s[5], a(2, 2), s[2], a(2, 3), s[1]),
        t3(a(1, 0), c[4], a(1, 1), c[2], a(1, 3), c[0]),  dneg(t3(a(0, 0), c[4], a(0, 1), c[2], a(0, 3), c[0])),
        t3(a(3, 0), s[4], a(3, 1), s[2], a(3, 3), s[0]),  dneg(t3(a(2, 0), s[4], a(2, 1), s[2], a(2, 3), s[0])),
        dneg(t3(a(1, 0), c[3], a(1, 1), c[1], a(1, 2), c[0])), t3(a(0, 0), c[3], a(0, 1), c[1], a(0, 2), c[0]),
        dneg(t3(a(3, 0), s[3], a(3, 1), s[1], a(3, 2), s[0])), t3(a(2, 0), s[3], a(2, 1), s[1], a(2, 2), s[0]),
    };
    Val out = makeMatrix();
    for (int k = 0; k < 16; ++k) out.c[k] = ddiv(r[k], n.det);
    return out;
  }
  Val matrixArith(Tok op, const Val& a, const Val& b) {
    const bool am = a.type.kind == TypeKind::Matrix, bm = b.type.kind == TypeKind::Matrix;
    if (am && bm) return op == Tok::Star ? matmul(a, b) : matmul(a, inverse(b));
    // RSL's f/m: f·inverse(m).
    if (op == Tok::Slash && bm) return matrixArith(Tok::Star, inverse(b), a);
    // With a scalar: element-wise (m*f, f*m, m/f).
    const Val& m = am ? a : b;
    const Dual f = toFloatScalar(am ? b : a).c[0];
    Val r = makeMatrix();
    for (int k = 0; k < 16; ++k) r.c[k] = op == Tok::Slash ? ddiv(m.c[k], f) : dmul(m.c[k], f);
    return r;
  }
  // Run-time (row, column), each clamped into 0..3 (one count when either was out of range).
  Value* matrixIndex(Value* row, Value* col) {
    auto clamp3 = [&](Value* i) {
      return b_.CreateSelect(b_.CreateICmpSLT(i, ci(0)), ci(0), b_.CreateSelect(b_.CreateICmpSGT(i, ci(3)), ci(3), i));
    };
    if (llvm::isa<llvm::ConstantInt>(row) && llvm::isa<llvm::ConstantInt>(col))
      return ci(int32_t(std::clamp<int64_t>(llvm::cast<llvm::ConstantInt>(row)->getSExtValue(), 0, 3) * 4 +
                        std::clamp<int64_t>(llvm::cast<llvm::ConstantInt>(col)->getSExtValue(), 0, 3)));
    if (indexClamped_) {
      Value* out = b_.CreateOr(b_.CreateICmpUGT(row, ci(3)), b_.CreateICmpUGT(col, ci(3)));
      b_.CreateStore(b_.CreateAdd(b_.CreateLoad(i32_, indexClamped_), b_.CreateZExt(out, i32_)), indexClamped_);
    }
    return b_.CreateAdd(b_.CreateMul(clamp3(row), ci(4)), clamp3(col));
  }
  Dual matrixElementAt(const Val& m, Value* row, Value* col) { return matrixElementAt(m, matrixIndex(row, col)); }
  void setMatrixElement(Val& m, Value* row, Value* col, Dual x) { setMatrixElement(m, matrixIndex(row, col), x); }
  // By a clamped row * 4 + column from matrixIndex.
  Dual matrixElementAt(const Val& m, Value* k) {
    if (auto* kc = llvm::dyn_cast<llvm::ConstantInt>(k)) return m.c[kc->getSExtValue()];
    Value* r = m.c[0].v;
    for (int i = 1; i < 16; ++i) r = b_.CreateSelect(b_.CreateICmpEQ(k, ci(i)), m.c[i].v, r);
    return {r, nullptr, nullptr};
  }
  void setMatrixElement(Val& m, Value* k, Dual x) {
    for (int i = 0; i < 16; ++i) m.c[i] = {b_.CreateSelect(b_.CreateICmpEQ(k, ci(i)), x.v, m.c[i].v), nullptr, nullptr};
  }
  // p * m by the type of p: point (w = 1, divided by w'), vector (w = 0), normal (inverse transpose).
  Val transformByMatrix(const Val& p, const Val& m0, int kind) {
    const Val m = kind == 2 ? transposed(inverse(m0)) : m0;
    Val r;
    r.type = p.type;
    for (int j = 0; j < 3; ++j) {
      Dual acc = dmul(p.c[0], m.c[j]);
      for (int i = 1; i < 3; ++i) acc = dadd(acc, dmul(p.c[i], m.c[i * 4 + j]));
      if (kind == 0) acc = dadd(acc, m.c[12 + j]);
      r.c[j] = acc;
    }
    if (kind == 0) {
      // Projective matrices: divide by w' unless it is 1 (or 0, which would only produce Inf).
      Dual w = dadd(dadd(dmul(p.c[0], m.c[3]), dmul(p.c[1], m.c[7])), dadd(dmul(p.c[2], m.c[11]), m.c[15]));
      Value* plain = b_.CreateOr(b_.CreateFCmpOEQ(w.v, cf(1)), b_.CreateFCmpOEQ(w.v, cf(0)));
      for (int j = 0; j < 3; ++j) r.c[j] = dselect(plain, r.c[j], ddiv(r.c[j], w));
    }
    return r;
  }
  // The matrices from the named space to current and back.
  std::pair<Val, Val> spaceMatrices(const Expr& spaceExpr, Value* name) {
    if (spaceExpr.kind != ExprKind::StringLiteral) {
      const auto [to, from] = dynamicSpace(name);
      return {loadMatrix(to), loadMatrix(from)};
    }
    const std::string& space = spaceExpr.text;
    if (space == "object")
      return {loadMatrix(bytePtr(spaces_, offsetof(RlfSpaces, currentFromObject))),
              loadMatrix(bytePtr(spaces_, offsetof(RlfSpaces, objectFromCurrent)))};
    if (space == "shader")
      return {loadMatrix(bytePtr(spaces_, offsetof(RlfSpaces, currentFromShader))),
              loadMatrix(bytePtr(spaces_, offsetof(RlfSpaces, shaderFromCurrent)))};
    if (space == "camera")
      return {loadMatrix(bytePtr(spaces_, offsetof(RlfSpaces, currentFromCamera))),
              loadMatrix(bytePtr(spaces_, offsetof(RlfSpaces, cameraFromCurrent)))};
    return {identity(), identity()};
  }
  Val genMatrixConstruct(const Expr& e) {
    size_t first = 0;
    while (first < e.operands.size() && first < 2 && e.operands[first]->type.kind == TypeKind::String) ++first;
    if (first == 2) {
      // matrix("from", "to") = from→current · current→to.
      const Val fromM = spaceMatrices(*e.operands[0], gen(*e.operands[0]).c[0].v).first;
      const Val toM = spaceMatrices(*e.operands[1], gen(*e.operands[1]).c[0].v).second;
      return matmul(fromM, toM);
    }
    Val m;
    const size_t n = e.operands.size() - first;
    if (n == 1) {
      const Val a = gen(*e.operands[first]);
      m = a.type.kind == TypeKind::Matrix ? a : splat(Type(TypeKind::Matrix), toFloatScalar(a).c[0]);
      for (int k = 0; k < 16; ++k) m.c[k].du = m.c[k].dv = nullptr;
    } else {
      m = makeMatrix();
      for (int k = 0; k < 16; ++k) m.c[k] = {toFloatScalar(gen(*e.operands[first + size_t(k)])).c[0].v, nullptr, nullptr};
    }
    // matrix("space", m) is given in the space, as in OSL: first m, then space→current.
    // RSL's matrix "space" m is what the RI spec (11.4) says: current→space, then m, so that
    // matrix "shader" 1 transforms points as transform("shader", p) does.
    if (first == 1) {
      const auto [toCurrent, fromCurrent] = spaceMatrices(*e.operands[0], gen(*e.operands[0]).c[0].v);
      m = e.spaceOutside ? matmul(fromCurrent, m) : matmul(m, toCurrent);
    }
    return m;
  }

  Val genConstruct(const Expr& e) {
    const Type t(e.constructType);
    if (t.kind == TypeKind::Matrix) return genMatrixConstruct(e);
    size_t first = 0;
    if (!e.operands.empty() && e.operands[0]->type.kind == TypeKind::String) first = 1;
    std::vector<Val> args;
    for (size_t i = first; i < e.operands.size(); ++i) args.push_back(gen(*e.operands[i]));
    if (t.isScalar()) return convert(args[0], t);
    Val r;
    if (args.size() == 1) {
      r = args[0].type.isTriple() ? args[0] : splat(t, toFloatScalar(args[0]).c[0]);
      r.type = t;
    } else {
      r = makeTriple(t, toFloatScalar(args[0]).c[0], toFloatScalar(args[1]).c[0], toFloatScalar(args[2]).c[0]);
    }
    if (first == 1 && t.kind != TypeKind::Color) r = toCurrentNamed(r, *e.operands[0], gen(*e.operands[0]).c[0].v);
    return r;
  }

  // ---- Built-in calls.
  static Type bindT(const std::vector<Val>& args, bool allowInt) {
    for (const Val& a : args)
      if (a.type.isTriple()) return a.type;
    if (allowInt) {
      bool allInt = true;
      for (const Val& a : args) allInt &= a.type.kind == TypeKind::Int;
      if (allInt) return Type(TypeKind::Int);
    }
    return Type(TypeKind::Float);
  }

  Dual unaryMath(BuiltinId id, Dual x) {
    using llvm::Intrinsic::ID;
    switch (id) {
      case BuiltinId::Sin: return chain(intrinsic(llvm::Intrinsic::sin, {x.v}), intrinsic(llvm::Intrinsic::cos, {x.v}), x);
      case BuiltinId::Cos:
        return chain(intrinsic(llvm::Intrinsic::cos, {x.v}), b_.CreateFNeg(intrinsic(llvm::Intrinsic::sin, {x.v})), x);
      case BuiltinId::Tan: {
        Value* c = intrinsic(llvm::Intrinsic::cos, {x.v});
        return chain(libcall("tanf", {x.v}), b_.CreateFDiv(cf(1), b_.CreateFMul(c, c)), x);
      }
      case BuiltinId::Asin:
      case BuiltinId::Acos: {
        Value* cl = b_.CreateSelect(b_.CreateFCmpOGT(x.v, cf(1)), cf(1), b_.CreateSelect(b_.CreateFCmpOLT(x.v, cf(-1)), cf(-1), x.v));
        Value* r = libcall(id == BuiltinId::Asin ? "asinf" : "acosf", {cl});
        Value* k2 = b_.CreateFSub(cf(1), b_.CreateFMul(cl, cl));
        Value* inside = b_.CreateFCmpOGT(k2, cf(0));
        Value* d = b_.CreateSelect(inside, b_.CreateFDiv(cf(id == BuiltinId::Asin ? 1.f : -1.f), intrinsic(llvm::Intrinsic::sqrt, {b_.CreateSelect(inside, k2, cf(1))})), cf(0));
        return chain(r, d, x);
      }
      case BuiltinId::Atan:
        return chain(libcall("atanf", {x.v}), b_.CreateFDiv(cf(1), b_.CreateFAdd(cf(1), b_.CreateFMul(x.v, x.v))), x);
      case BuiltinId::Exp: {
        Value* r = intrinsic(llvm::Intrinsic::exp, {x.v});
        return chain(r, r, x);
      }
      case BuiltinId::Sinh:
      case BuiltinId::Cosh: {
        Value* ep = intrinsic(llvm::Intrinsic::exp, {x.v});
        Value* en = intrinsic(llvm::Intrinsic::exp, {b_.CreateFNeg(x.v)});
        Value* sh = b_.CreateFMul(b_.CreateFSub(ep, en), cf(0.5f));
        Value* ch = b_.CreateFMul(b_.CreateFAdd(ep, en), cf(0.5f));
        return id == BuiltinId::Sinh ? chain(sh, ch, x) : chain(ch, sh, x);
      }
      case BuiltinId::Tanh: {
        // 1 - 2/(e^2x + 1) saturates to ±1 instead of Inf/Inf.
        Value* e2 = intrinsic(llvm::Intrinsic::exp, {b_.CreateFMul(x.v, cf(2))});
        Value* th = b_.CreateFSub(cf(1), b_.CreateFDiv(cf(2), b_.CreateFAdd(e2, cf(1))));
        return chain(th, b_.CreateFSub(cf(1), b_.CreateFMul(th, th)), x);
      }
      case BuiltinId::Exp2: {
        Value* r = intrinsic(llvm::Intrinsic::exp2, {x.v});
        return chain(r, b_.CreateFMul(r, cf(0.693147181f)), x);
      }
      case BuiltinId::Log: return dlogSafe(x, 1.0f);
      case BuiltinId::Log2: return dlogSafe(x, 1.44269504f);
      case BuiltinId::Log10: return dlogSafe(x, 0.434294482f);
      case BuiltinId::Sqrt: return dsqrtSafe(x);
      case BuiltinId::InverseSqrt: {
        const Dual s = dsqrtSafe(x);
        return ddiv(dconst(1), s);
      }
      case BuiltinId::Abs:
      case BuiltinId::Fabs: return dabs(x);
      case BuiltinId::Sign: {
        Value* r = b_.CreateSelect(b_.CreateFCmpOGT(x.v, cf(0)), cf(1), b_.CreateSelect(b_.CreateFCmpOLT(x.v, cf(0)), cf(-1), cf(0)));
        return {r, nullptr, nullptr};
      }
      case BuiltinId::Floor: return dfloorLike(llvm::Intrinsic::floor, x);
      case BuiltinId::Ceil: return dfloorLike(llvm::Intrinsic::ceil, x);
      case BuiltinId::Round: return dfloorLike(llvm::Intrinsic::round, x);
      case BuiltinId::Trunc: return dfloorLike(llvm::Intrinsic::trunc, x);
      case BuiltinId::Radians: return dmul(x, dconst(0.0174532925f));
      case BuiltinId::Degrees: return dmul(x, dconst(57.2957795f));
      default: return x;
    }
  }

  Dual modDual(Dual a, Dual b, bool cStyle) {
    // mod: a - b*floor(a/b); fmod: a - b*trunc(a/b); by 0: 0.
    Value* zero = b_.CreateFCmpOEQ(b.v, cf(0));
    Value* q = b_.CreateFDiv(a.v, b_.CreateSelect(zero, cf(1), b.v));
    Value* k = intrinsic(cStyle ? llvm::Intrinsic::trunc : llvm::Intrinsic::floor, {q});
    Dual r = dsub(a, dmul(b, {k, nullptr, nullptr}));
    return dselect(zero, dconst(0), r);
  }

  // Channel k (0..2) of a noise: the runtime's uncorrelated noise k on the same lattice.
  Dual noiseCall(const std::vector<Dual>& in, int channel) {
    static const char* kNames[] = {"rlf_noise1", "rlf_noise2", "rlf_noise3", "rlf_noise4"};
    const size_t d = in.size();
    std::vector<llvm::Type*> params(d, f32_);
    params.push_back(ptr_);
    params.push_back(i32_);
    llvm::FunctionCallee fnc =
        module_.getOrInsertFunction(kNames[d - 1], llvm::FunctionType::get(f32_, params, false));
    if (auto* fn = llvm::dyn_cast<llvm::Function>(fnc.getCallee())) {
      fn->setDoesNotThrow();
      fn->setWillReturn();
      fn->setMemoryEffects(llvm::MemoryEffects::argMemOnly(llvm::ModRefInfo::Mod));
    }
    if (!gradient_) gradient_ = entryAlloca(llvm::ArrayType::get(f32_, 4), "grad");
    std::vector<Value*> args;
    for (size_t i = 0; i < d; ++i) args.push_back(in[i].v);
    args.push_back(gradient_);
    args.push_back(ci(channel));
    Dual r;
    r.v = b_.CreateCall(fnc, args);
    for (size_t i = 0; i < d; ++i) {
      if (!in[i].du && !in[i].dv) continue;
      Value* g = b_.CreateLoad(f32_, b_.CreateConstInBoundsGEP2_32(gradient_->getAllocatedType(), gradient_, 0, unsigned(i)));
      r.du = lAdd(r.du, lMul(in[i].du, g));
      r.dv = lAdd(r.dv, lMul(in[i].dv, g));
    }
    return r;
  }

  Val cellnoiseOf(const std::vector<Val>& args, Type result) {
    std::vector<Value*> in;
    for (const Val& a : args) {
      if (a.type.isTriple())
        for (int k = 0; k < 3; ++k) in.push_back(a.c[k].v);
      else
        in.push_back(toFloatScalar(a).c[0].v);
    }
    if (!cellInput_) cellInput_ = entryAlloca(llvm::ArrayType::get(f32_, 4), "cell");
    for (size_t i = 0; i < in.size(); ++i)
      b_.CreateStore(in[i], b_.CreateConstInBoundsGEP2_32(cellInput_->getAllocatedType(), cellInput_, 0, unsigned(i)));
    llvm::FunctionCallee fnc =
        module_.getOrInsertFunction("rlf_cellnoise", llvm::FunctionType::get(f32_, {ptr_, i32_, i32_}, false));
    if (auto* fn = llvm::dyn_cast<llvm::Function>(fnc.getCallee())) {
      fn->setDoesNotThrow();
      fn->setWillReturn();
      fn->setMemoryEffects(llvm::MemoryEffects::argMemOnly(llvm::ModRefInfo::Ref));
    }
    Val r;
    r.type = result;
    for (int k = 0; k < numComponents(result); ++k)
      r.c[k] = {b_.CreateCall(fnc, {cellInput_, ci(int32_t(in.size())), ci(k)}), nullptr, nullptr};
    return r;
  }

  Dual pnoiseCall(const std::vector<Dual>& in, const std::vector<Value*>& periods, int channel) {
    llvm::FunctionCallee fnc =
        module_.getOrInsertFunction("rlf_pnoise", llvm::FunctionType::get(f32_, {ptr_, ptr_, i32_, ptr_, i32_}, false));
    if (auto* fn = llvm::dyn_cast<llvm::Function>(fnc.getCallee())) {
      fn->setDoesNotThrow();
      fn->setWillReturn();
      fn->setMemoryEffects(llvm::MemoryEffects::argMemOnly(llvm::ModRefInfo::ModRef));
    }
    auto* arr = llvm::ArrayType::get(f32_, 4);
    if (!gradient_) gradient_ = entryAlloca(arr, "grad");
    llvm::AllocaInst* p = entryAlloca(arr, "pnoise.p");
    llvm::AllocaInst* per = entryAlloca(arr, "pnoise.period");
    for (size_t i = 0; i < in.size(); ++i) {
      b_.CreateStore(in[i].v, b_.CreateConstInBoundsGEP2_32(arr, p, 0, unsigned(i)));
      b_.CreateStore(periods[i], b_.CreateConstInBoundsGEP2_32(arr, per, 0, unsigned(i)));
    }
    Dual r;
    r.v = b_.CreateCall(fnc, {p, per, ci(int32_t(in.size())), gradient_, ci(channel)});
    for (size_t i = 0; i < in.size(); ++i) {
      if (!in[i].du && !in[i].dv) continue;
      Value* g = b_.CreateLoad(f32_, b_.CreateConstInBoundsGEP2_32(gradient_->getAllocatedType(), gradient_, 0, unsigned(i)));
      r.du = lAdd(r.du, lMul(in[i].du, g));
      r.dv = lAdd(r.dv, lMul(in[i].dv, g));
    }
    return r;
  }

  Val noiseOf(const std::vector<Val>& args, Type result, bool isSigned) {
    std::vector<Dual> in;
    for (const Val& a : args) {
      if (a.type.isTriple())
        for (int k = 0; k < 3; ++k) in.push_back(a.c[k]);
      else
        in.push_back(toFloatScalar(a).c[0]);
    }
    // Triple results: three decorrelated channels, each 0.5 at the lattice points (§6.5).
    Val r;
    r.type = result;
    for (int k = 0; k < numComponents(result); ++k) {
      Dual n = noiseCall(in, k);
      if (isSigned) n = dsub(dmul(n, dconst(2)), dconst(1));
      r.c[k] = n;
    }
    return r;
  }

  void displaceBy(const Val& offset) {
    const Slot& pSlot = slotFor(globals_[size_t(GlobalId::P)]);
    const Slot& nSlot = slotFor(globals_[size_t(GlobalId::N)]);
    Val p = load(pSlot);
    Val np = map2(p.type, p, convert(offset, p.type), [&](Dual x, Dual y) { return dadd(x, y); });
    store(pSlot, np);
    Val n = normalize3(calculateNormal(np));
    n.type = Type(TypeKind::Normal);
    store(nSlot, n);
  }

  // User functions are inlined at every call (recursion is a compile error, so this terminates).
  // Output parameters alias a variable argument's storage; an element or component argument is
  // copied in and back out (Place). The other parameters are fresh copies.
  Val genUserCall(const Expr& e) {
    const FunctionDecl& f = *e.function;
    // Evaluate every argument before binding any parameter: an argument may call f itself.
    std::vector<Val> values(e.operands.size());
    std::vector<Place> places(e.operands.size());
    for (size_t i = 0; i < e.operands.size(); ++i) {
      const Expr& arg = *e.operands[i];
      if (!f.params[i]->isOutput) {
        values[i] = convert(gen(arg), f.params[i]->type);
        // A read-only array is copied, as values are: sharing the argument's storage would let
        // the body see its own writes through an output parameter or an extern naming that same
        // array. The copy is taken now, before a later argument's call can change the array.
        if (values[i].array) values[i].array = &copyArray(*values[i].array, f.params[i]->name);
      } else if (arg.kind != ExprKind::Identifier) {
        places[i] = resolvePlace(arg);
        values[i] = readPlace(places[i]);
      }
    }
    for (size_t i = 0; i < e.operands.size(); ++i) {
      const VarDecl* p = f.params[i].get();
      if (p->isOutput && places[i].slot) {
        slots_.erase(p);  // an earlier call may have bound p to another variable's storage
        store(slotFor(p), values[i]);
      } else if (p->isOutput) {
        const Slot target = slotFor(e.operands[i]->decl);
        slots_[p] = target;
      } else if (p->type.isArray()) {
        slots_[p] = *values[i].array;  // this call's own copy, made above
      } else if (!p->written) {
        // Read-only: the body reads the argument's value itself. Storing it in the parameter's
        // variable made a chain of copies through every call that the optimiser's promotion
        // resolves in quadratic time (20,000 calls `y = f(y)` took 21 s to compile).
        boundValues_[p] = values[i];
      } else {
        store(slotFor(p), values[i]);
      }
    }
    // A body that is one `return expr;` (most helper functions) needs no result variable and no
    // block to return to: its value is the call's. Each of those was one more link in a chain of
    // copies that the optimiser's promotion resolves in quadratic time (10,000 calls of a one-line
    // function took 3 s to compile, 20,000 took 21 s).
    if (f.returnType.kind != TypeKind::Void && !f.returnType.isArray() && f.body && f.body->kind == StmtKind::Block &&
        f.body->stmts.size() == 1 && f.body->stmts[0]->kind == StmtKind::Return && f.body->stmts[0]->expr) {
      std::vector<LoopTargets> savedLoops = std::move(loops_);
      loops_.clear();
      Val r = convert(gen(*f.body->stmts[0]->expr), f.returnType);
      loops_ = std::move(savedLoops);
      for (size_t i = 0; i < e.operands.size(); ++i)
        if (places[i].slot) writePlace(places[i], load(slotFor(f.params[i].get())));
      return r;
    }
    const Slot* result = nullptr;
    if (f.returnType.kind != TypeKind::Void) {
      temps_.push_back(std::make_unique<VarDecl>());
      temps_.back()->name = f.name + ".result";
      temps_.back()->type = f.returnType;
      result = &slotFor(temps_.back().get());
      store(*result, zeroOf(f.returnType));
    }
    llvm::BasicBlock* end = newBlock("call.end");
    returns_.push_back({end, result, f.returnType});
    std::vector<LoopTargets> savedLoops = std::move(loops_);
    loops_.clear();
    genStmt(*f.body);
    loops_ = std::move(savedLoops);
    returns_.pop_back();
    if (!terminated()) b_.CreateBr(end);
    b_.SetInsertPoint(end);
    for (size_t i = 0; i < e.operands.size(); ++i)
      if (places[i].slot) writePlace(places[i], load(slotFor(f.params[i].get())));
    if (result) return load(*result);
    Val r;
    r.type = Type(TypeKind::Void);
    return r;
  }

  // Fresh storage per call (a nested call of the same function must not share it) holding a copy.
  const Slot& copyArray(const Slot& from, const std::string& name) {
    temps_.push_back(std::make_unique<VarDecl>());
    temps_.back()->name = name + ".copy";
    temps_.back()->type = from.type;
    const Slot& s = slotFor(temps_.back().get());
    Val v;
    v.type = from.type;
    v.array = &from;
    store(s, v);
    return s;
  }

  // texture(): the footprint is (Du(s)·du, Du(t)·du, Dv(s)·dv, Dv(t)·dv) (§6.7), and the result's
  // derivatives follow from the texture's own ∂/∂s and ∂/∂t by the chain rule.
  Val genTexture(const Expr& e, const std::vector<Val>& args) {
    const Type rt = e.type;
    const int n = numComponents(rt);
    Dual s, t;
    size_t first = 1;
    if (args.size() >= 3 && args[1].type.isScalar() && args[2].type.isScalar()) {
      s = toFloatScalar(args[1]).c[0];
      t = toFloatScalar(args[2]).c[0];
      first = 3;
    } else {
      s = load(slotFor(globals_[size_t(GlobalId::s)])).c[0];
      t = load(slotFor(globals_[size_t(GlobalId::t)])).c[0];
    }
    Value* du = load(slotFor(globals_[size_t(GlobalId::du)])).c[0].v;
    Value* dv = load(slotFor(globals_[size_t(GlobalId::dv)])).c[0].v;
    auto lane = [&](Value* l) { return l ? l : cf(0); };
    Value* dsdx = b_.CreateFMul(lane(s.du), du);
    Value* dtdx = b_.CreateFMul(lane(t.du), du);
    Value* dsdy = b_.CreateFMul(lane(s.dv), dv);
    Value* dtdy = b_.CreateFMul(lane(t.dv), dv);

    llvm::AllocaInst* opts = entryAlloca(llvm::ArrayType::get(i8_, sizeof(RlfTextureOptions)), "texopts");
    opts->setAlignment(llvm::Align(8));
    auto field = [&](size_t off) { return bytePtr(opts, off); };
    auto setF = [&](size_t off, Value* v) { b_.CreateStore(v, field(off)); };
    setF(offsetof(RlfTextureOptions, sblur), cf(0));
    setF(offsetof(RlfTextureOptions, tblur), cf(0));
    setF(offsetof(RlfTextureOptions, swidth), cf(1));
    setF(offsetof(RlfTextureOptions, twidth), cf(1));
    setF(offsetof(RlfTextureOptions, fill), cf(0));
    for (int k = 0; k < 3; ++k) setF(offsetof(RlfTextureOptions, missingcolor) + 4 * size_t(k), cf(0));
    setF(offsetof(RlfTextureOptions, hasMissingColor), ci(0));
    setF(offsetof(RlfTextureOptions, firstchannel), ci(0));
    setF(offsetof(RlfTextureOptions, swrap), llvm::ConstantPointerNull::get(ptr_));
    setF(offsetof(RlfTextureOptions, twrap), llvm::ConstantPointerNull::get(ptr_));
    for (size_t i = first; i + 1 < args.size(); i += 2) {
      const std::string& name = e.operands[i]->text;
      const Val& value = args[i + 1];
      auto f = [&] { return toFloatScalar(value).c[0].v; };
      if (name == "blur" || name == "sblur") setF(offsetof(RlfTextureOptions, sblur), f());
      if (name == "blur" || name == "tblur") setF(offsetof(RlfTextureOptions, tblur), f());
      if (name == "width" || name == "swidth") setF(offsetof(RlfTextureOptions, swidth), f());
      if (name == "width" || name == "twidth") setF(offsetof(RlfTextureOptions, twidth), f());
      if (name == "fill") setF(offsetof(RlfTextureOptions, fill), f());
      if (name == "firstchannel") setF(offsetof(RlfTextureOptions, firstchannel), convert(value, Type(TypeKind::Int)).c[0].v);
      if (name == "wrap" || name == "swrap") setF(offsetof(RlfTextureOptions, swrap), value.c[0].v);
      if (name == "wrap" || name == "twrap") setF(offsetof(RlfTextureOptions, twrap), value.c[0].v);
      if (name == "missingcolor") {
        const Val c = convert(value, Type(TypeKind::Color));
        for (int k = 0; k < 3; ++k) setF(offsetof(RlfTextureOptions, missingcolor) + 4 * size_t(k), c.c[k].v);
        setF(offsetof(RlfTextureOptions, hasMissingColor), ci(1));
      }
    }
    auto* arr = llvm::ArrayType::get(f32_, 4);
    llvm::AllocaInst* out = entryAlloca(arr, "texout");
    llvm::AllocaInst* dds = entryAlloca(arr, "texds");
    llvm::AllocaInst* ddt = entryAlloca(arr, "texdt");
    llvm::FunctionCallee fnc = module_.getOrInsertFunction(
        "rlf_texture", llvm::FunctionType::get(i32_, {ptr_, ptr_, f32_, f32_, f32_, f32_, f32_, f32_, ptr_, i32_, ptr_, ptr_, ptr_}, false));
    if (auto* fn = llvm::dyn_cast<llvm::Function>(fnc.getCallee())) fn->setDoesNotThrow();
    Value* services = services_ ? services_ : llvm::ConstantPointerNull::get(ptr_);
    Value* ok = b_.CreateCall(fnc, {services, args[0].c[0].v, s.v, t.v, dsdx, dtdx, dsdy, dtdy, opts, ci(n), out, dds, ddt});
    bool silent = false;  // "missingcolor" stands in for an unreadable file without an error (§6.7)
    for (size_t i = 0; i < e.operands.size(); ++i)
      silent |= e.operands[i]->kind == ExprKind::StringLiteral && e.operands[i]->text == "missingcolor" && i > 0;
    if (textureErrors_ && !silent) {
      Value* failed = b_.CreateZExt(b_.CreateICmpEQ(ok, ci(0)), i32_);
      b_.CreateStore(b_.CreateAdd(b_.CreateLoad(i32_, textureErrors_), failed), textureErrors_);
    }
    Val r;
    r.type = rt;
    for (int k = 0; k < n; ++k) {
      auto at = [&](llvm::AllocaInst* a) { return b_.CreateLoad(f32_, b_.CreateConstInBoundsGEP2_32(arr, a, 0, unsigned(k))); };
      Value* ds = at(dds);
      Value* dt = at(ddt);
      r.c[k] = {at(out), lAdd(lMul(s.du, ds), lMul(t.du, dt)), lAdd(lMul(s.dv, ds), lMul(t.dv, dt))};
    }
    return r;
  }

  // spline (§6.6): every basis reads 4 knots from step·segment with a 4×4 basis matrix in
  // row-vector form, value = [t³ t² t 1]·M·[k0 k1 k2 k3]. A literal basis folds to constants; a
  // run-time name selects a row of a constant table (unknown or unfit names: catmull-rom, counted).
  struct SplineBasis {
    const char* name;
    int step;
    float m[16];
    bool fits(int knots) const {
      return step == 3 ? (knots - 1) % 3 == 0 : step == 2 ? knots % 2 == 0 : true;  // sema checked >= 4
    }
  };
  static constexpr SplineBasis kSplineBases[] = {
      {"catmull-rom", 1, {-0.5f, 1.5f, -1.5f, 0.5f, 1, -2.5f, 2, -0.5f, -0.5f, 0, 0.5f, 0, 0, 1, 0, 0}},
      {"bspline", 1, {-1 / 6.f, 0.5f, -0.5f, 1 / 6.f, 0.5f, -1, 0.5f, 0, -0.5f, 0, 0.5f, 0, 1 / 6.f, 4 / 6.f, 1 / 6.f, 0}},
      {"bezier", 3, {-1, 3, -3, 1, 3, -6, 3, 0, -3, 3, 0, 0, 1, 0, 0, 0}},
      {"hermite", 2, {2, 1, -2, 1, -3, -2, 3, -1, 0, 1, 0, 0, 1, 0, 0, 0}},
      {"linear", 1, {0, 0, 0, 0, 0, 0, 0, 0, 0, -1, 1, 0, 0, 1, 0, 0}},
      {"constant", 1, {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0}},
  };
  static constexpr int kNumSplineBases = int(std::size(kSplineBases));

  // Index into kSplineBases of the basis named by the string `name` at run time.
  Value* splineBasisIndex(Value* name, int knots) {
    llvm::FunctionCallee strcmpFn =
        module_.getOrInsertFunction("strcmp", llvm::FunctionType::get(i32_, {ptr_, ptr_}, false));
    Value* index = ci(0);
    Value* usable = b_.getFalse();
    for (int k = 0; k < kNumSplineBases; ++k) {
      if (!kSplineBases[k].fits(knots)) continue;
      Value* match = b_.CreateICmpEQ(b_.CreateCall(strcmpFn, {name, b_.CreateGlobalStringPtr(kSplineBases[k].name, "basis")}), ci(0));
      index = b_.CreateSelect(match, ci(k), index);
      usable = b_.CreateOr(usable, match);
    }
    if (splineBasisProblems_) {
      Value* bad = b_.CreateZExt(b_.CreateNot(usable), i32_);
      b_.CreateStore(b_.CreateAdd(b_.CreateLoad(i32_, splineBasisProblems_), bad), splineBasisProblems_);
    }
    return index;
  }

  Val genSpline(const Expr& e, const std::vector<Val>& args) {
    size_t first = 0;
    const SplineBasis* basis = &kSplineBases[0];
    Value* dynamicIndex = nullptr;  // a run-time basis: its index into kSplineBases
    const Type kt = e.type;
    // Knots in an array slot (the argument's own, or a temporary for listed knots).
    const Slot* knots = nullptr;
    const size_t firstKnot = args[0].type.kind == TypeKind::String ? 2 : 1;
    if (args.size() == firstKnot + 1 && args[firstKnot].array) {
      knots = args[firstKnot].array;
    } else {
      temps_.push_back(std::make_unique<VarDecl>());
      temps_.back()->name = "spline.knots";
      temps_.back()->type = Type(kt.kind, int(args.size() - firstKnot));
      knots = &slotFor(temps_.back().get());
      for (size_t i = firstKnot; i < args.size(); ++i) storeElement(*knots, ci(int32_t(i - firstKnot)), convert(args[i], kt));
    }
    const int n = knots->type.arrayLength;
    // Knots from an unsized array parameter are counted only here, where the call is inlined
    // (the type checker saw no length): a count no basis can use is a run-time spline problem, as
    // a run-time basis that does not fit is. Fewer than 4 knots give the first one.
    auto countProblem = [&] {
      if (splineBasisProblems_)
        b_.CreateStore(b_.CreateAdd(b_.CreateLoad(i32_, splineBasisProblems_), ci(1)), splineBasisProblems_);
    };
    if (n < 4) {
      countProblem();
      return convert(loadElement(*knots, ci(0)), kt);
    }
    if (args[0].type.kind == TypeKind::String) {
      first = 1;
      if (e.operands[0]->kind == ExprKind::StringLiteral) {
        for (const SplineBasis& candidate : kSplineBases)
          if (e.operands[0]->text == candidate.name) basis = &candidate;
        if (!basis->fits(n)) {
          countProblem();
          basis = &kSplineBases[0];
        }
      } else {
        dynamicIndex = splineBasisIndex(args[0].c[0].v, n);
      }
    }
    // The basis matrix entry M[i][j], or null where a literal basis has a zero.
    auto coefficient = [&](int i, int j) -> Value* {
      if (!dynamicIndex) return basis->m[i * 4 + j] != 0 ? cf(basis->m[i * 4 + j]) : nullptr;
      Value* at = b_.CreateAdd(b_.CreateMul(dynamicIndex, ci(16)), ci(i * 4 + j));
      return b_.CreateLoad(f32_, b_.CreateInBoundsGEP(f32_, splineTable(), at));
    };
    // Spans: (n - 4) / step + 1, so the last one starts at knot n - 4 whatever the step.
    Value* step = ci(basis->step);
    Value* spans = ci((n - 4) / basis->step + 1);
    if (dynamicIndex) {
      for (int k = 0; k < kNumSplineBases; ++k)
        if (kSplineBases[k].step != basis->step)
          step = b_.CreateSelect(b_.CreateICmpEQ(dynamicIndex, ci(k)), ci(kSplineBases[k].step), step);
      spans = b_.CreateAdd(b_.CreateSDiv(ci(n - 4), step), ci(1));
    }
    Value* spansF = b_.CreateSIToFP(spans, f32_);
    Value* lastSpan = b_.CreateFSub(spansF, cf(1));
    const Dual x = dclamp01(toFloatScalar(args[first]).c[0]);
    const Dual xs = dmul(x, {spansF, nullptr, nullptr});
    Value* segF = intrinsic(llvm::Intrinsic::floor, {xs.v});
    segF = b_.CreateSelect(b_.CreateFCmpOGT(segF, lastSpan), lastSpan, segF);
    // A NaN position passes the clamps above; its span is the first (the value stays NaN, for
    // the host's non-finite handling) rather than an index from the conversion of NaN.
    segF = b_.CreateSelect(b_.CreateFCmpOGE(segF, cf(0)), segF, cf(0));
    const Dual t = dsub(xs, {segF, nullptr, nullptr});
    Value* base = b_.CreateMul(b_.CreateFPToSI(segF, i32_), step);
    const Dual t2 = dmul(t, t);
    const Dual powers[4] = {dmul(t2, t), t2, t, dconst(1)};
    // Weight of knot j: Σ_i t^(3-i) · M[i][j].
    Val r = zeroOf(kt);
    for (int j = 0; j < 4; ++j) {
      Dual w = dconst(0);
      for (int i = 0; i < 4; ++i)
        if (Value* m = coefficient(i, j)) w = dadd(w, dmul(powers[i], {m, nullptr, nullptr}));
      const Val k = convert(loadElement(*knots, b_.CreateAdd(base, ci(j))), kt);
      for (int c = 0; c < numComponents(kt); ++c) r.c[c] = dadd(r.c[c], dmul(w, k.c[c]));
    }
    return r;
  }
  // kSplineBases' matrices as one constant array of the module.
  llvm::GlobalVariable* splineTable() {
    if (llvm::GlobalVariable* g = module_.getGlobalVariable("rlf.spline.bases", true)) return g;
    std::vector<llvm::Constant*> values;
    for (const SplineBasis& basis : kSplineBases)
      for (float m : basis.m) values.push_back(llvm::ConstantFP::get(f32_, m));
    auto* type = llvm::ArrayType::get(f32_, values.size());
    return new llvm::GlobalVariable(module_, type, true, llvm::GlobalValue::PrivateLinkage,
                                    llvm::ConstantArray::get(type, values), "rlf.spline.bases");
  }

  // random(): a hash of the invocation's input P, u, v and the call's ordinal (§6.5).
  Val randomOf(Type rt) {
    if (!randomInputs_) {
      Val r;
      r.type = rt;
      for (int k = 0; k < numComponents(rt); ++k) r.c[k] = dconst(0.5f);  // no invocation (defaults)
      return r;
    }
    Value* ordinal = b_.CreateLoad(i32_, randomOrdinal_);
    b_.CreateStore(b_.CreateAdd(ordinal, ci(1)), randomOrdinal_);
    llvm::FunctionCallee fnc = module_.getOrInsertFunction(
        "rlf_random", llvm::FunctionType::get(f32_, {ptr_, i32_, i32_}, false));
    if (auto* fn = llvm::dyn_cast<llvm::Function>(fnc.getCallee())) {
      fn->setDoesNotThrow();
      fn->setWillReturn();
      fn->setMemoryEffects(llvm::MemoryEffects::argMemOnly(llvm::ModRefInfo::Ref));
    }
    Val r;
    r.type = rt;
    for (int k = 0; k < numComponents(rt); ++k)
      r.c[k] = {b_.CreateCall(fnc, {randomInputs_, ordinal, ci(k)}), nullptr, nullptr};
    return r;
  }

  // A comp/setcomp index: int, or a float truncated toward zero (§2.1).
  Value* intIndex(const Val& a) { return convert(a, Type(TypeKind::Int)).c[0].v; }

  Val genCall(const Expr& e) {
    if (e.function) return genUserCall(e);
    std::vector<Val> args;
    for (const ExprPtr& a : e.operands) args.push_back(gen(*a));
    const BuiltinId id = e.builtin->id;
    const Type rt = e.type;
    switch (e.builtin->shape) {
      case BuiltinShape::UnaryT: {
        if (id == BuiltinId::Log && args.size() == 2) {
          // log(x, base) = ln x / ln base (both safe: ln of x ≤ 0 is ln FLT_MIN).
          const Type t = bindT(args, false);
          const Dual lb = dlogSafe(toFloatScalar(args[1]).c[0], 1.0f);
          return map(t, convert(args[0], t), [&](Dual x) { return ddiv(dlogSafe(x, 1.0f), lb); });
        }
        if (id == BuiltinId::Atan && args.size() == 2) {
          const Type t = bindT(args, false);
          const Val y = convert(args[0], t), x = convert(args[1], t);
          return map2(t, y, x, [&](Dual a, Dual b) {
            // d atan2(y, x) = (x dy - y dx) / (x² + y²)
            Value* r = libcall("atan2f", {a.v, b.v});
            const Dual den = dadd(dmul(a, a), dmul(b, b));
            // a is y, b is x: x dy - y dx, with y and x held constant in the other product.
            const Dual num = dsub(dmul({b.v, nullptr, nullptr}, a), dmul({a.v, nullptr, nullptr}, b));
            Dual q = ddiv({cf(0), num.du, num.dv}, {den.v, nullptr, nullptr});
            return Dual{r, q.du, q.dv};
          });
        }
        if (rt.kind == TypeKind::Int) {  // abs, the one int form here
          Value* x = args[0].c[0].v;
          return makeInt(b_.CreateSelect(b_.CreateICmpSLT(x, ci(0)), b_.CreateSub(ci(0), x), x));
        }
        return map(rt, convert(args[0], rt), [&](Dual x) { return unaryMath(id, x); });
      }
      case BuiltinShape::BinaryT: {
        const Val a = convert(args[0], rt), b = convert(args[1], rt);
        return map2(rt, a, b, [&](Dual x, Dual y) -> Dual {
          if (id == BuiltinId::Step) return {b_.CreateSelect(b_.CreateFCmpOLT(y.v, x.v), cf(0), cf(1)), nullptr, nullptr};
          return modDual(x, y, id == BuiltinId::Fmod);
        });
      }
      case BuiltinShape::PowT: {
        const Val a = convert(args[0], rt);
        const Val b = args[1].type.isScalar() ? splat(rt, toFloatScalar(args[1]).c[0]) : convert(args[1], rt);
        return map2(rt, a, b, [&](Dual x, Dual y) { return dpowSafe(x, y); });
      }
      case BuiltinShape::MinMax: {
        Val r = convert(args[0], rt);
        for (size_t i = 1; i < args.size(); ++i) {
          const Val b = convert(args[i], rt);
          if (rt.kind == TypeKind::Int) {
            Value* less = b_.CreateICmpSLT(b.c[0].v, r.c[0].v);
            r.c[0].v = id == BuiltinId::Min ? b_.CreateSelect(less, b.c[0].v, r.c[0].v) : b_.CreateSelect(less, r.c[0].v, b.c[0].v);
          } else {
            r = map2(rt, r, b, [&](Dual x, Dual y) { return id == BuiltinId::Min ? dmin(x, y) : dmax(x, y); });
          }
        }
        return r;
      }
      case BuiltinShape::Clamp: {
        const Val x = convert(args[0], rt), lo = convert(args[1], rt), hi = convert(args[2], rt);
        if (rt.kind == TypeKind::Int) {
          Value* v = b_.CreateSelect(b_.CreateICmpSLT(x.c[0].v, lo.c[0].v), lo.c[0].v, x.c[0].v);
          return makeInt(b_.CreateSelect(b_.CreateICmpSGT(v, hi.c[0].v), hi.c[0].v, v));
        }
        Val r;
        r.type = rt;
        for (int k = 0; k < numComponents(rt); ++k) r.c[k] = dmin(dmax(x.c[k], lo.c[k]), hi.c[k]);
        return r;
      }
      case BuiltinShape::Mix: {
        const Val a = convert(args[0], rt), b = convert(args[1], rt);
        const Val x = args[2].type.isScalar() ? splat(rt, toFloatScalar(args[2]).c[0]) : convert(args[2], rt);
        Val r;
        r.type = rt;
        for (int k = 0; k < numComponents(rt); ++k)
          r.c[k] = dadd(dmul(a.c[k], dsub(dconst(1), x.c[k])), dmul(b.c[k], x.c[k]));
        return r;
      }
      case BuiltinShape::Smoothstep: {
        const Type t = rt;
        const Val e0 = convert(args[0], t), e1 = convert(args[1], t), x = convert(args[2], t);
        Val r;
        r.type = t;
        for (int k = 0; k < numComponents(t); ++k) {
          const Dual tt = dclamp01(ddiv(dsub(x.c[k], e0.c[k]), dsub(e1.c[k], e0.c[k])));
          const Dual s = dmul(dmul(tt, tt), dsub(dconst(3), dmul(dconst(2), tt)));
          // e0 >= e1 degenerates to step(e1, x).
          Value* degenerate = b_.CreateFCmpOGE(e0.c[k].v, e1.c[k].v);
          const Dual st{b_.CreateSelect(b_.CreateFCmpOLT(x.c[k].v, e1.c[k].v), cf(0), cf(1)), nullptr, nullptr};
          r.c[k] = dselect(degenerate, st, s);
        }
        return r;
      }
      case BuiltinShape::Dot: return makeFloat(dot3(args[0], args[1]));
      case BuiltinShape::Cross: return cross3(args[0], args[1]);
      case BuiltinShape::Length: return makeFloat(length3(args[0]));
      case BuiltinShape::Normalize: return normalize3(args[0]);
      case BuiltinShape::Comp:
        if (args[0].type.kind == TypeKind::Matrix)
          return makeFloat(matrixElementAt(args[0], intIndex(args[1]), intIndex(args[2])));
        return makeFloat(component(args[0], intIndex(args[1])));
      case BuiltinShape::Setcomp:
      case BuiltinShape::SetXyz: {
        const Expr& target = *e.operands[0];
        Val base = args[0];
        if (base.type.kind == TypeKind::Matrix) {
          setMatrixElement(base, intIndex(args[1]), intIndex(args[2]), toFloatScalar(args[3]).c[0]);
          assignTo(target, base);
          Val r;
          r.type = Type(TypeKind::Void);
          return r;
        }
        Value* index = e.builtin->shape == BuiltinShape::Setcomp ? intIndex(args[1])
                       : id == BuiltinId::Setxcomp              ? ci(0)
                       : id == BuiltinId::Setycomp              ? ci(1)
                                                                : ci(2);
        const Dual x = toFloatScalar(args.back()).c[0];
        for (int k = 0; k < 3; ++k) {
          Value* hit = k == 0   ? b_.CreateICmpSLE(index, ci(0))
                       : k == 1 ? b_.CreateICmpEQ(index, ci(1))
                                : b_.CreateICmpSGE(index, ci(2));
          base.c[k] = dselect(hit, x, base.c[k]);
        }
        assignTo(target, base);
        Val r;
        r.type = Type(TypeKind::Void);
        return r;
      }
      case BuiltinShape::DerivRatio: {
        // Du(n)/Du(d) + Dv(n)/Dv(d), each quotient 0 where its denominator is 0.
        Val num = args[0].type.isScalar() ? toFloatScalar(args[0]) : args[0];
        const Dual den = toFloatScalar(args[1]).c[0];
        Val r;
        r.type = rt;
        for (int k = 0; k < numComponents(rt); ++k) {
          const Dual qu = ddiv({num.c[k].du ? num.c[k].du : cf(0), nullptr, nullptr}, {den.du ? den.du : cf(0), nullptr, nullptr});
          const Dual qv = ddiv({num.c[k].dv ? num.c[k].dv : cf(0), nullptr, nullptr}, {den.dv ? den.dv : cf(0), nullptr, nullptr});
          r.c[k] = {b_.CreateFAdd(qu.v, qv.v), nullptr, nullptr};
        }
        return r;
      }
      case BuiltinShape::Random: return randomOf(rt);
      case BuiltinShape::PNoise: {
        // Split the arguments into the point (first half) and its periods (second half).
        const size_t half = args.size() / 2;
        std::vector<Dual> in;
        std::vector<Value*> periods;
        for (size_t i = 0; i < args.size(); ++i) {
          const Val a = args[i].type.isTriple() ? args[i] : toFloatScalar(args[i]);
          for (int k = 0; k < numComponents(a.type); ++k) {
            if (i < half)
              in.push_back(a.c[k]);
            else
              periods.push_back(a.c[k].v);
          }
        }
        Val r;
        r.type = rt;
        for (int k = 0; k < numComponents(rt); ++k) {
          Dual n = pnoiseCall(in, periods, k);
          if (id == BuiltinId::Psnoise) n = dsub(dmul(n, dconst(2)), dconst(1));
          r.c[k] = n;
        }
        return r;
      }
      case BuiltinShape::Spline: return genSpline(e, args);
      case BuiltinShape::StringFn:
        if (id == BuiltinId::Concat) {
          std::vector<Value*> parts;
          for (const Val& a : args) parts.push_back(a.c[0].v);
          llvm::AllocaInst* arr = entryAlloca(llvm::ArrayType::get(ptr_, parts.size()), "concat.parts");
          for (size_t i = 0; i < parts.size(); ++i)
            b_.CreateStore(parts[i], b_.CreateConstInBoundsGEP2_32(arr->getAllocatedType(), arr, 0, unsigned(i)));
          llvm::FunctionCallee fnc = module_.getOrInsertFunction("rlf_concat", llvm::FunctionType::get(ptr_, {ptr_, i32_}, false));
          if (auto* fn = llvm::dyn_cast<llvm::Function>(fnc.getCallee())) fn->setDoesNotThrow();
          usesStrings_ = true;
          Val r;
          r.type = Type(TypeKind::String);
          r.c[0].v = b_.CreateCall(fnc, {arr, ci(int32_t(parts.size()))});
          return r;
        }
        [[fallthrough]];
      case BuiltinShape::Printf: {
        // Arguments travel in three typed arrays plus a kind per argument (builtins_print.h).
        std::vector<Value*> floats, ints, strings, kinds;
        for (size_t i = 1; i < args.size(); ++i) {
          const Val& a = args[i];
          if (a.type.kind == TypeKind::Int) {
            ints.push_back(a.c[0].v);
            kinds.push_back(ci(0));
          } else if (a.type.kind == TypeKind::String) {
            strings.push_back(a.c[0].v);
            kinds.push_back(ci(3));
          } else {
            for (int k = 0; k < numComponents(a.type); ++k) floats.push_back(a.c[k].v);
            kinds.push_back(ci(a.type.isTriple() ? 2 : a.type.kind == TypeKind::Matrix ? 4 : 1));
          }
        }
        auto array = [&](llvm::Type* t, const std::vector<Value*>& values, const char* name) -> Value* {
          llvm::AllocaInst* a = entryAlloca(llvm::ArrayType::get(t, std::max<size_t>(values.size(), 1)), name);
          for (size_t i = 0; i < values.size(); ++i)
            b_.CreateStore(values[i], b_.CreateConstInBoundsGEP2_32(a->getAllocatedType(), a, 0, unsigned(i)));
          return a;
        };
        Value* kindArr = array(i32_, kinds, "printf.kinds");
        Value* floatArr = array(f32_, floats, "printf.floats");
        Value* intArr = array(i32_, ints, "printf.ints");
        Value* strArr = array(ptr_, strings, "printf.strings");
        if (e.builtin->shape == BuiltinShape::StringFn) {
          llvm::FunctionCallee fnc = module_.getOrInsertFunction(
              "rlf_format", llvm::FunctionType::get(ptr_, {ptr_, ptr_, i32_, ptr_, ptr_, ptr_}, false));
          if (auto* fn = llvm::dyn_cast<llvm::Function>(fnc.getCallee())) fn->setDoesNotThrow();
          usesStrings_ = true;
          Val r;
          r.type = Type(TypeKind::String);
          r.c[0].v = b_.CreateCall(fnc, {args[0].c[0].v, kindArr, ci(int32_t(kinds.size())), floatArr, intArr, strArr});
          return r;
        }
        llvm::FunctionCallee fnc = module_.getOrInsertFunction(
            "rlf_printf", llvm::FunctionType::get(llvm::Type::getVoidTy(ctx_), {ptr_, ptr_, ptr_, i32_, ptr_, ptr_, ptr_}, false));
        if (auto* fn = llvm::dyn_cast<llvm::Function>(fnc.getCallee())) fn->setDoesNotThrow();
        Value* services = services_ ? services_ : llvm::ConstantPointerNull::get(ptr_);
        b_.CreateCall(fnc, {services, args[0].c[0].v, kindArr, ci(int32_t(kinds.size())), floatArr, intArr, strArr});
        Val r;
        r.type = Type(TypeKind::Void);
        return r;
      }
      case BuiltinShape::Arraylength: return makeInt(ci(args[0].array ? args[0].array->type.arrayLength : 0));
      case BuiltinShape::Component:
        return makeFloat(args[0].c[id == BuiltinId::Xcomp ? 0 : id == BuiltinId::Ycomp ? 1 : 2]);
      case BuiltinShape::Deriv: {
        Val a = args[0].type.isScalar() ? toFloatScalar(args[0]) : args[0];
        return derivOf(a, id == BuiltinId::Du);
      }
      case BuiltinShape::CalcNormal: return calculateNormal(args[0]);
      case BuiltinShape::Noise:
        if (id == BuiltinId::Cellnoise) return cellnoiseOf(args, rt);
        return noiseOf(args, rt, id == BuiltinId::Snoise);
      case BuiltinShape::Transform: {
        const size_t n = args.size();
        Val p = args[n - 1];
        if (id == BuiltinId::Vtransform) p.type = Type(TypeKind::Vector);
        if (id == BuiltinId::Ntransform) p.type = Type(TypeKind::Normal);
        if (args[0].type.kind == TypeKind::Matrix) return transformByMatrix(p, args[0], transformKind(p));
        if (n == 3) p = toCurrentNamed(p, *e.operands[0], args[0].c[0].v);
        return fromCurrentNamed(p, *e.operands[n - 2], args[n - 2].c[0].v);
      }
      case BuiltinShape::Filterwidth: {
        const Val du = load(slotFor(globals_[size_t(GlobalId::du)]));
        const Val dv = load(slotFor(globals_[size_t(GlobalId::dv)]));
        Val a = args[0].type.isScalar() ? toFloatScalar(args[0]) : args[0];
        const Val gu = derivOf(a, true), gv = derivOf(a, false);
        Val r;
        r.type = rt;
        for (int k = 0; k < numComponents(rt); ++k)
          r.c[k] = {b_.CreateFAdd(intrinsic(llvm::Intrinsic::fabs, {b_.CreateFMul(gu.c[k].v, du.c[0].v)}),
                                  intrinsic(llvm::Intrinsic::fabs, {b_.CreateFMul(gv.c[k].v, dv.c[0].v)})),
                    nullptr, nullptr};
        return r;
      }
      case BuiltinShape::Filterstep: {
        // Box-filtered step: the fraction of [lo, hi] at or above the edge.
        const Dual edge = toFloatScalar(args[0]).c[0];
        const Dual x = toFloatScalar(args[1]).c[0];
        const size_t n = args.size();
        const bool hasX2 = n >= 3 && args[2].type.kind != TypeKind::String;
        // The last "width" given wins, as with any repeated name/value option.
        const Val* widthScale = nullptr;
        for (size_t i = hasX2 ? 3 : 2; i + 1 < n; i += 2)
          if (e.operands[i]->text == "width") widthScale = &args[i + 1];
        Dual lo, hi;
        if (hasX2) {
          // The interval between the two values, in either order (RSL's filterstep(e, s1, s2)
          // filters a quantity that may decrease across the pixel).
          const Dual x2 = toFloatScalar(args[2]).c[0];
          Value* ordered = b_.CreateFCmpOLE(x.v, x2.v);
          lo = dselect(ordered, x, x2);
          hi = dselect(ordered, x2, x);
        } else {
          const Val du = load(slotFor(globals_[size_t(GlobalId::du)]));
          const Val dv = load(slotFor(globals_[size_t(GlobalId::dv)]));
          Value* w = b_.CreateFAdd(intrinsic(llvm::Intrinsic::fabs, {b_.CreateFMul(x.du ? x.du : cf(0), du.c[0].v)}),
                                   intrinsic(llvm::Intrinsic::fabs, {b_.CreateFMul(x.dv ? x.dv : cf(0), dv.c[0].v)}));
          if (widthScale) w = b_.CreateFMul(w, toFloatScalar(*widthScale).c[0].v);
          const Dual half{b_.CreateFMul(w, cf(0.5f)), nullptr, nullptr};
          lo = dsub(x, half);
          hi = dadd(x, half);
        }
        const Dual width = dsub(hi, lo);
        const Dual frac = dclamp01(ddiv(dsub(hi, edge), width));
        const Dual hard{b_.CreateSelect(b_.CreateFCmpOLT(x.v, edge.v), cf(0), cf(1)), nullptr, nullptr};
        return makeFloat(dselect(b_.CreateFCmpOLE(width.v, cf(0)), hard, frac));
      }
      case BuiltinShape::Texture: return genTexture(e, args);
      case BuiltinShape::MatrixFn:
        if (id == BuiltinId::Determinant) return makeFloat(determinant(args[0]));
        return id == BuiltinId::Inverse ? inverse(args[0]) : transposed(args[0]);
      case BuiltinShape::Displace: {
        if (args.size() == 1 && args[0].type.isTriple()) {
          displaceBy(args[0]);
        } else {
          const Val n = normalize3(load(slotFor(globals_[size_t(GlobalId::N)])));
          Dual amp = toFloatScalar(args.back()).c[0];
          if (args.size() == 2) {
            // Amplitude in `space` units (§6.8): amp * length(ntransform(space, normalize(N))). A
            // normal transforms by the inverse transpose, so that length is current units per
            // space unit along N.
            Val nn = n;
            nn.type = Type(TypeKind::Normal);
            const Val ns = fromCurrentNamed(nn, *e.operands[0], args[0].c[0].v);
            amp = dmul(amp, dsqrtSafe(dot3(ns, ns)));
          }
          displaceBy(map(Type(TypeKind::Vector), n, [&](Dual x) { return dmul(x, amp); }));
        }
        Val r;
        r.type = Type(TypeKind::Void);
        return r;
      }
      case BuiltinShape::FloatPred: {
        Value* x = toFloatScalar(args[0]).c[0].v;
        Value* a = intrinsic(llvm::Intrinsic::fabs, {x});
        Value* r = id == BuiltinId::Isnan ? b_.CreateFCmpUNO(x, x)
                   : id == BuiltinId::Isinf ? b_.CreateFCmpOEQ(a, cf(INFINITY))
                                            : b_.CreateFCmpOLT(a, cf(INFINITY));
        return boolToInt(r);
      }
    }
    return zeroOf(Type(TypeKind::Float));
  }

  struct LoopTargets {
    llvm::BasicBlock* breakTarget;
    llvm::BasicBlock* continueTarget;
  };
  struct ReturnTarget {
    llvm::BasicBlock* block;
    const Slot* slot;  // null for void functions
    Type type;
  };
  std::vector<ReturnTarget> returns_;

  llvm::LLVMContext& ctx_;
  llvm::Module& module_;
  const ShaderDecl& shader_;
  llvm::IRBuilder<> b_;
  llvm::Type* f32_;
  llvm::Type* i32_;
  llvm::Type* i64_;
  llvm::Type* i8_;
  llvm::PointerType* ptr_;
  llvm::Function* fn_ = nullptr;
  std::map<const VarDecl*, uint32_t> paramOffsets_;
  std::map<const VarDecl*, Slot> slots_;
  // Parameters of the user function being inlined that its body never writes: their argument's
  // value, without storage (genUserCall).
  std::unordered_map<const VarDecl*, Val> boundValues_;
  std::vector<std::unique_ptr<VarDecl>> temps_;
  const VarDecl* globals_[size_t(GlobalId::Count)] = {};
  std::vector<LoopTargets> loops_;
  llvm::BasicBlock* exitBlock_ = nullptr;
  llvm::BasicBlock* abortBlock_ = nullptr;
  llvm::GlobalVariable* zeroCell_ = nullptr;
  llvm::AllocaInst* nonFinite_ = nullptr;
  llvm::AllocaInst* badNormals_ = nullptr;
  Value* regularFrame_ = nullptr;  // per point: the undisplaced dPdu ^ dPdv is not zero
  llvm::AllocaInst* loopLimitHits_ = nullptr;
  llvm::AllocaInst* loopCounter_ = nullptr;
  llvm::AllocaInst* gradient_ = nullptr;
  llvm::AllocaInst* cellInput_ = nullptr;
  llvm::AllocaInst* textureErrors_ = nullptr;  // entry function only
  llvm::AllocaInst* randomInputs_ = nullptr;   // input P, u, v of the invocation (entry only)
  llvm::AllocaInst* randomOrdinal_ = nullptr;
  llvm::AllocaInst* indexClamped_ = nullptr;  // entry only
  llvm::AllocaInst* unknownSpace_ = nullptr;  // entry only
  llvm::AllocaInst* splineBasisProblems_ = nullptr;  // entry only
  Value* services_ = nullptr;                  // batch->services (entry function only)
  Value* spaces_ = nullptr;
  std::map<const VarDecl*, uint32_t> boundFlagOffsets_;
  bool usesStrings_ = false;  // format()/concat() seen: the entry frees their strings per point
  uint32_t loopLimit_ = kLoopIterationLimit;
  Value* orientation_ = nullptr;
  LanePlan& lanes_;
  std::map<const llvm::AllocaInst*, uint32_t> laneIds_;
};

// Codegen passes per shader before the lane plan is taken as it stands: every pass after the first
// is sound (it stores no non-zero derivative into a missing lane, or it says so), and two or three
// reach the fixed point on real shaders.
constexpr int kLanePasses = 4;

}  // namespace

std::unique_ptr<llvm::Module> generateModule(const TranslationUnit& unit, llvm::LLVMContext& context,
                                             std::vector<ShaderLayout>& layouts, uint32_t loopLimit,
                                             bool pruneLanes) {
  auto module = std::make_unique<llvm::Module>(unit.fileName, context);
  for (const auto& shader : unit.shaders) {
    LanePlan lanes;
    for (int pass = 1;; ++pass) {
      // A pass that allocates every lane is final even if it dropped a derivative: no pass
      // could keep it.
      const bool everyLane = lanes.allocate.empty();
      lanes.count = 0;
      ShaderCodegen cg(*module, *shader, std::max<uint32_t>(loopLimit, 1), lanes);
      cg.setGlobals(unit);
      ShaderLayout layout = cg.generate();
      // live ⊆ allocate; equal means another pass would generate the same code.
      bool converged = true;
      for (uint32_t id = 0; id < lanes.count; ++id)
        converged = converged && lanes.isLive(id) == lanes.allocates(id);
      const bool done = lanes.dropped ? everyLane : converged || pass >= kLanePasses || !pruneLanes;
      if (done) {
        layouts.push_back(std::move(layout));
        break;
      }
      module->getFunction(layout.entrySymbol)->eraseFromParent();
      module->getFunction(layout.defaultsSymbol)->eraseFromParent();
      // A dropped derivative (not expected, but cheap to guard): every lane; that pass cannot drop.
      lanes.allocate.clear();
      if (!lanes.dropped) lanes.allocate.assign(lanes.count, 0);
      for (uint32_t id = 0; id < lanes.count && !lanes.dropped; ++id) lanes.allocate[id] = lanes.isLive(id);
      lanes.live.clear();
      lanes.dropped = false;
    }
  }
  // Strings and tables of discarded passes.
  for (auto it = module->global_begin(); it != module->global_end();) {
    llvm::GlobalVariable& g = *it++;
    if (g.hasPrivateLinkage() && g.use_empty()) g.eraseFromParent();
  }
  return module;
}

}  // namespace relief::compiler
