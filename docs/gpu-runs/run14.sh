#!/bin/bash
# GPU run for issue 10, part 3: the far field's cost after the gather change, and its overhead with
# next to nothing shaded (--shading-cost 0).
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
b() { echo "== $*"; timeout -k 5 100 examples/bench --scale 1.0 --frames 240 --period 20 "$@" 2>&1 | tail -2; }
for cost in 0 64 512; do
  b --feature far_field --app-args "--submit-depth" --shading-cost $cost --layout per-eye
done
b --feature far_field --config 'far_field.shift = "depth"; far_field.split_px = 4' --app-args "--submit-depth" --shading-cost 64 --layout per-eye
b --feature mask,foveation,far_field --config 'far_field.shift = "depth"; far_field.split_px = 4' --app-args "--submit-depth" --shading-cost 64 --layout per-eye
