#!/usr/bin/python3
"""Compares the mock runtime's captures of hellovr_vulkan through xrizer with and without stereoshim.

usage: compare.py OUT [--frames N] [--preset balanced] [--first 2]

For every case folder in OUT (scripts/xrizer/run's layout) it reports: how the run ended, frames
captured, Vulkan validation messages, the layer's per-frame stats (stats.jsonl) and, for each
layer case against the plain case with the same MSAA (and validation setting), per region:
  hidden   the runtime's hidden-area mask (frames.json visibility_masks, rasterized at pixel
           centres), minus a 3 px band around its outline
  fovea    visible pixels less than inner_deg - 1 degree from the fovea centre
  ring     visible pixels more than inner_deg + 1 degree from it (RDM's periphery)
the count of differing pixels and the PSNR, plus "holes": 2x2-aligned quads of the periphery
that are exactly the clear colour (0,0,0) in the layer's capture while the plain capture has
something there (what an unreconstructed RDM quad looks like).
Frames compared: --first .. N-1 (frame 0 is never masked, frame 1 only for targets the
data-flow walk found on frame 0).
"""
import argparse, json, math, os, re, sys
import numpy as np
from PIL import Image

PRESETS = {"subtle": (30.0, 45.0), "balanced": (20.0, 35.0), "aggressive": (12.0, 25.0)}
EDGE_PX = 3
# hellovr's 640x320 companion window at its (700, 100) on the Xvfb root (no window manager);
# window.txt (xwininfo) overrides it.
COMPANION_BOX = (700, 100, 1340, 420)


def load(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.uint8)


def frames_json(case_dir):
    p = os.path.join(case_dir, "capture", "frames.json")
    if not os.path.exists(p):
        return None
    with open(p) as f:
        return json.load(f)


def hidden_mask(tris, fov, w, h):
    """Pixels whose centre is inside a hidden triangle (tangent plane, y up)."""
    l, r = math.tan(fov["angle_left"]), math.tan(fov["angle_right"])
    u, d = math.tan(fov["angle_up"]), math.tan(fov["angle_down"])
    xs = l + (np.arange(w) + 0.5) / w * (r - l)
    ys = u - (np.arange(h) + 0.5) / h * (u - d)
    tx, ty = np.meshgrid(xs, ys)
    out = np.zeros((h, w), bool)
    for i in range(0, len(tris) - 2, 3):
        (x0, y0), (x1, y1), (x2, y2) = tris[i], tris[i + 1], tris[i + 2]
        e0 = (x1 - x0) * (ty - y0) - (y1 - y0) * (tx - x0)
        e1 = (x2 - x1) * (ty - y1) - (y2 - y1) * (tx - x1)
        e2 = (x0 - x2) * (ty - y2) - (y0 - y2) * (tx - x2)
        out |= ((e0 >= 0) & (e1 >= 0) & (e2 >= 0)) | ((e0 <= 0) & (e1 <= 0) & (e2 <= 0))
    return out


def edge_band(mask, r):
    """Pixels within r px (Chebyshev) of a change of `mask`."""
    h, w = mask.shape
    pad = np.pad(mask, r, mode="edge")
    anyt = np.zeros_like(mask)
    allt = np.ones_like(mask)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            s = pad[r + dy:r + dy + h, r + dx:r + dx + w]
            anyt |= s
            allt &= s
    return anyt & ~allt


def angles(fov, w, h, center):
    l, r = math.tan(fov["angle_left"]), math.tan(fov["angle_right"])
    u, d = math.tan(fov["angle_up"]), math.tan(fov["angle_down"])
    xs = l + (np.arange(w) + 0.5) / w * (r - l)
    ys = u - (np.arange(h) + 0.5) / h * (u - d)
    tx, ty = np.meshgrid(xs, ys)
    cx, cy = center
    dot = tx * cx + ty * cy + 1.0
    n = np.sqrt(tx * tx + ty * ty + 1.0) * math.sqrt(cx * cx + cy * cy + 1.0)
    return np.degrees(np.arccos(np.clip(dot / n, -1, 1)))


