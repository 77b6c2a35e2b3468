#!/bin/bash
# GPU check of the final state of issue 9: VRS (pure planning rule) and RDM, every layout x rendering, plus record-once.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /usr/share/vulkan/explicit_layer.d
sed "s|\"libVkLayer_khronos_validation.so\"|\"$G/vl/libVkLayer_khronos_validation.so\"|" vl/VkLayer_khronos_validation.json > /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
timeout -k 5 250 examples/fovea_check --layouts per-eye,side-by-side,multiview --renderings render-pass,render-pass2,dynamic --methods vrs,rdm > $OUT/fovea_all.txt 2>&1; echo "exit $?" >> $OUT/fovea_all.txt
grep -c "| 0 | 3[78]\." $OUT/fovea_all.txt; tail -3 $OUT/fovea_all.txt
timeout -k 5 200 examples/fovea_check --layouts per-eye,side-by-side,multiview --renderings render-pass,dynamic --methods vrs,rdm --app-args "--record-once" > $OUT/fovea_once.txt 2>&1; echo "exit $?" >> $OUT/fovea_once.txt
tail -3 $OUT/fovea_once.txt
timeout -k 5 140 examples/bench --feature foveation --config 'foveation.method = "vrs"' --app-args "--rendering dynamic" --scale 1.0 --shading-cost 512 --frames 240 --period 20 --layout multiview 2>&1 | tail -1
