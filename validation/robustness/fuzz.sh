#!/usr/bin/env bash
# Issue 21: runs every libFuzzer target of validation/robustness/fuzz/ for a bounded time on
# seed corpora made by make_fuzz_seeds (small valid files from the toolkit's own writers).
# Builds build-fuzz/ with clang, -DRGBD_FUZZ=ON (ASan + UBSan + libFuzzer) when needed.
# A crash, sanitizer report, leak, hang (-timeout 10 s per input) or an allocation over
# 2 GB (-malloc_limit_mb) stops that target; its input is kept as build-fuzz/fuzz-out/<target>/
# crash-*, and the script exits 1 after running all targets.
# Usage: validation/robustness/fuzz.sh [SECONDS per target, default 60] [BUILD_DIR]
set -euo pipefail
if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'
  exit 0
fi
SECONDS_PER=${1:-60}
cd "$(dirname "$0")/../.."
BUILD=${2:-build-fuzz}
LAUNCHER=()
if command -v ccache >/dev/null; then
  LAUNCHER=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
if [ ! -f "$BUILD/CMakeCache.txt" ]; then
  cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DRGBD_FUZZ=ON \
    -DRGBD_BUILD_TESTS=OFF "${LAUNCHER[@]}" >/dev/null
fi
ninja -C "$BUILD" -j2 fuzz_all
OUT="$BUILD/fuzz-out"
rm -rf "$OUT/seeds"
"$BUILD/bin/make_fuzz_seeds" "$OUT/seeds"
export ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
failed=()
for t in fuzz_ply_stream fuzz_mesh_readers fuzz_capture_folder fuzz_foreign_layouts fuzz_rvl \
  fuzz_frame_message fuzz_calibration_board; do
  mkdir -p "$OUT/$t/corpus"
  echo "== $t: ${SECONDS_PER}s"
  if "$BUILD/bin/$t" -max_total_time="$SECONDS_PER" -timeout=10 -rss_limit_mb=4096 \
    -malloc_limit_mb=2048 -max_len=65536 -print_final_stats=1 \
    -artifact_prefix="$OUT/$t/" "$OUT/$t/corpus" "$OUT/seeds/$t" >"$OUT/$t.log" 2>&1; then
    grep -E "^stat::number_of_executed_units|^stat::peak_rss_mb" "$OUT/$t.log" | tr '\n' ' '
    echo "ok"
  else
    echo "FAILED: see $OUT/$t.log"; grep -m3 -E "ERROR|SUMMARY|runtime error" "$OUT/$t.log" || true
    failed+=("$t")
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz.sh: failing targets: ${failed[*]}" >&2
  exit 1
fi
echo "fuzz.sh: every target ran ${SECONDS_PER}s clean"
