// ORC LLJIT wrapper and the optimization pipeline (see jit.h).
#include "compiler/jit.h"

#include <mutex>

#include <llvm/ExecutionEngine/Orc/LLJIT.h>
#include <llvm/ExecutionEngine/Orc/ThreadSafeModule.h>
#include <llvm/ADT/DenseMap.h>
#include <llvm/ADT/DenseSet.h>
#include <llvm/IR/Instructions.h>
#include <llvm/IR/LLVMContext.h>
#include <llvm/IR/LegacyPassManager.h>
#include <llvm/IR/Module.h>
#include <llvm/IR/Verifier.h>
#include <llvm/Passes/PassBuilder.h>
#include <llvm/Transforms/InstCombine/InstCombine.h>
#include <llvm/Transforms/Scalar/ADCE.h>
#include <llvm/Transforms/Scalar/EarlyCSE.h>
#include <llvm/Transforms/Scalar/GVN.h>
#include <llvm/Transforms/Scalar/LICM.h>
#include <llvm/Transforms/Scalar/SROA.h>
#include <llvm/Transforms/Scalar/SimplifyCFG.h>
#include <llvm/Transforms/Scalar/LoopPassManager.h>
#include <llvm/Support/TargetSelect.h>
#include <llvm/Support/raw_ostream.h>
#include <llvm/Target/TargetMachine.h>
#include <llvm/Transforms/Utils/Cloning.h>

#include "runtime/symbols.h"

