#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
// Reconstruction of the quads radial density masking skipped, as a compute pass over the eye's
// periphery tiles only (src/features/foveation/rdm/rules.rs `periphery_tiles`: every tile of
// 16×16 quads that may hold a skipped quad; tiles wholly inside the inner ring are never
// dispatched). One workgroup per tile, 4 quads per invocation. A skipped quad evaluates the rule for
// its 8 neighbour quads (which were shaded), reads the shaded pixels among the 12 bordering it once
// and writes its 4 pixels, each the inverse-squared-distance weighted mean of them
// (`reconstruction_weight`, as rdm_fill.frag).
//
// `px` holds the eye's pixels (its rect within the image, row by row from `clip.xy`), copied out
// of the image just before and copied back (the tiles) just after: 4-byte RGBA8 / BGRA8 texels
// as plain words (with HALF, RGBA16F texels as two words, unpacked as half floats), which a software rasterizer reads far faster than an image (no format
// conversion per access; the channel order does not matter to a per-channel filter). Reads touch
// only shaded pixels and writes only skipped ones, so the pass works in place without a hazard.
// With an sRGB swapchain the filter works on linear values, as the fill's sRGB sampler and
// attachment do: decoded by `to_linear`, encoded by `to_srgb`, both from square roots (one
// instruction on a CPU; pow() is a long polynomial there, and a lookup table costs a gather per
// channel), together within 0.25 levels of the exact curve for the means this filter takes.
//
// Written without local arrays or loops over neighbours: every neighbour's four weights are
// constants (TAKE below), so the code is straight-line — what a SIMD-on-CPU compiler wants.
#include "rdm_rule.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// HALF: RGBA16F texels, two words each (an HDR target behind a post chain); otherwise one
// RGBA8 / BGRA8 word per texel.
layout(std430, set = 0, binding = 0) buffer Pixels {
    uint px[];
};

#ifdef FROM_LINK
// At an eye pass's end (src/features/foveation/rdm/pass_end_compute.rs): one dispatch over every
// eye's tiles, the eyes' parameters and tiles from the recording's link buffer, written when the
// recording is made or, for a pass whose eyes are known only then, at each submission. A tile
// word is x | y << 12 | eye << 24. No push constants: the app's compute push constants stay as
// they were.
struct Params {
    ivec4 rect;
    vec4 tanp;
    vec4 fovea;
    ivec4 misc;
    ivec4 clip;
};
layout(std430, set = 0, binding = 1) readonly buffer Link {
    uvec4 dispatch_args;   // read by vkCmdDispatchIndirect
    Params eyes[8];
    uint tiles[];
};
Params p;
#else
// Tiles of this dispatch from `misc.y`: x | y << 16, in tiles of the eye rect.
layout(std430, set = 0, binding = 1) readonly buffer Tiles {
    uint tiles[];
};

layout(push_constant) uniform Params {
    ivec4 rect;   // x, y, width, height of the eye rect (image pixels)
    vec4 tanp;
    vec4 fovea;
    ivec4 misc;   // first texel of the eye in `px`, first tile of the eye in `tiles`, sRGB (1), unused
    ivec4 clip;   // the rect within the image (image pixels): what `px` holds, rows of clip.z texels
} p;
#endif


// sRGB → linear: the curve's linear segment exactly, above it ((c + 0.055) / 1.055)^2.4 as x² times
// a least-squares fit of x^0.4 by x^(1/2), x^(1/4), x^(1/8) and x over the segment's range
// (relative error below 1e-4).
vec3 to_linear(vec3 c) {
    vec3 x = (c + 0.055) / 1.055;
    vec3 s1 = sqrt(x);
    vec3 s2 = sqrt(s1);
    vec3 s3 = sqrt(s2);
    vec3 curve = x * x * (0.589384853 * s1 + 0.594640401 * s2 - 0.160445306 * s3 - 0.0236081725 * x);
    return mix(curve, c / 12.92, lessThanEqual(c, vec3(0.04045)));
}

// Linear → sRGB: the curve's linear segment exactly, above it Ian Taylor's approximation of
// 1.055 l^(1/2.4) − 0.055 by three square roots (within 0.25 levels of the exact curve for the
// means this filter takes; a square root is one instruction on a CPU, pow() a long polynomial).
vec3 to_srgb(vec3 l) {
    vec3 s1 = sqrt(l);
    vec3 s2 = sqrt(s1);
    vec3 s3 = sqrt(s2);
    vec3 curve = max(vec3(0.0), 0.662002687 * s1 + 0.684122060 * s2 - 0.323583601 * s3 - 0.0225411470 * l);
    return mix(curve, l * 12.92, lessThanEqual(l, vec3(0.0031308)));
}

bool inside_clip(ivec2 pix) {
    return all(greaterThanEqual(pix, p.clip.xy)) && all(lessThan(pix, p.clip.xy + p.clip.zw));
}

uint word_index(ivec2 pix) {
    return uint(p.misc.x) + uint((pix.y - p.clip.y) * p.clip.z + (pix.x - p.clip.x));
}

vec4 load(ivec2 pix) {
#ifdef HALF
    uint i = 2u * word_index(pix);
    return vec4(unpackHalf2x16(px[i]), unpackHalf2x16(px[i + 1u]));
#else
    vec4 c = unpackUnorm4x8(px[word_index(pix)]);
    if (p.misc.z == 1) {
        c.rgb = to_linear(c.rgb);
    }
    return c;
#endif
}

