#!/bin/bash
# GPU run for issue 34: `stereoshim top`'s live A/B of the mask in a running xr-scene (mock runtime,
# Index at 100 %, per-eye, dynamic rendering, --shading-cost 64), top driven through a pseudo
# terminal of 80x24 (top35.py), against examples/bench on the same config. The A/B's outcome is
# what top leaves for the overlay (`<pid>.ab`); the frames' own lines (stats.file) sorted as bench
# sorts them give the same figure from the same frames. Layout under .gpu/: prologue.sh, new/.
set -u
cd "$(dirname "$0")"
. ./prologue.sh
W=/tmp/top35; rm -rf $W; mkdir -p $W
printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/new/libmock_runtime.so" > $G/new/mock-runtime.json
H=$W/home; mkdir -p $H/config/stereoshim $H/data $H/state $H/run; chmod 700 $H/run
export XDG_CONFIG_HOME=$H/config XDG_DATA_HOME=$H/data XDG_STATE_HOME=$H/state XDG_RUNTIME_DIR=$H/run XR_RUNTIME_JSON=$G/new/mock-runtime.json
$G/new/stereoshim install --user > /dev/null
printf 'stats.file = "%s"\n\n[app."xr-scene"]\nmask.enabled = true\n' "$W/stats.jsonl" > $H/config/stereoshim/config.toml
if [[ ${PART:-} == each ]]; then
  # Each feature on top of the others (key e), then k keeps only what paid.
  printf 'stats.file = "%s"\n\n[app."xr-scene"]\nmask.enabled = true\nfoveation.enabled = true\nfoveation.method = "vrs"\nfoveation.eye_tracking = "off"\nfar_field.enabled = true\n' "$W/stats.jsonl" > $H/config/stereoshim/config.toml
  rm -f $W/stop
  MOCK_XR_HMD=index MOCK_XR_EXIT_ON=$W/stop timeout -k 5 300 $G/new/xr-scene --scale 1.0 --shading-cost 64 --layout per-eye --rendering dynamic --submit-depth > $W/app-each.txt 2>&1 &
  app=$!
  KEY=e KEEP=1 python3 top35.py $app $W $G/new/stereoshim $W/stats.jsonl 2>&1 | tee $W/top-each.txt
  touch $W/stop; wait $app
  tar czf $OUT/top35-each.tgz -C $W --exclude=home .
  exit 0
fi
for round in 1 2; do
  rm -f $W/stop $W/stats.jsonl
  MOCK_XR_HMD=index MOCK_XR_EXIT_ON=$W/stop timeout -k 5 300 $G/new/xr-scene --scale 1.0 --shading-cost 64 --layout per-eye --rendering dynamic > $W/app$round.txt 2>&1 &
  app=$!
  python3 top35.py $app $W $G/new/stereoshim $W/stats.jsonl 2>&1 | tee $W/top$round.txt
  touch $W/stop; wait $app; echo "xr-scene exit $?"
  cp $W/stats.jsonl $W/stats$round.jsonl
  echo "== bench, the same config"
  timeout -k 5 200 new/examples/bench --hmd index --scale 1.0 --shading-cost 64 --frames 240 --period 30 --layout per-eye --feature mask --app-args "--rendering dynamic" > $W/bench$round.txt 2>&1
  grep -E "^\| index" $W/bench$round.txt | head -2
done
cp $H/state/stereoshim/stereoshim.log $W/layer.log 2>/dev/null
tar czf $OUT/top35.tgz -C $W --exclude=home .
