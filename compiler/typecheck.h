// The type checker: resolves names, types every expression (language.md §2, §4, §6), checks
// statements, and reports semantic errors and warnings. Expressions in error get the poison type
// so one mistake yields one diagnostic. Annotates the AST in place for codegen.
#pragma once

#include "compiler/ast.h"
#include "compiler/diagnostics.h"

namespace relief::compiler {

// Returns false if any error was reported (then codegen must not run).
bool typeCheck(TranslationUnit& unit, DiagnosticsEngine& diags);

}  // namespace relief::compiler
