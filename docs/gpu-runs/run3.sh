#!/bin/bash
# GPU proof, part 3: a Vulkan 1.0 app that creates its own instance (XR_KHR_vulkan_enable) on a
# runtime that does not list VK_KHR_get_physical_device_properties2 gets VRS through the layer.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /usr/share/vulkan/explicit_layer.d
sed "s|\"libVkLayer_khronos_validation.so\"|\"$G/vl/libVkLayer_khronos_validation.so\"|" vl/VkLayer_khronos_validation.json > /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
export MOCK_XR_DISABLE_EXTENSIONS=VK_KHR_get_physical_device_properties2,VK_KHR_external_memory_capabilities,VK_KHR_external_semaphore_capabilities,VK_KHR_external_fence_capabilities,VK_KHR_external_memory,VK_KHR_external_memory_fd,VK_KHR_external_semaphore,VK_KHR_external_fence
timeout -k 5 200 examples/fovea_check --layouts per-eye,side-by-side --renderings render-pass,render-pass2 --methods vrs --app-args "--vulkan-api 1.0 --vulkan enable" > $OUT/fovea_vk10_enable.txt 2>&1; echo "exit $?" >> $OUT/fovea_vk10_enable.txt
cat $OUT/fovea_vk10_enable.txt
grep -h "listing\|device created" test-output/*vrs/state/stereoshim/stereoshim.log | cut -c1-260 | sort | uniq -c | head -4
