#!/bin/bash
# GPU run for issue 10, part 8: the compute copy (replacing the image copies of single-sampled
# sources) with tiles reduced in the same pass. Quality at full size with validation, frame GPU
# time at shading cost 0 / 64 / 512 alone and with everything on, and the cost of the usage the
# layer adds (SAMPLED + TRANSFER_SRC on attachments) with every feature off.
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
grep -E "^\| (per|multi|side)|exit|panicked" $OUT/ffc.txt | cut -d'|' -f2-12 | head -14
timeout -k 5 120 examples/far_field_check --layouts per-eye --settings infinity:1,depth:4 --app-args "--depth reverse --rendering dynamic" > $OUT/ffc_rev.txt 2>&1; echo "exit $?" >> $OUT/ffc_rev.txt
grep -E "^\| per|exit|panicked" $OUT/ffc_rev.txt | cut -d'|' -f2-12 | head
b() { echo "== $*"; timeout -k 5 100 examples/bench --scale 1.0 --frames 240 --period 20 "$@" 2>&1 | tail -2; }
for cost in 0 64 512; do
  b --feature far_field --app-args "--submit-depth" --shading-cost $cost --layout per-eye
done
b --feature far_field --config 'far_field.split_m = 1000000.0' --app-args "--submit-depth" --shading-cost 0 --layout per-eye
b --feature far_field --config 'far_field.shift = "depth"; far_field.split_px = 4' --app-args "--submit-depth" --shading-cost 64 --layout per-eye
b --feature far_field --config 'far_field.split_px = 4' --app-args "--submit-depth" --shading-cost 64 --layout per-eye
b --feature far_field --config 'far_field.shift = "depth"' --app-args "--submit-depth" --shading-cost 64 --layout per-eye
b --feature far_field --app-args "--submit-depth" --shading-cost 64 --layout multiview
b --feature far_field --app-args "--submit-depth" --shading-cost 64 --layout side-by-side
b --feature mask,foveation --app-args "--submit-depth" --shading-cost 64 --layout per-eye
b --feature mask,foveation,far_field --config 'far_field.shift = "depth"; far_field.split_px = 4' --app-args "--submit-depth" --shading-cost 64 --layout per-eye
b --feature mask,foveation,far_field --app-args "--submit-depth" --shading-cost 64 --layout per-eye
b --feature mask,foveation,far_field --config 'far_field.shift = "depth"; far_field.split_px = 4' --app-args "--submit-depth" --shading-cost 512 --layout per-eye
echo "== usage cost with every feature off: no layer vs layer, 300 frames, shading-cost 64"
printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/libmock_runtime.so" > $G/mock-runtime.json
med() { grep -o '"gpu_time_ms": *[0-9.]*' "$1" | sed 's/.*: *//' | tail -n +20 | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
for i in 1 2 3; do
  for mode in off on; do
    d=$OUT/usage-$mode-$i; mkdir -p $d
    run=(); [ $mode = on ] && run=(./stereoshim run --)
    env XR_RUNTIME_JSON=$G/mock-runtime.json MOCK_XR_HMD=index MOCK_XR_EXIT_AFTER=300 \
      XDG_STATE_HOME=$d XDG_CONFIG_HOME=$d XDG_RUNTIME_DIR=$d "${run[@]}" ./xr-scene --scale 1.0 --shading-cost 64 --submit-depth --stats $d/stats.json > $d/out.txt 2>&1
    echo "run $i layer $mode: median GPU ms $(med $d/stats.json)"
  done
done
