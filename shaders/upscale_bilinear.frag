#version 450
// The bilinear upscale as a fragment pass into the runtime's image (`upscale.method = bilinear`):
// each pixel of `dst` samples `src` of the app's image with the linear sampler, its coordinates
// kept half a texel inside the rect so a side-by-side neighbour never bleeds in.

layout(set = 0, binding = 0) uniform sampler2D app;

layout(push_constant) uniform Params {
    ivec4 src;      // x, y, width, height in the app's image
    ivec4 dst;      // x, y, width, height in the runtime's image
} p;

layout(location = 0) out vec4 color;

void main() {
    vec2 uv = (gl_FragCoord.xy - vec2(p.dst.xy)) / vec2(p.dst.zw);
    vec2 texel = vec2(p.src.xy) + clamp(uv * vec2(p.src.zw), vec2(0.5), vec2(p.src.zw) - 0.5);
    color = vec4(texture(app, texel / vec2(textureSize(app, 0))).rgb, 1.0);
}
