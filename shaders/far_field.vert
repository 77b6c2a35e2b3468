#version 450
// stereoshim's monoscopic far field: one full-screen triangle per destination view, whose
// per-view parameters come as instance attributes from the recording's buffer (refreshed at every
// submission, so a command buffer recorded once follows the head). Depth is the split plane's
// (viewport depth range 0..1), so the app's own far fragments behind it fail the depth test.
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

layout(location = 0) flat out vec4 m0;
layout(location = 1) flat out vec4 m1;
layout(location = 2) flat out vec4 m2;
layout(location = 3) flat out vec4 k;
layout(location = 4) flat out vec4 depth;
layout(location = 5) flat out vec4 size;
layout(location = 6) flat out uvec4 flags;

void main() {
    vec2 p = vec2((gl_VertexIndex << 1) & 2, gl_VertexIndex & 2);
    gl_Position = vec4(p * 2.0 - 1.0, in_depth.w, 1.0);
    bool keep = in_flags.y != 0u;
#ifdef MULTIVIEW
    // Every instance reaches every view; each view keeps its own.
    keep = keep && in_flags.w == uint(gl_ViewIndex);
#endif
    if (!keep) {
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
