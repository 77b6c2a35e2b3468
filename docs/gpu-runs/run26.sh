#!/bin/bash
# GPU run for issue 21 (first piece): the upscale's passes (EASU then RCAS, compute, RGBA16F) at
# the Index's per-eye size from scale 0.77 and 0.7, timed by the device's timestamps
# (examples/upscale_bench; carried: .gpu/examples/upscale_bench, .gl/ the loader debs), from an
# RGBA8 input (what apps render) and from RGBA32F.
set -u
cd "$(dirname "$0")"
for f in ../.gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
nvidia-smi -L
for input in rgba8 rgba32f; do
  for s in 0.77 0.7 0.5; do
    examples/upscale_bench --width 2016 --height 2240 --scale $s --runs 9 --repeat 30 --input $input
  done
done
