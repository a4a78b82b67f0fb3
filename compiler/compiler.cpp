// The compile pipeline: parse → type check → codegen → optimize → JIT → reflection (compiler.h).
// Each stage runs only if no error was recorded before it.
#include "compiler/compiler.h"

#include <pthread.h>

#include <algorithm>
#include <cstring>
#include <exception>
#include <sstream>

#include <llvm/IR/LLVMContext.h>
#include <llvm/IR/Module.h>

#include "compiler/codegen.h"
#include "compiler/jit.h"
#include "compiler/lexer.h"
#include "compiler/parser.h"
#include "compiler/prelude.h"
#include "compiler/preprocessor.h"
#include "compiler/typecheck.h"
#include "runtime/shader_object.h"

namespace relief::compiler {

namespace {

void compileBuffer(CompileResult& result, SourceManager::FileId file, const CompileOptions& options,
                   const CompileFlags& flags) {
  DiagnosticsEngine& diags = *result.diagnostics;
  const std::string stdlibDir = options.stdlibDir.empty() ? defaultStdlibDir() : options.stdlibDir;
  std::string stdlibError;
  bool stdlibBroken = false;
  result.prelude = loadPrelude(stdlibDir, &stdlibError, &stdlibBroken);
  if (!result.prelude) {
    // A stdlib that does not compile is our bug; a missing one, a setup problem like a missing file.
    if (stdlibBroken) {
      result.internalError = stdlibError;
    } else {
      result.ioError = true;
      diags.report(DiagId::ErrStdlib, SourceLoc{}).arg(stdlibError).inFile(result.sources->name(file));
    }
    return;
  }
  PreprocessorOptions ppOptions;
  ppOptions.includeDirs = options.includeDirs;
  ppOptions.defines = options.defines;
  ppOptions.builtinIncludeDir = stdlibDir;
  Preprocessor preprocessor(*result.sources, diags, ppOptions);
  std::vector<Token> tokens = preprocessor.run(file);
  if (preprocessor.stopped()) return;
  Parser parser(std::move(tokens), result.sources->name(file), diags);
  std::unique_ptr<TranslationUnit> unit = parser.parseTranslationUnit();
  typeCheck(*unit, diags, result.prelude.get());
  if (flags.onChecked) flags.onChecked(*unit);
  if (unit->shaders.empty() && !diags.hasErrors())
    diags.report(DiagId::ErrNoShader, SourceLoc{}).inFile(result.sources->name(file));
  if (diags.hasErrors()) {
    if (flags.keepAst) result.ast = std::move(unit);
    return;
  }

  auto context = std::make_unique<llvm::LLVMContext>();
  std::vector<ShaderLayout> layouts;
  std::unique_ptr<llvm::Module> module = generateModule(*unit, *context, layouts, options.loopIterationLimit,
                                                         !flags.everyDerivativeLane);
  if (flags.keepAst) result.ast = std::move(unit);
  if (!optimizeModule(*module, options.optLevel, &result.internalError)) return;
  if (flags.emitLlvm) result.llvmIr = moduleText(*module);
  if (flags.emitObject) {
    if (!emitObject(*module, &result.object, &result.internalError)) return;
    for (ShaderLayout& layout : layouts)
      result.layouts.push_back({layout.name, layout.entrySymbol, layout.defaultsSymbol, layout.params,
                                layout.blockSize, layout.ownNormal});
  }
  if (!flags.jit) return;

  std::unique_ptr<ShaderJit> jit = ShaderJit::create(&result.internalError);
  if (!jit) return;
  if (!jit->addModule(std::move(module), std::move(context), &result.internalError)) return;
  std::shared_ptr<ShaderJit> keepAlive(std::move(jit));
  for (ShaderLayout& layout : layouts) {
    void* entry = keepAlive->lookup(layout.entrySymbol, &result.internalError);
    void* defaults = keepAlive->lookup(layout.defaultsSymbol, &result.internalError);
    if (!entry || !defaults) return;
    runtime::reflectDefaults(layout.params, layout.blockSize, reinterpret_cast<void (*)(void*)>(defaults));
    result.shaders.push_back(std::make_shared<runtime::CompiledShader>(
        layout.name, reinterpret_cast<RlfShaderEntry>(entry), std::move(layout.params), layout.blockSize,
        keepAlive, layout.ownNormal));
  }
}

CompileResult makeResult(const CompileOptions& options, const CompileFlags& flags) {
  CompileResult r;
  r.sources = std::make_shared<SourceManager>();
  DiagnosticOptions dopts;
  dopts.warningsAsErrors = options.warningsAsErrors;
  dopts.noWarnings = options.noWarnings;
  dopts.errorLimit = flags.errorLimit;
  dopts.disabledWarnings = flags.disabledWarnings;
  dopts.errorWarnings = flags.errorWarnings;
  dopts.notErrorWarnings = flags.notErrorWarnings;
  r.diagnostics = std::make_unique<DiagnosticsEngine>(dopts);
  return r;
}

}  // namespace

std::shared_ptr<const runtime::CompiledShader> CompileResult::find(std::string_view name) const {
  for (const auto& s : shaders)
    if (s->name() == name) return s;
  return nullptr;
}

// The recursive passes (parser, checker, codegen) are bounded by the nesting limits, yet a legal
// 1024-deep expression can need more than a default 8 MiB stack in a sanitizer build. Compile on a
// thread with a stack of its own (reserved, committed only as used), whoever the caller is.
static void compileBufferWithLargeStack(CompileResult& result, SourceManager::FileId file, const CompileOptions& options,
                                        const CompileFlags& flags) {
  struct Job {
    CompileResult* result;
    SourceManager::FileId file;
    const CompileOptions* options;
    const CompileFlags* flags;
    std::exception_ptr error;
  } job{&result, file, &options, &flags, nullptr};
  auto run = [](void* p) -> void* {
    Job* j = static_cast<Job*>(p);
    try {
      compileBuffer(*j->result, j->file, *j->options, *j->flags);
    } catch (...) {
      j->error = std::current_exception();
    }
    return nullptr;
  };
  constexpr size_t kStackBytes = size_t(256) << 20;
  pthread_attr_t attr;
  pthread_t thread;
  bool started = pthread_attr_init(&attr) == 0;
  started = started && pthread_attr_setstacksize(&attr, kStackBytes) == 0 &&
            pthread_create(&thread, &attr, run, &job) == 0;
  pthread_attr_destroy(&attr);
  if (started)
    pthread_join(thread, nullptr);
  else
    run(&job);  // no thread to be had: compile here, with the caller's stack
  if (job.error) std::rethrow_exception(job.error);
}

// No exception leaves the compiler (bad_alloc, a filesystem error, a bug): the host, reliefc or a
// renderer, reports an internal error and goes on.
static void compileGuarded(CompileResult& result, SourceManager::FileId file, const CompileOptions& options,
                           const CompileFlags& flags) {
  try {
    compileBufferWithLargeStack(result, file, options, flags);
  } catch (const std::exception& e) {
    result.internalError = std::string("unexpected exception: ") + e.what();
  } catch (...) {
    result.internalError = "unexpected exception";
  }
}

CompileResult compileSource(std::string name, std::string text, const CompileOptions& options,
                            const CompileFlags& flags) {
  CompileResult r = makeResult(options, flags);
  r.diagnostics->setFileName(name);
  const auto file = r.sources->addBuffer(std::move(name), std::move(text));
  compileGuarded(r, file, options, flags);
  return r;
}

CompileResult compileFile(const std::string& path, const CompileOptions& options, const CompileFlags& flags) {
  CompileResult r = makeResult(options, flags);
  r.diagnostics->setFileName(path);
  SourceManager::FileId file = 0;
  std::string error;
  if (!r.sources->addFile(path, &file, &error)) {
    r.ioError = true;
    r.diagnostics->report(DiagId::ErrCannotOpen, SourceLoc{}).arg(error).inFile(path);
    return r;
  }
  compileGuarded(r, file, options, flags);
  return r;
}

std::string renderDiagnostics(const CompileResult& result, bool color) {
  std::ostringstream out;
  TextDiagnosticOptions opts;
  opts.color = color;
  renderAllText(out, *result.sources, *result.diagnostics, opts);
  const std::string summary = summaryLine(result.diagnostics->numShownWarnings(*result.sources), result.diagnostics->numShownErrors());
  if (!summary.empty()) out << summary << '\n';
  return out.str();
}

}  // namespace relief::compiler
