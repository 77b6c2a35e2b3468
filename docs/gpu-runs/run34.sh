#!/bin/bash
# GPU run for issues 32 and 33 on one lease. (1) Issue 33: the OpenVR submission path against
# direct rendering, examples/bench with every Vulkan feature on (mask + VRS + far field, depth
# submitted) against the layer off, Index at 100 % (2016x2240 per eye), per-eye, dynamic rendering,
# at the ~9 ms load (--shading-cost 64): the eyes rendered straight into the swapchain (direct),
# into the app's own textures copied by the app (app copy), and copied by a second component in
# a submission of its own (xr-scene --submit-via openvr, as xrizer / OpenComposite). Two rounds.
# (2) Issue 32: the Bevy scene (engines/bevy-scene, 256 point lights, Index size) several times
# in a row on the machine, each run's per-frame GPU time from the layer's own timer: whether the
# timer reports every frame and whether a second run stalls, then off against mask + VRS.
# Layout under .gpu/: prologue.sh, this script, bevy-scene.xz, new/ with the release build.
set -u
cd "$(dirname "$0")"
. ./prologue.sh
W=/tmp/run34; mkdir -p $W
b() { # name, app args
  echo "== $1"
  timeout -k 5 200 new/examples/bench --hmd index --scale 1.0 --shading-cost 64 --frames 240 --period 30 --layout per-eye --feature mask,foveation,far_field --config "$VRS" --app-args "$2" > $W/$1.txt 2>&1; echo "exit $?" >> $W/$1.txt
  grep -E "^\| index|exit" $W/$1.txt | head -3
}
if [[ ${PART:-all} != bevy ]]; then
  for round in 1 2; do
    b direct_r$round "--rendering dynamic --submit-depth"
    b appcopy_r$round "--rendering dynamic --submit-depth --intermediate --samples 1"
    b openvr_r$round "--rendering dynamic --submit-depth --intermediate --samples 1 --submit-via openvr"
    b openvr_msaa_r$round "--rendering dynamic --intermediate --samples 4 --submit-via openvr"
    b appcopy_msaa_r$round "--rendering dynamic --intermediate --samples 4"
  done
  tar czf $OUT/run34-bench.tgz -C $W .
fi
[[ ${PART:-all} == bench ]] && exit 0
echo "== bevy"
xz -d -k -f bevy-scene.xz && chmod +x bevy-scene
ln -sf /usr/lib/x86_64-linux-gnu/libopenxr_loader.so.1 $G/libopenxr_loader.so
printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/new/libmock_runtime.so" > $G/new/mock-runtime.json
bevy() { # name, frames, config switching (off | on | cycle)
  local H=/tmp/h-$1; rm -rf $H; mkdir -p $H/config/stereoshim $H/data $H/state $H/run; chmod 700 $H/run
  local E=(env XDG_CONFIG_HOME=$H/config XDG_DATA_HOME=$H/data XDG_STATE_HOME=$H/state XDG_RUNTIME_DIR=$H/run XR_RUNTIME_JSON=$G/new/mock-runtime.json)
  "${E[@]}" $G/new/stereoshim install --user > /dev/null
  local S=$W/bevy_$1.jsonl
  cfg() { printf 'stats.file = "%s"\nstats.gpu_time = true\nmask.enabled = %s\nfoveation.enabled = %s\nfoveation.method = "vrs"\nfoveation.eye_tracking = "off"\n' "$S" $1 $1 > $H/config/stereoshim/c.tmp; mv $H/config/stereoshim/c.tmp $H/config/stereoshim/config.toml; }
  case $3 in on) cfg true ;; *) cfg false ;; esac
  local t0=$(date +%s.%N)
  "${E[@]}" MOCK_XR_HMD=index MOCK_XR_EXIT_AFTER=$2 timeout -k 5 ${T:-120} ./bevy-scene --lights 256 --frames $2 > $W/bevy_app_$1.txt 2>&1 &
  local app=$!
  if [[ $3 == cycle ]]; then while kill -0 $app 2>/dev/null; do cfg false; sleep 2; cfg true; sleep 2; done; fi
  wait $app; echo "bevy $1 exit $? in $(echo "$(date +%s.%N) - $t0" | bc) s"
  cp $H/state/stereoshim/stereoshim.log $W/bevy_$1.layer.log 2>/dev/null
  python3 - "$S" <<'PY'
import json, sys, statistics
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
with_gpu = [r for r in rows if (r.get("gpu_ms") or {}).get("busy") is not None]
print("  stats rows", len(rows), "with gpu_ms", len(with_gpu), "frames with gpu_ms", [r.get("frame") for r in with_gpu][:8])
groups = {}
for r in with_gpu[10:]:
    groups.setdefault((r.get("mask_enabled"), r.get("foveation_enabled")), []).append(r["gpu_ms"]["busy"])
for k, v in sorted(groups.items()):
    print("  mask, foveation", k, "frames", len(v), "median GPU ms %.3f" % statistics.median(v))
PY
  grep -iE "gpu time|timestamp|timer|query|fail|warn|error" $W/bevy_$1.layer.log | cut -c1-300 | head -10; grep -E "device stats" $W/bevy_$1.layer.log | tail -1 | tr " " "\n" | grep -E "gpu_time|timed" | head
  tar czf $OUT/run34-bevy.tgz -C $W .
}
bevy first_off ${FRAMES:-60} off
bevy second_off ${FRAMES:-60} off
bevy third_on ${FRAMES:-60} on
bevy fourth_cycle ${CYCLE_FRAMES:-150} cycle
nvidia-smi --query-gpu=name,driver_version --format=csv
