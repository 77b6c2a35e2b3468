#!/bin/bash
# Bevy on NVIDIA: which part makes the app hang at its exit (issue 32's Bevy pair). Four runs of
# 60 frames: without the layer; the layer with every feature off, the GPU timer off; the same with
# the timer on; mask + VRS with the timer on. A run still alive 25 s after the app's session
# reached EXITING is a hang: its threads' kernel wait channels and system calls are printed.
set -u
cd "$(dirname "$0")"
. ./prologue.sh
W=/tmp/diag34; mkdir -p $W
xz -d -k -f bevy-scene.xz && chmod +x bevy-scene
ln -sf /usr/lib/x86_64-linux-gnu/libopenxr_loader.so.1 $G/libopenxr_loader.so
printf '{"file_format_version":"1.0.0","runtime":{"name":"mock","library_path":"%s"}}\n' "$G/new/libmock_runtime.so" > $G/new/mock-runtime.json
one() { # name, layer (0/1), gpu_time, features
  local H=/tmp/h-$1; rm -rf $H; mkdir -p $H/config/stereoshim $H/data $H/state $H/run; chmod 700 $H/run
  local E=(env XDG_CONFIG_HOME=$H/config XDG_DATA_HOME=$H/data XDG_STATE_HOME=$H/state XDG_RUNTIME_DIR=$H/run XR_RUNTIME_JSON=$G/new/mock-runtime.json)
  [[ $2 == 1 ]] && "${E[@]}" $G/new/stereoshim install --user > /dev/null
  printf 'stats.file = "%s"\nstats.gpu_time = %s\nmask.enabled = %s\nfoveation.enabled = %s\nfoveation.method = "vrs"\nfoveation.eye_tracking = "off"\n' "$W/$1.jsonl" $3 $4 $4 > $H/config/stereoshim/config.toml
  local t0=$SECONDS
  "${E[@]}" MOCK_XR_HMD=index MOCK_XR_EXIT_AFTER=60 ./bevy-scene --lights 256 --frames 60 > $W/$1.app.txt 2>&1 &
  local app=$!
  while kill -0 $app 2>/dev/null && ! grep -q EXITING $W/$1.app.txt; do sleep 1; (( SECONDS - t0 > 80 )) && break; done
  local exiting=$SECONDS
  while kill -0 $app 2>/dev/null && (( SECONDS - exiting < 25 )); do sleep 1; done
  if kill -0 $app 2>/dev/null; then
    echo "$1: HUNG ($((SECONDS - t0)) s, EXITING at $((exiting - t0)) s)"
    for t in /proc/$app/task/*; do echo "  thread $(basename $t) $(cat $t/comm) wchan=$(cat $t/wchan 2>/dev/null) syscall=$(cut -d' ' -f1 $t/syscall 2>/dev/null)"; done | sort -k3 | uniq -c -f2 | head -20
    tail -3 $W/$1.app.txt | cut -c1-200
    kill -9 $app; wait $app 2>/dev/null
  else
    wait $app; echo "$1: exit $? after $((SECONDS - t0)) s"
  fi
  cp $H/state/stereoshim/stereoshim.log $W/$1.layer.log 2>/dev/null
  [[ -f $W/$1.jsonl ]] && python3 -c "
import json,sys
rows=[json.loads(l) for l in open('$W/$1.jsonl') if l.strip()]
g=[r['frame'] for r in rows if r.get('gpu_ms')]
print('  rows',len(rows),'with gpu_ms',len(g),g[:5],g[-3:])"
}
one no_layer 0 false false
one layer_off_no_timer 1 false false
one layer_off_timer 1 true false
one layer_on_timer 1 true true
tar czf $OUT/diag34.tgz -C $W .
