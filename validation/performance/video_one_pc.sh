#!/usr/bin/env bash
# The live 3D video with 8 playback nodes and the hub on ONE machine (issue 38), a smaller
# video_bench.sh: the same rgbd-synth ring capture (8 Kinect v2, bunny turning at 60 deg/s), the
# nodes making their views themselves (no --cache-views: what a user running everything on one
# PC gets), once per setting given. Prints per setting: views late (the hub's health check),
# frame sets fused / offered / skipped, latency p50 / p95 (capture instant -> frame written),
# the hub's warnings on why, and the load average before and after.
# Usage: video_one_pc.sh BUILD_DIR FRAMES OUT_DIR "HUB OPTIONS[|NODE OPTIONS]" ...
#        ("" = the defaults; node options default to --views, which --fuse-on nodes needs;
#        SYNTH_DIR=DIR reuses a capture of an earlier run)
set -euo pipefail
BUILD=${1:?build dir}
FRAMES=${2:?frames per node}
OUT=${3:?out dir}
shift 3
B=$BUILD/bin
mkdir -p "$OUT"
if [ -n "${SYNTH_DIR:-}" ]; then
  SYNTH=$SYNTH_DIR
else
  SYNTH=$OUT/synth
  if [ ! -f "$SYNTH/rig.json" ]; then
    tar -xzf /usr/share/doc/libcgal-dev/data.tar.gz -C "$OUT" --strip-components=2 data/meshes/bunny00.off
    "$B/rgbd-synth" "$OUT/bunny00.off" -o "$SYNTH" --sensors 8 --frames 30 --height-m 0.45 \
      --motion turn --motion-deg 60 --calib-error-deg 0 --calib-error-mm 0 --seed 1 -q
  fi
fi
k=0
for ARG in "$@"; do
  k=$((k + 1))
  OPTS=${ARG%%|*}
  NODE_OPTS=--views
  [[ "$ARG" == *"|"* ]] && NODE_OPTS=${ARG#*|}
  RUN=$OUT/run$k
  rm -rf "$RUN"
  mkdir -p "$RUN"
  PORT=$((20000 + RANDOM % 5000 * 2))
  LOAD_BEFORE=$(cut -d' ' -f1-3 /proc/loadavg)
  # shellcheck disable=SC2086
  "$B/rgbd-capture" --rig "$SYNTH/rig.json" --video "$RUN/video" --exit-after-bye \
    --listen "tcp://127.0.0.1:$PORT" --metrics "$RUN/hub.json" -q $OPTS 2>"$RUN/hub.err" &
  for s in 0 1 2 3 4 5 6 7; do
    # shellcheck disable=SC2086
    "$B/rgbd-node" --sensor "playback:$SYNTH#k2-$s" $NODE_OPTS --loop --frames "$FRAMES" \
      --hub "tcp://127.0.0.1:$PORT" --metrics "$RUN/node$s.json" -q &
  done
  wait
  LOAD_AFTER=$(cut -d' ' -f1-3 /proc/loadavg)
  echo "== hub options: ${OPTS:-(defaults)}; node options: ${NODE_OPTS:-(defaults)}"
  echo "   load average before: $LOAD_BEFORE, after: $LOAD_AFTER ($(nproc) cores)"
  /usr/bin/python3 - "$RUN/hub.json" <<'EOF'
import json, sys
m = json.load(open(sys.argv[1]))
h, v = m["health"], m["video"]
c = h["causes"]
print(f"   views late: {h['views_late']} of {h['views']} "
      f"({100.0 * h['views_late'] / max(1, h['views']):.0f}%; nodes behind "
      f"{c['nodes_behind']['views_late']}, hub behind {c['hub_behind']['views_late']})")
print(f"   frame sets: {v['sets_fused']} fused of {v['sets_offered']} offered, "
      f"{v['sets_skipped']} skipped for newer ones, {v['sets_thinned']} thinned; "
      f"fusion {v['hub_wall_ms_per_set']:.0f} ms wall / {v['hub_cpu_ms_per_set']:.0f} ms CPU per set")
print(f"   latency p50 {v['latency_ms_p50']:.0f} ms, p95 {v['latency_ms_p95']:.0f} ms; "
      f"hub CPU {m.get('cpu_s', 0):.1f} s in {m['duration_s']:.1f} s")
for w in h["warnings"]:
    print("   warning: " + w)
EOF
done
