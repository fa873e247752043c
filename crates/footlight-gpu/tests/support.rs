//! Test support: the shared device, seeded random sparse light buffers laid
//! out like footlight's `LightBuffer`, and a CPU reference that is a copy of
//! footlight's `src/render/composite.rs` (sum in light order, k = 0 skipped)
//! and `src/render/display.rs` (scale, clip, exact sRGB, round half up).

use footlight_gpu::{DisplayParams, EMPTY_SLOT, GpuContext, LightTiles, TILE, TILE_PIXELS};
use rand::{Rng, SeedableRng};
use std::sync::OnceLock;

/// The device shared by every test in this binary, or `None` (after
/// printing why) when there is no adapter. With `FOOTLIGHT_REQUIRE_GPU=1`
/// (CI, which installs lavapipe) a missing adapter fails instead, so a
/// broken install cannot pass as "skipped".
pub fn context() -> Option<&'static GpuContext> {
    static CTX: OnceLock<Option<GpuContext>> = OnceLock::new();
    CTX.get_or_init(|| match GpuContext::new() {
        Ok(ctx) => {
            let info = ctx.adapter_info();
            eprintln!("GPU tests on {} ({:?}, {:?})", info.name, info.backend, info.device_type);
            Some(ctx)
        }
        Err(e) if std::env::var_os("FOOTLIGHT_REQUIRE_GPU").is_some_and(|v| v == "1") => {
            panic!("FOOTLIGHT_REQUIRE_GPU=1 but {e} (install mesa-vulkan-drivers and libvulkan1)")
        }
        Err(e) => {
            eprintln!("skipping GPU tests: {e}");
            None
        }
    })
    .as_ref()
}

/// Gets the shared device or returns from the test with a message.
macro_rules! device_or_skip {
    () => {
        match crate::support::context() {
            Some(ctx) => ctx,
            None => {
                eprintln!("skipped: no GPU adapter on this machine");
                return;
            }
        }
    };
}
pub(crate) use device_or_skip;

/// Seeded generator (Pcg64).
pub fn rng(seed: u64) -> rand_pcg::Pcg64 {
    rand_pcg::Pcg64::seed_from_u64(seed)
}

/// One light's buffer as buffer.rs stores it: occupied tiles (edge tiles
/// zero-padded past the image) and a slot table.
#[derive(Clone, Debug)]
pub struct TestLight {
    pub tiles: Vec<[f32; 3]>,
    pub slots: Vec<u32>,
}

impl TestLight {
    pub fn view(&self) -> LightTiles<'_> {
        LightTiles { tiles: &self.tiles, slots: &self.slots }
    }

    /// Value at pixel (x, y) of a `width`-wide image.
    pub fn get(&self, width: u32, x: u32, y: u32) -> [f32; 3] {
        let tiles_x = width.div_ceil(TILE);
        match self.slots[((y / TILE) * tiles_x + x / TILE) as usize] {
            EMPTY_SLOT => [0.0; 3],
            s => self.tiles[s as usize * TILE_PIXELS + ((y % TILE) * TILE + x % TILE) as usize],
        }
    }

    /// An all-empty light.
    pub fn empty(width: u32, height: u32) -> Self {
        Self { tiles: Vec::new(), slots: vec![EMPTY_SLOT; (width.div_ceil(TILE) * height.div_ceil(TILE)) as usize] }
    }

    /// Occupied tiles.
    pub fn occupied(&self) -> usize {
        self.tiles.len() / TILE_PIXELS
    }
}

/// A light occupying each tile with probability `occupancy`, the tiles in a
/// shuffled order in the data (any slot table must work), values
/// `max · u³` per channel (biased dark so the sRGB linear segment is hit),
/// some pixels exactly 0, zero padding past the image edge.
pub fn random_light(rng: &mut impl Rng, width: u32, height: u32, occupancy: f64, max: f32) -> TestLight {
    let (tx, ty) = (width.div_ceil(TILE), height.div_ceil(TILE));
    let chosen: Vec<u32> = (0..tx * ty).filter(|_| rng.random_bool(occupancy)).collect();
    place_tiles(rng, width, height, &chosen, |rng| {
        if rng.random_bool(0.1) { [0.0; 3] } else { std::array::from_fn(|_| max * rng.random::<f32>().powi(3)) }
    })
}

/// A beam-like light: the tiles within `radius` tiles of a random centre.
pub fn beam_light(rng: &mut impl Rng, width: u32, height: u32, radius: f32) -> TestLight {
    let (tx, ty) = (width.div_ceil(TILE), height.div_ceil(TILE));
    let (cx, cy) = (rng.random::<f32>() * tx as f32, rng.random::<f32>() * ty as f32);
    let chosen: Vec<u32> = (0..tx * ty)
        .filter(|t| {
            let (x, y) = ((t % tx) as f32 + 0.5 - cx, (t / tx) as f32 + 0.5 - cy);
            x * x + y * y <= radius * radius
        })
        .collect();
    place_tiles(rng, width, height, &chosen, |rng| std::array::from_fn(|_| rng.random::<f32>() * 0.05))
}

