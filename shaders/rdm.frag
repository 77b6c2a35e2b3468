#version 450
#extension GL_GOOGLE_include_directive : require
// Keeps the draw's depth write only on skipped quads: kept quads discard, so the app's cleared
// depth stays there and its fragments pass as before.
#include "rdm_rule.glsl"

layout(location = 0) flat in ivec2 v_origin;
layout(location = 1) flat in vec4 v_tan;
layout(location = 2) flat in vec4 v_fovea;

void main() {
    ivec2 rel = ivec2(gl_FragCoord.xy) - v_origin;
    if (!rdm_skipped(rel >> 1, v_tan, v_fovea)) {
        discard;
    }
}
