#version 450
#extension GL_GOOGLE_include_directive : require
// RCAS as a compute pass: one invocation per pixel of `rect`, reading the EASU output `src`
// (texelFetch, clamped to the rect) and writing `dst` (upscale_rcas.glsl has the filter). With
// OUT_RGBA8 the output is 8-bit texels in the runtime image's encoding, copied into it bit for bit
// afterwards: sRGB-encoded when `sharpness.y` is 1, red and blue swapped (a BGRA image) when
// `sharpness.z` is 1.
layout(local_size_x = 16, local_size_y = 16) in;

#include "upscale_rcas.glsl"

// `upscale.skip_hidden`: the pass runs only the 16×16 tiles of the job the lens shows (or that
// a shown pixel's filter reads: src/features/upscale/lens.rs), listed from `tiles[skip.x]` as
// x | y << 16, one per workgroup of a one-dimensional dispatch; the others keep the black they
// were cleared to. skip.y = 0: a two-dimensional dispatch over the whole rect.
layout(set = 0, binding = 2, std430) readonly buffer Tiles {
    uint tiles[];
};

ivec2 pixel() {
    if (p.skip.y == 0) {
        return ivec2(gl_GlobalInvocationID.xy);
    }
    uint t = tiles[p.skip.x + int(gl_WorkGroupID.x)];
    return ivec2(int(t & 0xffffu), int(t >> 16)) * ivec2(gl_WorkGroupSize.xy) + ivec2(gl_LocalInvocationID.xy);
}

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
    ivec2 q = pixel();
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
