#!/usr/bin/env bash
# Installs dependencies, builds, and runs every test (GoogleTest through ctest).
# Tests that need ../shared/data skip with a message when it is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cd build
ctest --output-on-failure -j"$(nproc)" --timeout 900
