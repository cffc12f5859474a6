#!/usr/bin/env bash
# 3D video benchmark (issue 20 item 6): 8 Kinect v2 nodes at 30 fps on loopback replay an
# rgbd-synth ring capture of the Stanford bunny turning at 60 deg/s (exact rig calibration,
# Kinect v2 noise), the hub fuses every frame set into a video folder, for both placements of
# the per-view work:
#   nodes: the nodes send cleaned world-frame views (--fuse-on nodes); to measure the hub and
#          not this 2-core machine, each node makes the view of each recording position once
#          and sends it again on later loops (rgbd-node --cache-views); a separate run of one
#          node without the cache measures the per-view work of a node;
#   hub:   the nodes send frames (RVL depth + JPEG colour) and the hub does the per-view work.
# Prints per placement: fused sets per second, hub CPU per set (the fusion thread on one core;
# and the whole hub process), node CPU per frame, latency p50/p95 (capture instant -> frame
# written), sets lost (offered - fused - skipped - empty) and late frames, bytes per frame
# against the frame's binary PLY, and accuracy (share of fused points within 5 mm of the moved
# truth mesh, rgbd-eval) on sampled frames; then each issue target as met / not met.
# Usage: video_bench.sh [BUILD_DIR] [SETS] [OUT_DIR]   (SETS: frame sets per run, default 300;
#        SKIP_BUILD=1 uses the tools as built; SYNTH_DIR=DIR reuses a capture of an earlier run)
# The report is validation/performance/video_bench_report.py (run it again on OUT_DIR alone).
set -euo pipefail
BUILD=${1:-build}
SETS=${2:-300}
OUT=${3:-/tmp/video_bench}
B=$BUILD/bin
PY=/usr/bin/python3
rm -rf "$OUT"
mkdir -p "$OUT"
if [ -z "${SKIP_BUILD:-}" ]; then
  cmake --build "$BUILD" -j2 --target rgbd-synth rgbd-capture rgbd-node rgbd-info rgbd-eval \
    >"$OUT/build.log" 2>&1 || { tail -20 "$OUT/build.log"; exit 1; }
fi
MESH_SRC=/usr/share/doc/libcgal-dev/data.tar.gz
[ -f "$MESH_SRC" ] || { echo "video_bench: $MESH_SRC missing (apt-get install libcgal-demo)" >&2; exit 1; }
tar -xzf "$MESH_SRC" -C "$OUT" --strip-components=2 data/meshes/bunny00.off
if [ -n "${SYNTH_DIR:-}" ]; then  # a capture rendered by an earlier run, to save 2-3 minutes
  ln -s "$(cd "$SYNTH_DIR" && pwd)" "$OUT/synth"
else
  "$B/rgbd-synth" "$OUT/bunny00.off" -o "$OUT/synth" --sensors 8 --frames 30 --height-m 0.45 \
    --motion turn --motion-deg 60 --calib-error-deg 0 --calib-error-mm 0 --seed 1 -q
fi

# Per-view work of one node, without the cache (the work a node PC does per frame).
PORT=$((20000 + RANDOM % 5000 * 2))
"$B/rgbd-capture" --rig "$OUT/synth/rig.json" --video "$OUT/one_node" --fuse-on nodes \
  --start-wait-s 0.5 --exit-after-bye --listen "tcp://127.0.0.1:$PORT" -q &
"$B/rgbd-node" --sensor "playback:$OUT/synth#k2-0" --views --loop --frames 90 \
  --hub "tcp://127.0.0.1:$PORT" --metrics "$OUT/one_node.json" -q
wait

for PLACEMENT in nodes hub; do
  PORT=$((20000 + RANDOM % 5000 * 2 + 2))
  # Nodes placement: 30 s for the nodes to make their cached views before the common start.
  LEAD=300
  [ "$PLACEMENT" = nodes ] && LEAD=30000
  "$B/rgbd-capture" --rig "$OUT/synth/rig.json" --video "$OUT/video_$PLACEMENT" \
    --fuse-on "$PLACEMENT" --latency-ms 50 --start-lead-ms $LEAD --exit-after-bye --listen "tcp://127.0.0.1:$PORT" \
    --metrics "$OUT/hub_$PLACEMENT.json" -q &
  HUB=$!
  for s in 0 1 2 3 4 5 6 7; do
    EXTRA=""
    [ "$PLACEMENT" = nodes ] && EXTRA="--views --cache-views"
    "$B/rgbd-node" --sensor "playback:$OUT/synth#k2-$s" $EXTRA --loop --frames "$SETS" \
      --hub "tcp://127.0.0.1:$PORT" --clock-offset-ms $(( (s * 137) % 1000 - 500 )) \
      --metrics "$OUT/node_${PLACEMENT}_$s.json" -q &
  done
  wait
done

"$PY" "$(dirname "$0")/video_bench_report.py" "$OUT" "$B"
