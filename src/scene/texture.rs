//! Base-colour textures (glTF `baseColorTexture`): decoded once at import
//! into linear RGB, sampled at a surface point's texture coordinates as a
//! factor on the material's diffuse albedo ρ_d (so the BRDF is
//! ρ_d ⊙ texel / π; Vierjahn 2010 eq. 1's diffuse term).
//!
//! Data comes from the glTF importer (`gltf_import`): PNG only (the image
//! crate is built with its PNG decoder alone), from the GLB binary chunk, a
//! `data:` URI or a file beside the scene. glTF stores base colour in sRGB,
//! so each texel is decoded with the sRGB transfer function (IEC 61966-2-1);
//! alpha is ignored (no cut-outs). Filtering follows the glTF sampler:
//! `NEAREST` magnification → nearest texel, otherwise bilinear; wrap modes
//! `REPEAT` (default), `CLAMP_TO_EDGE` and `MIRRORED_REPEAT`.

use glam::{Vec2, Vec3};

/// Largest texture side accepted, texels (a 16k texture is 1 G of linear
/// RGB floats: beyond any stage set, refused with a warning).
pub const MAX_TEXTURE_SIDE: u32 = 8192;

/// How texture coordinates outside [0, 1] wrap (glTF sampler `wrapS`/`wrapT`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    /// Tiles (the glTF default).
    Repeat,
    /// Holds the edge texel.
    Clamp,
    /// Tiles, every other tile mirrored.
    Mirror,
}

/// A decoded base-colour texture in linear RGB.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Name for messages (image name or index).
    pub name: String,
    width: u32,
    height: u32,
    /// Row-major from the top row (glTF: uv (0, 0) is the image's top-left corner).
    texels: Vec<Vec3>,
    /// Nearest-texel lookup instead of bilinear.
    pub nearest: bool,
    /// Wrap along u.
    pub wrap_u: Wrap,
    /// Wrap along v.
    pub wrap_v: Wrap,
}

/// sRGB-encoded value (0..1) to linear (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

impl Texture {
    /// A texture from linear RGB texels, row-major from the top row.
    /// `None` when the size does not match or is zero.
    pub fn from_linear(name: &str, width: u32, height: u32, texels: Vec<Vec3>) -> Option<Self> {
        (width > 0 && height > 0 && texels.len() == width as usize * height as usize).then(|| Self {
            name: name.to_string(),
            width,
            height,
            texels,
            nearest: false,
            wrap_u: Wrap::Repeat,
            wrap_v: Wrap::Repeat,
        })
    }

    /// Decodes a PNG (sRGB → linear, alpha dropped). The error says why.
    pub fn decode_png(name: &str, bytes: &[u8]) -> Result<Self, String> {
        Self::decode_as(name, bytes, image::ImageFormat::Png)
    }

    /// Decodes a PNG or a JPEG (the two image types glTF 2.0 allows; told
    /// apart by their first bytes), sRGB → linear, alpha dropped.
    pub fn decode_image(name: &str, bytes: &[u8]) -> Result<Self, String> {
        match image::guess_format(bytes) {
            Ok(image::ImageFormat::Jpeg) => Self::decode_as(name, bytes, image::ImageFormat::Jpeg),
            _ => Self::decode_png(name, bytes),
        }
    }

    fn decode_as(name: &str, bytes: &[u8], format: image::ImageFormat) -> Result<Self, String> {
        let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(MAX_TEXTURE_SIDE);
        limits.max_image_height = Some(MAX_TEXTURE_SIDE);
        reader.limits(limits);
        let img = reader.decode().map_err(|e| format!("not a readable {format:?} ({e})"))?;
        let rgb = img.to_rgb32f();
        let (w, h) = rgb.dimensions();
        // to_rgb32f maps 8- and 16-bit samples onto 0..1 without a transfer function.
        let texels = rgb.pixels().map(|p| Vec3::new(p[0], p[1], p[2]).map(srgb_to_linear)).collect();
        Self::from_linear(name, w, h, texels).ok_or_else(|| "an empty image".to_string())
    }

    /// Width and height in texels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    fn texel(&self, x: i64, y: i64) -> Vec3 {
        let x = wrap(x, self.width, self.wrap_u);
        let y = wrap(y, self.height, self.wrap_v);
        self.texels[y * self.width as usize + x]
    }

    /// The linear colour at texture coordinates `uv` (glTF: u right, v down
    /// from the top-left corner). Non-finite coordinates read texel (0, 0).
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
        let x = f64::from(uv.x) * f64::from(self.width);
        let y = f64::from(uv.y) * f64::from(self.height);
        if self.nearest {
            return self.texel(x.floor() as i64, y.floor() as i64);
        }
        // Bilinear between texel centres.
        let (x, y) = (x - 0.5, y - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = self.texel(x0, y0).lerp(self.texel(x0 + 1, y0), fx);
        let bottom = self.texel(x0, y0 + 1).lerp(self.texel(x0 + 1, y0 + 1), fx);
        top.lerp(bottom, fy)
    }
}

/// Texel index `i` wrapped into 0..n.
fn wrap(i: i64, n: u32, mode: Wrap) -> usize {
    let n = i64::from(n);
    let i = i.clamp(-(1 << 40), 1 << 40);
    (match mode {
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Mirror => {
            let k = i.rem_euclid(2 * n);
            if k < n { k } else { 2 * n - 1 - k }
        }
    }) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        let t = vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE];
        Texture::from_linear("checker", 2, 2, t).unwrap()
    }

    #[test]
    fn nearest_and_wrap_modes_pick_the_right_texel() {
        let mut t = checker();
        t.nearest = true;
        assert_eq!(t.sample(Vec2::new(0.25, 0.25)), Vec3::X);
        assert_eq!(t.sample(Vec2::new(0.75, 0.25)), Vec3::Y);
        assert_eq!(t.sample(Vec2::new(0.25, 0.75)), Vec3::Z);
        assert_eq!(t.sample(Vec2::new(1.25, -0.25)), Vec3::Z, "repeat");
        t.wrap_u = Wrap::Clamp;
        assert_eq!(t.sample(Vec2::new(7.0, 0.25)), Vec3::Y);
        t.wrap_u = Wrap::Mirror;
        assert_eq!(t.sample(Vec2::new(1.25, 0.25)), Vec3::Y, "mirrored");
        assert_eq!(t.sample(Vec2::new(f32::NAN, 0.0)), Vec3::X);
    }

    #[test]
    fn bilinear_is_exact_at_texel_centres_and_averages_between() {
        let t = checker();
        assert!((t.sample(Vec2::new(0.25, 0.25)) - Vec3::X).length() < 1e-6);
        let mid = t.sample(Vec2::new(0.5, 0.5));
        assert!((mid - (Vec3::X + Vec3::Y + Vec3::Z + Vec3::ONE) / 4.0).length() < 1e-6, "{mid}");
    }

    #[test]
    fn srgb_decoding_matches_the_standard() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // 50 % sRGB grey is 21.4 % linear.
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
    }
}