// Writes pixel (px, py) of the quad at rect-relative pixel q2 (image pixel base): the weighted
// mean, when any neighbour counted and the pixel lies inside the rect and the image.
void store(ivec2 q2, ivec2 base, int px_, int py, vec4 sum, float wsum) {
    ivec2 rel = q2 + ivec2(px_, py);
    ivec2 pix = base + ivec2(px_, py);
    if (wsum == 0.0 || any(greaterThanEqual(rel, p.rect.zw)) || !inside_clip(pix)) {
        return;
    }
    vec4 r = sum / wsum;
#ifdef HALF
    uint i = 2u * word_index(pix);
    px[i] = packHalf2x16(r.xy);
    px[i + 1u] = packHalf2x16(r.zw);
#else
    if (p.misc.z == 1) {
        r.rgb = to_srgb(r.rgb);
    }
    px[word_index(pix)] = packUnorm4x8(r);
#endif
}

// Fills quad q (rect-relative quad coordinates) when the rule skipped it.
void quad(ivec2 q) {
    ivec2 quads = (p.rect.zw + 1) / 2;
    if (any(greaterThanEqual(q, quads)) || !rdm_skipped(q, p.tanp, p.fovea)) {
        return;
    }
    // Which of the 8 neighbour quads were shaded: the rule once per neighbour (no shared memory:
    // a workgroup barrier costs a software rasterizer far more than 8 evaluations of the rule).
#define SHADED(ox, oy) (all(greaterThanEqual(q + ivec2(ox, oy), ivec2(0))) && all(lessThan(q + ivec2(ox, oy), quads)) && !rdm_skipped(q + ivec2(ox, oy), p.tanp, p.fovea))
    bool n00 = SHADED(-1, -1), n10 = SHADED(0, -1), n20 = SHADED(1, -1);
    bool n01 = SHADED(-1, 0), n21 = SHADED(1, 0);
    bool n02 = SHADED(-1, 1), n12 = SHADED(0, 1), n22 = SHADED(1, 1);
    ivec2 q2 = q * 2;
    ivec2 base = p.rect.xy + q2;
    vec4 s00 = vec4(0.0), s10 = vec4(0.0), s01 = vec4(0.0), s11 = vec4(0.0);
    float w00 = 0.0, w10 = 0.0, w01 = 0.0, w11 = 0.0;
    // Neighbour pixel (dx, dy) of the quad's top-left pixel counts when its quad was shaded and it
    // lies inside the rect and the image; it adds to each of the quad's four pixels with weight
    // 1 / squared distance (constants folded at compile time).
#define W(dx, dy, px, py) (1.0 / float(((dx) - (px)) * ((dx) - (px)) + ((dy) - (py)) * ((dy) - (py))))
#define TAKE(shaded, dx, dy) { \
        ivec2 rel_ = q2 + ivec2(dx, dy); \
        ivec2 pix_ = base + ivec2(dx, dy); \
        if (shaded && all(lessThan(rel_, p.rect.zw)) && inside_clip(pix_)) { \
            vec4 v_ = load(pix_); \
            s00 += W(dx, dy, 0, 0) * v_; w00 += W(dx, dy, 0, 0); \
            s10 += W(dx, dy, 1, 0) * v_; w10 += W(dx, dy, 1, 0); \
            s01 += W(dx, dy, 0, 1) * v_; w01 += W(dx, dy, 0, 1); \
            s11 += W(dx, dy, 1, 1) * v_; w11 += W(dx, dy, 1, 1); \
        } \
    }
    TAKE(n00, -1, -1) TAKE(n10, 0, -1) TAKE(n10, 1, -1) TAKE(n20, 2, -1)
    TAKE(n01, -1, 0) TAKE(n21, 2, 0)
    TAKE(n01, -1, 1) TAKE(n21, 2, 1)
    TAKE(n02, -1, 2) TAKE(n12, 0, 2) TAKE(n12, 1, 2) TAKE(n22, 2, 2)
    store(q2, base, 0, 0, s00, w00);
    store(q2, base, 1, 0, s10, w10);
    store(q2, base, 0, 1, s01, w01);
    store(q2, base, 1, 1, s11, w11);
}

void main() {
#ifdef FROM_LINK
    uint t = tiles[gl_WorkGroupID.x];
    p = eyes[t >> 24];
    ivec2 q0 = ivec2(int(t & 0xfffu), int((t >> 12) & 0xfffu)) * 16;
#else
    uint t = tiles[uint(p.misc.y) + gl_WorkGroupID.x];
    ivec2 q0 = ivec2(int(t & 0xffffu), int(t >> 16)) * 16;
#endif
    // Each invocation takes 2×2 quads of the 16×16-quad tile, a row of invocations every other
    // quad, so neighbouring SIMD lanes hold quads of one parity (the same skip pattern within a
    // ring); 4 quads per invocation make 4× fewer workgroups, each of which a software rasterizer
    // pays a fixed cost for.
    ivec2 i = ivec2(gl_LocalInvocationID.xy) * 2;
    // Not unrolled: the body is large, and a JIT compiler (lavapipe) pays for it four times over
    // at pipeline creation.
    [[dont_unroll]] for (int k = 0; k < 4; k++) {
        quad(q0 + i + ivec2(k & 1, k >> 1));
    }
}
