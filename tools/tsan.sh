#!/usr/bin/env bash
# ThreadSanitizer check of the threaded renderer code (geometry cache, grid accelerator, render
# loop): builds the renderer tests with -DRELIEF_TSAN=ON in build-tsan/ and runs the tests that use
# more than one thread. Exits non-zero on any data race report or test failure.
# Usage: bash tools/tsan.sh            RELIEF_JOBS=N for a parallel build (default 1)
#        TSAN_FILTER='Cache*' bash tools/tsan.sh   to choose the tests (a GoogleTest filter)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$root/build-tsan"
jobs="${RELIEF_JOBS:-1}"
filter="${TSAN_FILTER:-GeometryCache.*:RenderIntegrator.CropWindow*:CacheRefine.*:CacheSide.*:CacheMemo.*:CacheImage.BudgetCheck*:CacheThreads.*:RenderIntegrator.*Thread*:Accel*:RenderLoop.*:RenderFilter.ImageIsBitIdentical*:RenderFilter.SamplesAre*:FilmOutput.PngBands*}"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRELIEF_TSAN=ON \
  -DRELIEF_BUILD_BENCH=OFF >"$build.log" 2>&1 || { cat "$build.log"; exit 1; }
cmake --build "$build" -j"$jobs" --target renderer_tests >>"$build.log" 2>&1 ||
  { grep -E "error|Error" -A3 "$build.log" | head -80; exit 1; }
# halt_on_error: the first race fails the run; second_deadlock_stack for useful lock reports.
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 ${TSAN_OPTIONS:-}"
"$build/bin/renderer_tests" --gtest_filter="$filter"
echo "tsan.sh: no data races in: $filter"
