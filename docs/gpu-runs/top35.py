# Drives `stereoshim top` for top35.sh through a pseudo terminal of 80x24: waits for the app's
# announcement, starts top, presses b (A/B of the features on), waits for the A/B's outcome file,
# presses q; then sorts the stats file's frames of the A/B window as examples/bench does.
import fcntl, json, os, pty, select, statistics, struct, sys, termios, time
pid, work, top, stats = int(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4]
live = os.path.join(os.environ["XDG_RUNTIME_DIR"], "stereoshim", "live")
# The app's pid is not the one top35.sh started (timeout wraps it): the one announcement there is.
deadline = time.time() + 60
while True:
    found = [f for f in (os.listdir(live) if os.path.isdir(live) else []) if f.endswith(".json") and f[:-5].isdigit()]
    if found:
        pid = int(found[0][:-5])
        break
    if time.time() > deadline: sys.exit("the app never announced itself")
    time.sleep(0.1)
child, fd = pty.fork()
if child == 0:
    os.environ["TERM"] = "xterm-256color"
    os.execv(top, [top, "top", "--pid", str(pid), "--ab-period", "30", "--ab-cycles", "4"])
fcntl.ioctl(fd, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
screen = b""
def pump(seconds):
    global screen
    end = time.time() + seconds
    while time.time() < end:
        r, _, _ = select.select([fd], [], [], 0.05)
        if r:
            try: screen = (screen + os.read(fd, 65536))[-200000:]
            except OSError: return
pump(4)
start = time.time()
key = os.environ.get("KEY", "b").encode()
os.write(fd, key)
ab = os.path.join(live, f"{pid}.ab")
while not os.path.exists(ab) and time.time() - start < 200:
    pump(0.5)
outcome = open(ab).read().strip() if os.path.exists(ab) else "no outcome"
print("top's A/B:", outcome.replace("\n", "\n  "), "after %.1f s" % (time.time() - start))
if os.environ.get("KEEP"):
    pump(1)
    os.write(fd, b"k")
    pump(1.5)
    print("config after k:", open(os.path.join(os.environ["XDG_CONFIG_HOME"], "stereoshim", "config.toml")).read().strip().replace("\n", " | "))
os.write(fd, b"q")
pump(2)
os.waitpid(child, 0)
rows = [json.loads(l) for l in open(stats) if l.strip()]
window = [r for r in rows if r["time"] >= start and r["time"] <= os.path.getmtime(ab) and (r.get("gpu_ms") or {}).get("busy") is not None] if os.path.exists(ab) else []
runs = []
for r in window:
    on = r["mask_enabled"]
    if not runs or runs[-1][0] != on: runs.append((on, []))
    runs[-1][1].append(r["gpu_ms"]["busy"])
pick = lambda on: [x for o, v in runs if o == on and len(v) > 8 for x in v[3:]]
if pick(False) and pick(True) and key == b"b":
    a, b = statistics.median(pick(False)), statistics.median(pick(True))
    print("the A/B's frames sorted as bench sorts them: %.3f -> %.3f ms, %.3fx (%d/%d frames)" % (a, b, a / b, len(pick(False)), len(pick(True))))
