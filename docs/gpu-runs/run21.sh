#!/bin/bash
# GPU run for issue 12, after the screenshot's read-back buffers moved to the layer's thread: what
# a screenshot costs the app inside xrReleaseSwapchainImage, three screenshots in one run (xr-scene,
# index profile at full size, the mask, VRS foveation and the overlay on, validation on).
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
"${E[@]}" ./stereoshim install --user > /dev/null
cat > $H/config/stereoshim/config.toml <<TOML
mask.enabled = true
foveation.enabled = true
foveation.method = "vrs"
overlay.enabled = true
screenshot.dir = "$OUT/pictures"
TOML
"${E[@]}" MOCK_XR_HMD=index MOCK_XR_EXIT_AFTER=4000 timeout -k 5 120 ./xr-scene --scale 1.0 --shading-cost 64 --rendering dynamic --validation > $OUT/app.txt 2>&1 &
app=$!
for i in 1 2 3; do
  sleep 2
  "${E[@]}" timeout -k 5 60 ./stereoshim screenshot --wait --timeout 30 > /dev/null; echo "screenshot $i exit $?"
done
wait $app; echo "xr-scene exit $?"; tail -1 $OUT/app.txt
grep "copies submitted\|screenshot of frame" $H/state/stereoshim/stereoshim.log
ls $OUT/pictures | wc -l
