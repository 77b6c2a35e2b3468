#version 450
// The post chain's full-screen draws (`--post`): bloom's down- and up-samples into RGBA16F images,
// and the final tonemap into the swapchain image (plus bloom, or the TAA history). Compiled twice:
// with MULTIVIEW the inputs are 2-layer arrays read at gl_ViewIndex (one multiview draw for both
// eyes), otherwise plain 2D images.
#extension GL_GOOGLE_include_directive : require
#ifdef MULTIVIEW
#extension GL_EXT_multiview : require
#endif

#include "post_common.glsl"

#ifdef MULTIVIEW
layout(set = 0, binding = 0) uniform sampler2DArray src;
layout(set = 0, binding = 1) uniform sampler2DArray aux;
#define LAYER float(gl_ViewIndex)
#define AT(uv) vec3(uv, LAYER)
#define FETCH_AT(p) ivec3(p, gl_ViewIndex)
#else
layout(set = 0, binding = 0) uniform sampler2D src;
layout(set = 0, binding = 1) uniform sampler2D aux;
#define AT(uv) (uv)
#define FETCH_AT(p) (p)
#endif

layout(location = 0) out vec4 out_color;

vec3 fetch_src(ivec2 p) { return texelFetch(src, FETCH_AT(p), 0).rgb; }
vec3 fetch_aux(ivec2 p) { return texelFetch(aux, FETCH_AT(p), 0).rgb; }
BILINEAR(src_bilinear, fetch_src, pc.src_origin, pc.src_size, pc.src_scale)
BILINEAR(aux_bilinear, fetch_aux, pc.aux_origin, pc.aux_size, pc.aux_scale)

// Filtered (hardware bilinear) reads for the bloom chain, clamped half a texel inside the rect so
// no tap reaches the other eye's half or what lies outside a `--viewport-scale` sub-rect.
vec3 src_tap(vec2 q, vec2 offset) {
    vec2 t = clamp(pc.src_origin + q * pc.src_scale + offset, pc.src_origin + 0.5, pc.src_origin + pc.src_size - 0.5);
    return textureLod(src, AT(t * pc.src_inv_extent), 0.0).rgb;
}

vec3 aux_tap(vec2 q) {
    vec2 t = clamp(pc.aux_origin + q * pc.aux_scale, pc.aux_origin + 0.5, pc.aux_origin + pc.aux_size - 0.5);
    return textureLod(aux, AT(t * pc.aux_inv_extent), 0.0).rgb;
}

void main() {
    vec2 q = gl_FragCoord.xy - pc.dst_origin;
    vec3 c;
    if (pc.mode == MODE_DOWN) {
        // Half size: a small blur of the source around this pixel (centre and 4 diagonals).
        c = 0.5 * src_tap(q, vec2(0.0));
        c += 0.125 * (src_tap(q, vec2(-1.0, -1.0)) + src_tap(q, vec2(1.0, -1.0)) + src_tap(q, vec2(-1.0, 1.0)) + src_tap(q, vec2(1.0, 1.0)));
    } else if (pc.mode == MODE_UP) {
        // Double size: a 3x3 tent of the smaller level, plus this level's down-sample.
        c = vec3(0.0);
        for (int y = -1; y <= 1; y++) {
            for (int x = -1; x <= 1; x++) {
                float w = float((2 - abs(x)) * (2 - abs(y))) / 16.0;
                c += w * src_tap(q, vec2(x, y));
            }
        }
        c += aux_tap(q);
    } else {
        c = src_bilinear(q);
        if ((pc.flags & FLAG_BLOOM) != 0u) {
            c += BLOOM_STRENGTH * aux_tap(q);
        }
        c = tonemap(c);
        if ((pc.flags & FLAG_TAA) != 0u) {
            // The history holds last frame's output as stored: decode what the hardware did not.
            vec3 h = aux_bilinear(q);
            if ((pc.flags & FLAG_MANUAL_SRGB) != 0u) {
                h = srgb_decode(h);
            }
            c = mix(c, h, HISTORY_WEIGHT);
        }
        if ((pc.flags & FLAG_MANUAL_SRGB) != 0u) {
            c = srgb_encode(c);
        }
    }
    out_color = vec4(c, 1.0);
}
