#!/usr/bin/env bash
# Installs dependencies, builds, and runs every test (GoogleTest through ctest).
# Tests that need ../shared/data skip with a message when it is absent.
# Then the sanitizer build of the input-parsing subset (scripts/sanitize.sh says which and
# why; RGBD_SKIP_SANITIZE=1 skips it).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
(cd build && ctest --output-on-failure -j"$(nproc)" --timeout 900)
if [ "${RGBD_SKIP_SANITIZE:-0}" != "1" ]; then
  bash scripts/sanitize.sh
fi
