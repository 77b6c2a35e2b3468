// stereoshim's upscale, second pass: RCAS (robust contrast-adaptive sharpening), written from the
// published description of FidelityFX Super Resolution 1, operation for operation as the CPU
// reference src/features/upscale/filter.rs `rcas`. Shared by the compute pass
// (upscale_rcas.comp, held to the reference by tests/features/upscale_filters.rs) and the fragment pass
// that writes the runtime's image as a colour attachment (upscale_rcas.frag).

layout(set = 0, binding = 0) uniform sampler2D src;

layout(push_constant) uniform Params {
    ivec4 rect;       // x, y, width, height (the same texels in `src` and the destination)
    vec4 sharpness;   // x: 0 (none) .. 1 (full); y, z: the compute pass's output encoding
    // Where RCAS sharpens (`upscale.fovea_only`): an ellipse in destination texels, centre x, y,
    // radii z, w; z = 0: everywhere.
    vec4 fovea;
    // `upscale.skip_hidden` (the compute pass's): x the first entry of its tile list, y 1 when
    // it has one.
    ivec4 skip;
} p;

// The largest lobe: a neighbour weight of -3/16.
const float LIMIT = 0.25 - 1.0 / 16.0;

vec3 at(ivec2 q) {
    return texelFetch(src, clamp(q, ivec2(0), p.rect.zw - 1) + p.rect.xy, 0).rgb;
}

// The sharpened texel `q` of the rect (rect-relative).
vec3 rcas(ivec2 q) {
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
    if (p.fovea.z > 0.0) {
        vec2 r = (vec2(p.rect.xy + q) + 0.5 - p.fovea.xy) / p.fovea.zw;
        lobe = dot(r, r) > 1.0 ? 0.0 : lobe;
    }
    return ((b + d + f + h) * lobe + e) / (4.0 * lobe + 1.0);
}
