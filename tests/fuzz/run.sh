#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan) and runs each for SECONDS (default
# 60), seeded with the SPD scenes and small generated files (the cell page target writes valid
# pages of both codecs into its corpus itself, FRONTIER_FUZZ_SEEDS; the BSP target decodes any
# bytes into a polygon soup of coplanar stacks, near-coplanar fans and slivers). Findings land in
# build-fuzz/findings/. Usage: tests/fuzz/run.sh [SECONDS]
set -euo pipefail
seconds=${1:-60}
root=$(cd "$(dirname "$0")/../.." && pwd)
build="$root/build-fuzz"
CC=clang CXX=clang++ cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DFRONTIER_FUZZ=ON -DFRONTIER_BUILD_TESTS=OFF > /dev/null
cmake --build "$build" --target fuzz_nff fuzz_ply fuzz_obj fuzz_off fuzz_stl fuzz_cell_page fuzz_bsp
mkdir -p "$build/findings"
for format in nff ply obj off stl cell_page bsp; do
  corpus="$build/corpus/$format"
  mkdir -p "$corpus"
  case $format in
    nff) for f in "$root"/../shared/data/spd/*.nff; do head -c 4000 "$f" > "$corpus/$(basename "$f")"; done ;;
    ply) printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n' > "$corpus/tri.ply" ;;
    obj) printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\nf -1 -2 -3\n' > "$corpus/quad.obj" ;;
    off) printf 'OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n' > "$corpus/quad.off" ;;
    stl) printf 'solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n' > "$corpus/tri.stl"
         { head -c 80 /dev/zero; printf '\1\0\0\0'; head -c 12 /dev/zero; printf '\0\0\200\77%.0s' 1 2 3 4 5 6 7 8 9; printf '\0\0'; } > "$corpus/tri_bin.stl" ;;
    cell_page) export FRONTIER_FUZZ_SEEDS="$corpus" ;;
    bsp) head -c 512 /dev/urandom > "$corpus/random" ;;  # any bytes decode to a polygon soup
  esac
  echo "fuzz_$format: $seconds s"
  "$build/tests/fuzz/fuzz_$format" -max_total_time="$seconds" -max_len=65536 -timeout=10 \
    -artifact_prefix="$build/findings/${format}-" "$corpus"
done
