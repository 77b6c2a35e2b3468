#!/bin/bash
# GPU run for issue 20 (run with LOAD=96 LIGHTS=256): radial density masking behind post-processing,
# reconstructed when the eye pass ends by the compute pass over periphery tiles (the fragment fill
# of run23 once more for comparison). (1) xr-scene --post bloom --render-scale 0.8 against direct
# rendering of the same scene-pass size (--scale 0.8), mask + RDM switched live within each run
# (examples/bench); the same with the fill; --dynamic-resolution (the eye's sub-rect changes every
# frame).
# (2) The Bevy scene (engines/bevy-scene, 256 point lights, Index size) with the layer's config
# cycled live between off, mask + RDM and mask + RDM + far field; per-frame GPU time from the
# layer's own timer (stats.gpu_time) in stats.file, which includes the layer's reconstruction.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export PATH=$G:$PATH
nvidia-smi -L
printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/libmock_runtime.so" > $G/mock-runtime.json

LOAD=${LOAD:-96}
RDM='foveation.method = "rdm"; foveation.eye_tracking = "off"'
echo "== bench: direct rendering, scene pass at 0.8 (Index 100 %, shading cost $LOAD), mask + RDM"
timeout -k 5 200 examples/bench --hmd index --scale 0.8 --shading-cost $LOAD --frames 240 --period 20 --layout per-eye --feature mask,foveation --config "$RDM" --app-args "--rendering dynamic" > $OUT/bench_direct.txt 2>&1; echo "exit $?" >> $OUT/bench_direct.txt
tail -4 $OUT/bench_direct.txt
echo "== bench: --post bloom --render-scale 0.8 (swapchain at 100 %), mask + RDM"
timeout -k 5 200 examples/bench --hmd index --scale 1.0 --shading-cost $LOAD --frames 240 --period 20 --layout per-eye --feature mask,foveation --config "$RDM" --app-args "--rendering dynamic --post bloom --render-scale 0.8" > $OUT/bench_post.txt 2>&1; echo "exit $?" >> $OUT/bench_post.txt
tail -4 $OUT/bench_post.txt
echo "== bench: --post bloom --render-scale 0.8, mask + RDM reconstructed by the fragment fill"
timeout -k 5 200 examples/bench --hmd index --scale 1.0 --shading-cost $LOAD --frames 240 --period 20 --layout per-eye --feature mask,foveation --config "$RDM; foveation.rdm_reconstruction = \"fill\"" --app-args "--rendering dynamic --post bloom --render-scale 0.8" > $OUT/bench_post_fill.txt 2>&1; echo "exit $?" >> $OUT/bench_post_fill.txt
tail -4 $OUT/bench_post_fill.txt
echo "== bench: --post tonemap --viewport-scale 0.8 --dynamic-resolution, mask + RDM"
timeout -k 5 200 examples/bench --hmd index --scale 1.0 --shading-cost $LOAD --frames 240 --period 20 --layout per-eye --feature mask,foveation --config "$RDM" --app-args "--rendering dynamic --post tonemap --viewport-scale 0.8 --dynamic-resolution" > $OUT/bench_dynamic.txt 2>&1; echo "exit $?" >> $OUT/bench_dynamic.txt
tail -4 $OUT/bench_dynamic.txt
echo "== bevy"
gzip -d -k -f bevy-scene.gz && chmod +x bevy-scene
ln -sf /usr/lib/x86_64-linux-gnu/libopenxr_loader.so.1 $G/libopenxr_loader.so
H=/tmp/h; mkdir -p $H/config/stereoshim $H/data $H/state $H/run; chmod 700 $H/run
E=(env XDG_CONFIG_HOME=$H/config XDG_DATA_HOME=$H/data XDG_STATE_HOME=$H/state XDG_RUNTIME_DIR=$H/run XR_RUNTIME_JSON=$G/mock-runtime.json)
"${E[@]}" ./stereoshim install --user > /dev/null
cfg() { printf 'stats.file = "%s"\nstats.gpu_time = true\nmask.enabled = %s\nfoveation.enabled = %s\nfoveation.method = "rdm"\nfoveation.eye_tracking = "off"\nfar_field.enabled = %s\n' "$STATS" $1 $2 $3 > $H/config/stereoshim/c.tmp; mv $H/config/stereoshim/c.tmp $H/config/stereoshim/config.toml; }
# bevy LIGHTS FRAMES MODES...: the scene with the config cycled every 2 s through MODES
# ("mask fov ff" triples), medians per mode from the layer's stats.
bevy() {
  local lights=$1 frames=$2; shift 2
  STATS=$OUT/bevy${lights}_stats.jsonl
  cfg false false false
  "${E[@]}" MOCK_XR_HMD=index MOCK_XR_EXIT_AFTER=$frames timeout -k 5 300 ./bevy-scene --lights $lights --frames $frames > $OUT/bevy${lights}_app.txt 2>&1 &
  local app=$!
  while kill -0 $app 2>/dev/null; do
    for m in "$@"; do cfg $m; sleep 2; done
  done
  wait $app; echo "bevy $lights lights: exit $?"; tail -2 $OUT/bevy${lights}_app.txt
  python3 - "$STATS" <<'PY'
import json, sys, statistics
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
groups = {}
for r in rows[30:]:
    g = (r.get("gpu_ms") or {}).get("busy")
    if g is None:
        continue
    key = (r.get("mask_enabled"), r.get("foveation_enabled"), r.get("far_field_enabled"))
    groups.setdefault(key, []).append(g)
for k, v in sorted(groups.items()):
    print(k, "frames", len(v), "median ms %.3f" % statistics.median(v))
PY
}
bevy ${LIGHTS:-256} 900 "false false false" "true true false" "true true true"
bevy 32 1500 "false false false" "true false false" "true true false"
grep -h "data-flow walk: colour\|far field depth range\|radial density\|pass end\|post chain" $H/state/stereoshim/stereoshim.log | cut -c1-300 | head -12
cp $H/state/stereoshim/stereoshim.log $OUT/bevy_layer.log
