// stereoshim's radial density masking rule, shared by the injected depth draw (rdm.frag) and the
// reconstruction (rdm_fill.frag). It must stay operation for operation equal to
// `RdmParams::ring` / `skipped` in src/rdm.rs: single f32 adds and multiplies in the same order,
// `precise` so no compiler fuses them into FMAs; then CPU statistics and test predictions match
// the GPU exactly.
//
// tanp  = (tan_left, tan_up, step_x, step_y): the rect's left / top tangents and tangent per pixel.
// fovea = (cx, cy, k_inner, k_middle): centre direction as a tangent-plane point and
//         cos²(ring angle) · |(cx, cy, −1)|².
// q: the quad (2×2 pixels aligned to the eye rect's origin), rect-relative, q >= 0.

// 0: inner (full rate), 1: middle (half), 2: outer (quarter).
int rdm_ring(ivec2 q, vec4 tanp, vec4 fovea) {
    precise float fx = float(2 * q.x + 1);
    precise float fy = float(2 * q.y + 1);
    precise float tx = tanp.x + fx * tanp.z;
    precise float ty = tanp.y - fy * tanp.w;
    precise float d = tx * fovea.x + ty * fovea.y + 1.0;
    precise float n2 = tx * tx + ty * ty + 1.0;
    precise float d2 = d * d;
    precise float lim_inner = fovea.z * n2;
    precise float lim_middle = fovea.w * n2;
    if (d > 0.0 && d2 >= lim_inner) {
        return 0;
    }
    if (d > 0.0 && d2 >= lim_middle) {
        return 1;
    }
    return 2;
}

// Middle ring: checkerboard, (qx + qy) odd skipped; outer ring: only qx, qy both even kept.
bool rdm_skipped(ivec2 q, vec4 tanp, vec4 fovea) {
    int ring = rdm_ring(q, tanp, fovea);
    if (ring == 0) {
        return false;
    }
    if (ring == 1) {
        return ((q.x + q.y) & 1) == 1;
    }
    return (q.x & 1) == 1 || (q.y & 1) == 1;
}
