#!/usr/bin/env bash
# Geometry-cache sweep: renders a scene with the cache unlimited and with budgets of 10% and 20% of
# the unlimited run's unique displaced triangles, per pixel order and thread count, and prints a
# markdown table (render time, peak RSS, hit rate, capacity misses, time ratio vs unlimited).
#
# usage: bench/render_cache.sh [scene.rib] [relief binary]
#   ORDERS="hilbert bucket scanline"  THREADS="1 2"  BUDGETS="10 20"  (environment, to run subsets)
#   RES=720x480  SPP=1  EXTRA="--no-refine"  (extra relief options)
# Reads relief --stats-json (docs/statistics.md); peak RSS is memory.peak_rss_bytes.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
scene="${1:-$here/../examples/scenes/facade.rib}"
relief="${2:-$here/../build-bench/bin/relief}"
orders="${ORDERS:-hilbert bucket scanline}"
threads_list="${THREADS:-1 2}"
budgets="${BUDGETS:-10 20}"
res="${RES:-720x480}"
spp="${SPP:-1}"

[[ -x "$relief" ]] || { echo "render_cache.sh: no relief binary at '$relief'" >&2; exit 1; }
[[ -f "$scene" ]] || { echo "render_cache.sh: no scene at '$scene'" >&2; exit 1; }
command -v python3 >/dev/null || { echo "render_cache.sh: python3 is needed to read the JSON" >&2; exit 1; }

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# run ORDER THREADS BUDGET -> sets: r_time r_rss r_hits r_cap r_unique r_peak r_cachemib
run() {
  local order="$1" threads="$2" budget="$3" log="$tmp/run.log" json="$tmp/stats.json"
  if ! "$relief" "$scene" --quiet --stats-json "$json" -o "$tmp/out.png" --resolution "$res" \
      --spp "$spp" --order "$order" --threads "$threads" --cache-triangles "$budget" \
      ${EXTRA:-} >"$log" 2>&1; then
    echo "render_cache.sh: relief failed (order $order, threads $threads, budget $budget):" >&2
    cat "$log" >&2
    exit 1
  fi
  read -r r_time r_rss r_hits r_cap r_unique r_peak r_cachemib < <(python3 - "$json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
print(s["time.render_s"], s["memory.peak_rss_bytes"] // 1024, "%.2f" % s["cache.hit_percent"],
      s["cache.capacity_misses"], s["cache.unique_displaced_triangles"],
      s["cache.peak_resident_triangles"], "%.1f" % (s["cache.peak_resident_bytes"] / 2**20))
PY
)
}

# The budgets are fractions of what an unlimited render creates once (2 threads, hilbert).
run hilbert 2 unlimited
unique="$r_unique"
echo "scene: $scene ($res, $spp spp); unlimited run: $unique unique displaced triangles"
echo
echo "| order | threads | cache budget (triangles) | render s | peak RSS MiB | cache peak MiB | hit % | capacity misses | peak resident tris | time / unlimited |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for threads in $threads_list; do
  for order in $orders; do
    run "$order" "$threads" unlimited
    base="$r_time"
    printf '| %s | %s | unlimited | %.2f | %.0f | %s | %s | %s | %s | 1.00 |\n' "$order" "$threads" \
      "$r_time" "$(echo "$r_rss / 1024" | bc -l)" "$r_cachemib" "$r_hits" "$r_cap" "$r_peak"
    for pct in $budgets; do
      budget=$(( unique * pct / 100 ))
      run "$order" "$threads" "$budget"
      printf '| %s | %s | %s%% = %s | %.2f | %.0f | %s | %s | %s | %s | %.2f |\n' "$order" "$threads" \
        "$pct" "$budget" "$r_time" "$(echo "$r_rss / 1024" | bc -l)" "$r_cachemib" "$r_hits" "$r_cap" "$r_peak" \
        "$(echo "$r_time / $base" | bc -l)"
    done
  done
done
