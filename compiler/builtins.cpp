// The built-in function table.
#include "compiler/builtins.h"

#include <unordered_map>

namespace relief::compiler {

namespace {
constexpr BuiltinInfo kBuiltins[] = {
#define RELIEF_BUILTIN(Id, Name, Shape) {BuiltinId::Id, Name, BuiltinShape::Shape},
#include "compiler/builtins.def"
};
}  // namespace

const BuiltinInfo* findBuiltin(std::string_view name) {
  static const std::unordered_map<std::string_view, const BuiltinInfo*> table = [] {
    std::unordered_map<std::string_view, const BuiltinInfo*> t;
    for (const BuiltinInfo& b : kBuiltins) t.emplace(b.name, &b);
    return t;
  }();
  auto it = table.find(name);
  return it == table.end() ? nullptr : it->second;
}

}  // namespace relief::compiler
