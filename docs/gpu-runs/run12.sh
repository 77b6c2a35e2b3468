#!/bin/bash
# GPU run for issue 10, part 1: the far field's quality at full size (far_field_check) and its cost
# of adding TRANSFER_SRC with the feature off.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /usr/share/vulkan/explicit_layer.d
sed "s|\"libVkLayer_khronos_validation.so\"|\"$G/vl/libVkLayer_khronos_validation.so\"|" vl/VkLayer_khronos_validation.json > /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
nvidia-smi -L
echo "== far_field_check (validation on)"
timeout -k 5 300 examples/far_field_check --layouts per-eye,multiview,side-by-side > $OUT/ffc.txt 2>&1; echo "exit $?" >> $OUT/ffc.txt
grep -E "^\||far_field_check|exit|panicked" $OUT/ffc.txt | head -30
echo "== far_field_check reverse depth + msaa? (per-eye, reverse)"
timeout -k 5 120 examples/far_field_check --layouts per-eye --settings infinity:1,depth:4 --app-args "--depth reverse --rendering dynamic" > $OUT/ffc_rev.txt 2>&1; echo "exit $?" >> $OUT/ffc_rev.txt
grep -E "^\| per|far_field_check|exit|panicked" $OUT/ffc_rev.txt | head
echo "== usage cost with the feature off: xr-scene without the layer vs with the layer (features off), 300 frames, shading-cost 64"
med() { grep -o '"gpu_time_ms": *[0-9.]*' "$1" | sed 's/.*: *//' | tail -n +20 | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
for i in 1 2 3; do
  for mode in off on; do
    d=$OUT/usage-$mode-$i; mkdir -p $d
    run=(); [ $mode = on ] && run=(./stereoshim run --)
    env XR_RUNTIME_JSON=$G/test-output/mock-runtime.json MOCK_XR_HMD=index MOCK_XR_EXIT_AFTER=300 \
      XDG_STATE_HOME=$d XDG_CONFIG_HOME=$d XDG_RUNTIME_DIR=$d "${run[@]}" ./xr-scene --scale 1.0 --shading-cost 64 --submit-depth --stats $d/stats.json > $d/out.txt 2>&1
    echo "run $i layer $mode: median GPU ms $(med $d/stats.json) ($(grep -c stereoshim $d/stereoshim/stereoshim.log 2>/dev/null || echo 0) log lines)"
  done
done
