#version 450
#extension GL_GOOGLE_include_directive : require
// Reconstruction of the quads radial density masking skipped: each pixel of a skipped quad becomes
// the inverse-squared-distance weighted mean of the shaded pixels among the 12 that border its quad
// (src/rdm.rs `reconstruction_weight`); pixels of shaded quads are left alone (discard). `src` is a
// copy of the swapchain image taken just before, so reads never see this pass's writes.
#include "rdm_rule.glsl"

layout(set = 0, binding = 0) uniform sampler2DArray src;
layout(push_constant) uniform Params {
    ivec4 rect;   // x, y, width, height of the eye rect (image pixels)
    vec4 tanp;
    vec4 fovea;
    int layer;
} p;

layout(location = 0) out vec4 out_color;

bool shaded(ivec2 pix) {
    ivec2 rel = pix - p.rect.xy;
    if (any(lessThan(rel, ivec2(0))) || any(greaterThanEqual(rel, p.rect.zw))) {
        return false;
    }
    return !rdm_skipped(rel >> 1, p.tanp, p.fovea);
}

void main() {
    ivec2 pix = ivec2(gl_FragCoord.xy);
    ivec2 rel = pix - p.rect.xy;
    ivec2 q = rel >> 1;
    if (!rdm_skipped(q, p.tanp, p.fovea)) {
        discard;
    }
    ivec2 base = p.rect.xy + q * 2;
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
