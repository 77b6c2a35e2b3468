#!/bin/bash
# GPU proof, part 2: hello_xr (a Vulkan 1.0 app linking libvulkan) gets VRS through the layer.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /usr/share/vulkan/explicit_layer.d
sed "s|\"libVkLayer_khronos_validation.so\"|\"$G/vl/libVkLayer_khronos_validation.so\"|" vl/VkLayer_khronos_validation.json > /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
timeout -k 5 300 examples/fovea_check --app hello_xr:Vulkan2 --methods vrs,rdm > $OUT/fovea_hello_xr.txt 2>&1; echo "exit $?" >> $OUT/fovea_hello_xr.txt
cat $OUT/fovea_hello_xr.txt
L=test-output/fovea-check-hello_xr-Vulkan2-vrs
grep -h "fragment shading rate\|adding \[\|capabilities\|WARN" $L/state/stereoshim/stereoshim.log | cut -c1-300 | head -8
echo "validation errors (plain, vrs, rdm):"; for d in test-output/fovea-check-hello_xr-Vulkan2*; do grep -c "Validation Error" $d/output.txt; grep -c "Inserted device layer \"VK_LAYER_KHRONOS_validation\"" $d/output.txt; done
