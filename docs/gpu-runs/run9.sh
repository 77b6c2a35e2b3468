#!/bin/bash
# GPU re-run for issue 9 (the chassis rewrite): fovea_check over every layout x rendering x method,
# also with command buffers recorded once, and VRS with the moving gaze; validation on.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /usr/share/vulkan/explicit_layer.d
sed "s|\"libVkLayer_khronos_validation.so\"|\"$G/vl/libVkLayer_khronos_validation.so\"|" vl/VkLayer_khronos_validation.json > /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
nvidia-smi -L
echo "== fovea_check all"
timeout -k 5 250 examples/fovea_check --layouts per-eye,side-by-side,multiview --renderings render-pass,render-pass2,dynamic --methods vrs,rdm > $OUT/fovea_all.txt 2>&1; echo "exit $?" >> $OUT/fovea_all.txt
tail -22 $OUT/fovea_all.txt
echo "== fovea_check record-once"
timeout -k 5 200 examples/fovea_check --layouts per-eye,side-by-side,multiview --renderings render-pass,dynamic --methods vrs,rdm --app-args "--record-once" > $OUT/fovea_once.txt 2>&1; echo "exit $?" >> $OUT/fovea_once.txt
tail -16 $OUT/fovea_once.txt
