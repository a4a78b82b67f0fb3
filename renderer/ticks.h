// A cheap clock for timing many short calls (rays, shader batches). Where the CPU's time-stamp
// counter runs at a constant rate (x86-64 with an invariant TSC) it reads that; elsewhere it falls
// back to steady_clock nanoseconds. clock_gettime cost about 25 ns a call on this machine, which
// was 10% of subdividing small triangles and 5% of an intersection-bound render.
#pragma once

#include <cstdint>

namespace relief {

// Ticks since an arbitrary origin; only differences mean anything.
uint64_t readTicks();
// Nanoseconds per tick, calibrated against steady_clock over the process's life so far (so it is
// more accurate the later it is asked; read it when reporting, not at start-up).
double nanosPerTick();

}  // namespace relief
