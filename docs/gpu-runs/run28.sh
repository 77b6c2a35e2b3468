#!/bin/bash
# GPU run for issue 21, after run27: upscale.method = cas, and EASU + RCAS again in the same lease
# (the ~9 ms load, scale 0.7 and 0.77; xr-scene --quad adds a quad layer from a static swapchain).
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export PATH=$G:$PATH
nvidia-smi -L
printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/libmock_runtime.so" > $G/mock-runtime.json
b() { # name, cost, feature, config, app args
  echo "== $1"
  timeout -k 5 150 examples/bench --hmd index --scale 1.0 --shading-cost $2 --frames 240 --period 30 --layout per-eye --feature $3 --config "$4" --app-args "--rendering dynamic $5" > $OUT/$1.txt 2>&1; echo "exit $?" >> $OUT/$1.txt
  grep -E "^\| index|phases" $OUT/$1.txt | head -3
}
b easu070 64 upscale 'upscale.scale = 0.7' ''
b cas070 64 upscale 'upscale.scale = 0.7; upscale.method = "cas"' ''
b easu077 64 upscale 'upscale.scale = 0.77' ''
b cas077 64 upscale 'upscale.scale = 0.77; upscale.method = "cas"' ''
b easu077_quad 64 upscale 'upscale.scale = 0.77' '--quad'
