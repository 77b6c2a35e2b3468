#version 450
// `--post-subpass`: the tonemap as the eye pass's second subpass (Godot Mobile), reading the
// scene subpass's colour at this pixel (and view) as an input attachment.
#extension GL_GOOGLE_include_directive : require

#include "post_common.glsl"

layout(input_attachment_index = 0, set = 0, binding = 0) uniform subpassInput scene;
layout(location = 0) out vec4 out_color;

void main() {
    vec3 c = tonemap(subpassLoad(scene).rgb);
    if ((pc.flags & FLAG_MANUAL_SRGB) != 0u) {
        c = srgb_encode(c);
    }
    out_color = vec4(c, 1.0);
}
