#!/usr/bin/env bash
# The checks to run before a release that do not fit CI's budget (issue 39):
#  1. every libFuzzer target for SECONDS (default 60): validation/robustness/fuzz.sh;
#  2. every tool with bad option values: validation/robustness/option_sweep.py on build/bin
#     (an exit 0 on an absurd value counts as a failure);
#  3. the whole suite under ASan + UBSan: scripts/sanitize.sh --all (RGBD_SKIP_SANITIZE=1
#     skips it; it takes about an hour on 2 cores).
# Each check's output goes to validation/results/<YYYY-MM-DD>-<check>-<commit>.md (the commit
# gets "-dirty" when the tree has changes). Runs every check, then exits 1 if any failed.
# Usage: bash scripts/pre-release.sh [SECONDS per fuzz target, default 60]
set -uo pipefail
if [ "${1:-}" = "--help" ] || [ "${1:-}" = "-h" ]; then
  sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'
  exit 0
fi
SECONDS_PER=${1:-60}
cd "$(dirname "$0")/.."
[ -x build/bin/rgbd-clean ] || bash scripts/setup.sh
DAY=$(date +%F)
COMMIT=$(git rev-parse --short HEAD)
git diff --quiet HEAD -- || COMMIT="$COMMIT-dirty"
RESULTS=validation/results
failed=()

# record NAME TITLE COMMAND...: runs COMMAND, writes its output with a header to
# $RESULTS/$DAY-NAME-$COMMIT.md and says where; a failing command is added to `failed`.
record() {
  local name=$1 title=$2
  shift 2
  local file="$RESULTS/$DAY-$name-$COMMIT.md" log rc start
  log=$(mktemp)
  start=$(date +%s)
  echo "== $title: $*"
  "$@" 2>&1 | tee "$log"
  rc=${PIPESTATUS[0]}
  {
    echo "# $title ($DAY)"
    echo
    echo "- command: \`$*\` (scripts/pre-release.sh)"
    echo "- code: commit $COMMIT; machine: $(nproc) cores, load average at the end" \
      "$(cut -d' ' -f1-3 /proc/loadavg); $(($(date +%s) - start)) s wall"
    if [ "$rc" -eq 0 ]; then echo "- result: **pass**"; else echo "- result: **FAIL** (exit $rc)"; fi
    echo
    echo '```'
    grep -v '^\[[0-9]*/[0-9]*\]' "$log"  # without ninja's progress lines
    echo '```'
  } >"$file"
  rm -f "$log"
  echo "== $title: exit $rc, written to $file"
  [ "$rc" -eq 0 ] || failed+=("$name")
}

record fuzz-${SECONDS_PER}s "Fuzzing every target for ${SECONDS_PER} s" \
  validation/robustness/fuzz.sh "$SECONDS_PER"
record option-sweep "Bad option values over every tool" \
  python3 validation/robustness/option_sweep.py build/bin
if [ "${RGBD_SKIP_SANITIZE:-0}" != "1" ]; then
  record sanitize-all "The whole suite under ASan + UBSan" bash scripts/sanitize.sh --all
fi

if [ ${#failed[@]} -gt 0 ]; then
  echo "pre-release: failed: ${failed[*]}" >&2
  exit 1
fi
echo "pre-release: every check passed"
