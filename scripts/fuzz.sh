#!/usr/bin/env bash
# Builds the loaders' libFuzzer targets (fuzz/, with clang, ASan+UBSan) and runs each for a
# bounded time on a seed corpus made from the repository's own files.
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]   (default 45 s each; all targets)
# Environment: FUZZ_BUILD_DIR (default build-fuzz); FUZZ_CORPUS_DIR (default ~/.cache/odvr-fuzz),
# where the inputs each run finds new coverage with are kept, so that successive runs (CI's) go on
# from where the last one stopped instead of from the seeds again. Exit status non-zero when a target finds a
# crash, a leak, a sanitizer report, a timeout or an out-of-memory: the input that did it is left
# in $FUZZ_BUILD_DIR/findings/<target>/ and printed; make it a unit test beside the loader's tests.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-45}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(image gltf rig trajectory lighting video)
build=${FUZZ_BUILD_DIR:-build-fuzz}

CC=clang CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DODVR_FUZZ=ON \
  -DODVR_BUILD_TESTS=OFF -DODVR_BUILD_BENCHMARKS=OFF -DODVR_WERROR=ON > /dev/null
cmake --build "$build" -j "$(nproc)" --target fuzz_targets

# Seeds: the small files in fuzz/seeds, and small versions of the demo's own media (the image and
# video readers get one file per container and codec a user's footage comes in).
corpus=$build/corpus
rm -rf "$corpus"
for t in "${targets[@]}"; do
  mkdir -p "$corpus/$t"
  [ -d "fuzz/seeds/$t" ] && cp fuzz/seeds/"$t"/* "$corpus/$t/"
done
seed() { [ -d "$corpus/$1" ] && cp "$2" "$corpus/$1/$3"; return 0; }
seed rig media/demo/rig.json demo_rig.json
seed trajectory media/demo/trajectory_gt.json demo.json
seed trajectory media/demo/trajectory_gt.tum demo.tum
seed gltf media/demo/car.glb demo_car.glb
if [ -d "$corpus/image" ]; then
  for ext in png jpg exr hdr tif; do
    oiiotool media/demo/pano_hdr/000000.exr --resize 32x16 -o "$corpus/image/pano.$ext"
  done
  oiiotool media/demo/pano/000000.png --resize 32x16 -o "$corpus/image/pano8.png"
fi
if [ -d "$corpus/video" ]; then
  tiny=(-v error -y -i media/demo/street.mp4 -frames:v 6 -vf scale=32:16 -an)
  ffmpeg "${tiny[@]}" -c:v libx264 -g 3 -movflags +faststart "$corpus/video/h264.mp4"
  ffmpeg "${tiny[@]}" -c:v libx264 -g 3 -f mpegts "$corpus/video/h264.ts"
  ffmpeg "${tiny[@]}" -c:v libx265 -x265-params log-level=none -g 3 "$corpus/video/hevc.mkv"
  ffmpeg "${tiny[@]}" -c:v mjpeg "$corpus/video/mjpeg.avi"
  ffmpeg "${tiny[@]}" -c:v libx264 -g 3 -metadata:s:v stereo_mode=top_bottom "$corpus/video/stereo.mkv"
fi

# Leaks inside Debian's libraries that live for the process (OpenImageIO's per-thread error
# string, Mesa's) are theirs: the same suppressions as the sanitized test run.
export LSAN_OPTIONS=suppressions=$PWD/.ci/lsan.supp:print_suppressions=0
kept=${FUZZ_CORPUS_DIR:-$HOME/.cache/odvr-fuzz}
failed=()
for t in "${targets[@]}"; do
  mkdir -p "$kept/$t"
  findings=$build/findings/$t
  rm -rf "$findings" && mkdir -p "$findings"
  echo "== fuzz $t: ${seconds} s from $(ls "$corpus/$t" | wc -l) seeds and $(ls "$kept/$t" | wc -l) inputs kept"
  # -timeout: one input may take at most 10 s; -rss_limit_mb: a loader must refuse what would
  # need more memory than that; -max_len: inputs as large as the largest seed (the car, 160 kB).
  if ! "$build/fuzz/${t}_fuzz" "$kept/$t" "$corpus/$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
      -max_len=200000 -print_final_stats=1 -artifact_prefix="$findings/" > "$findings/log.txt" 2>&1; then
    failed+=("$t")
    tail -40 "$findings/log.txt"
    ls "$findings"
  fi
  grep -E "^(stat::number_of_executed_units|stat::new_units_added|Done)" "$findings/log.txt" | tr '\n' ' '
  echo
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: ${failed[*]} found inputs that break them (in $build/findings)" >&2
  exit 1
fi
echo "fuzz: every target ran ${seconds} s without a finding"
