#!/usr/bin/env bash
# Quick start 2 (and CI): install what is missing, build everything, run every test with ctest.
# Usage: bash tools/test.sh        RELIEF_SANITIZE=1 for the ASan+UBSan build (build-asan/).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$root/tools/deps.sh"
relief_install_deps

jobs="${RELIEF_JOBS:-$(nproc)}"
build="$root/build"
flags=(-DCMAKE_BUILD_TYPE=Release -DRELIEF_WERROR=ON)
if [ "${RELIEF_SANITIZE:-0}" = 1 ]; then
  build="$root/build-asan"
  flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DRELIEF_SANITIZE=ON)
fi
cmake -S "$root" -B "$build" "${flags[@]}" >"$build.log" 2>&1 || { cat "$build.log"; exit 1; }
cmake --build "$build" -j"$jobs" >>"$build.log" 2>&1 || { grep -E "error|Error" -A3 "$build.log" | head -80; exit 1; }
cd "$build"
ctest --output-on-failure -j"$jobs" --timeout 600
