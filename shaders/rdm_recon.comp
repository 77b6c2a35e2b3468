#version 450
#extension GL_GOOGLE_include_directive : require
// Reconstruction of the quads radial density masking skipped, as a compute pass over the eye's
// periphery tiles only (src/features/foveation/rdm/rules.rs `periphery_tiles`: every tile of 8×8
// quads that may hold a skipped quad; tiles wholly inside the inner ring are never dispatched).
// One workgroup per tile, one invocation per quad. The workgroup evaluates the skip rule once per
// quad of its tile and the one-quad border around it (shared memory), so a skipped quad knows
// which of its 8 neighbour quads were shaded without re-evaluating the rule per pixel; it then
// reads the shaded pixels among the 12 bordering it once and writes its 4 pixels, each the
// inverse-squared-distance weighted mean of them (`reconstruction_weight`, as rdm_fill.frag).
//
// `img` is the layer's temp copy of the swapchain image: reads touch only shaded pixels and
// writes only skipped ones, so the pass works in place without a hazard between invocations. With
// an sRGB swapchain the temp image is the UNORM format of the same bytes (storage images cannot
// be sRGB on most GPUs): the shader decodes to linear, averages, and encodes, as the sampler and
// the colour attachment of the fallback fill do.
#include "rdm_rule.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

#ifdef HALF_FLOAT
layout(set = 0, binding = 0, rgba16f) uniform image2DArray img;
#else
layout(set = 0, binding = 0, rgba8) uniform image2DArray img;
#endif

// Tiles of this dispatch from `first`: x | y << 16, in tiles of the eye rect.
layout(std430, set = 0, binding = 1) readonly buffer Tiles {
    uint tiles[];
};

layout(push_constant) uniform Params {
    ivec4 rect;   // x, y, width, height of the eye rect (image pixels)
    vec4 tanp;
    vec4 fovea;
    ivec4 misc;   // array layer, first tile of this eye in `tiles`, sRGB (1) or linear (0), unused
    ivec4 size;   // image width, height, unused, unused: pixels outside the image are never touched
} p;

// Per quad of the tile plus a one-quad border: 0 shaded, 1 skipped, 2 outside the rect.
shared uint state[10 * 10];

float to_linear(float c) {
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

float to_srgb(float l) {
    return l <= 0.0031308 ? l * 12.92 : 1.055 * pow(l, 1.0 / 2.4) - 0.055;
}

vec4 load(ivec2 pix) {
    vec4 c = imageLoad(img, ivec3(pix, p.misc.x));
    if (p.misc.z == 1) {
        c.rgb = vec3(to_linear(c.r), to_linear(c.g), to_linear(c.b));
    }
    return c;
}

void main() {
    uint t = tiles[uint(p.misc.y) + gl_WorkGroupID.x];
    ivec2 q0 = ivec2(int(t & 0xffffu), int(t >> 16)) * 8;
    ivec2 quads = (p.rect.zw + 1) / 2;
    for (uint i = gl_LocalInvocationIndex; i < 100u; i += 64u) {
        ivec2 q = q0 - 1 + ivec2(int(i % 10u), int(i / 10u));
        uint v = 2u;
        if (all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, quads))) {
            v = rdm_skipped(q, p.tanp, p.fovea) ? 1u : 0u;
        }
        state[i] = v;
    }
    barrier();
    ivec2 l = ivec2(gl_LocalInvocationID.xy);
    if (state[(l.y + 1) * 10 + l.x + 1] != 1u) {
        return;
    }
    ivec2 q = q0 + l;
    ivec2 base = p.rect.xy + q * 2;
    // The 12 pixels around the quad, row by row; a pixel counts when its quad was shaded and it
    // lies inside the rect and the image.
    vec4 c[12];
    ivec2 o[12];
    bool ok[12];
    int n = 0;
    for (int dy = -1; dy <= 2; dy++) {
        for (int dx = -1; dx <= 2; dx++) {
            if (dx >= 0 && dx <= 1 && dy >= 0 && dy <= 1) {
                continue;
            }
            ivec2 nq = ivec2(dx < 0 ? 0 : (dx > 1 ? 2 : 1), dy < 0 ? 0 : (dy > 1 ? 2 : 1));
            ivec2 rel = q * 2 + ivec2(dx, dy);
            ivec2 pix = base + ivec2(dx, dy);
            bool shaded = state[(l.y + nq.y) * 10 + l.x + nq.x] == 0u && all(lessThan(rel, p.rect.zw)) && all(greaterThanEqual(rel, ivec2(0)))
                && all(greaterThanEqual(pix, ivec2(0))) && all(lessThan(pix, p.size.xy));
            o[n] = ivec2(dx, dy);
            ok[n] = shaded;
            c[n] = shaded ? load(pix) : vec4(0.0);
            n++;
        }
    }
    for (int py = 0; py <= 1; py++) {
        for (int px = 0; px <= 1; px++) {
            ivec2 rel = q * 2 + ivec2(px, py);
            ivec2 pix = base + ivec2(px, py);
            if (any(greaterThanEqual(rel, p.rect.zw)) || any(lessThan(pix, ivec2(0))) || any(greaterThanEqual(pix, p.size.xy))) {
                continue;
            }
            vec4 sum = vec4(0.0);
            float wsum = 0.0;
            for (int i = 0; i < 12; i++) {
                if (!ok[i]) {
                    continue;
                }
                vec2 d = vec2(o[i] - ivec2(px, py));
                float w = 1.0 / dot(d, d);
                sum += w * c[i];
                wsum += w;
            }
            if (wsum == 0.0) {
                continue;
            }
            vec4 r = sum / wsum;
            if (p.misc.z == 1) {
                r.rgb = vec3(to_srgb(r.r), to_srgb(r.g), to_srgb(r.b));
            }
            imageStore(img, ivec3(pix, p.misc.x), r);
        }
    }
}
