#version 450
// stereoshim's upscale by CAS (contrast-adaptive sharpening with scaling, `upscale.method = cas`),
// written from its published description, operation for operation as the CPU reference
// src/features/upscale/filter.rs `cas` (which documents it): the four source texels nearest the
// output's position, each sharpened by the CAS rule over its cross, blended bilinearly. The same
// interface as upscale_easu.comp; `params.x` is the sharpness.
layout(local_size_x = 16, local_size_y = 16) in;

layout(set = 0, binding = 0) uniform sampler2D src;
layout(set = 0, binding = 1, rgba16f) uniform writeonly image2D dst;

layout(push_constant) uniform Params {
    ivec4 src_rect;  // x, y, width, height (texels of `src`)
    ivec4 dst_rect;  // x, y, width, height (texels of `dst`)
    vec4 params;     // x: sharpness 0 .. 1
    ivec4 skip;      // x: the first entry of the tile list, y: 1 when there is one
} p;

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

vec3 tap(ivec2 t) {
    ivec2 c = clamp(t, ivec2(0), p.src_rect.zw - 1) + p.src_rect.xy;
    return texelFetch(src, c, 0).rgb;
}

vec3 sharp(ivec2 c, float peak) {
    vec3 e = tap(c);
    vec3 b = tap(c + ivec2(0, -1)), d = tap(c + ivec2(-1, 0)), f = tap(c + ivec2(1, 0)), h = tap(c + ivec2(0, 1));
    vec3 lo = min(e, min(min(b, d), min(f, h)));
    vec3 hi = max(e, max(max(b, d), max(f, h)));
    vec3 out_;
    for (int k = 0; k < 3; k++) {
        float amp = hi[k] > 0.0 ? sqrt(clamp(min(lo[k], 1.0 - hi[k]) / hi[k], 0.0, 1.0)) : 0.0;
        float w = amp * peak;
        float sum = b[k] + d[k] + f[k] + h[k];
        out_[k] = clamp((sum * w + e[k]) / (1.0 + 4.0 * w), 0.0, 1.0);
    }
    return out_;
}

void main() {
    ivec2 o = pixel();
    if (any(greaterThanEqual(o, p.dst_rect.zw))) {
        return;
    }
    float peak = -1.0 / (8.0 - 3.0 * clamp(p.params.x, 0.0, 1.0));
    vec2 pos = (vec2(o) + 0.5) * vec2(p.src_rect.zw) / vec2(p.dst_rect.zw) - 0.5;
    vec2 fl = floor(pos);
    vec2 t = pos - fl;
    ivec2 f = ivec2(fl);
    vec3 top = sharp(f, peak) * (1.0 - t.x) + sharp(f + ivec2(1, 0), peak) * t.x;
    vec3 bottom = sharp(f + ivec2(0, 1), peak) * (1.0 - t.x) + sharp(f + ivec2(1, 1), peak) * t.x;
    imageStore(dst, p.dst_rect.xy + o, vec4(top * (1.0 - t.y) + bottom * t.y, 1.0));
}
