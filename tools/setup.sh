#!/usr/bin/env bash
# Quick start 1: install what is missing, configure, build, and render the default example scene.
# Usage: bash tools/setup.sh [scene.rib]   (from anywhere; builds into <repo>/build)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$root/tools/deps.sh"
relief_install_deps

jobs="${RELIEF_JOBS:-$(nproc)}"
cmake -S "$root" -B "$root/build" -DCMAKE_BUILD_TYPE=Release >"$root/build.log" 2>&1 || { cat "$root/build.log"; exit 1; }
cmake --build "$root/build" -j"$jobs" --target relief reliefc >>"$root/build.log" 2>&1 || { tail -50 "$root/build.log"; exit 1; }

scene="${1:-$root/examples/scenes/sphere.rib}"
mkdir -p "$root/out"
image="$root/out/$(basename "${scene%.rib}").png"
"$root/build/bin/relief" "$scene" -o "$image" --stats
echo "relief: image written to $image"
