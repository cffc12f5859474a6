#!/usr/bin/env bash
# Benchmark of rgbd-calibrate against the targets of issue 19, on synthetic captures with truth:
#  1. board: rgbd-synth --target charuco, 8 Kinect v2 sensors, 40 frame sets, noise on,
#     rig.json 10 deg / 100 mm off -> rgbd-calibrate; errors relative to sensor 0 (rig_errors.py):
#     target every sensor <= 0.3 deg and <= 2 mm RMS in a 0.3 m ball at the ring centre,
#     and the run under 30 s on this machine (wall time; CPU time printed beside it).
#     The same with 4 sensors / 16 frame sets (the smallest ring of the issue).
#  2. refine: the Max Planck bust (../shared/data; skipped when absent), 8 sensors, rig.json
#     3 deg / 30 mm off -> rgbd-calibrate --refine; target <= 0.2 deg and <= 1.5 mm RMS on the
#     bust's surface (gt/mesh.ply).
# There is no peer for board calibration among the installed tools (Open3D 0.16 has none), so
# the speed line prints the ratio to the issue's 30 s target instead of a peer's time.
# Writes validation/results/<date>-calibration-<commit>.md. Usage: run.sh [BUILD_DIR]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
src="$(cd "$here/../../.." && pwd)"
build="${1:-$src/build}"
ninja -C "$build" -j2 rgbd-synth rgbd-calibrate >/dev/null
bin="$build/bin"
work="$(mktemp -d /tmp/calibration_bench.XXXXXX)"
trap 'rm -rf "$work"' EXIT
commit="$(git -C "$src" rev-parse --short HEAD)"
date="$(date -u +%Y-%m-%d)"
out="$src/validation/results/$date-calibration-$commit.md"
py=/usr/bin/python3
report="$work/report.md"
{
  echo "# rgbd-calibrate against issue 19's targets ($date, commit $commit)"
  echo
  echo "Command: \`validation/quality/calibration/run.sh\` (machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg))."
  echo "Errors relative to sensor 0 (validation/quality/calibration/rig_errors.py)."
} >"$report"

# timed OUT CMD...: runs CMD with stdout to OUT; prints "wall_s cpu_s" (user + system).
timed() {
  local dest=$1
  shift
  $py - "$dest" "$@" <<'PY'
import resource, subprocess, sys, time
t = time.monotonic()
with open(sys.argv[1], "w") as f:
    subprocess.run(sys.argv[2:], stdout=f, check=True)
r = resource.getrusage(resource.RUSAGE_CHILDREN)
print(f"{time.monotonic() - t:.3f} {r.ru_utime + r.ru_stime:.3f}")
PY
}

board_case() {  # name sensors frames seed
  local name=$1 sensors=$2 frames=$3 seed=$4
  "$bin/rgbd-synth" --target charuco -q -o "$work/$name" --sensors "$sensors" --frames "$frames" \
    --seed "$seed" --calib-error-deg 10 --calib-error-mm 100
  local wall cpu
  read -r wall cpu < <(timed "$work/$name.table" "$bin/rgbd-calibrate" "$work/$name" -q \
    -o "$work/$name.json")
  {
    echo
    echo "## Board capture: $sensors sensors, $frames frame sets, rig.json 10 deg / 100 mm off"
    echo
    echo "\`rgbd-synth --target charuco --sensors $sensors --frames $frames --seed $seed --calib-error-deg 10 --calib-error-mm 100\`, then \`rgbd-calibrate CAP -o rig.json\`:"
    echo
    echo '```'
    cat "$work/$name.table"
    echo
    echo "before (the capture's rig.json):"
    $py "$here/rig_errors.py" "$work/$name" "$work/$name/rig.json" | tail -1
    echo "after:"
    $py "$here/rig_errors.py" "$work/$name" "$work/$name.json"
    printf "time: %.1f s wall, %.1f s CPU; wall / 30 s target = %.2f\n" "$wall" "$cpu" \
      "$($py -c "print($wall / 30)")"
    echo '```'
  } >>"$report"
}
board_case ring8 8 40 1
board_case ring4 4 16 4

mesh="$src/../shared/data/meshes/max_planck/max-planck.obj"
if [ -f "$mesh" ]; then
  "$bin/rgbd-synth" "$mesh" -q -o "$work/bust" --up y --height-m 0.45 --sensors 8 \
    --calib-error-deg 3 --calib-error-mm 30
  read -r wall cpu < <(timed "$work/bust.table" "$bin/rgbd-calibrate" "$work/bust" --refine -q \
    -o "$work/bust.json")
  {
    echo
    echo "## --refine on the Max Planck bust: 8 sensors, rig.json 3 deg / 30 mm off"
    echo
    echo "\`rgbd-synth max-planck.obj --up y --height-m 0.45 --sensors 8 --calib-error-deg 3 --calib-error-mm 30\`, then \`rgbd-calibrate CAP --refine -o rig.json\`:"
    echo
    echo '```'
    cat "$work/bust.table"
    echo
    echo "before:"
    $py "$here/rig_errors.py" "$work/bust" "$work/bust/rig.json" --mesh | tail -1
    echo "after:"
    $py "$here/rig_errors.py" "$work/bust" "$work/bust.json" --mesh
    printf "time: %.1f s wall, %.1f s CPU\n" "$wall" "$cpu"
    echo '```'
  } >>"$report"
else
  echo -e "\n## --refine: skipped (no $mesh)" >>"$report"
fi
cp "$report" "$out"
cat "$out"
echo "wrote $out" >&2
