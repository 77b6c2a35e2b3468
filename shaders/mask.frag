#version 450
// Colour of the masked area with `mask.debug` (colour writes are off otherwise): magenta, stored as
// the same bytes in UNORM and sRGB formats.
layout(location = 0) out vec4 out_color;

void main() {
    out_color = vec4(1.0, 0.0, 1.0, 1.0);
}
