#!/bin/bash
# GPU run for issue 12, the user's side on NVIDIA: `stereoshim doctor` (per device: the shading
# rate attachment, what foveation.method = auto picks), xr-scene with the installed implicit layer,
# the mask, VRS foveation and the overlay on under validation, a screenshot asked for mid-run with
# `stereoshim screenshot --wait`, and the overlay's cost in frame GPU time (examples/bench A/B).
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
mkdir -p /usr/share/vulkan/explicit_layer.d
sed "s|\"libVkLayer_khronos_validation.so\"|\"$G/vl/libVkLayer_khronos_validation.so\"|" vl/VkLayer_khronos_validation.json > /usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/libmock_runtime.so" > $G/mock-runtime.json
H=$OUT/home; mkdir -p $H/config/stereoshim $H/data $H/state $H/run; chmod 700 $H/run
E=(env XDG_CONFIG_HOME=$H/config XDG_DATA_HOME=$H/data XDG_STATE_HOME=$H/state XDG_RUNTIME_DIR=$H/run XR_RUNTIME_JSON=$G/mock-runtime.json)
"${E[@]}" ./stereoshim install --user
echo "== doctor"
"${E[@]}" ./stereoshim doctor > $OUT/doctor.txt 2> $OUT/doctor.err; echo "exit $?" >> $OUT/doctor.txt
cat $OUT/doctor.txt
cat > $H/config/stereoshim/config.toml <<TOML
mask.enabled = true
foveation.enabled = true
foveation.method = "vrs"
overlay.enabled = true
screenshot.dir = "$OUT/pictures"
stats.file = "$OUT/layer-stats.jsonl"
TOML
echo "== xr-scene, implicit layer: mask + VRS + overlay, validation, a screenshot mid-run"
"${E[@]}" MOCK_XR_HMD=index MOCK_XR_EXIT_AFTER=3000 MOCK_XR_CAPTURE=$OUT/capture MOCK_XR_CAPTURE_FRAMES=300 \
  timeout -k 5 120 ./xr-scene --scale 1.0 --shading-cost 64 --rendering dynamic --validation > $OUT/app.txt 2>&1 &
app=$!
sleep 3
"${E[@]}" timeout -k 5 60 ./stereoshim screenshot --wait --timeout 30; echo "screenshot exit $?"
wait $app; echo "xr-scene exit $?"
tail -3 $OUT/app.txt
ls -la $OUT/pictures $OUT/capture | head -20
cp $OUT/capture/frame-00300-layer-1-quad.png $OUT/overlay-h100.png
cat $OUT/pictures/*.json 2>/dev/null | head -30
grep -i "overlay\|screenshot\|vrs" $H/state/stereoshim/stereoshim.log | head -20
# A/B in one process: the bench switches overlay.enabled live (the frame's `overlay_enabled`).
b() { echo "== $*"; timeout -k 5 100 examples/bench --scale 1.0 --frames 480 --period 20 "$@" 2>&1 | tail -3; }
b --feature overlay --shading-cost 64 --layout per-eye
b --feature overlay --shading-cost 0 --app-args "--empty" --layout per-eye
b --feature overlay --shading-cost 64 --layout multiview
