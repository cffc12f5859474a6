#!/usr/bin/env bash
# Installs the build into a temporary prefix (cmake --install), builds examples/ against the
# installed package (find_package(RgbdToolkit)), and runs every example from the repository
# root without arguments. Exit status: 0 when all build and run, else the failing step's.
# Usage: scripts/examples.sh [BUILD_DIR]   (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$(mktemp -d "${TMPDIR:-/tmp}/rgbd-examples.XXXXXX")
trap 'rm -rf "$work"' EXIT
start=$(date +%s)
cmake --install "$build" --prefix "$work/prefix" > "$work/install.log"
# No CGAL type beyond the data model (kernel, Point_set_3, Surface_mesh) in installed headers.
if grep -rl '#include <CGAL/' "$work/prefix/include/rgbd-toolkit" |
    grep -v -e '/toolkit/types.hpp$' -e '/toolkit/point_cloud.hpp$' -e '/toolkit/mesh.hpp$'; then
  echo "examples.sh: the installed headers above include CGAL headers" >&2
  exit 1
fi
cmake -S examples -B "$work/build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" > "$work/configure.log"
cmake --build "$work/build" -j 2 > "$work/build.log" || { cat "$work/build.log" >&2; exit 1; }
for example in read_capture clean_view fill_holes reconstruct_and_evaluate; do
  echo "== $example"
  "$work/build/$example"
done
echo "examples: installed, built and ran in $(( $(date +%s) - start )) s"
