#!/usr/bin/env bash
# Capture network benchmark (docs/algorithms.md §1, issue 8):
#  1. RVL vs PNG (bench_rvl, Google Benchmark): compression ratio and encode time per frame,
#     as ratios to PNG, on full-frame Kinect v2 like depth (the synthetic sensor recorded through
#     rgbd-node -> rgbd-capture), on the 8-Kinect rgbd-synth ring capture (object only, so
#     mostly zeros) and, when ../shared/data is there, on real Kinect v1 class depth (uva).
#  2. Hub CPU: rgbd-capture receiving, decoding and recording 8 x 30 fps Kinect v2 streams
#     (512x424 RVL depth + 1920x1080 JPEG colour) from 8 rgbd-node processes on loopback,
#     printed as a fraction of one core (user + system CPU time / wall time), nodes likewise.
# Usage: capture_bench.sh [BUILD_DIR] [SECONDS] [OUT_DIR]   (builds what it needs)
set -euo pipefail
BUILD=${1:-build}
SECONDS_RUN=${2:-20}
OUT=${3:-/tmp/capture_bench}
B=$BUILD/bin
rm -rf "$OUT"
mkdir -p "$OUT"
if [ -z "${SKIP_BUILD:-}" ]; then
  cmake --build "$BUILD" -j2 --target rgbd-synth rgbd-capture rgbd-node >"$OUT/build.log" 2>&1 ||
    { tail -20 "$OUT/build.log"; exit 1; }
  cmake --build "$BUILD" -j2 --target bench_rvl >>"$OUT/build.log" 2>&1 ||
    echo "capture_bench: bench_rvl not built (libbenchmark-dev missing?)" >&2
fi

# The Stanford bunny that Debian's libcgal-demo ships (as scripts/demo.sh).
MESH_SRC=/usr/share/doc/libcgal-dev/data.tar.gz
[ -f "$MESH_SRC" ] || { echo "capture_bench: $MESH_SRC missing (apt-get install libcgal-demo)" >&2; exit 1; }
tar -xzf "$MESH_SRC" -C "$OUT" --strip-components=2 data/meshes/bunny00.off
"$B/rgbd-synth" "$OUT/bunny00.off" -o "$OUT/synth" --sensors 8 --frames 8 --height-m 0.45 --seed 1 -q

# Full-frame Kinect v2 depth (wall + sphere, Kinect v2 noise): the synthetic sensor recorded
# through rgbd-node -> rgbd-capture (rgbd-synth renders the object only, no room behind it).
PORT=$((20000 + RANDOM % 5000 * 2))
cat >"$OUT/synthetic_rig.json" <<JSON
{"format": "rgbd-capture", "version": 1, "units": "m", "sensors": [{"id": "synthetic-0",
 "model": "synthetic_kinect_v2",
 "depth": {"width": 512, "height": 424, "fx": 365.5, "fy": 365.5, "cx": 256.0, "cy": 212.0},
 "color": {"width": 640, "height": 360, "fx": 360.4567, "fy": 360.4567, "cx": 319.6667,
           "cy": 179.6667}, "depth_scale": 1000.0}]}
JSON
"$B/rgbd-capture" --rig "$OUT/synthetic_rig.json" -o "$OUT/kinect_v2" --exit-after-bye \
  --listen "tcp://127.0.0.1:$PORT" -q &
"$B/rgbd-node" --sensor synthetic: --frames 60 --hub "tcp://127.0.0.1:$PORT" -q
wait

echo "== RVL depth codec (ratio = raw 16-bit bytes / compressed bytes; CPU time per frame)"
if [ -x "$B/bench_rvl" ]; then
  SHARED=$(cd "$(dirname "$0")/../.." && pwd)/../shared/data
  for cap in "$OUT/kinect_v2" "$OUT/synth" "$SHARED/multiview/uva_cv2_person_kinect1"; do
    [ -d "$cap" ] || continue
    "$B/bench_rvl" "$cap" --benchmark_min_time=0.3 2>&1 | tee -a "$OUT/bench_rvl.txt" | tail -1
  done
fi

echo "== hub CPU, 8 x 30 fps for $SECONDS_RUN s"
TICK=$(getconf CLK_TCK)
cpu_ticks() { awk '{print $14 + $15}' "/proc/$1/stat" 2>/dev/null || echo 0; }
PORT=$((20000 + RANDOM % 5000 * 2 + 2))
FRAMES=$((SECONDS_RUN * 30))
"$B/rgbd-capture" --rig "$OUT/synth/rig.json" -o "$OUT/rec" --listen "tcp://127.0.0.1:$PORT" \
  --exit-after-bye --metrics "$OUT/hub.json" -q &
HUB=$!
NODES=()
for s in 0 1 2 3 4 5 6 7; do
  "$B/rgbd-node" --sensor "playback:$OUT/synth#k2-$s" --loop --frames "$FRAMES" \
    --hub "tcp://127.0.0.1:$PORT" --clock-offset-ms $(( (s * 137) % 1000 - 500 )) \
    --clock-drift-ppm $(( (s * 31) % 100 - 50 )) --metrics "$OUT/node$s.json" -q &
  NODES+=($!)
done
START=$(date +%s.%N)
HUB_TICKS=0; NODE_TICKS=0
declare -A LAST
while kill -0 "$HUB" 2>/dev/null; do
  t=$(cpu_ticks "$HUB"); [ "$t" -gt 0 ] && HUB_TICKS=$t
  for p in "${NODES[@]}"; do t=$(cpu_ticks "$p"); [ "$t" -gt 0 ] && LAST[$p]=$t; done
  sleep 0.2
done
END=$(date +%s.%N)
wait "$HUB"
for p in "${NODES[@]}"; do NODE_TICKS=$((NODE_TICKS + ${LAST[$p]:-0})); done
python3 - "$OUT" "$HUB_TICKS" "$NODE_TICKS" "$TICK" "$START" "$END" <<'PY'
import json, sys
out, hub_t, node_t, tick, start, end = sys.argv[1], *map(float, sys.argv[2:])
wall = end - start
hub = json.load(open(out + "/hub.json"))
sent = sum(json.load(open(f"{out}/node{s}.json"))["frames_sent"] for s in range(8))
ratio = [json.load(open(f"{out}/node{s}.json"))["rvl_ratio"] for s in range(8)]
stream_s = hub["frames_recorded"] / 240.0  # seconds of 8 x 30 fps streams recorded
print(f"hub CPU: {hub_t / tick / stream_s:.2f} of one core to receive, decode and record 8 x 30 fps "
      f"Kinect v2 streams (CPU time / stream time; {hub['frames_recorded']} of {sent} frames "
      f"recorded, {hub['dropped_messages']} dropped, {hub['late_frames']} late, "
      f"{hub['framesets_complete']} of {hub['framesets']} frame sets complete; wall {wall:.1f} s "
      f"for {stream_s:.1f} s of streams)")
print(f"node CPU: {node_t / tick / stream_s / 8:.3f} of one core per node (RVL ratio on the wire "
      f"{min(ratio):.2f}-{max(ratio):.2f})")
PY
