#version 450
#extension GL_GOOGLE_include_directive : require
// Reconstruction of the quads radial density masking skipped: each pixel of a skipped quad becomes
// the inverse-squared-distance weighted mean of the shaded pixels among the 12 that border its quad
// (src/rdm.rs `reconstruction_weight`); pixels of shaded quads are left alone (discard). `src` is a
// copy of the swapchain image taken just before, so reads never see this pass's writes.
#include "rdm_rule.glsl"

layout(set = 0, binding = 0) uniform sampler2DArray src;
#ifdef FROM_BUFFER
// The eye's parameters from the vertex buffer (rdm_fill.vert); the framebuffer is one layer of
// the target, which the temp copy holds at that same layer (`layer` stays in the push constants).
layout(location = 0) flat in ivec4 v_rect;
layout(location = 1) flat in vec4 v_tanp;
layout(location = 2) flat in vec4 v_fovea;
layout(push_constant) uniform Params {
    int layer;
} p;
#define RECT v_rect
#define TANP v_tanp
#define FOVEA v_fovea
#else
layout(push_constant) uniform Params {
    ivec4 rect;   // x, y, width, height of the eye rect (image pixels)
    vec4 tanp;
    vec4 fovea;
    int layer;
} p;
#define RECT p.rect
#define TANP p.tanp
#define FOVEA p.fovea
#endif

layout(location = 0) out vec4 out_color;

bool shaded(ivec2 pix) {
    ivec2 rel = pix - RECT.xy;
    if (any(lessThan(rel, ivec2(0))) || any(greaterThanEqual(rel, RECT.zw))) {
        return false;
    }
    return !rdm_skipped(rel >> 1, TANP, FOVEA);
}

void main() {
    ivec2 pix = ivec2(gl_FragCoord.xy);
    ivec2 rel = pix - RECT.xy;
    // Outside the eye's rect (the buffer variant's triangle covers the whole target).
    if (any(lessThan(rel, ivec2(0))) || any(greaterThanEqual(rel, RECT.zw))) {
        discard;
    }
    ivec2 q = rel >> 1;
    if (!rdm_skipped(q, TANP, FOVEA)) {
        discard;
    }
    ivec2 base = RECT.xy + q * 2;
    vec4 sum = vec4(0.0);
    float wsum = 0.0;
    for (int dy = -1; dy <= 2; dy++) {
        for (int dx = -1; dx <= 2; dx++) {
            if (dx >= 0 && dx <= 1 && dy >= 0 && dy <= 1) {
                continue;
            }
            ivec2 s = base + ivec2(dx, dy);
            if (!shaded(s)) {
                continue;
            }
            vec2 d = vec2(s - pix);
            float w = 1.0 / dot(d, d);
            sum += w * texelFetch(src, ivec3(s, p.layer), 0);
            wsum += w;
        }
    }
    if (wsum == 0.0) {
        discard;
    }
    out_color = sum / wsum;
}
