#!/usr/bin/env bash
# pixel_error_curve: what accuracy costs in time on one walk (issue 25 item 5) — frontier-view's
# --pixel-error T against frame time, bytes read, resident memory and the image's error.
#
#   tests/bench/pixel_error_curve.sh --store S --path P --dir D [--build B] [--size WxH]
#       [--cache 512M] [--frame-ms 33] [--threads 2] [--errors "0 0.5 1 2 4 8"] [--label NAME]
#       [--repeats N] [--tsv F] [--json F] [--markdown F] [--commands F]
#       [--cold] [--reuse-exact] [--pair FRAME:OUT.png] [--supersampled DIR]
#
# 1. the exact reference: T = 0 with --sync-paging (every frame complete), PNGs and ids of
#    every frame (D/exact);
# 2. every T of --errors with --frame-ms (the pegged walk a user sees), PNGs and ids of every
#    frame (D/T<T>; with --repeats N > 1, N walks per T, D/T<T>.<k>, a row each: pegged walks
#    depend on timing, and the rows show how much);
# 3. tests/bench/frame_compare.py: per T, p50/p95 frame ms, MiB read, max resident MiB, mean PSNR
#    against the exact PNGs and id agreement (frames 2.. as the issue's targets say "from the
#    third frame on"; identical frames count as 99 dB), coverage of the exact geometry pixels,
#    the first frame with >= 99 % coverage and the walk time until it, the proxies' share of the
#    pixels and how many of their ids differ, and how far drawn silhouettes reach out of the
#    exact ones (pixels, to set against T, the bound the proxies are chosen by).
# --cold drops the OS page cache before every walk (root only: the first frames then read the
# store from disk, as a user's first walk does). --reuse-exact keeps D/exact when an earlier run
# left it complete (the exact frames do not depend on timing; at 1280x720 on 20 M triangles they
# take seconds each). --pair FRAME:OUT.png writes the T = 1 walk's frame FRAME beside the exact one.
# --supersampled DIR: the exact walk at twice the width and height (DIR/png, e.g. another run's
# exact/): frame_compare.py's PSNR against its 2x2 means (4 samples a pixel) too.
# The store's proxy error bounds by depth (frontier-store info, when built) go to D/store_info.txt.
# Markdown table to --markdown (default: stdout); rows appended to --tsv/--json. Every run
# starts the viewer afresh (the OS page cache is dropped only with --cold).
# Exit codes: 0 ok, 1 a run failed, 2 bad options.
set -euo pipefail

store=""
path=""
dir=""
build=build
size=320x240
cache=512M
frame_ms=33
threads=2
errors="0 0.5 1 2 4 8"
repeats=1
label=""
tsv=""
json=""
markdown=""
commands=""
cold=0
reuse_exact=0
supersampled=""
pair=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    --store) store="$2"; shift 2 ;;
    --path) path="$2"; shift 2 ;;
    --dir) dir="$2"; shift 2 ;;
    --build) build="$2"; shift 2 ;;
    --size) size="$2"; shift 2 ;;
    --cache) cache="$2"; shift 2 ;;
    --frame-ms) frame_ms="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --errors) errors="$2"; shift 2 ;;
    --repeats) repeats="$2"; shift 2 ;;
    --label) label="$2"; shift 2 ;;
    --tsv) tsv="$2"; shift 2 ;;
    --json) json="$2"; shift 2 ;;
    --markdown) markdown="$2"; shift 2 ;;
    --commands) commands="$2"; shift 2 ;;
    --cold) cold=1; shift ;;
    --reuse-exact) reuse_exact=1; shift ;;
    --pair) pair="$2"; shift 2 ;;
    --supersampled) supersampled="$2"; shift 2 ;;
    -h|--help) sed -n '2,30p' "$0"; exit 0 ;;
    *) echo "pixel_error_curve: unknown option $1" >&2; exit 2 ;;
  esac
done
[[ -n "$store" && -n "$path" && -n "$dir" ]] ||
  { echo "usage: tests/bench/pixel_error_curve.sh --store S --path P --dir D [options] (--help)" >&2; exit 2; }
