// A mutex that spins before it sleeps, for critical sections of a few dozen instructions taken
// very often by every thread: the side cache's lookups (a hash probe and a list splice).
// std::mutex (glibc) parks a waiter on a futex at once; with two filling threads, a hit then cost
// a pair of context switches, 32,757 per fill of the sphere against 15 on one thread
// (docs/performance.md). Spinning waits out a holder that is only a few hundred cycles from
// releasing; a holder that was descheduled is yielded to after a while instead of burned against.
#pragma once

#include <atomic>
#include <thread>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace relief {

class SpinMutex {
 public:
  void lock() {
    for (;;) {
      if (!locked_.exchange(true, std::memory_order_acquire)) return;
      // Waits on a plain load, so the cache line is shared until the holder writes it back.
      for (int spins = 0; locked_.load(std::memory_order_relaxed); ++spins) {
        if (spins < kSpinsBeforeYield)
          pause();
        else
          std::this_thread::yield();
      }
    }
  }
  bool try_lock() { return !locked_.load(std::memory_order_relaxed) && !locked_.exchange(true, std::memory_order_acquire); }
  void unlock() { locked_.store(false, std::memory_order_release); }

 private:
  // A few to some tens of microseconds of pause instructions (their latency varies by CPU):
  // far beyond a critical section's length, well short of a scheduler quantum.
  static constexpr int kSpinsBeforeYield = 1024;
  static void pause() {
#if defined(__x86_64__) || defined(__i386__)
    _mm_pause();
#endif
  }
  std::atomic<bool> locked_{false};
};

}  // namespace relief
