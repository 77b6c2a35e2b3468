#version 450
// The scene's vertex shader. Compiled twice: with MULTIVIEW the view comes from gl_ViewIndex
// (one draw renders both eyes), otherwise from the push-constant eye index (one draw per eye).
#ifdef MULTIVIEW
#extension GL_EXT_multiview : require
#endif

layout(location = 0) in vec3 in_pos;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec3 in_color;
layout(location = 3) in uint in_flags;

layout(set = 0, binding = 0) uniform Frame {
    mat4 view_proj[2];
    mat4 cube_model;
    vec4 eye_pos[2];
    // `--far-movers`: the far mover's model matrix (identity without the option).
    mat4 mover_model;
    // Each view's projection alone (`--draw-hidden-area` places tangent-plane points with it).
    mat4 proj[2];
} frame;

layout(push_constant) uniform Push {
    uint eye;
    uint shading_cost;
    uint flags;
    // `--pixel-stats`: the eye rect's origin x in the framebuffer and its size, and how many
    // elements apart the views' regions are in the bound range (multiview; 0 otherwise, where the
    // dynamic offset selects the region).
    int pix_origin_x;
    uint pix_width;
    uint pix_height;
    uint pix_view_stride;
} pc;

layout(location = 0) out vec3 v_world;
layout(location = 1) out vec3 v_normal;
layout(location = 2) out vec3 v_color;
layout(location = 3) flat out uint v_flags;

const uint FLAG_ANIMATED = 2u;
const uint FLAG_MOVER = 16u;
const uint FLAG_HIDDEN_AREA = 32u;

void main() {
#ifdef MULTIVIEW
    uint view = gl_ViewIndex;
#else
    uint view = pc.eye;
#endif
    if ((in_flags & FLAG_HIDDEN_AREA) != 0u) {
        // The runtime's hidden-area mesh, drawn by the app as games do: the tangent-plane point
        // through the view's projection, at the near depth (in_normal.x) so that nothing behind
        // it passes the depth test. The other view's triangles land outside the clip volume.
        vec4 c = frame.proj[view] * vec4(in_pos.xy, -1.0, 1.0);
        c.z = in_normal.x * c.w;
        gl_Position = uint(in_pos.z) == view ? c : vec4(4.0, 4.0, 0.5, 1.0);
        v_world = vec3(0.0);
        v_normal = vec3(0.0, 1.0, 0.0);
        v_color = vec3(0.0);
        v_flags = in_flags;
        return;
    }
    vec4 world = vec4(in_pos, 1.0);
    vec3 n = in_normal;
    if ((in_flags & FLAG_ANIMATED) != 0u) {
        world = frame.cube_model * world;
        n = mat3(frame.cube_model) * n;
    }
    if ((in_flags & FLAG_MOVER) != 0u) {
        world = frame.mover_model * world;
        n = mat3(frame.mover_model) * n;
    }
    v_world = world.xyz;
    v_normal = n;
    v_color = in_color;
    v_flags = in_flags;
    gl_Position = frame.view_proj[view] * world;
}
