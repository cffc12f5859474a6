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
# Usage: video_bench.sh [BUILD_DIR] [SETS] [OUT_DIR]   (SETS: frame sets per run, default 300)
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
"$B/rgbd-synth" "$OUT/bunny00.off" -o "$OUT/synth" --sensors 8 --frames 30 --height-m 0.45 \
  --motion turn --motion-deg 60 --calib-error-deg 0 --calib-error-mm 0 --seed 1 -q

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

"$PY" - "$OUT" "$B" <<'PY'
import json, os, subprocess, sys
import numpy as np
out, b = sys.argv[1], sys.argv[2]
motion = json.load(open(f"{out}/synth/gt/motion.json"))["world_from_mesh"]
period_ns = 1e9 / 30
one = json.load(open(f"{out}/one_node.json"))
node_view_ms = one["cpu_ms_per_frame"]

def moved_mesh(position):
    path = f"{out}/truth_{position}.ply"
    if not os.path.exists(path):
        import open3d as o3d
        mesh = o3d.io.read_triangle_mesh(f"{out}/synth/gt/mesh.ply")
        mesh.transform(np.array(motion[str(position)]))
        o3d.io.write_triangle_mesh(path, mesh)
    return path

results = {}
for placement in ("nodes", "hub"):
    hub = json.load(open(f"{out}/hub_{placement}.json"))
    v = hub["video"]
    video = json.load(open(f"{out}/video_{placement}/video.json"))
    frames = video["frames"]
    start = min(s["clock"]["start_hub_ns"] for s in hub["sensors"].values())
    span_s = (frames[-1]["time_ns"] - frames[0]["time_ns"]) * 1e-9 + 1 / 30 if frames else 0
    nodes = [json.load(open(f"{out}/node_{placement}_{s}.json")) for s in range(8)]
    lost = v["sets_offered"] - v["sets_fused"] - v["sets_skipped"] - v["sets_empty"]
    # Accuracy and PLY size on 10 frames spread over the run.
    picks = [frames[i] for i in np.linspace(0, len(frames) - 1, 10).astype(int)]
    within, ply_ratio = [], []
    for f in picks:
        ply = f"{out}/{placement}_{f['frame']}.ply"
        subprocess.run([f"{b}/rgbd-info", f"{out}/video_{placement}", "--frame", str(f["frame"]),
                        "-o", ply, "-q"], check=True)
        position = round((f["time_ns"] - start) / period_ns) % 30
        ev = subprocess.run([f"{b}/rgbd-eval", ply, "--reference", moved_mesh(position),
                             "--tau-mm", "5", "--samples", "100000", "-q"],
                            check=True, capture_output=True, text=True)
        m = json.loads(ev.stdout)
        within.append(m["precision_5mm"])
        ply_ratio.append(f["bytes"] / os.path.getsize(ply))
    r = {
        "sets_fused": v["sets_fused"], "sets_offered": v["sets_offered"],
        "sets_skipped": v["sets_skipped"], "sets_empty": v["sets_empty"],
        "sets_thinned": v["sets_thinned"], "lost_uncounted": lost,
        "late_frames": hub["late_frames"], "dropped": hub["dropped_messages"],
        "fused_sets_per_s": v["sets_fused"] / span_s if span_s else 0,
        "offered_sets_per_s": v["sets_offered"] / span_s if span_s else 0,
        "hub_fusion_cpu_ms_per_set": v["hub_cpu_ms_per_set"],
        "hub_process_cpu_ms_per_set": 1e3 * hub["cpu_s"] / max(1, v["sets_fused"]),
        "node_cpu_ms_per_frame": float(np.mean([n["cpu_ms_per_frame"] for n in nodes])),
        "latency_ms_p50": v["latency_ms_p50"], "latency_ms_p95": v["latency_ms_p95"],
        "points_per_frame": float(np.mean([f["points"] for f in frames])),
        "bytes_per_frame": float(np.mean([f["bytes"] for f in frames])),
        "draco_over_ply": float(np.mean(ply_ratio)),
        "within_5mm_min": float(np.min(within)), "within_5mm_mean": float(np.mean(within)),
    }
    results[placement] = r
    print(f"== per-view work on the {placement}")
    for k, x in r.items():
        print(f"  {k}: {x:.4g}" if isinstance(x, float) else f"  {k}: {x}")
print(f"== one node, per-view work without the cache: {node_view_ms:.1f} ms CPU per frame "
      f"({one.get('view_points_per_frame', 0):.0f} points per view)")
json.dump({"placements": results, "node_view_cpu_ms_per_frame": node_view_ms},
          open(f"{out}/video_bench.json", "w"), indent=1)

n = results["nodes"]
def verdict(name, ok, figure):
    print(f"  {'MET    ' if ok else 'NOT MET'} {name}: {figure}")
print("== targets (per-view work on the nodes, the placement that keeps the hub at 30 sets/s)")
verdict(">= 30 fused sets/s", n["fused_sets_per_s"] >= 29.5,
        f"{n['fused_sets_per_s']:.1f} sets/s fused of {n['offered_sets_per_s']:.1f} offered")
verdict("hub work <= 33 ms per set on one core", n["hub_fusion_cpu_ms_per_set"] <= 33,
        f"{n['hub_fusion_cpu_ms_per_set']:.1f} ms (fusion thread); whole hub process "
        f"{n['hub_process_cpu_ms_per_set']:.1f} ms")
verdict("latency p95 <= 100 ms", n["latency_ms_p95"] <= 100,
        f"p50 {n['latency_ms_p50']:.0f} ms, p95 {n['latency_ms_p95']:.0f} ms")
verdict("no set lost without being counted", n["lost_uncounted"] == 0,
        f"{n['lost_uncounted']} uncounted; {n['sets_skipped']} skipped, {n['sets_empty']} "
        f"empty, {n['sets_thinned']} thinned, {n['late_frames']} late frames (counted)")
verdict(">= 95% of fused points within 5 mm", n["within_5mm_min"] >= 0.95,
        f"worst sampled frame {100 * n['within_5mm_min']:.1f}%, mean "
        f"{100 * n['within_5mm_mean']:.1f}%")
verdict("fused frame <= 1/8 of its PLY", n["draco_over_ply"] <= 1 / 8,
        f"1/{1 / n['draco_over_ply']:.1f} ({n['bytes_per_frame']:.0f} bytes for "
        f"{n['points_per_frame']:.0f} points)")
h = results["hub"]
print(f"== hub placement for comparison: {h['fused_sets_per_s']:.1f} sets/s, hub fusion "
      f"{h['hub_fusion_cpu_ms_per_set']:.1f} ms/set, latency p95 {h['latency_ms_p95']:.0f} ms, "
      f"within 5 mm {100 * h['within_5mm_min']:.1f}%")
PY
