#!/usr/bin/env bash
# Runs the GL tests and the GPU benches from a bundle made by scripts/gpu_bundle.sh, on a machine
# with a GPU driver but without our build dependencies, from the repository root. Each step has
# its own time limit so that a slow one cannot cost the others; everything lands in OUT_DIR,
# packed into results.tar.gz at the end, with log.txt beside it.
#   [PARTS_DIR=DIR] scripts/gpu_run.sh BUNDLE_DIR OUT_DIR [quick|stages|shade]
# quick: small sizes, to check the bundle itself; stages: per-stage timings of lighting and render;
# shade: the shading's time, with list options and shader variants (VARIANTS, default BUNDLE_DIR/var:
# NAME/* files that replace shaders/*; scripts/shade_probes.py writes the probes that leave one part out).
set -uo pipefail
bundle=$(cd "${1:?bundle directory}" && pwd)
out=$(mkdir -p "${2:?output directory}" && cd "$2" && pwd)
quick=${3:-}
log=$out/log.txt
root=$PWD
work=$(mktemp -d)
results=$work/results
mkdir -p "$results"

say() { echo "[$(date +%T)] $*" | tee -a "$log"; }
budget=${BUDGET:-100000}  # seconds: a step that could end past it is skipped
step() {  # step NAME SECONDS COMMAND...
  local name=$1 limit=$2
  shift 2
  if [ $((SECONDS + limit)) -gt "$budget" ]; then
    say "== $name skipped: ${limit}s would pass the ${budget}s budget"
    return
  fi
  say "== $name (limit ${limit}s): $*"
  local t0=$SECONDS
  timeout --kill-after=5 "$limit" "$@" >"$results/$name.out" 2>"$results/$name.err"
  local rc=$?
  say "   $name: rc $rc in $((SECONDS - t0)) s"
  tail -n 25 "$results/$name.out" "$results/$name.err" >>"$log"
}

# The parts may have travelled apart: PARTS_DIR holds those that are not in the bundle directory.
for p in "$bundle"/part*.tar ${PARTS_DIR:+"$PARTS_DIR"/part*.tar}; do tar -C "$work" -xf "$p"; done
ls "$work"/bin/*.xz "$work"/lib/*.xz | xargs -P "$(nproc)" -n 8 unxz
bin=$work/bin
# The programs find the repository and ../shared by the paths they were built with.
src=$(cat "$bundle/source_dir")
if [ ! -e "$src" ]; then
  mkdir -p "$(dirname "$src")" && ln -s "$root" "$src"
fi
if [ ! -e "$src/../shared" ]; then ln -s "$bundle/shared" "$src/../shared"; fi
loader=$(ls "$work"/lib/ld-linux-x86-64.so.* | head -1)
# Our C library and loader travel with the programs, so the target's own may be older or newer.
libpath=$work/lib
# The driver's own libraries (libEGL_nvidia and what it loads), where the target keeps them apart.
for d in /usr/local/nvidia/lib64 /usr/local/nvidia/lib; do [ -d "$d" ] && libpath=$libpath:$d; done
for p in odvr engine_gl_tests capture_gl_tests; do
  printf '#!/bin/sh\nexec %s --library-path %s %s "$@"\n' "$loader" "$libpath" "$bin/$p" >"$work/$p"
  chmod +x "$work/$p"
done
odvr=$work/odvr
cd "$src"

say "machine: $(nproc) cores; $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null || echo 'no nvidia-smi')"
step info 30 "$odvr" info --json
env=$src/../shared/data/env
if [ "$quick" = stages ]; then
  # Where the time goes, stage by stage, before whole benches: the lighting transform's levels
  # (cold, then warm), and 1280x720 renders' voxelize, G-buffer, shade, composite and read-back.
  # The players first: bench player crashed (SIGSEGV) on the H200 at a37eb02 and not on llvmpipe.
  step player_gl_debug 60 env ODVR_GL_DEBUG=1 "$odvr" bench player --size 640x360 --frames 3 --out "$results/player_debug.md"
  step player 60 "$odvr" bench player --size 1280x720 --frames 30 --out "$results/player.md"
  for run in cold warm; do
    step "light_levels_$run" 30 "$odvr" light "$env/sunset.exr" --device gpu --json
  done
  step light_levels_nopeaks 30 "$odvr" light "$env/sunset.exr" --device gpu --no-peaks --json
  render() { step "render_$1" 60 "$odvr" render --model "$src/media/demo/car.glb" --env "$env/sky.exr" \
    --repeat 10 --out "$results/render_$1.png" --json "${@:2}"; }
  render 720p --size 1280x720
  render 720p_composite --size 1280x720 --composite-only
  render 720p_cone_peaks --size 1280x720 --composite-only --peak-cone-shadows
  render 720p_no_bounce --size 1280x720 --composite-only --no-specular-bounce
  render 720p_lanes2 --size 1280x720 --shade-lanes 2
  render 720p_lanes4 --size 1280x720 --shade-lanes 4
  render 720p_v64_l4 --size 1280x720 --voxels 64 --levels 4
  render 720p_l1 --size 1280x720 --voxels 64 --levels 1
  render 320 --size 320x180
  render 320_lanes1 --size 320x180 --shade-lanes 1
  step player_live 60 "$odvr" bench player --live --frames 30 --out "$results/player_live.md"
  # The GPU stitch's 12.3 ms a frame in parts: upload, passes (GL timestamps), read-back.
  step stitch 30 "$odvr" bench stitch --gpu --repeats 5 --out "$results/stitch"
  step tests_render 150 "$work/engine_gl_tests" --gtest_filter='SgShadePassGL*:PeakShadowGL*:GroundShadowGL*:MonteCarloShadePassGL*:ShadingRateGL*:CompositePassGL*:CountsPassGL*:ResolvePassGL*:GbufferPassGL*:VoxelizePassGL*:HardCasesGL*:CyclesReference*GL*'
  step light_park 60 "$odvr" bench light --gpu --widths 2048 --max-levels 5 --no-least-squares \
    --repeats 9 --min-time-ms 200 --out "$results/light_park" "$env/park.exr"
  # The 1280x720 row timed both as the bench renders (read back) and as the window player does.
  step render_hd 60 "$odvr" bench render --only sunset_glossy --levels 5 --cones 7 --voxels 128 --mc-samples 16 \
    --no-lobe-modes --no-ground-bounce --out "$results/render_hd"
elif [ "$quick" = shade ]; then
  # Where the shading's time goes: 1280x720 renders as the players make them, with the lighting
  # lists' options, then with each shader variant in VARIANTS/NAME (ODVR_SHADER_DIR).
  render() { step "render_$1" 60 "$odvr" render --model "$src/media/demo/car.glb" --env "$env/sky.exr" \
    --repeat 10 --out "$results/render_$1.png" --json "${@:2}"; }
  render 720p --size 1280x720
  render 720p_composite --size 1280x720 --composite-only
  render 720p_cone_peaks --size 1280x720 --composite-only --peak-cone-shadows
  render 320 --size 320x180
  render 320_lanes1 --size 320x180 --shade-lanes 1
  render 720p_bin_depth --size 1280x720 --composite-only --bin-depth
  render 720p_cutoff1e-2 --size 1280x720 --composite-only --overlap-cutoff 0.01
  render 720p_v64_l4 --size 1280x720 --composite-only --voxels 64 --levels 4
  render 720p_traced_ground --size 1280x720 --composite-only --ground-lit-map 0
  render 720p_rate2 --size 1280x720 --composite-only --shading-rate 2
  render 720p_no_bounce --size 1280x720 --composite-only --no-specular-bounce
  render 720p_v64_l4_rate2 --size 1280x720 --composite-only --voxels 64 --levels 4 --shading-rate 2
  render 720p_v64_l4_traced_ground --size 1280x720 --composite-only --voxels 64 --levels 4 --ground-lit-map 0
  for v in "${VARIANTS:-$bundle/var}"/*/; do
    [ -d "$v" ] || continue
    name=$(basename "$v")
    step "render_720p_$name" 60 env ODVR_SHADER_DIR="$v" "$odvr" render --model "$src/media/demo/car.glb" \
      --env "$env/sky.exr" --repeat 10 --out "$results/render_720p_$name.png" --json --size 1280x720 --composite-only
  done
  step player 60 "$odvr" bench player --size 1280x720 --frames 30 --out "$results/player.md"
  step player_l5 60 "$odvr" bench player --size 1280x720 --frames 30 --levels 5 --voxels 128 \
    --out "$results/player_l5.md"
  step player_rate1 60 "$odvr" bench player --size 1280x720 --frames 30 --shading-rate 1 \
    --out "$results/player_rate1.md"
  step player_live 60 "$odvr" bench player --live --size 1280x720 --frames 30 --out "$results/player_live.md"
  step render_hd 60 "$odvr" bench render --only sunset_glossy --levels 5 --cones 7 --voxels 128 --mc-samples 16 \
    --no-lobe-modes --no-ground-bounce --out "$results/render_hd"