[[ "$repeats" =~ ^[1-9][0-9]*$ ]] ||
  { echo "pixel_error_curve: --repeats $repeats: expected a count >= 1" >&2; exit 2; }
[[ -z "$pair" || "$pair" =~ ^[0-9]+:.+$ ]] ||
  { echo "pixel_error_curve: --pair $pair: expected FRAME:OUT.png" >&2; exit 2; }
[[ -f "$store" ]] || { echo "pixel_error_curve: --store $store: no such file" >&2; exit 2; }
[[ -f "$path" ]] || { echo "pixel_error_curve: --path $path: no such file" >&2; exit 2; }
view="$build/viewer/frontier-view"
[[ -x "$view" ]] ||
  { echo "pixel_error_curve: $view not built (cmake --build $build --target frontier-view)" >&2; exit 2; }
here="$(cd "$(dirname "$0")" && pwd)"
label="${label:-$(basename "$store" .frontier)}"
mkdir -p "$dir"

run() {
  [[ -z "$commands" ]] || echo "\$ $*" >> "$commands"
  "$@"
}

# One walk into D/NAME: report.jsonl, png/, ids/ (fresh, so no frame of an earlier run stays).
walk() {
  local name="$1"; shift
  rm -rf "${dir:?}/$name"
  mkdir -p "$dir/$name"
  if ((cold)); then
    sync
    { echo 3 > /proc/sys/vm/drop_caches; } 2> /dev/null ||
      echo "pixel_error_curve: --cold: cannot drop the OS page cache (not root): $name runs warm" >&2
  fi
  run "$view" "$store" --headless --path "$path" --size "$size" --threads "$threads" --cache "$cache" \
    --report "$dir/$name/report.jsonl" --png-dir "$dir/$name/png" --png-every 1 --ids-dir "$dir/$name/ids" "$@" \
    2> "$dir/$name/stderr.txt" > /dev/null ||
    {
      echo "pixel_error_curve: $label $name failed (see $dir/$name/stderr.txt)" >&2
      tail -n 5 "$dir/$name/stderr.txt" >&2
      exit 1
    }
}

store_tool="$build/preprocess/frontier-store"
if [[ -x "$store_tool" ]]; then
  "$store_tool" info "$store" > "$dir/store_info.txt" 2>&1 || true
fi

if ((reuse_exact)) && [[ -f "$dir/exact/report.jsonl" ]] && grep -q '"summary"' "$dir/exact/report.jsonl"; then
  echo "== $label: exact reference kept from an earlier run ($dir/exact)" >&2
else
  echo "== $label: exact reference (T = 0, --sync-paging)" >&2
  walk exact --pixel-error 0 --sync-paging
fi
runs=()
for t in $errors; do
  for ((k = 1; k <= repeats; ++k)); do
    name="T$t" row="$t"
    if ((repeats > 1)); then name="T$t.$k" row="$t #$k"; fi
    echo "== $label: T = $t, --frame-ms $frame_ms$( ((repeats > 1)) && echo ", run $k of $repeats")" >&2
    walk "$name" --pixel-error "$t" --frame-ms "$frame_ms"
    runs+=(--run "$row=$dir/$name")
  done
done

args=(--exact "$dir/exact" --label "$label" "${runs[@]}")
if [[ -n "$pair" ]]; then
  t1="1"; ((repeats > 1)) && t1="1 #1"
  [[ " $errors " == *" 1 "* ]] || { echo "pixel_error_curve: --pair needs T = 1 among --errors" >&2; exit 2; }
  args+=(--pair "$t1:$pair")
fi
[[ -z "$supersampled" ]] || args+=(--supersampled "$supersampled")
[[ -z "$tsv" ]] || args+=(--tsv "$tsv")
[[ -z "$json" ]] || args+=(--json "$json")
[[ -z "$markdown" ]] || args+=(--markdown "$markdown")
python3 "$here/frame_compare.py" "${args[@]}"
