#!/bin/bash
# GPU re-run for issue 9, part 2: the mask and foveation benches (live A/B in one run).
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f / ; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export LD_LIBRARY_PATH=$G/lib:${LD_LIBRARY_PATH:-} PATH=$G/bin:$PATH
for layout in per-eye multiview; do
  echo "== bench mask $layout"
  timeout -k 5 140 examples/bench --scale 1.0 --shading-cost 512 --frames 240 --period 20 --layout $layout 2>&1 | tail -4
done
echo "== bench mask draw cost (--empty)"
timeout -k 5 100 examples/bench --scale 1.0 --frames 400 --period 40 --app-args --empty 2>&1 | tail -3
for layout in per-eye multiview; do
  echo "== bench vrs $layout"
  timeout -k 5 140 examples/bench --feature foveation --config 'foveation.method = "vrs"' --app-args "--rendering dynamic" --scale 1.0 --shading-cost 512 --frames 240 --period 20 --layout $layout 2>&1 | tail -4
done
echo "== bench rdm multiview"
timeout -k 5 140 examples/bench --feature foveation --config 'foveation.method = "rdm"' --app-args "--rendering dynamic" --scale 1.0 --shading-cost 512 --frames 240 --period 20 --layout multiview 2>&1 | tail -4
