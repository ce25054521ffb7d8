#!/usr/bin/env bash
# lod_sizes: REPORT.md section 9 at the sizes users run (issue 41's targets): pegged walks at
# --pixel-error T against their exact frames, on stores made beforehand, at 640x360 and 1280x720.
#
#   tests/bench/lod_sizes.sh OUT_DIR --walk LABEL=STORE:PATH [--walk ...] [--build B]
#       [--sizes "640x360 1280x720"] [--errors "0.5 1 2 4"] [--frames N] [--pair-frame 10]
#       [--cache 512M] [--frame-ms 33] [--threads 2]
#
# For every walk and size, tests/bench/pixel_error_curve.sh with --cold (the OS page cache
# dropped before each walk: a user's first walk reads the store from disk) and --reuse-exact
# (the exact frames, T = 0 with --sync-paging, are made once and kept in OUT_DIR/LABEL_SIZE/exact:
# they take seconds each at 1280x720 on tens of millions of triangles). Writes
#   OUT_DIR/lod_sizes.md          a table per walk and size (frame_compare.py's columns)
#   OUT_DIR/lod_sizes.jsonl       one line per run (walk, size, T, the figures)
#   OUT_DIR/plots/LABEL_SIZE_frame10.png   the T = 1 walk's frame beside the exact one
#   OUT_DIR/plots/lod_t_curve.png          mean PSNR, the worst frame's sampled share of geometry
#                                          pixels and the median frame time against T (gnuplot,
#                                          Debian's gnuplot-nox, when installed)
# Sizes run largest first: a size whose double is among them (640x360 and 1280x720) is also
# compared against that size's exact frames, 2x2 averaged (frame_compare.py --supersampled: four
# samples a pixel, the model as it looks rather than one aliased sample of it).
# The stores and paths are made by the commands REPORT.md section 9 lists (a 100 M-triangle
# store takes most of an hour to build). Exit codes: 0 ok, 1 a walk failed, 2 bad options.
set -euo pipefail

out=""
build=build
sizes="640x360 1280x720"
errors="0.5 1 2 4"
frames=""
pair_frame=10
cache=512M
frame_ms=33
threads=2
walks=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --walk) walks+=("$2"); shift 2 ;;
    --build) build="$2"; shift 2 ;;
    --sizes) sizes="$2"; shift 2 ;;
    --errors) errors="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --pair-frame) pair_frame="$2"; shift 2 ;;
    --cache) cache="$2"; shift 2 ;;
    --frame-ms) frame_ms="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    -h|--help) sed -n '2,23p' "$0"; exit 0 ;;
    -*) echo "lod_sizes: unknown option $1" >&2; exit 2 ;;
    *) [[ -z "$out" ]] || { echo "lod_sizes: one OUT_DIR, got $out and $1" >&2; exit 2; }; out="$1"; shift ;;
  esac
