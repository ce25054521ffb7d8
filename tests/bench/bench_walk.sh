#!/usr/bin/env bash
# bench_walk: the walkthrough benchmark of frontier-view (issue 5's targets), end to end.
#
#   tests/bench/bench_walk.sh [--triangles 100000000] [--cache 512M] [--frames 300] [--dir DIR]
#                             [--build BUILD_DIR] [--oracle-every 10]
#
# 1. generates a building (frontier-gen) and a walk path through it, and appends 45 copies of
#    the path's last camera (the camera stops for 1.5 s at 30 frames/s);
# 2. builds the store (frontier-build, Draco 16 bits) unless DIR already holds it;
# 3. walks the path headless at 640x480, 2 threads, --frame-ms 33, --cache CACHE (drops the OS
#    page cache first when run as root, so pages come from the disk);
# 4. walks every Nth frame again with --sync-paging --oracle for cells_touched / oracle_cells;
# 5. prints the targets against what was measured.
# Needs python3 for the summary. Everything lands in DIR (default bench-walk/).
set -euo pipefail

triangles=100000000
cache=512M
frames=300
dir=bench-walk
build=build
oracle_every=10
while [[ $# -gt 0 ]]; do
  case "$1" in
    --triangles) triangles="$2"; shift 2 ;;
    --cache) cache="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --dir) dir="$2"; shift 2 ;;
    --build) build="$2"; shift 2 ;;
    --oracle-every) oracle_every="$2"; shift 2 ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    *) echo "bench_walk: unknown option $1" >&2; exit 2 ;;
  esac
done

gen="$build/data_gen/frontier-gen"
fbuild="$build/preprocess/frontier-build"
view="$build/viewer/frontier-view"
for b in "$gen" "$fbuild" "$view"; do
  [[ -x "$b" ]] || { echo "bench_walk: $b not built (cmake --build $build)" >&2; exit 2; }
done
mkdir -p "$dir"
model="$dir/building.ply"
store="$dir/building.frontier"
path="$dir/walk.cam"

if [[ ! -f "$store" ]]; then
  echo "== generating a building of about $triangles triangles"
  /usr/bin/time -f "gen: %e s, peak RSS %M KiB" "$gen" building --triangles "$triangles" -o "$model" --quiet
  "$gen" path --model "$model" --sidecar "$dir/building.json" --kind walk --frames "$frames" -o "$dir/moving.cam"
  echo "== building the store"
  /usr/bin/time -f "build: %e s, peak RSS %M KiB" "$fbuild" "$model" -o "$store" --threads 2 --no-walkable --quiet
  rm -f "$model"  # keep the sidecar (the path needs it), drop the big PLY
fi
if [[ ! -f "$path" ]]; then
  { cat "$dir/moving.cam"; for _ in $(seq 45); do grep -v '^#' "$dir/moving.cam" | tail -n 1; done; } > "$path"
fi

drop_caches() {
  if [[ $(id -u) == 0 ]]; then sync; echo 3 > /proc/sys/vm/drop_caches 2>/dev/null || true; fi
}

echo "== walk: 640x480, 2 threads, --frame-ms 33, --cache $cache"
drop_caches
"$view" "$store" --headless --path "$path" --size 640x480 --threads 2 --frame-ms 33 --cache "$cache" \
  --report "$dir/frames.jsonl" --png-dir "$dir/png" --png-every 60

echo "== oracle: every ${oracle_every}th frame with --sync-paging --oracle"
grep -v '^#' "$path" | awk -v n="$oracle_every" 'NR % n == 1' > "$dir/oracle.cam"
"$view" "$store" --headless --path "$dir/oracle.cam" --size 640x480 --threads 2 --cache "$cache" \
  --sync-paging --oracle --report "$dir/oracle.jsonl"

python3 - "$dir" "$cache" "$frames" <<'EOF'
import json, sys
d, cache, moving = sys.argv[1], sys.argv[2], int(sys.argv[3])
def load(p):
    frames, summary = [], None
    for line in open(p):
        j = json.loads(line)
        if "summary" in j: summary = j["summary"]
        else: frames.append(j)
    return frames, summary
frames, s = load(f"{d}/frames.jsonl")
oracle, so = load(f"{d}/oracle.jsonl")
ms = sorted(f["frame_ms"] for f in frames)
p95 = ms[min(len(ms) - 1, int(0.95 * (len(ms) - 1) + 0.5))]
mov = frames[1:moving]  # the first frame starts cold
half = sum(1 for f in mov if f["samples"] >= f["pixels"] / 2)
stop_ms, complete = 0.0, False
for f in frames[moving:]:
    stop_ms += f["frame_ms"]
    if f["complete"]:
        complete = True
        break
budget = s["cache_budget"]
rss = s["peak_rss_mib"]
ratios = [f["touched_oracle_ratio"] for f in oracle if "touched_oracle_ratio" in f]
def row(name, target, value, ok):
    print(f"| {name} | {target} | {value} | {'met' if ok else 'NOT met'} |")
print()
print(f"| measure | target | measured | |")
print(f"|---|---|---|---|")
row("p95 frame ms (all frames)", "<= 40", f"{p95:.1f} (p50 {s['p50_frame_ms']:.1f})", p95 <= 40)
row("moving frames sampling >= half the pixels", "all", f"{half} of {len(mov)}", half == len(mov))
row("image complete after the camera stops", "<= 1000 ms", f"{stop_ms:.0f} ms" if complete else "never", complete and stop_ms <= 1000)
row("peak RSS", f"<= budget + 200 MiB = {budget/2**20 + 200:.0f} MiB", f"{rss:.0f} MiB", rss <= budget / 2**20 + 200)
if ratios:
    row("cells_touched / oracle_cells (max over sampled frames)", "<= 1.2", f"{max(ratios):.3f} (mean {sum(ratios)/len(ratios):.3f}, {len(ratios)} frames)", max(ratios) <= 1.2)
print()
print(f"bytes read per frame: mean {s['total_bytes_read']/len(frames)/1024:.1f} KiB, total {s['total_bytes_read']/2**20:.1f} MiB; mean samples {s['mean_samples']:.0f}")
over = [f["floor_ms"] for f in frames if f.get("floor_ms", 0) > 0]
low = min(f["samples"] / f["pixels"] for f in mov)
print(f"sample floor (--min-sampled 0.5): {len(over)} frames ran past the peg" +
      (f", by {min(over):.1f}-{max(over):.1f} ms" if over else "") + f"; fewest moving samples {low:.2f} of the pixels")
EOF
