#version 450
// stereoshim's radial density masking draw: one triangle per view covering the whole viewport (the
// eye's rect); depth comes from the viewport (minDepth = maxDepth = the value failing the app's
// test). The rule's parameters travel as flat vertex attributes from the layer's own vertex
// buffer, so the app's descriptor sets and push constants stay untouched.
#ifdef MULTIVIEW
#extension GL_EXT_multiview : require
#endif

layout(location = 0) in vec2 in_pos;
layout(location = 1) in uint in_view;
layout(location = 2) in ivec2 in_origin;
layout(location = 3) in vec4 in_tan;
layout(location = 4) in vec4 in_fovea;

layout(location = 0) flat out ivec2 v_origin;
layout(location = 1) flat out vec4 v_tan;
layout(location = 2) flat out vec4 v_fovea;

void main() {
    gl_Position = vec4(in_pos, 0.5, 1.0);
    v_origin = in_origin;
    v_tan = in_tan;
    v_fovea = in_fovea;
#ifdef MULTIVIEW
    if (in_view != uint(gl_ViewIndex)) {
        // Another view's triangle: collapsed outside the clip volume, no fragment.
        gl_Position = vec4(-2.0, -2.0, 0.5, 1.0);
    }
#endif
}
