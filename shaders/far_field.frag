#version 450
// stereoshim's monoscopic far field: map this destination pixel into the source eye's copy
// (rotation + both FOVs; with the depth shift also the disparity of the source's own depth there),
// and write the source's colour only where every source sample of the footprint lies beyond the
// split distance. Anywhere else nothing is written: the app renders the pixel itself.
//
// The vertex shader classed the fragment's tile (`cls`): in a FULL tile every source texel any of
// its fragments may read is far, so the tests below are known to pass and are skipped.
//
// MSAA (multisampled eye passes): the copies are multisampled too; a source texel is far only if
// every sample is, and its colour is the mean of its samples (what a resolve gives), filtered
// bilinearly by hand.
#ifdef MSAA
#define SAMPLER sampler2DMS
#else
#define SAMPLER sampler2D
#endif
layout(set = 0, binding = 0) uniform SAMPLER color0;
layout(set = 0, binding = 1) uniform SAMPLER depth0;
layout(set = 0, binding = 2) uniform SAMPLER color1;
layout(set = 0, binding = 3) uniform SAMPLER depth1;

// xyz: the map's columns; m0.w, m1.w: 1 / the slot image's extent (it may be larger than the copy).
layout(location = 0) flat in vec4 m0;
layout(location = 1) flat in vec4 m1;
layout(location = 2) flat in vec4 m2;
// xyz: the destination's position in source pixels; w: 1 for the depth shift.
layout(location = 3) flat in vec4 k;
// 1/z = x + y * depth; z: 1/split distance; w: the split plane's depth.
layout(location = 4) flat in vec4 depth;
// The copy's extent (pixels); z: samples per pixel.
layout(location = 5) flat in vec4 size;
layout(location = 6) flat in uvec4 flags;
// The tile's class (far_field.vert): 1 = FULL, 2 = MIXED (culled tiles have no fragments).
layout(location = 7) flat in uint cls;

layout(location = 0) out vec4 out_color;

#ifdef MSAA
// The farthest-looking test needs every sample: the nearest sample decides (largest 1/z).
float stored_depth(ivec2 t) {
    float nearest_inv_z = -1.0e30;
    float chosen = 0.0;
    for (int s = 0; s < int(size.z); s++) {
        float d = flags.x == 0u ? texelFetch(depth0, t, s).r : texelFetch(depth1, t, s).r;
        float inv_z = depth.x + depth.y * d;
        if (inv_z > nearest_inv_z) {
            nearest_inv_z = inv_z;
            chosen = d;
        }
    }
    return chosen;
}

vec4 texel(ivec2 t) {
    vec4 sum = vec4(0.0);
    for (int s = 0; s < int(size.z); s++) {
        sum += flags.x == 0u ? texelFetch(color0, t, s) : texelFetch(color1, t, s);
    }
    return sum / size.z;
}
#else
float stored_depth(ivec2 t) {
    return flags.x == 0u ? texelFetch(depth0, t, 0).r : texelFetch(depth1, t, 0).r;
}
#endif

bool inside(ivec2 t) {
    return t.x >= 0 && t.y >= 0 && t.x < int(size.x) && t.y < int(size.y);
}

// Beyond the split: 1/z below the split's (the clear value's 1/z is the farthest there is).
bool far_at(ivec2 t) {
    return inside(t) && depth.x + depth.y * stored_depth(t) < depth.z;
}

void main() {
    bool full = cls == 1u;
    mat3 m = mat3(m0.xyz, m1.xyz, m2.xyz);
    vec3 h = m * vec3(gl_FragCoord.xy, 1.0);
    if (!full && h.z <= 0.0) {
        discard;
    }
    vec2 uv = h.xy / h.z;
    if (k.w > 0.5) {
        ivec2 t = ivec2(floor(uv));
        if (!full && !far_at(t)) {
            discard;
        }
        float inv_z = max(depth.x + depth.y * stored_depth(t), 0.0);
        vec3 shifted = h + k.xyz * inv_z;
        if (!full && shifted.z <= 0.0) {
            discard;
        }
        uv = shifted.xy / shifted.z;
    }
    // The bilinear footprint: all four samples must be far.
    ivec2 t0 = ivec2(floor(uv - 0.5));
#ifdef MSAA
    if (!full && (!far_at(t0) || !far_at(t0 + ivec2(1, 0)) || !far_at(t0 + ivec2(0, 1)) || !far_at(t0 + ivec2(1, 1)))) {
        discard;
    }
#else
    if (!full) {
        // One gather fetches the four depths (fragment shading is the scarce resource on some
        // GPUs: one fetch instead of four).
        if (!inside(t0) || !inside(t0 + ivec2(1, 1))) {
            discard;
        }
        vec2 centre = (vec2(t0) + 1.0) * vec2(m0.w, m1.w);
        vec4 d4 = flags.x == 0u ? textureGather(depth0, centre, 0) : textureGather(depth1, centre, 0);
        if (any(greaterThanEqual(depth.x + depth.y * d4, vec4(depth.z)))) {
            discard;
        }
    }
#endif
#ifdef MSAA
    vec2 f = fract(uv - 0.5);
    vec4 c = mix(mix(texel(t0), texel(t0 + ivec2(1, 0)), f.x), mix(texel(t0 + ivec2(0, 1)), texel(t0 + ivec2(1, 1)), f.x), f.y);
#else
    vec2 st = uv * vec2(m0.w, m1.w);
    vec4 c = flags.x == 0u ? texture(color0, st) : texture(color1, st);
#endif
    if (flags.z != 0u) {
        c = vec4(mix(c.rgb, vec3(1.0, 0.0, 1.0), 0.4), c.a);
    }
    out_color = c;
}
