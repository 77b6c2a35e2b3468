#!/bin/bash
# GPU run for issue 22: what symmetric and parallel views cost (view.symmetric, view.parallel),
# xr-scene at 100 % of each headset's recommended size, the ~9 ms load, per-eye, dynamic
# rendering. Both are latched per XR instance, so examples/bench alternates whole xr-scene
# instances and takes each frame's mode and end-to-end GPU time from the layer's stats.file.
# The mask comes on with them (it hides the padding the runtime does not show), so it is on in
# both modes here: the numbers are the views' own cost, not the mask's saving.
set -u
cd "$(dirname "$0")"
. ./prologue.sh
b() { # name, hmd, cost, feature, config, app args; ONLY (a regex) picks runs by name
  [[ -n "${ONLY:-}" && ! $1 =~ $ONLY ]] && return
  echo "== $1"
  timeout -k 5 150 examples/bench --hmd $2 --scale 1.0 --shading-cost $3 --frames 240 --period 30 --layout per-eye --feature $4 --config "mask.enabled = true; $5" --app-args "--rendering dynamic $6" > $OUT/$1.txt 2>&1; echo "exit $?" >> $OUT/$1.txt
  grep -E "^\| $2|exit" $OUT/$1.txt | head -3
}
b sym_vive64 vive 64 symmetric '' ''
b symfull_vive64 vive 64 symmetric_full '' ''
b symfull_index64 index 64 symmetric_full '' ''
b par_pimax64 pimax 64 parallel '' ''
b par_pimax64_multiview pimax 64 parallel '' '--layout multiview'
b par_pimax_all64 pimax 64 parallel "foveation.enabled = true; far_field.enabled = true; $VRS" '--submit-depth'
