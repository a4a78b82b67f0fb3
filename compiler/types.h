// The types of the language (language.md §2) and the conversion/arithmetic rules between them.
// Used by the type checker and codegen; no LLVM here.
#pragma once

#include <cstdint>
#include <string>

namespace relief::compiler {

enum class TypeKind : uint8_t {
  Error,  // poison: an expression already diagnosed; never diagnosed again
  Void,
  Int,
  Float,
  Point,
  Vector,
  Normal,
  Color,
  Matrix,
  String,
};

struct Type {
  TypeKind kind = TypeKind::Error;
  int arrayLength = 0;  // 0: not an array; -1: unsized parameter

  Type() = default;
  constexpr Type(TypeKind k, int n = 0) : kind(k), arrayLength(n) {}

  bool isError() const { return kind == TypeKind::Error; }
  bool isArray() const { return arrayLength != 0; }
  bool isScalar() const { return !isArray() && (kind == TypeKind::Int || kind == TypeKind::Float); }
  bool isTriple() const {
    return !isArray() && (kind == TypeKind::Point || kind == TypeKind::Vector ||
                          kind == TypeKind::Normal || kind == TypeKind::Color);
  }
  bool isSpatial() const { return isTriple() && kind != TypeKind::Color; }
  bool isNumeric() const { return isScalar() || isTriple(); }
  Type element() const { return Type(kind); }
  int components() const { return isTriple() ? 3 : kind == TypeKind::Matrix ? 16 : 1; }

  friend bool operator==(const Type&, const Type&) = default;
};

std::string typeName(Type t);

enum class Conversion : uint8_t { None, Identity, Implicit, Narrowing };
// Whether a value of type `from` may be assigned/passed to `to` (§2.1).
Conversion conversion(Type from, Type to);

// Result type of `a + b` / `a - b` between spatial types (§4.1 table); also used by ?:.
TypeKind spatialSum(TypeKind a, TypeKind b, bool subtract);

}  // namespace relief::compiler
