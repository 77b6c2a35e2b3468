#!/bin/bash
# GPU run for issue 32 (one-way dependencies): the reshaped layer against the last build before it
# (ab04ef1), on one lease, the two builds alternated twice: (1) examples/bench with every Vulkan
# feature on (mask + VRS + far field, depth submitted) against the layer off, Index at 100 %
# (2016x2240 per eye), at the ~9 ms load (--shading-cost 64) and fragment-bound (512); (2) the
# Bevy scene (engines/bevy-scene, 256 point lights, Index size) with the config switched live
# between off and mask + VRS, per-frame GPU time from the layer's own timer (stats.gpu_time).
# Layout under .gpu/: prologue.sh, this script, bevy-scene.xz, and old/ and new/ each holding
# one build's xr-scene, libstereoshim.so, libmock_runtime.so, stereoshim and examples/bench.
set -u
cd "$(dirname "$0")"
. ./prologue.sh
W=/tmp/run33; mkdir -p $W
b() { # build, name, cost
  echo "== $1 $2"
  timeout -k 5 200 $1/examples/bench --hmd index --scale 1.0 --shading-cost $3 --frames 240 --period 30 --layout per-eye --feature mask,foveation,far_field --config "$VRS" --app-args "--rendering dynamic --submit-depth" > $W/$1_$2.txt 2>&1; echo "exit $?" >> $W/$1_$2.txt
  grep -E "^\| index|exit" $W/$1_$2.txt | head -3
}
# PART=bench or PART=bevy runs one half (each fits one call of the GPU machine); both by default.
if [[ ${PART:-all} != bevy ]]; then
  for round in 1 2; do
    for v in old new; do b $v all64_r$round 64; b $v all512_r$round 512; done
  done
fi
[[ ${PART:-all} == bench ]] && { tar czf $OUT/run33-bench.tgz -C $W .; exit 0; }
echo "== bevy"
xz -d -k -f bevy-scene.xz && chmod +x bevy-scene
ln -sf /usr/lib/x86_64-linux-gnu/libopenxr_loader.so.1 $G/libopenxr_loader.so
bevy() { # build, round
  local H=/tmp/h-$1-$2; rm -rf $H; mkdir -p $H/config/stereoshim $H/data $H/state $H/run; chmod 700 $H/run
  # Each build with its own mock runtime (the builds are in old/ and new/).
  printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/$1/libmock_runtime.so" > $G/$1/mock-runtime.json
  local E=(env XDG_CONFIG_HOME=$H/config XDG_DATA_HOME=$H/data XDG_STATE_HOME=$H/state XDG_RUNTIME_DIR=$H/run XR_RUNTIME_JSON=$G/$1/mock-runtime.json)
  "${E[@]}" $G/$1/stereoshim install --user > /dev/null
  local S=$W/bevy_$1_r$2.jsonl
  cfg() { printf 'stats.file = "%s"\nstats.gpu_time = true\nmask.enabled = %s\nfoveation.enabled = %s\nfoveation.method = "vrs"\nfoveation.eye_tracking = "off"\n' "$S" $1 $1 > $H/config/stereoshim/c.tmp; mv $H/config/stereoshim/c.tmp $H/config/stereoshim/config.toml; }
  cfg false
  "${E[@]}" MOCK_XR_HMD=index MOCK_XR_EXIT_AFTER=$F timeout -k 5 ${T:-240} ./bevy-scene --lights 256 --frames $F > $W/bevy_app_$1_r$2.txt 2>&1 &
  local app=$!
  while kill -0 $app 2>/dev/null; do cfg false; sleep 2; cfg true; sleep 2; done
  wait $app; echo "bevy $1 round $2 exit $? at $(date +%T)"
  python3 - "$S" <<'PY'
import json, sys, statistics
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
groups = {}
for r in rows[30:]:
    g = (r.get("gpu_ms") or {}).get("busy")
    if g is not None:
        groups.setdefault((r.get("mask_enabled"), r.get("foveation_enabled")), []).append(g)
for k, v in sorted(groups.items()):
    print("  mask, foveation", k, "frames", len(v), "median GPU ms %.3f" % statistics.median(v))
PY
}
# Frames per run (600 took over 200 s with the layer off at ~136 ms a frame) and rounds.
F=${FRAMES:-300}
for round in $(seq ${ROUNDS:-1}); do for v in new old; do bevy $v $round; tar czf $OUT/run33-bevy.tgz -C $W .; done; done
