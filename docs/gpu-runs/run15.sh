#!/bin/bash
# GPU run for issue 10, part 4: RDM with its compute reconstruction, end-to-end frame GPU time
# (the layer's timer includes the reconstruction it submits at image release), at the ~9 ms load
# and the fragment-bound one; and fovea_check for RDM (quality with the compute pass).
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /usr/share/vulkan/explicit_layer.d
sed "s|\"libVkLayer_khronos_validation.so\"|\"$G/vl/libVkLayer_khronos_validation.so\"|" vl/VkLayer_khronos_validation.json > /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
b() { echo "== $*"; timeout -k 5 100 examples/bench --scale 1.0 --frames 240 --period 20 "$@" 2>&1 | tail -2; }
for cost in 64 512; do
  for layout in per-eye multiview; do
    b --feature foveation --config 'foveation.method = "rdm"' --shading-cost $cost --layout $layout
  done
  b --feature foveation --config 'foveation.method = "rdm"; foveation.rdm_reconstruction = "fill"' --shading-cost $cost --layout per-eye
  b --feature foveation --config 'foveation.method = "vrs"' --shading-cost $cost --layout per-eye
done
echo "== fovea_check rdm"
timeout -k 5 200 examples/fovea_check --layouts per-eye,side-by-side,multiview --renderings render-pass,dynamic --methods rdm > $OUT/fovea_rdm.txt 2>&1; echo "exit $?" >> $OUT/fovea_rdm.txt
grep -E "^\||OK|exit|FAIL" $OUT/fovea_rdm.txt | tail -10