fn place_tiles<R: Rng>(
    rng: &mut R,
    width: u32,
    height: u32,
    chosen: &[u32],
    mut value: impl FnMut(&mut R) -> [f32; 3],
) -> TestLight {
    let tx = width.div_ceil(TILE);
    let mut light = TestLight::empty(width, height);
    // Fisher-Yates: data order unrelated to screen order.
    let mut order: Vec<u32> = (0..chosen.len() as u32).collect();
    for i in (1..order.len()).rev() {
        order.swap(i, rng.random_range(0..=i));
    }
    light.tiles = vec![[0.0; 3]; chosen.len() * TILE_PIXELS];
    for (&t, &slot) in chosen.iter().zip(&order) {
        light.slots[t as usize] = slot;
        for p in 0..TILE_PIXELS as u32 {
            let (x, y) = ((t % tx) * TILE + p % TILE, (t / tx) * TILE + p / TILE);
            if x < width && y < height {
                light.tiles[slot as usize * TILE_PIXELS + p as usize] = value(rng);
            }
        }
    }
    light
}

/// Random weights in [0, max) per channel, with about `dark` of them exactly 0
/// and some single channels 0.
pub fn random_k(rng: &mut impl Rng, n: usize, max: f32, dark: f64) -> Vec<[f32; 3]> {
    (0..n)
        .map(|_| {
            if rng.random_bool(dark) {
                [0.0; 3]
            } else {
                std::array::from_fn(|_| if rng.random_bool(0.1) { 0.0 } else { max * rng.random::<f32>() })
            }
        })
        .collect()
}

/// composite.rs: I = Σ k_i ⊙ buffer_i in light order, from zero, lights with
/// k = 0 skipped, f32 throughout.
pub fn cpu_composite(lights: &[TestLight], k: &[[f32; 3]], width: u32, height: u32) -> Vec<[f32; 3]> {
    let mut out = vec![[0.0f32; 3]; (width * height) as usize];
    for (light, k) in lights.iter().zip(k).filter(|(_, k)| **k != [0.0; 3]) {
        for y in 0..height {
            for x in 0..width {
                let v = light.get(width, x, y);
                let o = &mut out[(y * width + x) as usize];
                for c in 0..3 {
                    o[c] += k[c] * v[c]; // Vierjahn 2010, eq. (5)
                }
            }
        }
    }
    out
}

/// display.rs with the exact IEC 61966-2-1 curve: scale, clip to [0, 1],
/// encode, 8 bits rounded half up. RGB triplets.
pub fn cpu_srgb8(linear: &[[f32; 3]], display: &DisplayParams) -> Vec<u8> {
    let s = display.scale();
    linear
        .iter()
        .flat_map(|v| {
            std::array::from_fn::<u8, 3, _>(|c| {
                let x = (v[c] * s[c]).clamp(0.0, 1.0);
                let e = if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 };
                (e * 255.0 + 0.5) as u8
            })
        })
        .collect()
}

/// display.rs's 64 Ki-entry table path, copied, to check the GPU against
/// what the CPU compositor shows today.
pub fn cpu_srgb8_table(linear: &[[f32; 3]], display: &DisplayParams) -> Vec<u8> {
    const N: usize = 1 << 16;
    static LUT: OnceLock<Vec<u8>> = OnceLock::new();
    let lut = LUT.get_or_init(|| {
        (0..N)
            .map(|i| {
                let c = (i as f32 / (N - 1) as f32).clamp(0.0, 1.0);
                let e = if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
                (e * 255.0 + 0.5) as u8
            })
            .collect()
    });
    let s = display.scale().map(|s| s * (N - 1) as f32);
    linear
        .iter()
        .flat_map(|v| {
            std::array::from_fn::<u8, 3, _>(|c| lut[((v[c] * s[c]).clamp(0.0, (N - 1) as f32) + 0.5) as usize])
        })
        .collect()
}

/// Largest per-channel difference between an RGBA8 frame and RGB8 pixels;
/// also checks alpha is 255.
pub fn max_code_diff(rgba: &[u8], rgb: &[u8]) -> u8 {
    assert_eq!(rgba.len() / 4, rgb.len() / 3, "pixel count");
    let mut worst = 0;
    for (p, q) in rgba.chunks_exact(4).zip(rgb.chunks_exact(3)) {
        assert_eq!(p[3], 255, "alpha");
        for c in 0..3 {
            worst = worst.max(p[c].abs_diff(q[c]));
        }
    }
    worst
}