def rdm_skipped(fov, w, h, center, inner_deg, middle_deg):
    """Per-pixel skip pattern of stereoshim's RDM rule (src/features/foveation/rdm/rules.rs,
    restated in f32 numpy: ring of each 2x2 quad judged at its centre; middle ring: checkerboard
    of quads, outer ring: 3 of 4 quads)."""
    f32 = np.float32
    tl, tr = f32(math.tan(f32(fov["angle_left"]))), f32(math.tan(f32(fov["angle_right"])))
    tu, td = f32(math.tan(f32(fov["angle_up"]))), f32(math.tan(f32(fov["angle_down"])))
    sx, sy = (tr - tl) / f32(w), (tu - td) / f32(h)
    cx, cy = f32(center[0]), f32(center[1])
    c2 = float(cx) ** 2 + float(cy) ** 2 + 1.0
    k = lambda deg: f32(math.cos(math.radians(min(max(deg, 0.0), 90.0))) ** 2 * c2)
    ki, km = k(inner_deg), k(max(middle_deg, inner_deg))
    qw, qh = (w + 1) // 2, (h + 1) // 2
    qx, qy = np.meshgrid(np.arange(qw, dtype=np.uint32), np.arange(qh, dtype=np.uint32))
    tx = tl + (2 * qx + 1).astype(f32) * sx
    ty = tu - (2 * qy + 1).astype(f32) * sy
    d = tx * cx + ty * cy + f32(1.0)
    n2 = tx * tx + ty * ty + f32(1.0)
    d2 = d * d
    inner = (d > 0) & (d2 >= ki * n2)
    middle = ~inner & (d > 0) & (d2 >= km * n2)
    outer = ~inner & ~middle
    sk = (middle & (((qx + qy) & 1) == 1)) | (outer & (((qx & 1) == 1) | ((qy & 1) == 1)))
    return np.repeat(np.repeat(sk, 2, 0), 2, 1)[:h, :w]


def srgb_to_lin(c):
    c = c / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def lin_to_srgb(l):
    return 255.0 * np.where(l <= 0.0031308, l * 12.92, 1.055 * np.power(np.maximum(l, 0), 1 / 2.4) - 0.055)


def reconstruction(img, skipped):
    """What the layer's reconstruction should give each skipped pixel from the image's own shaded
    pixels: the 1/d^2-weighted mean, in linear light (sRGB swapchain), of the shaded pixels among
    the 12 bordering its quad (rules.rs reconstruction_weight; tests/common/rdm.rs)."""
    h, w = skipped.shape
    lin = srgb_to_lin(img.astype(np.float64))
    P = 2
    linp = np.pad(lin, ((P, P), (P, P), (0, 0)))
    shp = np.pad(~skipped, P, constant_values=False)
    ys, xs = np.mgrid[0:h, 0:w]
    ox, oy = xs & 1, ys & 1            # position inside the quad
    num = np.zeros((h, w, 3))
    den = np.zeros((h, w))
    for dy in range(-1, 3):
        for dx in range(-1, 3):
            if 0 <= dx <= 1 and 0 <= dy <= 1:
                continue
            # neighbour at quad origin + (dx, dy) = pixel + (dx - ox, dy - oy)
            for px in (0, 1):
                for py in (0, 1):
                    sel = (ox == px) & (oy == py)
                    ddx, ddy = dx - px, dy - py
                    wgt = 1.0 / (ddx * ddx + ddy * ddy)
                    nb = linp[P + ddy:P + ddy + h, P + ddx:P + ddx + w]
                    ok = shp[P + ddy:P + ddy + h, P + ddx:P + ddx + w] & sel
                    num += (wgt * ok)[..., None] * nb
                    den += wgt * ok
    with np.errstate(invalid="ignore", divide="ignore"):
        out = num / den[..., None]
    return out, den > 0


