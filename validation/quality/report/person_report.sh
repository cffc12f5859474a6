#!/usr/bin/env bash
# Issue 7 on real data: a coloured mesh of the real person sequence
# (shared/data/multiview/uva_cv2_person_kinect1, one Kinect v1 class sensor, 50 frames around
# 360 degrees, per-frame pseudo ground-truth poses) and its report page, with the existing tools:
#   rgbd-cloud SEQ | rgbd-clean --statistical | rgbd-align -o aligned.ply
#   rgbd-mesh aligned.ply --watertight -o person.ply
#   rgbd-eval person.ply --points aligned.ply --baseline screened-poisson --report report/
# There is no true surface: the heat maps show each mesh's distance to the aligned input
# points (where the surface strays from what was measured), for ours and for Open3D's Screened
# Poisson (depths 8-10, best = 9 without a reference). Then headless Chromium takes a
# screenshot of the page (report_screenshot.png). Prints the stage times.
#
# Usage: validation/quality/report/person_report.sh [--bin build/bin] [--out DIR]
#                                                   [--frames A:B[:STEP]] [--no-baseline]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../../.." && pwd)
BIN=$ROOT/build/bin
OUT=${TMPDIR:-/tmp}/person_report
FRAMES=0:50
BASELINE=(--baseline screened-poisson)
while [ $# -gt 0 ]; do
  case $1 in
    --bin) BIN=$(cd "$2" && pwd); shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --frames) FRAMES=$2; shift 2 ;;
    --no-baseline) BASELINE=(); shift ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    *) echo "person_report.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
SEQ=$ROOT/../shared/data/multiview/uva_cv2_person_kinect1
if [ ! -d "$SEQ" ]; then
  echo "person_report.sh: needs $SEQ (../shared/data is absent)" >&2
  exit 1
fi
mkdir -p "$OUT"
cd "$OUT"

echo "person_report: frames $FRAMES of $SEQ -> $OUT" >&2
start=$(date +%s.%N)
"$BIN/rgbd-cloud" "$SEQ" --frames "$FRAMES" -q | "$BIN/rgbd-clean" --statistical -q |
  "$BIN/rgbd-align" -q --metrics align.json -o aligned.ply
align_end=$(date +%s.%N)
"$BIN/rgbd-mesh" aligned.ply --watertight -o person.ply -q --metrics mesh.json
mesh_end=$(date +%s.%N)
"$BIN/rgbd-eval" person.ply --points aligned.ply "${BASELINE[@]}" --report report \
  -o eval.json
eval_end=$(date +%s.%N)
python3 - "$start" "$align_end" "$mesh_end" "$eval_end" <<'PY'
import sys
s, a, m, e = map(float, sys.argv[1:])
print(f"times: cloud+clean+align {a - s:.1f} s, mesh {m - a:.1f} s, eval+baseline+report {e - m:.1f} s",
      file=sys.stderr)
PY
"$BIN/rgbd-info" person.ply --json > person_info.json 2>/dev/null || true

if [ -x /usr/bin/chromium ]; then
  timeout 180 /usr/bin/chromium --headless --no-sandbox --disable-gpu --hide-scrollbars \
    --force-device-scale-factor=1 --user-data-dir="$OUT/.chromium" \
    --screenshot="$OUT/report_screenshot.png" --window-size=1400,2000 \
    "file://$OUT/report/index.html" 2>/dev/null || true
  rm -rf "$OUT/.chromium"
fi
echo "mesh:       $OUT/person.ply" >&2
echo "report:     $OUT/report/index.html" >&2
[ -f "$OUT/report_screenshot.png" ] && echo "screenshot: $OUT/report_screenshot.png" >&2
exit 0