namespace relief::compiler {

namespace {
void initializeLlvm() {
  static std::once_flag once;
  std::call_once(once, [] {
    llvm::InitializeNativeTarget();
    llvm::InitializeNativeTargetAsmPrinter();
  });
}

std::string errorText(llvm::Error e) { return llvm::toString(std::move(e)); }

// Within each block, in program order, a load of a local variable takes the value last stored to
// it in that block. Inlined calls chain copies through variables (argument -> parameter ->
// local -> result -> caller); LLVM's promotion resolves such chains one variable at a time, each
// replacement moving every use gathered so far, which is quadratic in the chain (20,000 calls of a
// three-line function: 8 s to compile). In program order each load's value is already final, so
// each replacement moves only the load's own few uses. What is left for SROA is stores.
struct ForwardLocalStoresPass : llvm::PassInfoMixin<ForwardLocalStoresPass> {
  llvm::PreservedAnalyses run(llvm::Function& function, llvm::FunctionAnalysisManager&) {
    // Variables used only as the address of whole loads and stores of one type: nothing else
    // reads or writes them, so no call or store elsewhere can change them.
    llvm::DenseSet<const llvm::AllocaInst*> plain;
    for (llvm::Instruction& i : function.getEntryBlock()) {
      auto* alloca = llvm::dyn_cast<llvm::AllocaInst>(&i);
      if (!alloca || alloca->isArrayAllocation() || !alloca->getAllocatedType()->isSingleValueType()) continue;
      bool ok = true;
      for (const llvm::User* user : alloca->users()) {
        if (const auto* load = llvm::dyn_cast<llvm::LoadInst>(user))
          ok &= !load->isVolatile() && load->getType() == alloca->getAllocatedType();
        else if (const auto* store = llvm::dyn_cast<llvm::StoreInst>(user))
          ok &= !store->isVolatile() && store->getPointerOperand() == alloca &&
                store->getValueOperand()->getType() == alloca->getAllocatedType();
        else
          ok = false;
        if (!ok) break;
      }
      if (ok) plain.insert(alloca);
    }
    if (plain.empty()) return llvm::PreservedAnalyses::all();
    bool changed = false;
    llvm::DenseMap<const llvm::AllocaInst*, llvm::Value*> last;
    for (llvm::BasicBlock& block : function) {
      last.clear();
      for (llvm::Instruction& i : llvm::make_early_inc_range(block)) {
        if (auto* store = llvm::dyn_cast<llvm::StoreInst>(&i)) {
          if (auto* a = llvm::dyn_cast<llvm::AllocaInst>(store->getPointerOperand()); a && plain.contains(a))
            last[a] = store->getValueOperand();
        } else if (auto* load = llvm::dyn_cast<llvm::LoadInst>(&i)) {
          auto* a = llvm::dyn_cast<llvm::AllocaInst>(load->getPointerOperand());
          if (!a || !plain.contains(a)) continue;
          if (const auto known = last.find(a); known != last.end()) {
            load->replaceAllUsesWith(known->second);
            load->eraseFromParent();
            changed = true;
          } else {
            last[a] = load;  // later loads in the block read the same value
          }
        }
      }
    }
    if (!changed) return llvm::PreservedAnalyses::all();
    llvm::PreservedAnalyses kept;
    kept.preserveSet<llvm::CFGAnalyses>();
    return kept;
  }
};
}  // namespace

bool optimizeModule(llvm::Module& module, int optLevel, std::string* error) {
  initializeLlvm();
  auto jtmb = llvm::orc::JITTargetMachineBuilder::detectHost();
  if (!jtmb) {
    *error = errorText(jtmb.takeError());
    return false;
  }
  auto tm = jtmb->createTargetMachine();
  if (!tm) {
    *error = errorText(tm.takeError());
    return false;
  }
  module.setDataLayout((*tm)->createDataLayout());
  module.setTargetTriple((*tm)->getTargetTriple().str());

  std::string verifyMessage;
  llvm::raw_string_ostream vs(verifyMessage);
  if (llvm::verifyModule(module, &vs)) {
    *error = "generated invalid LLVM IR: " + vs.str();
    return false;
  }

  llvm::LoopAnalysisManager lam;
  llvm::FunctionAnalysisManager fam;
  llvm::CGSCCAnalysisManager cgam;
  llvm::ModuleAnalysisManager mam;
  llvm::PassBuilder pb(tm->get());
  pb.registerModuleAnalyses(mam);
  pb.registerCGSCCAnalyses(cgam);
  pb.registerFunctionAnalyses(fam);
  pb.registerLoopAnalyses(lam);
  pb.crossRegisterProxies(lam, fam, cgam, mam);
  const llvm::OptimizationLevel level = optLevel <= 0   ? llvm::OptimizationLevel::O0
                                        : optLevel == 1 ? llvm::OptimizationLevel::O1
                                        : optLevel == 2 ? llvm::OptimizationLevel::O2
                                                        : llvm::OptimizationLevel::O3;
  if (level == llvm::OptimizationLevel::O1 || level == llvm::OptimizationLevel::O2) {
    // A lean function pipeline: the generated code has no calls left to inline (user functions are
    // inlined by codegen), one loop over the batch and many allocas. These passes give the
    // throughput of the full -O2 pipeline at a fraction of its compile time; -O3 runs the full
    // pipeline (with vectorization) for the last few percent.
    llvm::FunctionPassManager fpm;
    // Every inlined call ends in a block of its own: SROA's promotion and InstCombine over
    // thousands of chained blocks are quadratic (2,048 calls: 5.8 s of 6.1 s in InstCombine;
    // 10,000 calls of a one-line function: 15 s, mostly SROA's dominance frontiers), over the
    // merged block linear. So the blocks are merged first.
    fpm.addPass(llvm::SimplifyCFGPass());
    fpm.addPass(ForwardLocalStoresPass());
    fpm.addPass(llvm::SROAPass(llvm::SROAOptions::ModifyCFG));
    fpm.addPass(llvm::SimplifyCFGPass());
    fpm.addPass(llvm::EarlyCSEPass(true));
    fpm.addPass(llvm::InstCombinePass());
    fpm.addPass(llvm::SimplifyCFGPass());
    if (level == llvm::OptimizationLevel::O2) {
      fpm.addPass(llvm::SROAPass(llvm::SROAOptions::ModifyCFG));
      fpm.addPass(llvm::createFunctionToLoopPassAdaptor(llvm::LICMPass(llvm::LICMOptions()), true));
      fpm.addPass(llvm::GVNPass());
      fpm.addPass(llvm::InstCombinePass());
    }
    fpm.addPass(llvm::ADCEPass());
    fpm.addPass(llvm::SimplifyCFGPass());
    llvm::ModulePassManager mpm;
    mpm.addPass(llvm::createModuleToFunctionPassAdaptor(std::move(fpm)));
    mpm.run(module, mam);
    return true;
  }
  llvm::ModulePassManager mpm = level == llvm::OptimizationLevel::O0
                                    ? pb.buildO0DefaultPipeline(level)
                                    : pb.buildPerModuleDefaultPipeline(level);
  mpm.run(module, mam);
  return true;
}

std::string moduleText(const llvm::Module& module) {
  std::string text;
  llvm::raw_string_ostream os(text);
  module.print(os, nullptr);
  return os.str();
}

bool emitObject(const llvm::Module& module, std::string* object, std::string* error) {
  initializeLlvm();
  auto jtmb = llvm::orc::JITTargetMachineBuilder::detectHost();
  if (!jtmb) {
    *error = errorText(jtmb.takeError());
    return false;
  }
  // As LLJIT sets up its target machine for x86-64 ELF.
  jtmb->setRelocationModel(llvm::Reloc::PIC_);
  jtmb->setCodeModel(llvm::CodeModel::Small);
  auto tm = jtmb->createTargetMachine();
  if (!tm) {
    *error = errorText(tm.takeError());
    return false;
  }
  llvm::SmallVector<char, 0> buffer;
  llvm::raw_svector_ostream os(buffer);
  llvm::legacy::PassManager pm;
  if ((*tm)->addPassesToEmitFile(pm, os, nullptr, llvm::CodeGenFileType::ObjectFile)) {
    *error = "the target cannot emit an object file";
    return false;
  }
  // Code generation rewrites the IR it is given (CodeGenPrepare and others); the module may still
  // go to the JIT.
  std::unique_ptr<llvm::Module> copy = llvm::CloneModule(module);
  pm.run(*copy);
  object->assign(buffer.data(), buffer.size());
  return true;
}

struct ShaderJit::Impl {
  std::unique_ptr<llvm::orc::LLJIT> jit;
};

ShaderJit::ShaderJit(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ShaderJit::~ShaderJit() = default;

std::unique_ptr<ShaderJit> ShaderJit::create(std::string* error) {
  initializeLlvm();
  auto jtmb = llvm::orc::JITTargetMachineBuilder::detectHost();
  if (!jtmb) {
    *error = errorText(jtmb.takeError());
    return nullptr;
  }
  // No process symbols and no platform runtime: generated code may call only what we register.
  auto jit = llvm::orc::LLJITBuilder()
                 .setJITTargetMachineBuilder(std::move(*jtmb))
                 .setLinkProcessSymbolsByDefault(false)
                 .setPlatformSetUp(llvm::orc::setUpInactivePlatform)
                 .create();
  if (!jit) {
    *error = errorText(jit.takeError());
    return nullptr;
  }
  llvm::orc::SymbolMap symbols;
  for (const runtime::RuntimeSymbol& s : runtime::runtimeSymbols())
    symbols[(*jit)->mangleAndIntern(s.name)] = {llvm::orc::ExecutorAddr::fromPtr(s.address),
                                                llvm::JITSymbolFlags::Exported | llvm::JITSymbolFlags::Callable};
  if (llvm::Error e = (*jit)->getMainJITDylib().define(llvm::orc::absoluteSymbols(std::move(symbols)))) {
    *error = errorText(std::move(e));
    return nullptr;
  }
  auto impl = std::make_unique<Impl>();
  impl->jit = std::move(*jit);
  return std::unique_ptr<ShaderJit>(new ShaderJit(std::move(impl)));
}

bool ShaderJit::addModule(std::unique_ptr<llvm::Module> module, std::unique_ptr<llvm::LLVMContext> context,
                          std::string* error) {
  if (llvm::Error e = impl_->jit->addIRModule(llvm::orc::ThreadSafeModule(std::move(module), std::move(context)))) {
    *error = errorText(std::move(e));
    return false;
  }
  return true;
}

void* ShaderJit::lookup(const std::string& name, std::string* error) {
  auto addr = impl_->jit->lookup(name);
  if (!addr) {
    *error = errorText(addr.takeError());
    return nullptr;
  }
  return addr->toPtr<void*>();
}

}  // namespace relief::compiler
