// The tick clock of ticks.h: the time-stamp counter where it is invariant, steady_clock otherwise.
#include "renderer/ticks.h"

#include <chrono>

#if defined(__x86_64__)
#include <cpuid.h>
#include <x86intrin.h>
#endif

namespace relief {
namespace {

uint64_t steadyNanos() {
  return uint64_t(std::chrono::duration_cast<std::chrono::nanoseconds>(
                      std::chrono::steady_clock::now().time_since_epoch())
                      .count());
}

struct TickSource {
  bool tsc = false;
  uint64_t tick0 = 0, nanos0 = 0;
  TickSource() {
#if defined(__x86_64__)
    // The counter serves as a clock only where it is invariant (CPUID 0x80000007, EDX bit 8).
    unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
    tsc = __get_cpuid(0x80000007, &eax, &ebx, &ecx, &edx) && (edx >> 8 & 1);
    tick0 = tsc ? __rdtsc() : 0;
#endif
    nanos0 = steadyNanos();
  }
};

// Set up during static initialisation, before any render thread exists.
const TickSource source;

}  // namespace

uint64_t readTicks() {
#if defined(__x86_64__)
  if (source.tsc) return __rdtsc();
#endif
  return steadyNanos();
}

double nanosPerTick() {
  if (!source.tsc) return 1.0;
  const uint64_t nanos = steadyNanos() - source.nanos0;
  const uint64_t ticks = readTicks() - source.tick0;
  return ticks > 0 && nanos > 0 ? double(nanos) / double(ticks) : 0.0;
}

}  // namespace relief
