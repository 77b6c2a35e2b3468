#!/bin/bash
# GPU run for issue 20 (run with LOAD=96 LIGHTS=256): VRS for eye passes whose eyes only each
# submission's data-flow walk gives (every pass the walk traced, passes recorded before it knew
# their target, dynamic resolution): (1) examples/fovea_check behind a tonemap with the eye's
# sub-rect changing every frame (--viewport-scale 0.8 --dynamic-resolution) and with command
# buffers recorded once: the inner ring bit-identical, VRS engaged; (2) examples/bench, mask + VRS
# switched live, on those structures and on the bloom chain of run22; (3) the Bevy scene, off /
# mask + VRS / mask + VRS + far field, cycled live.
set -u
cd "$(dirname "$0")"
G=$PWD
for f in ../.gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
export PATH=$G:$PATH
nvidia-smi -L
printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/libmock_runtime.so" > $G/mock-runtime.json

LOAD=${LOAD:-96}
VRS='foveation.method = "vrs"; foveation.eye_tracking = "off"'
echo "== fovea_check vrs: tonemap, viewport 0.8, dynamic resolution"
timeout -k 5 240 examples/fovea_check --layouts per-eye,multiview,side-by-side --renderings dynamic,render-pass2 --methods vrs --app-args "--post tonemap --viewport-scale 0.8 --dynamic-resolution" > $OUT/fovea_dynamic.txt 2>&1; echo "exit $?" >> $OUT/fovea_dynamic.txt
grep -E "^\||OK|exit|FAIL|fail" $OUT/fovea_dynamic.txt | tail -12
echo "== fovea_check vrs: tonemap, command buffers recorded once"
timeout -k 5 240 examples/fovea_check --layouts per-eye,multiview --renderings dynamic,render-pass --methods vrs --app-args "--post tonemap --record-once" > $OUT/fovea_once.txt 2>&1; echo "exit $?" >> $OUT/fovea_once.txt
grep -E "^\||OK|exit|FAIL|fail" $OUT/fovea_once.txt | tail -8
b() { timeout -k 5 200 examples/bench --hmd index --shading-cost $LOAD --frames 240 --period 20 --layout per-eye --feature mask,foveation --config "$VRS" "$@" 2>&1 | tail -4; }
echo "== bench: direct --scale 0.8, mask + VRS"
b --scale 0.8 --app-args "--rendering dynamic" | tee $OUT/bench_direct.txt
echo "== bench: --post bloom --render-scale 0.8, mask + VRS"
b --scale 1.0 --app-args "--rendering dynamic --post bloom --render-scale 0.8" | tee $OUT/bench_bloom.txt
echo "== bench: --post tonemap --viewport-scale 0.8 --dynamic-resolution, mask + VRS (dynamic rendering, then render pass objects)"
b --scale 1.0 --app-args "--rendering dynamic --post tonemap --viewport-scale 0.8 --dynamic-resolution" | tee $OUT/bench_dynamic.txt
b --scale 1.0 --app-args "--rendering render-pass2 --post tonemap --viewport-scale 0.8 --dynamic-resolution" | tee $OUT/bench_dynamic_rp.txt
echo "== bevy"
gzip -d -k -f bevy-scene.gz && chmod +x bevy-scene
ln -sf /usr/lib/x86_64-linux-gnu/libopenxr_loader.so.1 $G/libopenxr_loader.so
H=/tmp/h; mkdir -p $H/config/stereoshim $H/data $H/state $H/run; chmod 700 $H/run
E=(env XDG_CONFIG_HOME=$H/config XDG_DATA_HOME=$H/data XDG_STATE_HOME=$H/state XDG_RUNTIME_DIR=$H/run XR_RUNTIME_JSON=$G/mock-runtime.json)
"${E[@]}" ./stereoshim install --user > /dev/null
STATS=$OUT/bevy_stats.jsonl
cfg() { printf 'stats.file = "%s"\nstats.gpu_time = true\nmask.enabled = %s\nfoveation.enabled = %s\nfoveation.method = "vrs"\nfoveation.eye_tracking = "off"\nfar_field.enabled = %s\n' "$STATS" $1 $2 $3 > $H/config/stereoshim/c.tmp; mv $H/config/stereoshim/c.tmp $H/config/stereoshim/config.toml; }
cfg false false false
"${E[@]}" MOCK_XR_HMD=index MOCK_XR_EXIT_AFTER=900 timeout -k 5 300 ./bevy-scene --lights ${LIGHTS:-256} --frames 900 > $OUT/bevy_app.txt 2>&1 &
app=$!
while kill -0 $app 2>/dev/null; do
  cfg false false false; sleep 2; cfg true true false; sleep 2; cfg true true true; sleep 2
done
wait $app; echo "bevy exit $?"; tail -1 $OUT/bevy_app.txt
grep -h "vrs on\|vrs not applied" $H/state/stereoshim/stereoshim.log | cut -c1-260 | head -6
python3 - "$STATS" <<'PY'
import json, sys, statistics
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
groups = {}
for r in rows[30:]:
    g = (r.get("gpu_ms") or {}).get("busy")
    if g is None:
        continue
    key = (r.get("mask_enabled"), r.get("foveation_enabled"), r.get("far_field_enabled"))
    groups.setdefault(key, []).append((g, (r.get("vrs") or {}).get("passes", 0)))
for k, v in sorted(groups.items()):
    print(k, "frames", len(v), "median ms %.3f" % statistics.median(x[0] for x in v), "vrs passes/frame median", statistics.median(x[1] for x in v))
PY
