#version 300 es
// Footlight browser composite (issue 17): eq. 5, I = sum_i k_i * buffer_i,
// then the CPU reference's display step (src/render/display.rs,
// Display::to_srgb8): white balance and exposure, the highlight roll-off
// when on (HighlightRolloff, the same curve as shaders/composite.wgsl),
// clip to [0, 1], quantise to the reference's 65536-entry table index,
// sRGB curve, 8-bit rounding. Fixture bodies replace the sum where they
// cover a pixel (below).
precision highp float;
precision highp int;
precision highp sampler2D;
precision highp sampler2DArray;

// One layer per light: the light's unit buffer (f16 RGB, value / scale).
uniform sampler2DArray u_buffers;
// Texel i: (k_i * scale_i, time factor) of light i (RGBA32F, one row).
uniform sampler2D u_k;
uniform int u_lights;
// white balance * exposure * 65535, as the reference computes it in f32.
uniform vec3 u_scale;
// white balance * exposure (the roll-off path scales before the curve).
uniform vec3 u_display_scale;
// Highlight roll-off: knee, white (display-linear), on (1) or off (0).
uniform vec3 u_rolloff;
// Picture height (rows are sent top to bottom; gl_FragCoord counts up).
uniform int u_height;
// Fixture bodies (message 6, src/live/bodies.rs): per pixel (base, glow,
// light, 0); base < 0 where no body covers the pixel. The body's radiance
// base + k_light * glow replaces the composite there, as the server's
// BodyLayer::overlay_srgb8 does, before the same display step.
uniform sampler2D u_body;
// Texel i: k_i of light i (cd; RGBA32F, one row).
uniform sampler2D u_kbody;
uniform int u_has_bodies;

out vec4 color;

// display.rs HighlightRolloff::apply: on the largest channel m, identity up
// to the knee, then u = (m - knee) / (1 - knee), U = (white - knee) / (1 - knee),
// f = knee + (1 - knee) u (1 + u / U^2) / (1 + u), 1 from white on; all
// three channels scaled by f / m (hue kept).
vec3 rolloff(vec3 c) {
  float knee = u_rolloff.x, white = u_rolloff.y;
  float m = max(c.r, max(c.g, c.b));
  if (m <= knee) return c;
  float f = 1.0;
  if (m < white) {
    float u = (m - knee) / (1.0 - knee), U = (white - knee) / (1.0 - knee);
    f = knee + (1.0 - knee) * u * (1.0 + u / (U * U)) / (1.0 + u);
  }
  return c * (f / m);
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    p.y = u_height - 1 - p.y;
    vec3 sum = vec3(0.0);
    for (int i = 0; i < u_lights; ++i) {
        vec4 k = texelFetch(u_k, ivec2(i, 0), 0);
        sum += (k.rgb * k.a) * texelFetch(u_buffers, ivec3(p, i), 0).rgb;
    }
    if (u_has_bodies != 0) {
        vec4 b = texelFetch(u_body, p, 0);
        if (b.r >= 0.0) {
            vec3 kb = b.g != 0.0 ? texelFetch(u_kbody, ivec2(int(b.b), 0), 0).rgb : vec3(0.0);
            sum = vec3(b.r) + kb * b.g;
        }
    }
    vec3 x0 = u_rolloff.z == 0.0 ? sum * u_scale : rolloff(sum * u_display_scale) * 65535.0;
    vec3 index = floor(clamp(x0, 0.0, 65535.0) + 0.5);
    vec3 x = index / 65535.0;
    vec3 lo = 12.92 * x;
    vec3 hi = 1.055 * pow(max(x, vec3(0.0031308)), vec3(1.0 / 2.4)) - 0.055;
    vec3 s = mix(lo, hi, step(vec3(0.0031308), x));
    color = vec4(floor(s * 255.0 + 0.5) / 255.0, 1.0);
}