def xwd_to_png(src, dst, box=None):
    """An `xwd -root` dump (ZPixmap, 24 or 32 bits per pixel, rows of bytes_per_line) as PNG,
    cropped to `box` or to what is not black."""
    data = open(src, "rb").read()
    hdr = np.frombuffer(data[:100], ">u4")
    size, w, h, order, bpp, bpl, ncol = (int(x) for x in (hdr[0], hdr[4], hdr[5], hdr[7], hdr[11], hdr[12], hdr[19]))
    if bpp not in (24, 32):
        return False
    B = bpp // 8
    off = size + ncol * 12
    rows = np.frombuffer(data[off:off + bpl * h], np.uint8).reshape(h, bpl)[:, :w * B].reshape(h, w, B)
    rgb = rows[..., [2, 1, 0]] if order == 0 else rows[..., [B - 3, B - 2, B - 1]]
    if box is None:
        nz = np.argwhere(rgb.sum(axis=2) > 0)
        if nz.size == 0:
            return False
        (y0, x0), (y1, x1) = nz.min(0), nz.max(0)
        box = (int(x0), int(y0), int(x1) + 1, int(y1) + 1)
    Image.fromarray(np.ascontiguousarray(rgb)).crop(box).save(dst)
    return True


def psnr(a, b):
    if a.size == 0:
        return None
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * math.log10(255.0 ** 2 / mse)


def stats_lines(case_dir):
    p = os.path.join(case_dir, "stats.jsonl")
    if not os.path.exists(p):
        return []
    out = []
    with open(p) as f:
        for line in f:
            line = line.strip()
            if line:
                out.append(json.loads(line))
    return out


def run_info(case_dir, nframes):
    info = {"case": os.path.basename(case_dir)}
    try:
        with open(os.path.join(case_dir, "result.txt")) as f:
            info["result"] = f.read().strip()
    except OSError:
        info["result"] = "not run"
    fj = frames_json(case_dir)
    info["frames_captured"] = 0 if fj is None else sum(1 for fr in fj["frames"] if any(l.get("views") for l in fr["layers"]))
    if fj and fj["frames"]:
        v0 = fj["frames"][-1]["layers"][0]["views"][0] if fj["frames"][-1]["layers"] else None
        info["image_rect"] = v0["image_rect"] if v0 else None
    log = open(os.path.join(case_dir, "out.log"), errors="replace").read() if os.path.exists(os.path.join(case_dir, "out.log")) else ""
    val = [l for l in log.splitlines() if "Validation Error" in l or "Validation Warning" in l]
    ids = {}
    for l in val:
        m = re.search(r"\[ (VUID-[^ ]+|UNASSIGNED-[^ ]+) \]", l)
        k = m.group(1) if m else l[:120]
        ids[k] = ids.get(k, 0) + 1
    info["validation_messages"] = len(val)
    info["validation_ids"] = ids
    info["validation_first"] = {}
    for k in ids:
        for l in val:
            if k in l:
                info["validation_first"][k] = l[:700]
                break
    info["panics"] = [l for l in log.splitlines() if "panicked" in l][:5]
    info["xrizer_errors"] = [l for l in log.splitlines() if " ERROR " in l][:5]
    slog = os.path.join(case_dir, "stereoshim.log")
    if os.path.exists(slog):
        s = open(slog, errors="replace").read().splitlines()
        info["layer_warn_error"] = [l[:400] for l in s if " WARN " in l or " ERROR " in l]
        info["layer_internal_failure"] = [l[:400] for l in s if "internal failure" in l]
        dev = [l for l in s if "vulkan device stats:" in l]
        info["device_stats"] = " ".join(w for w in dev[-1].split() if "=" in w and not w.endswith("=0")) if dev else None
    st = stats_lines(case_dir)
    if st:
        cap = [r for r in st if r["frame"] < nframes]
        info["stats_frames"] = len(st)
        info["stats_frames_captured_range"] = len(cap)
        masked = [r["frame"] for r in cap if r.get("passes_masked", 0) > 0]
        rdm = [r["frame"] for r in cap if r.get("rdm", {}).get("passes", 0) > 0]
        info["first_frame_masked"] = masked[0] if masked else None
        info["first_frame_rdm"] = rdm[0] if rdm else None
        info["passes_masked_per_frame"] = sorted({r.get("passes_masked", 0) for r in cap[2:]}) if len(cap) > 2 else None
        info["rdm_passes_per_frame"] = sorted({r.get("rdm", {}).get("passes", 0) for r in cap[2:]}) if len(cap) > 2 else None
        tot = lambda key: sum_dicts([r.get(key, {}) for r in cap])
        info["not_masked_total"] = tot("not_masked")
        info["rdm_not_applied_total"] = sum_dicts([r.get("rdm", {}).get("not_applied", {}) for r in cap])
        info["rdm_reconstructed_total"] = sum_dicts([r.get("rdm", {}).get("reconstructed", {}) for r in cap])
        info["rdm_compute_total"] = sum(r.get("rdm", {}).get("compute", 0) for r in cap)
        info["rdm_fill_fallback_total"] = sum_dicts([r.get("rdm", {}).get("fill_fallback", {}) for r in cap])
        info["mask_by_source_total"] = tot("mask_by_source")
        px = [r.get("pixels_masked", {}) for r in cap if r.get("pixels_masked")]
        info["pixels_masked_per_view"] = px[-1] if px else None
        q = [r.get("rdm", {}).get("pixels_skipped", {}) for r in cap if r.get("rdm", {}).get("pixels_skipped")]
        info["rdm_pixels_skipped_per_view"] = q[-1] if q else None
    return info


