// Type names, implicit conversions and the spatial arithmetic table (language.md §2.1, §4.1).
#include "compiler/types.h"

namespace relief::compiler {

std::string typeName(Type t) {
  std::string base;
  switch (t.kind) {
    case TypeKind::Error: base = "<error>"; break;
    case TypeKind::Void: base = "void"; break;
    case TypeKind::Int: base = "int"; break;
    case TypeKind::Float: base = "float"; break;
    case TypeKind::Point: base = "point"; break;
    case TypeKind::Vector: base = "vector"; break;
    case TypeKind::Normal: base = "normal"; break;
    case TypeKind::Color: base = "color"; break;
    case TypeKind::Matrix: base = "matrix"; break;
    case TypeKind::String: base = "string"; break;
  }
  if (t.arrayLength > 0) return base + "[" + std::to_string(t.arrayLength) + "]";
  if (t.arrayLength < 0) return base + "[]";
  return base;
}

Conversion conversion(Type from, Type to) {
  if (from.isError() || to.isError()) return Conversion::Identity;
  if (from == to) return Conversion::Identity;
  if (from.isArray() || to.isArray()) {
    if (from.kind == to.kind && (to.arrayLength < 0 || to.arrayLength == from.arrayLength))
      return Conversion::Identity;
    return Conversion::None;
  }
  if (from.kind == TypeKind::Int && to.kind == TypeKind::Float) return Conversion::Implicit;
  if (from.kind == TypeKind::Float && to.kind == TypeKind::Int) return Conversion::Narrowing;
  if (from.isScalar() && (to.isTriple() || to.kind == TypeKind::Matrix)) return Conversion::Implicit;
  if (from.isSpatial() && to.isSpatial()) return Conversion::Implicit;
  return Conversion::None;
}

TypeKind spatialSum(TypeKind a, TypeKind b, bool subtract) {
  if (a == TypeKind::Point && b == TypeKind::Point) return subtract ? TypeKind::Vector : TypeKind::Point;
  if (a == TypeKind::Point || b == TypeKind::Point) return TypeKind::Point;
  if (a == TypeKind::Vector || b == TypeKind::Vector) return TypeKind::Vector;
  return TypeKind::Normal;
}

}  // namespace relief::compiler
