// The binary interface between JIT-compiled displacement shaders and the host (renderer, reliefc).
// C layout only: generated code reads and writes these structs directly, so any change here bumps
// kRlfAbiVersion. Depended on by compiler/ (to lay out and emit the entry) and by renderer/.
#pragma once

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

enum { kRlfAbiVersion = 2 };

// Three SoA component arrays of one batch. Any of x/y/z may be null only where a field says so.
typedef struct RlfFloat3Array {
  float* x;
  float* y;
  float* z;
} RlfFloat3Array;

// Transforms uniform over a batch (a batch never mixes primitives). Matrices are row-major with row
// vectors, as in the language (p' = p * M, translation in elements 12..14). "current" is world space.
typedef struct RlfSpaces {
  float currentFromObject[16];
  float objectFromCurrent[16];
  float currentFromShader[16];
  float shaderFromCurrent[16];
  float currentFromCamera[16];
  float cameraFromCurrent[16];
} RlfSpaces;

struct RlfHostServices;

// One batch of `count` shading points, structure of arrays. Inputs are the undisplaced local
// differential geometry; derivative seeds feed forward-mode differentiation in (u, v) (language.md
// 6.4). Output arrays may alias nothing else; the shader writes every element of Pout and Nout.
typedef struct RlfShadingBatch {
  uint32_t count;
  uint32_t reserved;

  RlfFloat3Array P;     // position, current space
  RlfFloat3Array N;     // unit shading normal
  RlfFloat3Array Ng;    // unit geometric normal of the undisplaced surface
  RlfFloat3Array dPdu;  // dP/du, not normalized
  RlfFloat3Array dPdv;
  const float* u;
  const float* v;
  const float* s;
  const float* t;
  const float* du;  // parametric spacing of the tessellation (> 0)
  const float* dv;

  // Derivative seeds. Each pointer may be null, meaning zero for the whole batch.
  const float* dsdu;
  const float* dsdv;
  const float* dtdu;
  const float* dtdv;
  RlfFloat3Array dNdu;  // x == null: zero (flat faces)
  RlfFloat3Array dNdv;

  const RlfSpaces* spaces;                 // never null
  const struct RlfHostServices* services;  // may be null: no textures, warnings dropped

  // Outputs.
  RlfFloat3Array Pout;
  RlfFloat3Array Nout;
} RlfShadingBatch;

// Runtime problems of one evaluate call, counted rather than thrown (nothing unwinds through JIT
// frames). The host reports each kind once per shader instance.
typedef struct RlfStatus {
  uint32_t nonFinite;     // points whose final P was NaN/Inf (left undisplaced)
  uint32_t loopLimit;     // invocations aborted by the loop-iteration guard
  uint32_t indexClamped;  // run-time array/component indices clamped into range
  uint32_t unknownSpace;  // non-literal coordinate-space names that resolved to identity
  uint32_t textureErrors; // texture lookups that failed (missing file, ...)
  uint32_t splineBasis;   // run-time spline basis names unknown or unfit for the knot count
                          // (the call used "catmull-rom")
  uint32_t badNormal;     // points with a finite P whose final N was NaN/Inf or zero (the input N
                          // is returned; hosts use the displaced surface's own normal)
  uint32_t reserved[1];
} RlfStatus;

// Callbacks the generated code may make into the host. All are noexcept and report failure by
// return value plus a default result.
typedef struct RlfHostServices {
  void* context;
  // Filtered lookup of `nchannels` channels starting at `firstchannel`; returns 0 on failure (out
  // then holds `fill`). Derivatives are the footprint of language.md 6.7.
  int (*texture)(void* context, const char* filename, float s, float t, float dsdx, float dtdx,
                 float dsdy, float dtdy, const void* options, int nchannels, float* out,
                 float* dsdu_out, float* dtdu_out);
  // A message from printf() in a shader; may be null.
  void (*print)(void* context, const char* text);
  // Where the host bound the shader ("scene.rib:12") and what it is ("displacement shader
  // 'bumps'), prefixed to runtime errors such as an unreadable texture; each may be null.
  const char* origin;
  const char* subject;
} RlfHostServices;

// The signature of every compiled shader entry point. `params` points at the instance's parameter
// block, laid out as the compiler's reflection says (ParamInfo in shader.h). The block is shared by
// all threads: generated code copies parameters into locals and never writes it.
typedef void (*RlfShaderEntry)(const RlfShadingBatch* batch, const void* params, RlfStatus* status);

#ifdef __cplusplus
}
#endif
