#version 450
// The scene's fragment shader: flat/Lambert colour, a procedural ground checker, distance fog, an
// optional cost loop and the shaded-fragment counters behind `--stats` and `--pixel-stats`.
#ifdef MULTIVIEW
#extension GL_EXT_multiview : require
#endif

// Early tests make "shaded" mean "passed the depth test", so the counter measures real shading
// work: fragments killed by the depth test never run this shader.
layout(early_fragment_tests) in;

layout(location = 0) in vec3 v_world;
layout(location = 1) in vec3 v_normal;
layout(location = 2) in vec3 v_color;
layout(location = 3) flat in uint v_flags;

layout(set = 0, binding = 0) uniform Frame {
    mat4 view_proj[2];
    mat4 cube_model;
    vec4 eye_pos[2];
    // `--far-movers`: the far mover's model matrix (identity without the option).
    mat4 mover_model;
    // Each view's projection alone (`--draw-hidden-area` places tangent-plane points with it).
    mat4 proj[2];
} frame;

layout(set = 0, binding = 1, std430) buffer Counts {
    uint counts[];
};

// `--pixel-stats`: shaded fragments per pixel of the eye rect (row-major, rect-relative).
layout(set = 0, binding = 2, std430) buffer PixelCounts {
    uint pixel_counts[];
};

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

layout(location = 0) out vec4 out_color;

const uint FLAG_LIT = 1u;
const uint FLAG_CHECKER = 4u;
const uint FLAG_FOG = 8u;
const uint FLAG_HIDDEN_AREA = 32u;
const uint PC_MANUAL_SRGB = 1u;
const uint PC_PIXEL_STATS = 2u;

const vec3 SUN = vec3(0.3, 0.8, 0.4) / 0.9434;
const vec3 HAZE = vec3(0.62, 0.72, 0.88);

vec3 srgb_encode(vec3 c) {
    vec3 lo = c * 12.92;
    vec3 hi = 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055;
    return mix(hi, lo, lessThanEqual(c, vec3(0.0031308)));
}

void main() {
#ifdef MULTIVIEW
    uint view = gl_ViewIndex;
#else
    uint view = pc.eye;
#endif
    // Helper invocations never reach the framebuffer; counting them would make the number depend on
    // how the driver packs quads.
    if (!gl_HelperInvocation) {
        atomicAdd(counts[view], 1u);
        if ((pc.flags & PC_PIXEL_STATS) != 0u) {
            int x = int(gl_FragCoord.x) - pc.pix_origin_x;
            int y = int(gl_FragCoord.y);
            if (x >= 0 && y >= 0 && uint(x) < pc.pix_width && uint(y) < pc.pix_height) {
                atomicAdd(pixel_counts[view * pc.pix_view_stride + uint(y) * pc.pix_width + uint(x)], 1u);
            }
        }
    }

    // The app's own hidden-area mask: black, and as cheap as a game's mask shader.
    if ((v_flags & FLAG_HIDDEN_AREA) != 0u) {
        out_color = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }

    vec3 c = v_color;
    if ((v_flags & FLAG_CHECKER) != 0u) {
        ivec2 cell = ivec2(floor(v_world.xz));
        c = ((cell.x + cell.y) & 1) == 0 ? vec3(0.22, 0.45, 0.18) : vec3(0.42, 0.45, 0.42);
    }
    if ((v_flags & FLAG_LIT) != 0u) {
        c *= 0.55 + 0.45 * max(dot(normalize(v_normal), SUN), 0.0);
    }
    if ((v_flags & FLAG_FOG) != 0u) {
        float d = distance(v_world, frame.eye_pos[view].xyz);
        c = mix(c, HAZE, 0.7 * (1.0 - exp(-d / 900.0)));
    }

    // Busy work that the compiler cannot remove (it depends on a push constant and a varying) but
    // that never changes the image: |acc| stays below 1, so the branch is never taken.
    float acc = 0.0;
    for (uint i = 0u; i < pc.shading_cost; i++) {
        acc = 0.5 * acc + 0.25 * sin(acc * 1.3 + float(i) * 0.1 + v_world.x);
    }
    if (acc > 2.0) {
        c = vec3(0.0);
    }

    // UNORM swapchains store what we write; encode so both colour families look alike.
    if ((pc.flags & PC_MANUAL_SRGB) != 0u) {
        c = srgb_encode(clamp(c, 0.0, 1.0));
    }
    out_color = vec4(c, 1.0);
}
