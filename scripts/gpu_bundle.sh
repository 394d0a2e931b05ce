#!/usr/bin/env bash
# Packs a built odvr (the program and the test binaries with every shared library they load, the
# C library too) and the data the GPU benches read, so that scripts/gpu_run.sh can time the GPU
# paths on a machine that has a GPU driver but not our build dependencies.
#   scripts/gpu_bundle.sh BUILD_DIR OUT_DIR
# OUT_DIR gets part1.tar, part2.tar, … (programs and libraries, each file xz-compressed), shared/
# (a subset of ../shared/data) and source_dir.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:?build directory}
out=${2:?output directory}
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT

mkdir -p "$stage/bin" "$stage/lib" "$out"
programs=("$build/app/odvr")
for t in engine_gl_tests capture_gl_tests; do
  [ -x "$build/tests/$t" ] && programs+=("$build/tests/$t")
done
cp "${programs[@]}" "$stage/bin/"
strip --strip-debug "$stage"/bin/*
# The OpenGL front ends (libglvnd) stay the target's: they pick its driver.
skip='^(libEGL|libGL|libGLX|libOpenGL|libGLdispatch|libGLESv2)\.so'
for p in "${programs[@]}"; do ldd "$p"; done | awk '/=> \// {print $3} /^\t\/lib64\/ld-linux/ {print $1}' |
  sort -u | while read -r lib; do
    base=$(basename "$lib")
    [[ $base =~ $skip ]] && continue
    cp -L "$lib" "$stage/lib/$base"
  done
strip --strip-unneeded "$stage"/lib/* 2>/dev/null || true
# Each file compressed alone and the files packed into parts of at most PART_MB, so that a
# bundle can travel in pieces where one transfer is size-limited.
part_bytes=$(( ${PART_MB:-48} * 1000 * 1000 ))
(cd "$stage" && ls bin/* lib/* | xargs -P "$(nproc)" -I{} xz -9e {})
rm -f "$out"/part*.tar
# First fit, largest file first.
(cd "$stage" && du -b bin/*.xz lib/*.xz | sort -rn) | awk -v cap="$part_bytes" '{
    for (p = 1; p <= n && used[p] + $1 > cap; ++p) {}
    if (p > n) n = p
    used[p] += $1
    print p, $2
  }' | while read -r part file; do tar -C "$stage" -rf "$out/part$part.tar" "$file"; done
ls -l "$out"/part*.tar

# The data the benches and the GL tests read: the environment maps, street_a's frame-10 relight
# reference, the frames the stitch bench and test read, and the glTF car the voxelizer test uses.
data=../shared/data
rm -rf "$out/shared"
mkdir -p "$out/shared/data/street_a/pano_hdr" "$out/shared/data/street_a/pano" "$out/shared/data/gltf" \
  "$out/shared/data/street_a/augment/frame_000010"
cp -r "$data/env" "$out/shared/data/"
cp "$data/gltf/ToyCar.glb" "$out/shared/data/gltf/"
cp "$data/street_a/"{rig.json,car.glb,car_pose.json,scene.json,checks.json,trajectory_gt.json} "$out/shared/data/street_a/"
cp "$data/street_a/pano_hdr/000010.exr" "$out/shared/data/street_a/pano_hdr/"
cp "$data/street_a/augment/frame_000010/relight_ref.exr" "$out/shared/data/street_a/augment/frame_000010/"
for f in 0 8 16 20 24 32; do
  n=$(printf '%06d' "$f")
  cp "$data/street_a/pano/$n".* "$out/shared/data/street_a/pano/"
  for cam in "$data"/street_a/rig/*/; do
    c=$(basename "$cam")
    mkdir -p "$out/shared/data/street_a/rig/$c"
    cp "$cam$n".* "$out/shared/data/street_a/rig/$c/"
  done
done
# The programs find the repository (and ../shared beside it) by the path they were built in.
pwd >"$out/source_dir"
du -sh "$out/shared"
