#!/bin/bash
# GPU run for issue 33, item 3: an app that draws the hidden-area mesh itself (xr-scene
# --draw-hidden-area: the runtime's mesh, black at the near depth, first in every eye pass, as
# OpenVR games drawing GetHiddenAreaMesh do) with the layer's mask switched off (A) and on (B)
# every 30 frames by examples/bench: GPU time and shaded fragments with both against the app's
# mask alone. Control: the same app without its own mask (the layer's mask against nothing).
# Index at 100 % (2016x2240 per eye), per-eye, dynamic rendering, the ~9 ms load
# (--shading-cost 64). Two rounds. Layout under .gpu/: prologue.sh, this script, new/.
set -u
cd "$(dirname "$0")"
. ./prologue.sh
W=/tmp/run35; mkdir -p $W
b() { # name, app args
  echo "== $1"
  timeout -k 5 200 new/examples/bench --hmd index --scale 1.0 --shading-cost 64 --frames 240 --period 30 --layout per-eye --feature mask --app-args "$2" > $W/$1.txt 2>&1; echo "exit $?" >> $W/$1.txt
  grep -E "^\| index|shaded|exit" $W/$1.txt | head -6
}
for round in 1 2; do
  b app_mask_r$round "--rendering dynamic --draw-hidden-area"
  b no_app_mask_r$round "--rendering dynamic"
done
tar czf $OUT/run35.tgz -C $W .
