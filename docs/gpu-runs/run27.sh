#!/bin/bash
# GPU run for issue 21: the upscale end to end. xr-scene on the mock runtime (Index at 100 %,
# per-eye), the layer's config switched between whole xr-scene instances (the told size is
# latched per instance; examples/bench --feature ...upscale uses --instances), each frame's mode
# and end-to-end GPU time (every submission, the upscale's included) from the layer's own
# stats.file. (1) upscale alone at scale 0.7 and 0.77 at the ~9 ms load (--shading-cost 64);
# (2) its cost with nothing shaded (--empty); (3) everything on (mask + VRS + far field + upscale
# 0.77) at ~9 ms and fragment-bound (--shading-cost 256), and each feature's share (the live A/B
# of mask, mask + VRS, mask + VRS + far field within one run, as before).
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
  grep -E "^\| index|phases|far field" $OUT/$1.txt | head -4
}
b upscale070 64 upscale 'upscale.scale = 0.7' ''
b upscale077 64 upscale 'upscale.scale = 0.77' ''
b upscale070_fovea 64 upscale 'upscale.scale = 0.7; upscale.fovea_only = true' ''
b upscale070_bilinear 64 upscale 'upscale.scale = 0.7; upscale.method = "bilinear"' ''
b upscale099_empty 64 upscale 'upscale.scale = 0.99' '--empty'
b upscale077_multiview 64 upscale 'upscale.scale = 0.77' '--layout multiview'
b all64 64 mask,foveation,far_field,upscale "upscale.scale = 0.77; $VRS" '--submit-depth'
b all256 256 mask,foveation,far_field,upscale "upscale.scale = 0.77; $VRS" '--submit-depth'
b share_mask64 64 mask "$VRS" '--submit-depth'
b share_vrs64 64 mask,foveation "$VRS" '--submit-depth'
b share_ff64 64 mask,foveation,far_field "$VRS" '--submit-depth'
b share_mask256 256 mask "$VRS" '--submit-depth'
b share_vrs256 256 mask,foveation "$VRS" '--submit-depth'
b share_ff256 256 mask,foveation,far_field "$VRS" '--submit-depth'
examples/upscale_bench --width 2016 --height 2240 --scale 0.77 --runs 9 --repeat 30 --input rgba8 | tail -2
