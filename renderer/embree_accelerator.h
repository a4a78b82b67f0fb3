// The Embree baseline behind makeEmbreeAccelerator (accel.h): the conventional way to ray-trace
// displacement maps, which the geometry cache is measured against (docs/paper-results.md). Every
// input triangle is subdivided and displaced up front with the same subdivideTriangle and settings
// the cache uses, and the whole displaced scene goes into one Embree BVH. Nothing is lazy and
// nothing is ever discarded, so its memory grows with the scene; that is the point of comparison.
//
// Hits carry the same fields as the grid accelerator's (mesh, input triangle, micro-triangle id,
// bary, st, unit Ng), so the integrator cannot tell them apart. What may differ: Embree's own
// triangle test is not bit-identical to intersect.h, and among hits at exactly equal t it picks
// any; images therefore agree within a tolerance (tests/renderer/embree_test.cpp), not bit for bit.
//
// Out of memory (an allocation failure, e.g. under `prlimit --as`) raises EmbreeOutOfMemory from
// the constructor, so the caller can report it and exit cleanly.
#pragma once

#include <stdexcept>
#include <string>

#include "renderer/accel.h"

namespace relief {

struct EmbreeOptions {
  bool compact = false;  // RTC_SCENE_FLAG_COMPACT: smaller BVH, slower traversal
  int threads = 0;       // tessellation and BVH-build threads; 0: all hardware threads
};

class EmbreeOutOfMemory : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// True when this build links Embree (RELIEF_HAVE_EMBREE); otherwise makeEmbreeAccelerator throws.
bool haveEmbree();

}  // namespace relief
