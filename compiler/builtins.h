// The built-in function library (language.md §6) as seen by the type checker and codegen: names,
// ids. (The runtime symbols generated code may call are runtime/symbols.h.) No LLVM here.
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

namespace relief::compiler {

// How arguments and result relate, for the type checker (T = float or triple bound to the first
// triple argument; S = spatial).
enum class BuiltinShape : uint8_t {
  UnaryT,      // T f(T)
  BinaryT,     // T f(T, T)
  PowT,        // T f(T, T) or T f(T, float)
  MinMax,      // T f(T, T, ...), int forms
  Clamp,       // T f(T, T, T), int form
  Mix,         // T f(T, T, T|float)
  Smoothstep,  // T f(T, T, T)
  Dot,         // float f(S, S) or (color, color)
  Cross,       // vector f(S, S)
  Length,      // float f(S)
  Normalize,   // S f(S)
  Component,   // float f(S)
  Deriv,       // float→float, S→vector, color→color
  CalcNormal,  // vector f(point)
  Noise,       // context-typed: (float[, float]) or (point[, float])
  Displace,    // void f(vector) | f(float) | f(string, float)
  MatrixFn,    // determinant: float f(matrix); transpose, inverse: matrix f(matrix)
  StringFn,    // concat: string f(string, ...); format: string f(string fmt, ...)
  FloatPred,   // int f(float)
  Transform,   // S f([string from,] string to, S p) or f(matrix, S p)
  Filterwidth, // float→float, S→vector
  Filterstep,  // float f(float e, float x[, float x2][, "width", float w])
  Texture,     // context-typed: (string file[, float s, float t][, "option", value ...])
  Comp,        // float f(triple, int) or f(matrix, int, int)
  Setcomp,     // void f(output triple, int, float) or f(output matrix, int, int, float)
  SetXyz,      // void f(output S, float)
  DerivRatio,  // Deriv: float f(float, float), vector f(S, float)
  Random,      // context-typed, no arguments
  Arraylength, // int f(T a[])
  PNoise,      // context-typed: (u, pu), (u, v, pu, pv), (p, pp), (p, t, pp, pt)
  Spline,      // T f([string basis,] float x, T k0, ..., kn) or f([basis,] x, T k[])
  Printf,      // void f(string format, ...)
};

enum class BuiltinId : uint8_t {
#define RELIEF_BUILTIN(Id, Name, Shape) Id,
#include "compiler/builtins.def"
};

struct BuiltinInfo {
  BuiltinId id;
  std::string_view name;
  BuiltinShape shape;
};

const BuiltinInfo* findBuiltin(std::string_view name);

}  // namespace relief::compiler
