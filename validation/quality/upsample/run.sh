#!/usr/bin/env bash
# Colour-guided super-resolution (ALGORITHMS.md §5) on 8-Kinect ring captures of the two busts:
# rgbd-upsample 4/8 and midpoints vs CGAL edge_aware_upsample_point_set (same views, same
# metrics, upsample_quality). Usage: run.sh BUILD_DIR OUT_DIR
set -euo pipefail
B=${1:-/work/main/build-upsample}/bin
OUT=${2:-/tmp/upsample_validation}
DATA=/work/shared/data/meshes
mkdir -p "$OUT"
declare -A MESH=([max_planck]="$DATA/max_planck/max-planck.obj --height-m 0.6"
                 [wreath]="$DATA/danish_statues/BustManWreath_welded.ply --up y --height-m 0.61")
printf "%-11s %-14s %6s %9s %9s %8s %9s %9s %8s\n" capture method ratio rms_orig rms_new far3s% col_new col_nncp time_s
for cap in max_planck wreath; do
  C="$OUT/$cap"
  [ -d "$C" ] || "$B/rgbd-synth" ${MESH[$cap]} -o "$C" -q
  "$B/rgbd-cloud" "$C" | "$B/rgbd-clean" -o "$OUT/$cap.views.ply"
  for m in "8:--neighbors 8" "4:--neighbors 4" "mid8:--midpoints --neighbors 8"; do
    name=${m%%:*}; args=${m#*:}
    t0=$(date +%s.%N)
    "$B/rgbd-upsample" $args --threads 1 "$OUT/$cap.views.ply" -o "$OUT/$cap.up$name.ply"
    t=$(echo "$(date +%s.%N) - $t0" | bc)
    r=$("$B/upsample_quality" "$C" "$OUT/$cap.up$name.ply")
    python3 -c "import json,sys; r=json.loads(sys.argv[1]); print('%-11s %-14s %6.2f %9.3f %9.3f %8.3f %9.2f %9.2f %8.2f' % (sys.argv[2], sys.argv[3], r['ratio'], r['rms_orig_mm'], r['rms_new_mm'], r['far_3sigma_pct'], r['colour_err_new'], r['colour_err_nn_copy'], float(sys.argv[4])))" "$r" "$cap" "ours-$name" "$t"
  done
  r=$("$B/upsample_quality" "$C" "$OUT/$cap.views.ply" --peer cgal --views 2 --factor 9)
  python3 -c "import json,sys; r=json.loads(sys.argv[1]); print('%-11s %-14s %6.2f %9.3f %9.3f %8.3f %9.2f %9.2f %8.2f' % (sys.argv[2], 'cgal-eau(2v)', r['ratio'], r['rms_orig_mm'], r['rms_new_mm'], r['far_3sigma_pct'], r['colour_err_new'], r['colour_err_nn_copy'], r['peer_time_s']))" "$r" "$cap"
done
echo "rms in mm; far3s% = new points farther than 3 sigma_z from gt/mesh.ply; col_* = mean |RGB| error vs texture (new points / nearest-original copy)"
echo "PCL MLS upsampling: not run (pcl-tools not installed in this run; pcl_mls_smoothing upsampling support unverified)"
