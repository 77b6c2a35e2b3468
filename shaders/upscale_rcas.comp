#version 450
// stereoshim's upscale, second pass: RCAS (robust contrast-adaptive sharpening), written from the
// published description of FidelityFX Super Resolution 1, operation for operation as the CPU
// reference src/features/upscale/filter.rs `rcas`. One invocation per pixel of `rect`, reading
// the EASU output `src` (texelFetch, clamped to the rect) and writing `dst`.
layout(local_size_x = 16, local_size_y = 16) in;

layout(set = 0, binding = 0) uniform sampler2D src;
layout(set = 0, binding = 1, rgba16f) uniform writeonly image2D dst;

layout(push_constant) uniform Params {
    ivec4 rect;       // x, y, width, height (the same texels in `src` and `dst`)
    vec4 sharpness;   // x: 0 (none) .. 1 (full)
} p;

// The largest lobe: a neighbour weight of -3/16.
const float LIMIT = 0.25 - 1.0 / 16.0;

vec3 at(ivec2 q) {
    return texelFetch(src, clamp(q, ivec2(0), p.rect.zw - 1) + p.rect.xy, 0).rgb;
}

void main() {
    ivec2 q = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(q, p.rect.zw))) {
        return;
    }
    vec3 e = at(q);
    vec3 b = at(q + ivec2(0, -1)), d = at(q + ivec2(-1, 0)), f = at(q + ivec2(1, 0)), h = at(q + ivec2(0, 1));
    vec3 mn = min(min(b, d), min(f, h));
    vec3 mx = max(max(b, d), max(f, h));
    float lobe = -1.0e30;
    for (int c = 0; c < 3; c++) {
        float low = mx[c] > 0.0 ? -min(mn[c], e[c]) / (4.0 * mx[c]) : 0.0;
        float high = mn[c] < 1.0 ? (1.0 - max(mx[c], e[c])) / (4.0 * mn[c] - 4.0) : 0.0;
        lobe = max(lobe, max(low, high));
    }
    lobe = clamp(lobe, -LIMIT, 0.0) * clamp(p.sharpness.x, 0.0, 1.0);
    vec3 r = ((b + d + f + h) * lobe + e) / (4.0 * lobe + 1.0);
    imageStore(dst, p.rect.xy + q, vec4(r, 1.0));
}
