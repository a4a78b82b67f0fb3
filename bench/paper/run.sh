#!/usr/bin/env bash
# Reproduces the paper's experiments (Tables 1-2, Figure 3), the Embree baseline, the street-of-
# facades scaling test and the gallery, and writes docs/paper-results.md, docs/images/figure3.png
# and docs/images/gallery_*.png entirely from what it measures (plus the paper's own numbers).
#
# usage: bench/paper/run.sh [relief binary]      (default: build/bin/relief; build it first)
#   QUICK=1            fewer budgets and copies (a smoke run of a few minutes)
#   BUILD_NOTE="..."   a sentence about the binary, printed in the results header
#   CACHE_THREADS=1    threads for Tables 1-2 and Figure 3 (the paper's runs were single-threaded)
#   BASE_THREADS=2     threads for the Embree comparisons (both renderers alike)
#   MEM_CAP=4G         address-space cap (prlimit --as) for the scaling runs: "runs out" = exceeds it
#   COPIES="1 8 16 24"        framed-street sizes;  VIEW_COPIES="1 2 4"  down-the-street sizes
#   STREET_BUDGET=1000000     Relief's fixed cache budget on the streets
#   CACHE_TIMEOUT_S=240       per budgeted facade run;  STREET_TIMEOUT_S=300  per street run;  REPEAT=3 REPEAT_UNDER_S=30  best-of-N for short runs
# Needs GNU time (/usr/bin/time), prlimit (util-linux), python3 and gnuplot; gnuplot-nox is
# installed with apt-get when missing (as root). Takes about 15 minutes on 2 cores.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
relief="${1:-$root/build/bin/relief}"

[[ -x "$relief" ]] || { echo "run.sh: no relief binary at '$relief' (build target 'relief' first)" >&2; exit 1; }
[[ -x /usr/bin/time ]] || { echo "run.sh: GNU time (/usr/bin/time) is needed for wall time and peak RSS" >&2; exit 1; }
command -v prlimit >/dev/null || { echo "run.sh: prlimit (util-linux) is needed to cap memory" >&2; exit 1; }
if ! command -v gnuplot >/dev/null; then
  if [[ $(id -u) -eq 0 ]] && command -v apt-get >/dev/null; then
    echo "run.sh: installing gnuplot-nox for Figure 3" >&2
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q gnuplot-nox >/dev/null \
      || { apt-get update -q >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -q gnuplot-nox >/dev/null; }
  fi
  command -v gnuplot >/dev/null || { echo "run.sh: gnuplot is needed (apt-get install gnuplot-nox)" >&2; exit 1; }
fi

exec python3 "$here/experiments.py" --relief "$relief" --root "$root"
