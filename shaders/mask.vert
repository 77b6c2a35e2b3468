#version 450
// stereoshim's hidden-area mask: triangles in NDC from the layer's vertex buffer. Depth comes from
// the viewport (minDepth = maxDepth = the value that fails the app's depth test), so z only has to
// lie inside the clip volume and one pipeline serves both depth conventions.
#ifdef MULTIVIEW
#extension GL_EXT_multiview : require
#endif

layout(location = 0) in vec2 in_pos;
// The view a triangle belongs to: in a multiview pass one draw carries every view's triangles and
// each view keeps only its own.
layout(location = 1) in uint in_view;

void main() {
    gl_Position = vec4(in_pos, 0.5, 1.0);
#ifdef MULTIVIEW
    if (in_view != uint(gl_ViewIndex)) {
        // All three vertices collapse to one point outside the clip volume: no fragment.
        gl_Position = vec4(-2.0, -2.0, 0.5, 1.0);
    }
#endif
}
