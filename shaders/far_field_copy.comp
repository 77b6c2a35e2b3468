#version 450
// stereoshim's monoscopic far field: the copy of a source view into its slot, as a compute pass
// at the end of the source's pass (src/features/far_field/copy.rs), and the depth range of each
// 16×16-pixel tile of it in the same pass.
//
// Why compute and not vkCmdCopyImage: on GPUs whose graphics units are few (the H100 measured in
// docs/benchmarks.md) image copies run there and cost ~0.3 ms each at 2016×2240, as much as the
// app's own cheapest shading; compute runs on every unit.
//
// The slot holds linear colour in RGBA16F (texelFetch of an sRGB view decodes; the reuse draw's
// sRGB attachment encodes again; 8-bit values survive the round trip) and depth as R32F.
// The tiles feed the reuse draw's vertex shader, which gives each destination tile a class from
// them: every texel it may read is far (no per-pixel test), none is (culled), or some are. A tile
// entry is (smallest, largest) depth over the tile's texels inside the copy; depth is
// non-negative, so its bit patterns order as unsigned integers and shared-memory atomics reduce
// them. A tile with no texel inside the copy gets (NaN, 0): unknown.

layout(local_size_x = 16, local_size_y = 16) in;

layout(set = 0, binding = 0) uniform sampler2D src_color;
layout(set = 0, binding = 1) uniform sampler2D src_depth;
layout(set = 0, binding = 2, rgba16f) uniform writeonly image2D slot_color;
layout(set = 0, binding = 3, r32f) uniform writeonly image2D slot_depth;
// Both slots' tiles, row by row: slot s, tile (x, y) at (s * rows + y) * per_row + x.
layout(std430, set = 0, binding = 4) buffer Tiles {
    vec2 tiles[];
};
layout(std430, set = 0, binding = 5) readonly buffer Copy {
    // The source view's pixels in its image: x, y, width, height.
    ivec4 rect;
    // Tiles per row, rows, the slot.
    uvec4 grid;
} u;

shared uint lo;
shared uint hi;

void main() {
    if (gl_LocalInvocationIndex == 0u) {
        lo = 0xffffffffu;
        hi = 0u;
    }
    barrier();
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x < u.rect.z && p.y < u.rect.w) {
        vec4 c = texelFetch(src_color, u.rect.xy + p, 0);
        float d = texelFetch(src_depth, u.rect.xy + p, 0).r;
        imageStore(slot_color, p, c);
        imageStore(slot_depth, p, vec4(d));
        uint bits = floatBitsToUint(max(d, 0.0));
        atomicMin(lo, bits);
        atomicMax(hi, bits);
    }
    barrier();
    if (gl_LocalInvocationIndex == 0u) {
        tiles[(u.grid.z * u.grid.y + gl_WorkGroupID.y) * u.grid.x + gl_WorkGroupID.x] = vec2(uintBitsToFloat(lo), uintBitsToFloat(hi));
    }
}
