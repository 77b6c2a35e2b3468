#version 450
#extension GL_GOOGLE_include_directive : require
// RCAS as a compute pass: one invocation per pixel of `rect`, reading the EASU output `src`
// (texelFetch, clamped to the rect) and writing `dst` (upscale_rcas.glsl has the filter). With
// OUT_RGBA8 the output is 8-bit texels in the runtime image's encoding, copied into it bit for bit
// afterwards: sRGB-encoded when `sharpness.y` is 1, red and blue swapped (a BGRA image) when
// `sharpness.z` is 1.
layout(local_size_x = 16, local_size_y = 16) in;

#include "upscale_rcas.glsl"

#ifdef OUT_RGBA8
layout(set = 0, binding = 1, rgba8) uniform writeonly image2D dst;
#else
layout(set = 0, binding = 1, rgba16f) uniform writeonly image2D dst;
#endif

vec3 srgb_encode(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main() {
    ivec2 q = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(q, p.rect.zw))) {
        return;
    }
    vec3 c = rcas(q);
#ifdef OUT_RGBA8
    if (p.sharpness.y > 0.5) {
        c = srgb_encode(c);
    }
    if (p.sharpness.z > 0.5) {
        c = c.bgr;
    }
#endif
    imageStore(dst, p.rect.xy + q, vec4(c, 1.0));
}
