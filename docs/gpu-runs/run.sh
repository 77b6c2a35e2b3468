#!/bin/bash
# GPU proof for issue 8: VRS for Vulkan 1.0 apps (xr-scene --vulkan-api 1.0, hello_xr -g Vulkan2),
# RDM with secondary command buffers; validation on.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /usr/share/vulkan/explicit_layer.d
sed "s|\"libVkLayer_khronos_validation.so\"|\"$G/vl/libVkLayer_khronos_validation.so\"|" vl/VkLayer_khronos_validation.json > /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
# glvnd (libGLdispatch, which the NVIDIA ICD needs) comes from the .gl debs unpacked into /, as the device notes do
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
nvidia-smi -L
echo "== fovea_check Vulkan 1.0 xr-scene"
timeout -k 5 200 examples/fovea_check --layouts per-eye,side-by-side --renderings render-pass,render-pass2 --methods vrs,rdm --app-args "--vulkan-api 1.0" > $OUT/fovea_vk10.txt 2>&1; echo "exit $?" >> $OUT/fovea_vk10.txt
tail -12 $OUT/fovea_vk10.txt
echo "== fovea_check hello_xr -g Vulkan2"
timeout -k 5 200 examples/fovea_check --app hello_xr:Vulkan2 --methods vrs,rdm > $OUT/fovea_hello_xr.txt 2>&1; echo "exit $?" >> $OUT/fovea_hello_xr.txt
tail -8 $OUT/fovea_hello_xr.txt
grep -h "fragment shading rate\|adding \[\|capabilities" test-output/fovea-check-hello_xr-Vulkan2-vrs/state/stereoshim/stereoshim.log | cut -c1-400 | head -5
grep -c "Validation Error" test-output/fovea-check-hello_xr-Vulkan2-vrs/output.txt
echo "== fovea_check RDM with secondaries, 1.3"
timeout -k 5 150 examples/fovea_check --layouts per-eye,side-by-side,multiview --renderings render-pass,dynamic --methods rdm --app-args "--secondary" > $OUT/fovea_secondary.txt 2>&1; echo "exit $?" >> $OUT/fovea_secondary.txt
tail -3 $OUT/fovea_secondary.txt
tar czf $OUT/logs.tgz test-output/*/state/stereoshim/stereoshim.log test-output/fovea-check-hello_xr*/output.txt 2>/dev/null
