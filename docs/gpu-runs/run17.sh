#!/bin/bash
# GPU run for issue 10, part 6: the reuse draw as a grid of classified tiles (culled / full /
# mixed, from the source depth reduced per tile after the copy). Quality at full size with
# validation, then the frame GPU time at shading cost 0 / 64 / 512, alone and with everything on.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /usr/share/vulkan/explicit_layer.d
sed "s|\"libVkLayer_khronos_validation.so\"|\"$G/vl/libVkLayer_khronos_validation.so\"|" vl/VkLayer_khronos_validation.json > /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
echo "== far_field_check (validation on)"
timeout -k 5 300 examples/far_field_check --layouts per-eye,multiview,side-by-side > $OUT/ffc.txt 2>&1; echo "exit $?" >> $OUT/ffc.txt
grep -E "^\||exit|panicked" $OUT/ffc.txt | head -30
b() { echo "== $*"; timeout -k 5 100 examples/bench --scale 1.0 --frames 240 --period 20 "$@" 2>&1 | tail -2; }
for cost in 0 64 512; do
  b --feature far_field --app-args "--submit-depth" --shading-cost $cost --layout per-eye
done
b --feature far_field --config 'far_field.split_m = 1000000.0' --app-args "--submit-depth" --shading-cost 0 --layout per-eye
b --feature far_field --config 'far_field.shift = "depth"; far_field.split_px = 4' --app-args "--submit-depth" --shading-cost 64 --layout per-eye
b --feature far_field --app-args "--submit-depth" --shading-cost 64 --layout multiview
b --feature mask,foveation --app-args "--submit-depth" --shading-cost 64 --layout per-eye
b --feature mask,foveation,far_field --config 'far_field.shift = "depth"; far_field.split_px = 4' --app-args "--submit-depth" --shading-cost 64 --layout per-eye
b --feature mask,foveation,far_field --config 'far_field.shift = "depth"; far_field.split_px = 4' --app-args "--submit-depth" --shading-cost 512 --layout per-eye
