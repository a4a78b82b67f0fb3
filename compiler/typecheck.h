// The type checker: resolves names, types every expression (language.md §2, §4, §6), checks
// statements, and reports semantic errors and warnings. Expressions in error get the poison type
// so one mistake yields one diagnostic. Annotates the AST in place for codegen.
#pragma once

#include "compiler/ast.h"
#include "compiler/diagnostics.h"

namespace relief::compiler {

struct Prelude;

// Returns false if any error was reported (then codegen must not run). Calls may resolve to the
// functions `prelude` makes visible (library functions, hidden by a user function of their name).
bool typeCheck(TranslationUnit& unit, DiagnosticsEngine& diags, const Prelude* prelude = nullptr);

}  // namespace relief::compiler