done
[[ -n "$out" && ${#walks[@]} -gt 0 ]] ||
  { echo "usage: tests/bench/lod_sizes.sh OUT_DIR --walk LABEL=STORE:PATH [...] (--help)" >&2; exit 2; }
[[ " $errors " == *" 1 "* ]] || { echo "lod_sizes: --errors must include 1 (the paired frames are T = 1's)" >&2; exit 2; }
[[ -z "$frames" || "$frames" =~ ^[1-9][0-9]*$ ]] || { echo "lod_sizes: --frames $frames: expected a count" >&2; exit 2; }
for w in "${walks[@]}"; do
  [[ "$w" =~ ^[A-Za-z0-9_.-]+=[^:]+:.+$ ]] ||
    { echo "lod_sizes: --walk $w: expected LABEL=STORE:PATH" >&2; exit 2; }
  s="${w#*=}"; s="${s%%:*}"; p="${w#*:}"
  [[ -f "$s" ]] || { echo "lod_sizes: --walk $w: no store $s" >&2; exit 2; }
  [[ -f "$p" ]] || { echo "lod_sizes: --walk $w: no camera path $p" >&2; exit 2; }
done
here="$(cd "$(dirname "$0")" && pwd)"
mkdir -p "$out/plots"
md="$out/lod_sizes.md"
jsonl="$out/lod_sizes.jsonl"
: > "$md"
: > "$jsonl"
{
  echo "Measured $(date -u +%Y-%m-%d\ %H:%M) UTC at $(git -C "$here" rev-parse --short HEAD 2>/dev/null || echo unknown)"
  echo "on $(lscpu | sed -n 's/^Model name: *//p' | head -n 1), $(nproc) cores; \`--frame-ms $frame_ms --cache $cache"
  echo "--threads $threads\`, T in {$errors} against the exact frames (\`--sync-paging --pixel-error 0\`), the OS"
  echo "page cache dropped before every walk."
  echo
} >> "$md"
sizes="$(for z in $sizes; do echo "$z"; done | awk -Fx '{ print $1 * $2, $0 }' | sort -rn | cut -d' ' -f2 | tr '\n' ' ')"
for w in "${walks[@]}"; do
  label="${w%%=*}"; rest="${w#*=}"; store="${rest%%:*}"; path="${rest#*:}"
  for size in $sizes; do
    double="$((2 * ${size%x*}))x$((2 * ${size#*x}))"
    ss=()
    [[ " $sizes " == *" $double "* ]] && ss=(--supersampled "$out/${label}_$double/exact")
    dir="$out/${label}_$size"
    cam="$path"
    if [[ -n "$frames" ]]; then  # the first N frames of the path
      cam="$out/${label}.$frames.cam"
      awk -v n="$frames" '/^#/ || /^[[:space:]]*$/ { print; next } { if (k++ < n) print }' "$path" > "$cam"
    fi
    echo "== lod_sizes: $label at $size" >&2
    tests=("$here/pixel_error_curve.sh" --store "$store" --path "$cam" --dir "$dir" --build "$build" --size "$size"
           --cache "$cache" --frame-ms "$frame_ms" --threads "$threads" --errors "$errors" --label "${label}_$size"
           --cold --reuse-exact --pair "$pair_frame:$out/plots/${label}_${size}_frame$pair_frame.png"
           --markdown "$dir.md" --json "$dir.jsonl" --commands "$out/commands.txt" "${ss[@]}")
    rm -f "$dir.jsonl"
    "${tests[@]}" || { echo "lod_sizes: $label at $size failed" >&2; exit 1; }
    python3 - "$dir.jsonl" "$label" "$size" >> "$jsonl" <<'EOF'
import json, sys
for line in open(sys.argv[1]):
    r = json.loads(line)
    r["walk"], r["size"] = sys.argv[2], sys.argv[3]
    print(json.dumps(r))
EOF
    {
      echo "### $label, $size ($(grep -c -v '^#' "$cam") frames, load $(cut -d' ' -f1-3 /proc/loadavg))"
      echo
      grep -E "^(primitives|proxies) " "$dir/store_info.txt" 2>/dev/null | sed 's/^/    /' || true
      echo
      cat "$dir.md"
      echo
    } >> "$md"
  done
done
if command -v gnuplot > /dev/null; then
  python3 - "$jsonl" "$out/plots/lod_t_curve.dat" <<'EOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
with open(sys.argv[2], "w") as f:
    for key in sorted({(r["walk"], r["size"]) for r in rows}):
        f.write(f'"{key[0]} {key[1]}"\n')
        for r in rows:
            if (r["walk"], r["size"]) == key and not r["pixel_error"].startswith("exact"):
                f.write(f'{r["pixel_error"]} {r["mean_psnr_db"]:.2f} {r["min_coverage"]:.4f} {r["p50_frame_ms"]:.1f}\n')
        f.write("\n\n")
EOF
  n=$(grep -c '^"' "$out/plots/lod_t_curve.dat")
  gnuplot <<EOF
set terminal pngcairo size 1800,520 font ",10"
set termoption noenhanced
set output "$out/plots/lod_t_curve.png"
set multiplot layout 1,3
set logscale x 2
set xlabel "--pixel-error T (pixels)"
set key bottom right
set grid
set title "mean PSNR against the exact frames (frames 2..)"
set ylabel "dB"
plot for [i=0:$((n - 1))] "$out/plots/lod_t_curve.dat" index i using 1:2 with linespoints title columnheader(1)
set title "worst frame: share of the exact geometry pixels sampled"
set ylabel "share"
set yrange [0:1]
plot for [i=0:$((n - 1))] "$out/plots/lod_t_curve.dat" index i using 1:3 with linespoints title columnheader(1)
set title "median frame time (pegged at $frame_ms ms)"
set ylabel "ms"
set yrange [0:*]
set key top right
plot for [i=0:$((n - 1))] "$out/plots/lod_t_curve.dat" index i using 1:4 with linespoints title columnheader(1)
unset multiplot
EOF
fi
echo "lod_sizes: $md" >&2