def sum_dicts(ds):
    out = {}
    for d in ds:
        for k, v in d.items():
            if isinstance(v, (int, float)):
                out[k] = out.get(k, 0) + v
    return out


def compare(plain_dir, layer_dir, first, nframes, preset, diff_png=None):
    fp, fl = frames_json(plain_dir), frames_json(layer_dir)
    if not fp or not fl:
        return None
    st = {r["frame"]: r for r in stats_lines(layer_dir)}
    byf = lambda fj: {fr["frame"]: fr for fr in fj["frames"]}
    P, L = byf(fp), byf(fl)
    acc = {k: {"pixels": 0, "diff": 0, "sq": 0.0, "n": 0} for k in ("hidden", "fovea", "ring", "visible")}
    holes = quads = 0
    rdm_acc = {"kept": 0, "kept_diff": 0, "skipped": 0, "bad": 0, "ratios": []}
    hidden_black_layer = hidden_n = hidden_nonblack_plain = 0
    per_frame = []
    for f in range(first, nframes):
        if f not in P or f not in L:
            continue
        for vi, (vp, vl) in enumerate(zip(P[f]["layers"][0]["views"], L[f]["layers"][0]["views"])):
            a = load(os.path.join(plain_dir, "capture", vp["file"]))
            b = load(os.path.join(layer_dir, "capture", vl["file"]))
            if a.shape != b.shape:
                per_frame.append((f, vi, "size differs", a.shape, b.shape))
                continue
            h, w = a.shape[:2]
            masks = {m["view"]: m["hidden_triangles"] for m in L[f].get("visibility_masks", [])}
            hid = hidden_mask(masks.get(vi, []), vl["fov"], w, h)
            edge = edge_band(hid, EDGE_PX)
            rec = st.get(f)
            inner = PRESETS[preset][0]
            center = (0.0, 0.0)
            if rec and rec.get("fovea"):
                fv = [x for x in rec["fovea"] if x["view"] == vi]
                if fv:
                    inner, center = fv[0]["inner_deg"], tuple(fv[0]["center"])
            ang = angles(vl["fov"], w, h, center)
            regions = {
                "hidden": hid & ~edge,
                "visible": ~hid & ~edge,
                "fovea": ~hid & ~edge & (ang < inner - 1.0),
                "ring": ~hid & ~edge & (ang > inner + 1.0),
            }
            d = np.any(a != b, axis=2)
            fr = {"frame": f, "view": vi}
            for k, m in regions.items():
                acc[k]["pixels"] += int(m.sum())
                acc[k]["diff"] += int((d & m).sum())
                diffsq = (a.astype(np.float64) - b.astype(np.float64)) ** 2
                acc[k]["sq"] += float(diffsq[m].sum())
                acc[k]["n"] += int(m.sum()) * 3
                fr[k + "_diff"] = int((d & m).sum())
            blk_b = np.all(b == 0, axis=2)
            blk_a = np.all(a == 0, axis=2)
            hidden_n += int(regions["hidden"].sum())
            hidden_black_layer += int((blk_b & regions["hidden"]).sum())
            hidden_nonblack_plain += int((~blk_a & regions["hidden"]).sum())
            # 2x2-aligned quads wholly inside the ring
            H2, W2 = h // 2 * 2, w // 2 * 2
            q = lambda m: m[:H2:2, :W2:2] & m[1:H2:2, :W2:2] & m[:H2:2, 1:W2:2] & m[1:H2:2, 1:W2:2]
            qany = lambda m: m[:H2:2, :W2:2] | m[1:H2:2, :W2:2] | m[:H2:2, 1:W2:2] | m[1:H2:2, 1:W2:2]
            ringq = q(regions["ring"])
            content = ringq & qany(~blk_a)
            hole = content & q(blk_b)
            quads += int(content.sum())
            holes += int(hole.sum())
            fr["holes"] = int(hole.sum())
            # RDM: kept pixels of the periphery must equal the plain run; skipped ones must be the
            # reconstruction from the layer image's own kept pixels.
            sk = rdm_skipped(vl["fov"], w, h, center, inner, rec["fovea"][vi]["middle_deg"] if rec and rec.get("fovea") else PRESETS[preset][1])
            ring = regions["ring"]
            rdm_acc["kept"] += int((ring & ~sk).sum())
            rdm_acc["kept_diff"] += int((ring & ~sk & d).sum())
            want_lin, ok = reconstruction(b, sk)
            sel = ring & sk & ok
            want = lin_to_srgb(want_lin)
            err = np.abs(b.astype(np.float64) - want).max(axis=2)
            rdm_acc["skipped"] += int(sel.sum())
            rdm_acc["bad"] += int((sel & (err > 3.0)).sum())
            got_lin = srgb_to_lin(b.astype(np.float64)).mean(axis=2)
            want_l = want_lin.mean(axis=2)
            bright = sel & (want_l > 0.05)
            if bright.any():
                rdm_acc["ratios"].append(got_lin[bright] / want_l[bright])
            per_frame.append(fr)
            if diff_png and f == nframes // 2 and vi == 0:
                img = np.zeros((h, w, 3), np.uint8)
                img[..., :] = (b // 3)
                img[d & regions["visible"]] = (255, 0, 0)
                img[d & regions["hidden"]] = (0, 0, 160)
                hq = np.zeros((h, w), bool)
                hq[:H2, :W2] = np.repeat(np.repeat(hole, 2, 0), 2, 1)
                img[hq] = (255, 255, 0)
                Image.fromarray(img).save(diff_png)
    res = {}
    for k, v in acc.items():
        mse = v["sq"] / v["n"] if v["n"] else None
        res[k] = {"pixels": v["pixels"], "differing": v["diff"],
                  "psnr_db": (None if mse is None else (float("inf") if mse == 0 else 10 * math.log10(255 ** 2 / mse)))}
    res["holes"] = holes
    res["rdm_kept_ring_pixels"] = rdm_acc["kept"]
    res["rdm_kept_ring_differing"] = rdm_acc["kept_diff"]
    res["rdm_skipped_ring_pixels"] = rdm_acc["skipped"]
    res["rdm_skipped_not_reconstructed"] = rdm_acc["bad"]
    if rdm_acc["ratios"]:
        r = np.concatenate(rdm_acc["ratios"])
        res["rdm_skipped_linear_ratio_p25_p50_p75"] = [float(np.percentile(r, q)) for q in (25, 50, 75)]
    res["ring_quads_with_content"] = quads
    res["hidden_black_in_layer"] = hidden_black_layer
    res["hidden_pixels"] = hidden_n
    res["hidden_nonblack_in_plain"] = hidden_nonblack_plain
    res["per_frame_holes"] = sorted({x.get("holes", -1) for x in per_frame if isinstance(x, dict)})
    res["frames_compared"] = sorted({x["frame"] for x in per_frame if isinstance(x, dict)})
    return res


def determinism(plain_dir, first, nframes):
    """Differing pixels between consecutive captured frames of the plain run (is the scene static?)."""
    fj = frames_json(plain_dir)
    if not fj:
        return None
    fr = {x["frame"]: x for x in fj["frames"]}
    n = 0
    for f in range(first + 1, nframes):
        if f in fr and f - 1 in fr:
            for v0, v1 in zip(fr[f - 1]["layers"][0]["views"], fr[f]["layers"][0]["views"]):
                n += int(np.any(load(os.path.join(plain_dir, "capture", v0["file"])) != load(os.path.join(plain_dir, "capture", v1["file"])), axis=2).sum())
    return n


def fmt(x):
    if x is None:
        return "—"
    if isinstance(x, float):
        return "∞" if x == float("inf") else f"{x:.2f}"
    return str(x)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--first", type=int, default=2)
    ap.add_argument("--preset", default="balanced")
    a = ap.parse_args()
    cases = sorted(d for d in os.listdir(a.out) if os.path.isfile(os.path.join(a.out, d, "result.txt")))
    infos = {c: run_info(os.path.join(a.out, c), a.frames) for c in cases}
    comps = {}
    for c in cases:
        if c.startswith("plain-"):
            continue
        m = re.match(r"[a-z]+-(msaa\d)(-val)?$", c)
        if not m:
            continue
        plain = f"plain-{m.group(1)}{m.group(2) or ''}"
        if plain not in infos:
            continue
        comps[c] = (plain, compare(os.path.join(a.out, plain), os.path.join(a.out, c), a.first, a.frames, a.preset,
                                   diff_png=os.path.join(a.out, f"diff-{c}.png")))
    for c in cases:
        shots = [os.path.join(a.out, c, f"screen-mid-{i}.xwd") for i in range(3)]
        shots = [x for x in shots if os.path.exists(x)]
        if shots:
            best = max(shots, key=lambda x: np.count_nonzero(np.frombuffer(open(x, "rb").read()[-1920 * 1080:], np.uint8)))
            box = COMPANION_BOX
            try:
                m = re.search(r"(\d+)x(\d+)\+(-?\d+)\+(-?\d+)\s+\+(-?\d+)\+(-?\d+)", open(os.path.join(a.out, c, "window.txt")).read())
                if m:
                    w, h, x, y = int(m.group(1)), int(m.group(2)), int(m.group(5)), int(m.group(6))
                    box = (x, y, x + w, y + h)
            except OSError:
                pass
            png = os.path.join(a.out, f"companion-{c}.png")
            if xwd_to_png(best, png, box=box):
                img = load(png)
                infos[c]["companion_black_fraction"] = float(np.all(img == 0, axis=2).mean())
    det = {c: determinism(os.path.join(a.out, c), a.first, a.frames) for c in cases if c.startswith("plain-")}
    with open(os.path.join(a.out, "summary.json"), "w") as f:
        json.dump({"runs": infos, "comparisons": {k: {"plain": v[0], **(v[1] or {})} for k, v in comps.items()},
                   "plain_frame_to_frame_differing_pixels": det}, f, indent=1, default=str)

    print("## Runs\n")
    print("| case | result | frames captured | eye size | validation msgs (IDs) | first masked / RDM frame | passes masked per frame | RDM passes per frame | not masked (frames 0..N-1) | RDM not applied | RDM reconstructed (compute) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for c in cases:
        i = infos[c]
        rect = i.get("image_rect")
        vids = ", ".join(f"{k}×{v}" for k, v in i["validation_ids"].items()) or "0"
        print(f"| {c} | {i['result']} | {i['frames_captured']} | {rect['width']}×{rect['height'] if rect else ''} | {i['validation_messages']} ({vids}) | "
              f"{fmt(i.get('first_frame_masked'))} / {fmt(i.get('first_frame_rdm'))} | {fmt(i.get('passes_masked_per_frame'))} | {fmt(i.get('rdm_passes_per_frame'))} | "
              f"{fmt(i.get('not_masked_total'))} | {fmt(i.get('rdm_not_applied_total'))} | {fmt(i.get('rdm_reconstructed_total'))} ({fmt(i.get('rdm_compute_total'))}) |")
    print("\n## Captures through the layer against the plain run (frames %d..%d, both views)\n" % (a.first, a.frames - 1))
    print("| case | vs | hidden px: differing / total (layer black) | fovea: differing / total, PSNR dB | ring (periphery): differing / total, PSNR dB | visible: PSNR dB | black quads / ring quads with content | ring kept px: differing / total | ring skipped px: not reconstructed (>3/255 off) / total | skipped px, linear got/want p25/p50/p75 |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for c, (plain, r) in comps.items():
        if not r:
            print(f"| {c} | {plain} | no captures | | | | | | | |")
            continue
        print(f"| {c} | {plain} | {r['hidden']['differing']} / {r['hidden']['pixels']} ({r['hidden_black_in_layer']}) | "
              f"{r['fovea']['differing']} / {r['fovea']['pixels']}, {fmt(r['fovea']['psnr_db'])} | {r['ring']['differing']} / {r['ring']['pixels']}, {fmt(r['ring']['psnr_db'])} | "
              f"{fmt(r['visible']['psnr_db'])} | {r['holes']} / {r['ring_quads_with_content']} | "
              + (f"{r['rdm_kept_ring_differing']} / {r['rdm_kept_ring_pixels']} | {r['rdm_skipped_not_reconstructed']} / {r['rdm_skipped_ring_pixels']} | "
                 f"{'/'.join(f'{x:.2f}' for x in r.get('rdm_skipped_linear_ratio_p25_p50_p75', [])) or '—'} |"
                 if infos[c].get("first_frame_rdm") is not None else "n/a (no RDM) | n/a | n/a |"))
    print("\n## Vulkan validation messages the layer adds (message IDs in the layer run and not in the plain run of the same MSAA)\n")
    for c in cases:
        m = re.match(r"[a-z]+-(msaa\d)-val$", c)
        if not m or c.startswith("plain-"):
            continue
        plain = f"plain-{m.group(1)}-val"
        if plain not in infos:
            continue
        added = {k: v for k, v in infos[c]["validation_ids"].items() if k not in infos[plain]["validation_ids"]}
        print(f"- {c}: " + (", ".join(f"{k} ×{v}" for k, v in added.items()) or "none") + f" (plain {plain}: " +
              (", ".join(f"{k} ×{v}" for k, v in infos[plain]["validation_ids"].items()) or "none") + ")")
    print("\nhellovr's companion (desktop mirror) window mid-run, fraction of black pixels: " + ", ".join(
        f"{c}: {infos[c]['companion_black_fraction']:.3f}" for c in cases if "companion_black_fraction" in infos[c]))
    print("\nPlain runs, differing pixels between consecutive frames (0 = static scene): " + ", ".join(f"{k}: {v}" for k, v in det.items()))
    for c in cases:
        i = infos[c]
        if i["validation_ids"]:
            print(f"\n### Validation messages, {c}\n")
            for k, v in i["validation_ids"].items():
                print(f"- {k} ×{v}: `{i['validation_first'][k][:500]}`")
        if i.get("panics"):
            print(f"\n### Panics, {c}\n")
            for l in i["panics"]:
                print(f"- `{l}`")
        if i.get("layer_warn_error"):
            print(f"\n### Layer WARN/ERROR lines, {c}\n")
            for l in i["layer_warn_error"]:
                print(f"- `{l[:300]}`")
        if i.get("device_stats"):
            print(f"\n{c} device stats: `{i['device_stats'][:900]}`")


if __name__ == "__main__":
    main()
