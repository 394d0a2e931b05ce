#!/usr/bin/env bash
# Runs the built test suite as a user's clone meets it: without ../shared beside the repository
# and on a busy machine (two busy loops). Tests that need ../shared must skip, saying why; no
# assertion may depend on an idle machine.
#   scripts/busy_clone_tests.sh [BUILD_DIR [CTEST_ARGS...]]   (as root: hides ../shared in a mount
#   namespace; e.g. scripts/busy_clone_tests.sh build -R app/ runs the app's tests alone)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${1:-build}
shift || true
extra=$(printf " %q" "$@")
shared=$(realpath -m ../shared)

busy() { while :; do :; done; }
busy &
b1=$!
busy &
b2=$!
trap 'kill $b1 $b2 2>/dev/null || true' EXIT

run_tests="ctest --test-dir '$BUILD_DIR' --output-on-failure -j $(nproc) --timeout 1800$extra"
if [ ! -d "$shared" ]; then
  echo "busy_clone_tests: $shared is absent already"
  bash -c "$run_tests"
elif unshare -m true 2>/dev/null; then
  unshare -m bash -c "mount -t tmpfs -o ro,size=1m none '$shared' && test -z \"\$(ls -A '$shared')\" && $run_tests"
else
  echo "busy_clone_tests: cannot hide $shared (unshare -m needs root): run from a clone without ../shared" >&2
  exit 1
fi
