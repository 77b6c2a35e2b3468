#version 450
#extension GL_GOOGLE_include_directive : require
// RCAS as a fragment pass into the runtime's image, drawn as a colour attachment over `rect`
// (viewport and scissor): the attachment stays in the layout the runtime expects, and its format's
// encoding (sRGB) is applied on write. `src` is the EASU output, in the same coordinates.

#include "upscale_rcas.glsl"

layout(location = 0) out vec4 color;

void main() {
    color = vec4(rcas(ivec2(gl_FragCoord.xy) - p.rect.xy), 1.0);
}
