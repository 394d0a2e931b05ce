#!/usr/bin/env bash
# odvr set-up on Debian 12, as root (or with sudo). Idempotent: a second run reuses the build.
#   scripts/setup.sh demo   install, build the player alone, play the default demo (media/drive, with the car)
#   scripts/setup.sh test   install, build, run every test
#   scripts/setup.sh deps   install the Debian packages only
#   scripts/setup.sh build  install and build
#   scripts/setup.sh tools  install the reference tools (Blender, COLMAP) for media and benches
# Environment: BUILD_DIR (default build), ODVR_CMAKE_ARGS (extra CMake arguments).
set -euo pipefail
cd "$(dirname "$0")/.."

BUILD_DIR=${BUILD_DIR:-build}
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

# The list's first part is what builds and tests need; after the "-- reference tools" marker
# come tools only the media script and the benches use.
packages_of() {
  local part=$1
  awk -v part="$part" '/^# -- reference tools/ { tools = 1; next }
    /^[[:space:]]*#/ || /^[[:space:]]*$/ { next }
    (part == "tools") == (tools == 1) { print $1 }' deps/debian-packages.txt
}

install_deps() {
  mapfile -t packages < <(packages_of "${1:-build}")
  local missing=()
  for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "odvr setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
  fi
}

# build [TARGET]: everything (the tests and benchmarks too), or only TARGET and what it needs.
build() {
  # shellcheck disable=SC2086
  cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo ${ODVR_CMAKE_ARGS:-}
  cmake --build "$BUILD_DIR" -j "$(nproc)" ${1:+--target "$1"}
}

case "${1:-}" in
  deps) install_deps ;;
  tools) install_deps tools ;;
  build) install_deps; build ;;
  test)
    install_deps
    build
    ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$(nproc)" --timeout 1200
    ;;
  demo)
    install_deps
    build odvr  # the player alone: the test binaries and benchmarks are the other command's
    # odvr with no arguments plays the demo (media/drive) with its car: a window when there is a
    # display, PNG frames (and where they went) when there is none.
    "$BUILD_DIR"/app/odvr
    ;;
  *)
    echo "usage: scripts/setup.sh demo|test|deps|build|tools" >&2
    exit 2
    ;;
esac
