// Footlight GPU compositor: Vierjahn 2010, section 3.3 and eq. (5),
//     I = Σ_i k_i ⊙ buffer_i,
// then white balance and exposure (a per-channel scale), the highlight
// roll-off when on (footlight src/render/display.rs HighlightRolloff, its
// constants in `params.rolloff`), clipping to [0, 1] and the sRGB transfer
// function (IEC 61966-2-1) to RGBA8.
//
// Lives in the top-level shaders/ with the browser's GLSL; the
// footlight-gpu crate includes it from here.
//
// One workgroup per 16×16 screen tile, one invocation per pixel. Each screen
// tile has a list of (light, pool slot) entries, sorted by light index (the
// CPU reference's summation order); every invocation of the workgroup walks
// the same list, so the k_i = 0 test is uniform and a dark light costs one
// 8-byte entry read per tile, never its tile data.
//
// The tile pool may be split over several storage buffers ("pages", each
// within the adapter's max_storage_buffer_binding_size); the host then runs
// one dispatch per page, carrying the running sum in `linear` (flags
// READ_ACC / WRITE_ACC) and encoding only on the last one (WRITE_DISPLAY).
//
// Rust mirror of `Params`: `crate::composite::Params` (#[repr(C)], Pod).

// Tile edge in pixels (footlight src/render/buffer.rs TILE).
const TILE: u32 = 16u;

// Start from the running sum in `linear` instead of zero.
const READ_ACC: u32 = 1u;
// Store the sum into `linear` (next page, or a linear readback).
const WRITE_ACC: u32 = 2u;
// Encode the sum to sRGB into `rgba8`.
const WRITE_DISPLAY: u32 = 4u;
// No light can contribute this frame: skip the entry lists.
const NO_LIGHTS: u32 = 8u;

// Tiles are stored as packed IEEE half floats (3 per pixel, 2 per u32)
// instead of f32 bit patterns (set by the host per pipeline).
override TILE_F16: bool = false;

struct Params {
    // white_balance * exposure in xyz; w unused (16-byte alignment).
    scale: vec4<f32>,
    width: u32,
    height: u32,
    tiles_x: u32,
    flags: u32,
    // Highlight roll-off: knee, white (display-linear), on (1) or off (0), unused.
    rolloff: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: Params;
// k_i per light (xyz; w unused), indexed by light.
@group(0) @binding(1) var<storage, read> weights: array<vec4<f32>>;
// Per screen tile t: its entries are entries[offsets[t] .. offsets[t + 1]].
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
// (light index, tile slot in this page).
@group(0) @binding(3) var<storage, read> entries: array<vec2<u32>>;
// This page's tiles: TILE×TILE pixels, row-major, RGB, as f32 bits or f16 pairs.
@group(0) @binding(4) var<storage, read> tiles: array<u32>;
// Running / final linear sum, RGB f32 per pixel, row-major.
@group(0) @binding(5) var<storage, read_write> linear: array<f32>;
// Display pixels, RGBA8 (R in the low byte), row-major.
@group(0) @binding(6) var<storage, read_write> rgba8: array<u32>;

// Pixel p (0..256) of the tile in `slot`.
fn load_texel(slot: u32, p: u32) -> vec3<f32> {
    if (TILE_F16) {
        // 3 halves per pixel: pixel p starts at half 3p, spanning two words.
        let h = 3u * p;
        let w = slot * (TILE * TILE * 3u / 2u) + h / 2u;
        let a = unpack2x16float(tiles[w]);
        let b = unpack2x16float(tiles[w + 1u]);
        if ((h & 1u) == 0u) {
            return vec3<f32>(a.x, a.y, b.x);
        }
        return vec3<f32>(a.y, b.x, b.y);
    }
    let i = (slot * TILE * TILE + p) * 3u;
    return vec3<f32>(bitcast<f32>(tiles[i]), bitcast<f32>(tiles[i + 1u]), bitcast<f32>(tiles[i + 2u]));
}

// sRGB transfer function (IEC 61966-2-1), input clipped to [0, 1].
fn srgb_encode(linear_rgb: vec3<f32>) -> vec3<f32> {
    let c = clamp(linear_rgb, vec3<f32>(0.0), vec3<f32>(1.0));
    let lo = 12.92 * c;
    let hi = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}

// Highlight roll-off of a display-linear colour (1 = white), display.rs
// HighlightRolloff::apply: on the largest channel m, identity up to the
// knee, then u = (m - knee) / (1 - knee), U = (white - knee) / (1 - knee),
// f = knee + (1 - knee) u (1 + u / U²) / (1 + u), 1 from white on; all
// three channels scaled by f / m (hue kept).
fn rolloff(c: vec3<f32>) -> vec3<f32> {
    let knee = params.rolloff.x;
    let white = params.rolloff.y;
    let m = max(c.x, max(c.y, c.z));
    if (params.rolloff.z == 0.0 || m <= knee) {
        return c;
    }
    var f = 1.0;
    if (m < white) {
        let u = (m - knee) / (1.0 - knee);
        let big_u = (white - knee) / (1.0 - knee);
        f = knee + (1.0 - knee) * u * (1.0 + u / (big_u * big_u)) / (1.0 + u);
    }
    return c * (f / m);
}

@compute @workgroup_size(16, 16, 1)
fn composite(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let x = wg.x * TILE + lid.x;
    let y = wg.y * TILE + lid.y;
    // Edge tiles: pixels past the image exist in the tile (padded with 0) but not on screen.
    if (x >= params.width || y >= params.height) {
        return;
    }
    let pixel = y * params.width + x;
    let p = lid.y * TILE + lid.x;

    var acc = vec3<f32>(0.0);
    if ((params.flags & READ_ACC) != 0u) {
        acc = vec3<f32>(linear[3u * pixel], linear[3u * pixel + 1u], linear[3u * pixel + 2u]);
    }

    if ((params.flags & NO_LIGHTS) == 0u) {
        let screen_tile = wg.y * params.tiles_x + wg.x;
        let end = offsets[screen_tile + 1u];
        for (var e = offsets[screen_tile]; e < end; e++) {
            let entry = entries[e];
            let k = weights[entry.x].xyz;
            // Uniform across the workgroup: a dark light reads no tile data.
            if (all(k == vec3<f32>(0.0))) {
                continue;
            }
            acc += k * load_texel(entry.y, p); // Vierjahn 2010, eq. (5)
        }
    }

    if ((params.flags & WRITE_ACC) != 0u) {
        linear[3u * pixel] = acc.x;
        linear[3u * pixel + 1u] = acc.y;
        linear[3u * pixel + 2u] = acc.z;
    }
    if ((params.flags & WRITE_DISPLAY) != 0u) {
        // White balance and exposure, roll-off, clip, transfer function;
        // pack4x8unorm rounds as floor(0.5 + 255 c), like the CPU path.
        let srgb = srgb_encode(rolloff(acc * params.scale.xyz));
        rgba8[pixel] = pack4x8unorm(vec4<f32>(srgb, 1.0));
    }
}
