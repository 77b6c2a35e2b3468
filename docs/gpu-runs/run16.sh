#!/bin/bash
# GPU run for issue 10, part 5: where the far field's fixed cost goes (shading cost 0):
# default; nothing reused (split 1e6 m: every reuse fragment discards after its gather);
# --empty (every destination pixel reused: the all-write cost).
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
b() { echo "== $*"; timeout -k 5 100 examples/bench --scale 1.0 --frames 240 --period 20 "$@" 2>&1 | tail -2; }
b --feature far_field --app-args "--submit-depth" --shading-cost 0 --layout per-eye
b --feature far_field --config 'far_field.split_m = 1000000.0' --app-args "--submit-depth" --shading-cost 0 --layout per-eye
b --feature far_field --app-args "--submit-depth --empty" --shading-cost 0 --layout per-eye
b --feature far_field --app-args "--submit-depth" --shading-cost 0 --layout multiview
