#!/bin/bash
# GPU run for issue 22: the FOV cut (view.fov_cut = lens) on the Index profile at 100 %
# (2016x2240 per eye), the ~9 ms load, per-eye, dynamic rendering; alone, and with everything on
# (mask + VRS + far field + upscale 0.77, the cut first). The cut is latched per XR instance, so
# examples/bench alternates whole xr-scene instances (as for the upscale, run27) and takes each
# frame's mode and end-to-end GPU time from the layer's stats.file.
set -u
cd "$(dirname "$0")"
. ./prologue.sh
b() { # name, cost, feature, config, app args
  echo "== $1"
  timeout -k 5 150 examples/bench --hmd index --scale 1.0 --shading-cost $2 --frames 240 --period 30 --layout per-eye --feature $3 --config "$4" --app-args "--rendering dynamic $5" > $OUT/$1.txt 2>&1; echo "exit $?" >> $OUT/$1.txt
  grep -E "^\| index|exit" $OUT/$1.txt | head -3
}
b cut64 64 fov_cut '' ''
b cut256 256 fov_cut '' ''
b cut64_multiview 64 fov_cut '' '--layout multiview'
b all_but_cut64 64 mask,foveation,far_field,upscale "upscale.scale = 0.77; $VRS" '--submit-depth'
b all64 64 mask,foveation,far_field,fov_cut,upscale "upscale.scale = 0.77; $VRS" '--submit-depth'
b all256 256 mask,foveation,far_field,fov_cut,upscale "upscale.scale = 0.77; $VRS" '--submit-depth'
