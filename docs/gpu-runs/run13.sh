#!/bin/bash
# GPU run for issue 10, part 2: live A/B benches of the far field (both shifts, split_px 1 and 4),
# and of mask + foveation + far field together, at a fragment-bound load (--shading-cost 512) and a
# lighter one (--shading-cost 64); end-to-end frame GPU time from the layer's timer.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
b() { echo "== $*"; timeout -k 5 100 examples/bench --scale 1.0 --frames 240 --period 20 "$@" 2>&1 | tail -3; }
for cost in 512 64; do
  for s in "infinity 1" "infinity 4" "depth 1" "depth 4"; do
    set -- $s
    b --feature far_field --config "far_field.shift = \"$1\"; far_field.split_px = $2" --app-args "--submit-depth" --shading-cost $cost --layout per-eye
  done
  b --feature mask,foveation,far_field --config 'far_field.shift = "depth"; far_field.split_px = 4' --app-args "--submit-depth" --shading-cost $cost --layout per-eye
  b --feature mask,foveation --app-args "--submit-depth" --shading-cost $cost --layout per-eye
done
b --feature far_field --app-args "--submit-depth" --shading-cost 512 --layout multiview
b --feature far_field --app-args "--submit-depth" --shading-cost 512 --layout side-by-side
echo "== far field's own cost, nothing shaded"
timeout -k 5 100 examples/bench --scale 1.0 --frames 400 --period 40 --feature far_field --app-args "--submit-depth --empty" --layout per-eye 2>&1 | tail -3
