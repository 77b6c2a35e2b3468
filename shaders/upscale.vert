#version 450
// One triangle over the whole viewport (the upscale's fragment passes set it to a view's rect).

void main() {
    vec2 c = vec2((gl_VertexIndex << 1) & 2, gl_VertexIndex & 2);
    gl_Position = vec4(c * 2.0 - 1.0, 0.0, 1.0);
}
