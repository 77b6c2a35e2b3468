#!/bin/bash
# GPU run for issue 21, after run28: the upscale skipping the tiles the lens never shows
# (upscale.skip_hidden, on by default: the mock's Index mesh is SteamVR's published one) against
# the same upscale without skipping, and multisampled swapchains (xr-scene --swapchain-samples 4:
# the layer resolves them before the upscale). Same harness as run27: xr-scene on the mock
# runtime (Index at 100 %, per-eye), the config switched between whole xr-scene instances, each
# frame's end-to-end GPU time (the upscale's submission included) and the upscale's own GPU time
# from the layer's stats.file. Then everything on (mask + VRS + far field + upscale 0.77).
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export PATH=$G:$PATH
nvidia-smi -L
printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/libmock_runtime.so" > $G/mock-runtime.json
VRS='foveation.method = "vrs"; foveation.eye_tracking = "off"'
b() { # name, cost, feature, config, app args
  echo "== $1"
  timeout -k 5 150 examples/bench --hmd index --scale 1.0 --shading-cost $2 --frames 240 --period 30 --layout per-eye --feature $3 --config "$4" --app-args "--rendering dynamic $5" > $OUT/$1.txt 2>&1; echo "exit $?" >> $OUT/$1.txt
  grep -E "^\| index|phases" $OUT/$1.txt | head -3
}
b upscale070 64 upscale 'upscale.scale = 0.7' ''
b upscale070_noskip 64 upscale 'upscale.scale = 0.7; upscale.skip_hidden = false' ''
b upscale077 64 upscale 'upscale.scale = 0.77' ''
b upscale077_noskip 64 upscale 'upscale.scale = 0.77; upscale.skip_hidden = false' ''
b upscale077_cas 64 upscale 'upscale.scale = 0.77; upscale.method = "cas"' ''
b upscale077_bilinear 64 upscale 'upscale.scale = 0.77; upscale.method = "bilinear"' ''
b upscale077_fovea 64 upscale 'upscale.scale = 0.77; upscale.fovea_only = true' ''
b upscale077_msaa4 64 upscale 'upscale.scale = 0.77' '--swapchain-samples 4'
b upscale077_msaa4_noskip 64 upscale 'upscale.scale = 0.77; upscale.skip_hidden = false' '--swapchain-samples 4'
b all64 64 mask,foveation,far_field,upscale "upscale.scale = 0.77; $VRS" '--submit-depth'
b all256 256 mask,foveation,far_field,upscale "upscale.scale = 0.77; $VRS" '--submit-depth'
