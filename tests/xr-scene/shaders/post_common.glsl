// Shared by the post-processing shaders (post.frag, post_compute.comp, post_subpass.frag): their
// push constants, the tonemap operator, sRGB encoding and a bilinear filter in texel space.
// Everything here is per-pixel arithmetic with no state, so the same input gives the same bytes.

// Must match `post::PostPush` (std430 push constant layout: vec2s 8-aligned, no padding).
layout(push_constant) uniform Push {
    // The destination rect (viewport, or the dispatch's region of the storage image), pixels.
    vec2 dst_origin;
    vec2 dst_size;
    // The source rect in texels, the source texels per destination pixel, and 1 / the source
    // texture's extent.
    vec2 src_origin;
    vec2 src_size;
    vec2 src_scale;
    vec2 src_inv_extent;
    // The second input (bloom's up-sampled image, TAA's history, an up-sample's same-size level).
    vec2 aux_origin;
    vec2 aux_size;
    vec2 aux_scale;
    vec2 aux_inv_extent;
    uint mode;
    uint flags;
} pc;

const uint MODE_FINAL = 0u;
const uint MODE_DOWN = 1u;
const uint MODE_UP = 2u;

// The destination stores the bytes it is given (UNORM swapchain, storage image): encode sRGB here.
const uint FLAG_MANUAL_SRGB = 1u;
// The destination's bytes are B, G, R, A (a storage image copied into a BGRA swapchain).
const uint FLAG_BGRA = 2u;
const uint FLAG_BLOOM = 4u;
const uint FLAG_TAA = 8u;

const float EXPOSURE = 1.0;
const float BLOOM_STRENGTH = 0.08;
const float HISTORY_WEIGHT = 0.1;

// Narkowicz's fit of the ACES filmic curve: the per-pixel operator engines default to.
vec3 tonemap(vec3 c) {
    vec3 x = c * EXPOSURE;
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

vec3 srgb_encode(vec3 c) {
    vec3 lo = c * 12.92;
    vec3 hi = 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055;
    return mix(hi, lo, lessThanEqual(c, vec3(0.0031308)));
}

vec3 srgb_decode(vec3 c) {
    vec3 lo = c / 12.92;
    vec3 hi = pow((c + 0.055) / 1.055, vec3(2.4));
    return mix(hi, lo, lessThanEqual(c, vec3(0.04045)));
}

// Bilinear in texel space from integer fetches: `q` is the destination pixel's centre relative to
// the destination rect. At a scale of exactly 1 the weights are exactly 0, so every pixel is its
// source texel unchanged; below 1 it is the same arithmetic whatever the rect's place in its
// texture (`--render-scale` and `--viewport-scale` of one size give the same image). Texels
// outside the source rect are never read (clamped to its edge).
#define BILINEAR(name, fetch, origin, size, scale)                                              \
    vec3 name(vec2 q) {                                                                         \
        vec2 l = clamp(q * scale - 0.5, vec2(0.0), size - 1.0);                                 \
        vec2 f = floor(l);                                                                      \
        vec2 w = l - f;                                                                         \
        ivec2 a = ivec2(f);                                                                     \
        ivec2 b = min(a + 1, ivec2(size) - 1);                                                  \
        ivec2 o = ivec2(origin);                                                                \
        vec3 c00 = fetch(o + a);                                                                \
        vec3 c10 = fetch(o + ivec2(b.x, a.y));                                                  \
        vec3 c01 = fetch(o + ivec2(a.x, b.y));                                                  \
        vec3 c11 = fetch(o + b);                                                                \
        return mix(mix(c00, c10, w.x), mix(c01, c11, w.x), w.y);                                \
    }