elif [ "$quick" = quick ]; then
  step tests_engine 300 "$work/engine_gl_tests" --gtest_filter='ContextGL.*:ComputeGL.*'
  step bench_light 300 "$odvr" bench light --gpu --widths 1024 --max-levels 3 --no-least-squares --repeats 1 \
    --min-time-ms 0 --out "$results/light" "$src/../shared/data/env/park.exr"
  step bench_render 300 "$odvr" bench render --only sky_diffuse --levels 3 --cones 7 \
    --voxels 64 --mc-samples 4 --no-lobe-modes --no-ground-bounce --out "$results/render"
else
  # On the H200 one map took ~35 s per width; a cold driver compiled the GL tests' shaders for
  # over 90 s (the second run took 12 s).
  light() { step "light_$1" "$2" "$odvr" bench light --gpu --widths 2048 --max-levels 6 --no-least-squares \
    --repeats 9 --min-time-ms 200 --out "$results/light_$1" "$env/$1.exr"; }
  step tests_engine 150 "$work/engine_gl_tests" --gtest_filter='*GL.*:*/*GL.*'
  step tests_capture 30 "$work/capture_gl_tests" --gtest_filter='*GL.*:*/*GL.*'
  # Stage by stage: the lighting transform's levels, and a 1280x720 render's voxelize, G-buffer,
  # shade, composite and read-back.
  step light_levels 30 "$odvr" light "$env/sunset.exr" --device gpu --json
  step render_720p 60 "$odvr" render --model "$src/media/demo/car.glb" --env "$env/sky.exr" --size 1280x720 \
    --repeat 10 --out "$results/render_720p.png" --json
  light park 60
  light sunset 60
  step player 50 "$odvr" bench player --size 1280x720 --frames 30 --out "$results/player.md"
  step render_hd 40 "$odvr" bench render --only sunset_glossy --levels 5 --cones 7 --voxels 128 --mc-samples 16,256 \
    --no-lobe-modes --out "$results/render_hd"
  step player_live 40 "$odvr" bench player --live --frames 30 --out "$results/player_live.md"
  step render 120 "$odvr" bench render --mc-samples 4,16,64,256,1024 --out "$results/render"
  step stitch 45 "$odvr" bench stitch --gpu --repeats 5 --out "$results/stitch"
  light sky 60
  light dawn 60
fi
tar -C "$work" -czf "$out/results.tar.gz" results
say "done"
