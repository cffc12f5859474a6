#!/usr/bin/env bash
# rgbd-calibrate --refine on busts it was not tuned on (issue 39 item 2): the busts of a variety
# set (validation/quality/variety/objects.py: lion_head, mannequin_devil, plus bust_man_wreath
# and max_planck as checks), 8 Kinect v2 sensors, 8 frame sets of the still bust, rig.json
# 3 deg / 30 mm off; errors relative to sensor 0 (rig_errors.py --mesh). Prints one markdown
# row per capture and binary directory: worst sensor's rotation (deg), surface RMS (mm, the
# bust's vertices), ball RMS (mm, 0.3 m ball at the object).
# Usage: refine_heldout.sh SET_DIR WORK_DIR "SEEDS" BIN_DIR... (captures are made once in
# WORK_DIR and reused). Env SENSORS (default 8), BUSTS (default the four above).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
set_dir=$1 work=$2 seeds=$3
shift 3
sensors="${SENSORS:-8}"
busts="${BUSTS:-lion_head mannequin_devil bust_man_wreath max_planck}"
mkdir -p "$work"
py=/usr/bin/python3
echo "| bust | sensors | seed | binaries | worst rotation (deg) | worst surface RMS (mm) | worst ball RMS (mm) | worst sensor | wall (s) |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"
for bust in $busts; do
  read -r file synth < <($py - "$set_dir/objects.json" "$bust" <<'PY'
import json, sys
o = next(o for o in json.load(open(sys.argv[1]))["objects"] if o["name"] == sys.argv[2])
print(o["file"], " ".join(o["synth"]))
PY
)
  for seed in $seeds; do
    cap="$work/$bust-$sensors-$seed"
    if [ ! -f "$cap/rig.json" ]; then
      # shellcheck disable=SC2086
      "$1/rgbd-synth" "$set_dir/$file" $synth -q -o "$cap" --sensors "$sensors" --frames 8 \
        --seed "$seed" --calib-error-deg 3 --calib-error-mm 30
    fi
    for bin in "$@"; do
      tag="$(basename "$(dirname "$(dirname "$(realpath "$bin")")")")"
      out="$work/$bust-$sensors-$seed.$tag"
      t0=$(date +%s.%N)
      if ! "$bin/rgbd-calibrate" "$cap" --refine -q -o "$out.json" >"$out.table" 2>"$out.err"; then
        echo "| $bust | $sensors | $seed | $tag | refused: $(tail -1 "$out.err") | | | | |"
        continue
      fi
      t1=$(date +%s.%N)
      $py "$here/rig_errors.py" "$cap" "$out.json" --mesh --json "$out.err.json" >/dev/null
      $py - "$out.err.json" "$bust" "$sensors" "$seed" "$tag" "$t0" "$t1" <<'PY'
import json, sys
e = json.load(open(sys.argv[1]))
w = e["worst"]
who = max(e["sensors"], key=lambda r: r["rotation_deg"])["id"]
a = sys.argv
print(f"| {a[2]} | {a[3]} | {a[4]} | {a[5]} | {w['rotation_deg']:.3f} | {w['surface_rms_mm']:.2f} | "
      f"{w['ball_rms_mm']:.2f} | {who} | {float(a[7]) - float(a[6]):.1f} |")
PY
    done
  done
done
