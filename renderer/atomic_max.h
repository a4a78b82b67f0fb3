// Raising a maximum shared by several threads: the peaks and largest values the statistics report.
#pragma once

#include <atomic>

namespace relief {

// Raises `to` to `value` when that is larger. Relaxed: a statistic, which orders nothing else.
template <typename T>
void atomicMax(std::atomic<T>& to, T value) {
  T seen = to.load(std::memory_order_relaxed);
  while (value > seen && !to.compare_exchange_weak(seen, value, std::memory_order_relaxed)) {
  }
}

}  // namespace relief
