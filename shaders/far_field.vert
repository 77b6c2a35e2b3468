#version 450
// stereoshim's monoscopic far field: the destination view as a grid of 16×16-pixel tiles (6
// vertices each), drawn per view with per-view parameters as instance attributes from the
// recording's buffer (refreshed at every submission, so a command buffer recorded once follows the
// head). Depth is the split plane's (viewport depth range 0..1), so the app's own far fragments
// behind it fail the depth test.
//
// Each tile gets a class before any of its fragments runs, from the depth range of the source
// tiles it may read (`far_field_tiles.comp`, reduced when the source was copied): every texel far
// (FULL: the fragment shader skips its per-pixel tests), none far (the tile is culled) or some
// (MIXED: the per-pixel tests). Fragment shading is the scarce resource on some GPUs; this turns a
// full-screen pass into one over the reused region and its edges.
#ifdef MULTIVIEW
#extension GL_EXT_multiview : require
#endif

layout(location = 0) in vec4 in_m0;
layout(location = 1) in vec4 in_m1;
layout(location = 2) in vec4 in_m2;
layout(location = 3) in vec4 in_k;
layout(location = 4) in vec4 in_depth;
layout(location = 5) in vec4 in_size;
// (slot read, active, debug tint, view)
layout(location = 6) in uvec4 in_flags;
// The destination view's rect (framebuffer pixels): x, y, width, height.
layout(location = 7) in vec4 in_dst;
// The source tiles' grid: tiles per row, rows.
layout(location = 8) in uvec4 in_grid;
// The draw's viewport (framebuffer pixels): the destination rect, or the render area it lies in
// for a pass whose eyes were known only at submission.
layout(location = 9) in vec4 in_viewport;

layout(std430, set = 0, binding = 4) readonly buffer Tiles {
    vec2 tiles[];
};

layout(location = 0) flat out vec4 m0;
layout(location = 1) flat out vec4 m1;
layout(location = 2) flat out vec4 m2;
layout(location = 3) flat out vec4 k;
layout(location = 4) flat out vec4 depth;
layout(location = 5) flat out vec4 size;
layout(location = 6) flat out uvec4 flags;
layout(location = 7) flat out uint cls;

const uint CULL = 0u;
const uint FULL = 1u;
const uint MIXED = 2u;
const int TILE = 16;

// The class of the destination tile [p0, p1) (framebuffer pixels).
uint classify(vec2 p0, vec2 p1) {
    mat3 m = mat3(in_m0.xyz, in_m1.xyz, in_m2.xyz);
    // A far texel's 1/z is below the split's: the depth shift moves a sample by at most k / split.
    float most_shift = in_k.w > 0.5 ? in_depth.z : 0.0;
    vec2 lo = vec2(1.0e30);
    vec2 hi = vec2(-1.0e30);
    // The tile's image in the source is convex (a projective map of a square, swept along k for
    // the shift): the box of its corners' images bounds every position a fragment may sample.
    for (int i = 0; i < 8; i++) {
        vec2 c = vec2((i & 1) == 0 ? p0.x + 0.5 : p1.x - 0.5, (i & 2) == 0 ? p0.y + 0.5 : p1.y - 0.5);
        vec3 q = m * vec3(c, 1.0) + ((i & 4) == 0 ? vec3(0.0) : in_k.xyz * most_shift);
        if (q.z <= 0.0) {
            return MIXED;
        }
        vec2 uv = q.xy / q.z;
        lo = min(lo, uv);
        hi = max(hi, uv);
    }
    // Outside the copy with a margin: no fragment's footprint is inside.
    if (hi.x < -2.0 || hi.y < -2.0 || lo.x > in_size.x + 2.0 || lo.y > in_size.y + 2.0) {
        return CULL;
    }
    // Partly outside: the per-pixel test decides.
    if (lo.x < 2.0 || lo.y < 2.0 || hi.x > in_size.x - 2.0 || hi.y > in_size.y - 2.0) {
        return MIXED;
    }
    // Texels a fragment may read (the bilinear footprint of floor(uv - 0.5), and floor(uv) for
    // the shift), one more each side for rounding.
    ivec2 t_lo = ivec2(floor(lo - 0.5)) - 1;
    ivec2 t_hi = ivec2(floor(hi - 0.5)) + 2;
    ivec2 g_lo = t_lo / TILE;
    ivec2 g_hi = t_hi / TILE;
    if ((g_hi.x - g_lo.x + 1) * (g_hi.y - g_lo.y + 1) > 64) {
        return MIXED;
    }
    bool all_far = true;
    bool all_near = true;
    uint base = in_flags.x * in_grid.y;
    for (int y = g_lo.y; y <= g_hi.y; y++) {
        for (int x = g_lo.x; x <= g_hi.x; x++) {
            vec2 r = tiles[(base + uint(y)) * in_grid.x + uint(x)];
            // Not reduced (a multisampled copy, or the reduction could not run): unknown.
            if (!(r.x <= r.y)) {
                return MIXED;
            }
            float a = in_depth.x + in_depth.y * r.x;
            float b = in_depth.x + in_depth.y * r.y;
            all_far = all_far && max(a, b) < in_depth.z;
            all_near = all_near && min(a, b) >= in_depth.z;
        }
    }
    return all_far ? FULL : (all_near ? CULL : MIXED);
}

void main() {
    int tiles_x = (int(in_dst.z) + TILE - 1) / TILE;
    int tile = gl_VertexIndex / 6;
    int corner = gl_VertexIndex % 6;
    // Two triangles: (0,0) (1,0) (0,1), (0,1) (1,0) (1,1).
    ivec2 c = ivec2(corner == 1 || corner == 4 || corner == 5 ? 1 : 0, corner == 2 || corner == 3 || corner == 5 ? 1 : 0);
    vec2 p0 = in_dst.xy + vec2(tile % tiles_x, tile / tiles_x) * float(TILE);
    vec2 p1 = min(p0 + float(TILE), in_dst.xy + in_dst.zw);
    vec2 p = mix(p0, p1, vec2(c));
    gl_Position = vec4((p - in_viewport.xy) / in_viewport.zw * 2.0 - 1.0, in_depth.w, 1.0);
    bool keep = in_flags.y != 0u;
#ifdef MULTIVIEW
    // Every instance reaches every view; each view keeps its own.
    keep = keep && in_flags.w == uint(gl_ViewIndex);
#endif
    cls = keep ? classify(p0, p1) : CULL;
    if (cls == CULL) {
        gl_Position = vec4(-2.0, -2.0, 0.5, 1.0);
    }
    m0 = in_m0;
    m1 = in_m1;
    m2 = in_m2;
    k = in_k;
    depth = in_depth;
    size = in_size;
    flags = in_flags;
}
