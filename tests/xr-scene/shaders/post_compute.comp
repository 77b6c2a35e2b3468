#version 450
// `--post-compute`: the tonemap as a compute dispatch. Reads the scene target as a sampled image
// (texelFetch, no sampler), writes one eye rect of an RGBA8 storage image, which the app then
// copies into the swapchain image byte for byte: so it encodes sRGB itself and stores in the
// swapchain's channel order. Compiled twice: with ARRAY (multiview) z is the layer.
#extension GL_GOOGLE_include_directive : require
// texelFetch on a texture without a sampler (a SAMPLED_IMAGE descriptor).
#extension GL_EXT_samplerless_texture_functions : require

#include "post_common.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

#ifdef ARRAY
layout(set = 0, binding = 0) uniform texture2DArray scene;
layout(set = 0, binding = 1, rgba8) uniform writeonly image2DArray result;
#define AT(p) ivec3(p, gl_GlobalInvocationID.z)
#else
layout(set = 0, binding = 0) uniform texture2D scene;
layout(set = 0, binding = 1, rgba8) uniform writeonly image2D result;
#define AT(p) (p)
#endif

vec3 fetch_scene(ivec2 p) { return texelFetch(scene, AT(p), 0).rgb; }
BILINEAR(scene_bilinear, fetch_scene, pc.src_origin, pc.src_size, pc.src_scale)

void main() {
    uvec2 g = gl_GlobalInvocationID.xy;
    if (g.x >= uint(pc.dst_size.x) || g.y >= uint(pc.dst_size.y)) {
        return;
    }
    vec3 c = srgb_encode(tonemap(scene_bilinear(vec2(g) + 0.5)));
    vec4 o = vec4(c, 1.0);
    if ((pc.flags & FLAG_BGRA) != 0u) {
        o = o.bgra;
    }
    imageStore(result, AT(ivec2(pc.dst_origin) + ivec2(g)), o);
}
