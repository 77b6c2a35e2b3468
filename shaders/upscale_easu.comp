#version 450
// stereoshim's upscale, first pass: EASU (edge-adaptive spatial upsampling), written from the
// published description of FidelityFX Super Resolution 1, operation for operation as the CPU
// reference src/features/upscale/filter.rs `easu` (which documents the algorithm). One invocation
// per output pixel of `dst_rect`; the source is `src_rect` of `src` (read with texelFetch,
// clamped to the rect's edge), in linear values (an sRGB image decodes on fetch).
layout(local_size_x = 16, local_size_y = 16) in;

layout(set = 0, binding = 0) uniform sampler2D src;
layout(set = 0, binding = 1, rgba16f) uniform writeonly image2D dst;

layout(push_constant) uniform Params {
    ivec4 src_rect;  // x, y, width, height (texels of `src`)
    ivec4 dst_rect;  // x, y, width, height (texels of `dst`)
    // The region EASU runs in (`upscale.fovea_only`): an ellipse, centre x, y and radii in texels
    // of `dst`; bilinear outside. z = 0: EASU everywhere; z < 0: bilinear everywhere
    // (`upscale.method = bilinear`).
    vec4 fovea;
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

float luma(vec3 c) {
    return 0.5 * c.r + c.g + 0.5 * c.b;
}

// One "+" shape: gradient into `dir`, edge strength into `len`, weighted `w`.
void plus(inout vec2 dir, inout float len, float w, float l, float c, float r, float u, float d) {
    float steep_x = max(abs(c - l), abs(r - c));
    float grad_x = r - l;
    float sx = steep_x > 0.0 ? clamp(abs(grad_x) / steep_x, 0.0, 1.0) : 0.0;
    float steep_y = max(abs(c - u), abs(d - c));
    float grad_y = d - u;
    float sy = steep_y > 0.0 ? clamp(abs(grad_y) / steep_y, 0.0, 1.0) : 0.0;
    dir += vec2(grad_x, grad_y) * w;
    len += (sx * sx + sy * sy) * w;
}

void main() {
    ivec2 o = pixel();
    if (any(greaterThanEqual(o, p.dst_rect.zw))) {
        return;
    }
    vec2 pos = (vec2(o) + 0.5) * vec2(p.src_rect.zw) / vec2(p.dst_rect.zw) - 0.5;
    vec2 fl = floor(pos);
    vec2 t = pos - fl;
    ivec2 f = ivec2(fl);
    if (p.fovea.z != 0.0) {
        vec2 d = p.fovea.z > 0.0 ? (vec2(p.dst_rect.xy + o) + 0.5 - p.fovea.xy) / p.fovea.zw : vec2(2.0);
        if (dot(d, d) > 1.0) {
            vec3 top = mix(tap(f), tap(f + ivec2(1, 0)), t.x);
            vec3 bottom = mix(tap(f + ivec2(0, 1)), tap(f + ivec2(1, 1)), t.x);
            imageStore(dst, p.dst_rect.xy + o, vec4(mix(top, bottom, t.y), 1.0));
            return;
        }
    }
    // The 12 taps: rows -1..2, the 4×4 block without its corners.
    vec3 b = tap(f + ivec2(0, -1)), c = tap(f + ivec2(1, -1));
    vec3 e = tap(f + ivec2(-1, 0)), ff = tap(f + ivec2(0, 0)), g = tap(f + ivec2(1, 0)), h = tap(f + ivec2(2, 0));
    vec3 i = tap(f + ivec2(-1, 1)), j = tap(f + ivec2(0, 1)), k = tap(f + ivec2(1, 1)), l = tap(f + ivec2(2, 1));
    vec3 n = tap(f + ivec2(0, 2)), q = tap(f + ivec2(1, 2));
    float lb = luma(b), lc = luma(c), le = luma(e), lf = luma(ff), lg = luma(g), lh = luma(h);
    float li = luma(i), lj = luma(j), lk = luma(k), ll = luma(l), ln = luma(n), lq = luma(q);
    vec2 dir = vec2(0.0);
    float len = 0.0;
    plus(dir, len, (1.0 - t.x) * (1.0 - t.y), le, lf, lg, lb, lj);
    plus(dir, len, t.x * (1.0 - t.y), lf, lg, lh, lc, lk);
    plus(dir, len, (1.0 - t.x) * t.y, li, lj, lk, lf, ln);
    plus(dir, len, t.x * t.y, lj, lk, ll, lg, lq);
    float d2 = dot(dir, dir);
    vec2 nd = d2 < 1.0 / 32768.0 ? vec2(1.0, 0.0) : dir / sqrt(d2);
    len = len * 0.5;
    len = len * len;
    float stretch = dot(nd, nd) / max(abs(nd.x), abs(nd.y));
    vec2 scale = vec2(1.0 + (stretch - 1.0) * len, 1.0 - 0.5 * len);
    float lobe = 0.5 + ((1.0 / 4.0 - 0.04) - 0.5) * len;
    float clip_d = 1.0 / lobe;
    vec3 sum = vec3(0.0);
    float wsum = 0.0;
#define TAKE(col, ox, oy) { \
        vec2 v_ = vec2(float(ox), float(oy)) - t; \
        vec2 r_ = vec2(dot(v_, nd), dot(v_, vec2(-nd.y, nd.x))) * scale; \
        float dd_ = min(dot(r_, r_), clip_d); \
        float base_ = 25.0 / 16.0 * (2.0 / 5.0 * dd_ - 1.0) * (2.0 / 5.0 * dd_ - 1.0) - (25.0 / 16.0 - 1.0); \
        float win_ = (lobe * dd_ - 1.0) * (lobe * dd_ - 1.0); \
        float w_ = base_ * win_; \
        sum += col * w_; \
        wsum += w_; \
    }
    TAKE(b, 0, -1) TAKE(c, 1, -1)
    TAKE(e, -1, 0) TAKE(ff, 0, 0) TAKE(g, 1, 0) TAKE(h, 2, 0)
    TAKE(i, -1, 1) TAKE(j, 0, 1) TAKE(k, 1, 1) TAKE(l, 2, 1)
    TAKE(n, 0, 2) TAKE(q, 1, 2)
    vec3 mean = abs(wsum) > 1e-12 ? sum / wsum : ff;
    vec3 lo = min(min(ff, g), min(j, k));
    vec3 hi = max(max(ff, g), max(j, k));
    imageStore(dst, p.dst_rect.xy + o, vec4(clamp(mean, lo, hi), 1.0));
}
