#!/bin/bash
# GPU run for issue 10, part 7 (measurement build with STEREOSHIM_FF_SKIP switches, not committed):
# what the far field's fixed cost is made of, nothing reused (split 1e6 m), shading cost 0.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
b() { echo "== skip=${STEREOSHIM_FF_SKIP:-} $*"; timeout -k 5 100 examples/bench --scale 1.0 --frames 240 --period 20 "$@" 2>&1 | tail -2 | head -1; }
for skip in none color depth color,depth reduce draw color,depth,reduce,draw; do
  STEREOSHIM_FF_SKIP=$skip b --feature far_field --config 'far_field.split_m = 1000000.0' --app-args "--submit-depth" --shading-cost 0 --layout per-eye
done
STEREOSHIM_FF_SKIP=color b --feature far_field --app-args "--submit-depth" --shading-cost 0 --layout per-eye
