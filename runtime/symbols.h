// The host functions compiled shader code may call, by name (symbols.cpp).
#pragma once

#include <span>
#include <string_view>

namespace relief::runtime {

struct RuntimeSymbol {
  const char* name;
  void* address;
};
std::span<const RuntimeSymbol> runtimeSymbols();
// The address of `name`, or null when shader code may not call it.
void* findRuntimeSymbol(std::string_view name);

}  // namespace relief::runtime
