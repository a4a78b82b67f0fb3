#!/usr/bin/env bash
# Installs the Debian 12 packages Relief builds with, if any is missing. Sourced by setup.sh and
# test.sh so both quick-start commands work on a fresh machine. Needs root (or sudo).
set -euo pipefail

RELIEF_PACKAGES=(
  cmake make g++ pkg-config
  llvm-19-dev libzstd-dev          # the shader JIT (libzstd-dev: LLVM's CMake targets reference it)
  libopenimageio-dev               # texture() lookups and image formats other than PNG/PNM (a plugin)
  zlib1g-dev                       # PNG output, written by Relief itself; .rib.gz scenes
  libglm-dev                       # vector math
  googletest libgtest-dev          # unit tests
  libbenchmark-dev                 # bench/
  libtinyobjloader-dev             # Geometry "objmesh": OBJ files read by a real OBJ parser
  libembree-dev                    # the `--accel embree` baseline of bench/paper (optional at build)
  ccache                           # lets several build trees of one checkout share objects
)

relief_install_deps() {
  local missing=()
  for p in "${RELIEF_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then return 0; fi
  echo "relief: installing ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}
