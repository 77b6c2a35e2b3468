#version 450
// Reconstruction: one triangle covering the viewport (the eye's rect), from gl_VertexIndex.
// FROM_BUFFER (behind a post chain, for a pass whose eyes are known only at submission): the
// triangle and the eye's rule parameters come from the recording's vertex buffer, filled at each
// submission, and go to the fragment shader unchanged.
#ifdef FROM_BUFFER
layout(location = 0) in vec2 pos;
layout(location = 1) in ivec4 rect;
layout(location = 2) in vec4 tanp;
layout(location = 3) in vec4 fovea;
layout(location = 0) flat out ivec4 v_rect;
layout(location = 1) flat out vec4 v_tanp;
layout(location = 2) flat out vec4 v_fovea;
#endif

void main() {
#ifdef FROM_BUFFER
    v_rect = rect;
    v_tanp = tanp;
    v_fovea = fovea;
    gl_Position = vec4(pos, 0.0, 1.0);
#else
    vec2 p = vec2(float((gl_VertexIndex << 1) & 2), float(gl_VertexIndex & 2));
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
#endif
}
