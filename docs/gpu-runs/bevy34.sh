#!/bin/bash
# Issue 32's Bevy pair: the Bevy scene (engines/bevy-scene, 256 point lights, Index size) on the
# mock runtime paced at 5 Hz (MOCK_XR_PACE_HZ: below the GPU's ~7 frames a second, so frames do
# not pile up on the GPU and the layer's timer reports every frame), off and with mask + VRS, for
# the build before the reshaping (old/, ab04ef1) and the reshaped one (new/), alternated. Medians
# of the layer's per-frame GPU time (stats.gpu_time) after 10 frames of warm-up.
set -u
cd "$(dirname "$0")"
. ./prologue.sh
W=/tmp/bevy34; mkdir -p $W
xz -d -k -f bevy-scene.xz && chmod +x bevy-scene
ln -sf /usr/lib/x86_64-linux-gnu/libopenxr_loader.so.1 $G/libopenxr_loader.so
one() { # build, features (false/true), round
  local n=$1_$2_r$3 H=/tmp/h-$1-$2-$3; rm -rf $H; mkdir -p $H/config/stereoshim $H/data $H/state $H/run; chmod 700 $H/run
  printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/$1/libmock_runtime.so" > $G/$1/mock-runtime.json
  local E=(env XDG_CONFIG_HOME=$H/config XDG_DATA_HOME=$H/data XDG_STATE_HOME=$H/state XDG_RUNTIME_DIR=$H/run XR_RUNTIME_JSON=$G/$1/mock-runtime.json)
  "${E[@]}" $G/$1/stereoshim install --user > /dev/null
  printf 'stats.file = "%s"\nstats.gpu_time = true\nmask.enabled = %s\nfoveation.enabled = %s\nfoveation.method = "vrs"\nfoveation.eye_tracking = "off"\n' "$W/$n.jsonl" $2 $2 > $H/config/stereoshim/config.toml
  "${E[@]}" MOCK_XR_HMD=index MOCK_XR_PACE_HZ=5 MOCK_XR_EXIT_AFTER=40 timeout -k 2 ${T:-30} ./bevy-scene --lights 256 --frames 40 > $W/$n.app.txt 2>&1
  local rc=$?
  python3 - "$W/$n.jsonl" "$n" "$rc" <<'PY'
import json, sys, statistics
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
g = [r["gpu_ms"]["busy"] for r in rows[10:] if (r.get("gpu_ms") or {}).get("busy") is not None]
print(sys.argv[2], "exit", sys.argv[3], "rows", len(rows), "timed", len(g), "median GPU ms %.3f" % statistics.median(g) if g else "no GPU time", "masked", sum(r.get("passes_masked") or 0 for r in rows))
PY
}
for round in 1 2; do for b in new old; do one $b false $round; one $b true $round; done; done
tar czf $OUT/bevy34.tgz -C $W .
