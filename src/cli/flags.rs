//! Flag validators of the `footlight` command line: every numeric flag is
//! checked at parse time, with a message naming the allowed range (clap
//! prefixes the flag's name).

/// A finite number in `lo..=hi`.
fn number(v: &str, lo: f64, hi: f64, unit: &str) -> Result<f64, String> {
    let x: f64 = v.trim().parse().map_err(|_| format!("expected a number from {lo} to {hi}{unit}"))?;
    if x.is_finite() && (lo..=hi).contains(&x) {
        Ok(x)
    } else {
        Err(format!("must be a number from {lo} to {hi}{unit}"))
    }
}

/// `--fps`: 1-240 Hz.
pub fn fps(v: &str) -> Result<f64, String> {
    number(v, 1.0, 240.0, " Hz")
}

/// `--speed`: 0.01-1000 × real time.
pub fn speed(v: &str) -> Result<f64, String> {
    number(v, 0.01, 1000.0, " (× real time)")
}

/// `--at`: 0 s to one week.
pub fn at(v: &str) -> Result<f64, String> {
    number(v, 0.0, 7.0 * 86400.0, " seconds")
}

/// `--white-lux`: (0, 10^7] lx.
pub fn white_lux(v: &str) -> Result<f32, String> {
    let x = number(v, 0.0, 1e7, " lx")?;
    if x > 0.0 { Ok(x as f32) } else { Err("must be above 0 lx (the illuminance shown as display white)".into()) }
}

/// `--rolloff`: off, on, or the display-linear level shown as white.
pub fn rolloff(v: &str) -> Result<Rolloff, String> {
    crate::render::display::parse_rolloff(v).map(Rolloff)
}

/// `--white-balance` of `run`: auto, none, tungsten or 1000-25000 K (`auto` is
/// resolved on the loaded rig).
pub fn white_balance(v: &str) -> Result<String, String> {
    crate::render::display::white_balance_for(v, None).map(|_| v.trim().to_string())
}

/// A parsed `--rolloff` (`None`: clip at display white).
#[derive(Clone, Copy, Debug)]
pub struct Rolloff(pub Option<crate::render::display::HighlightRolloff>);

/// `--aa-threshold`: 0-255 on the light's relative scale
/// ([`crate::render::view::AA_THRESHOLD`]), not display steps.
pub fn aa_threshold(v: &str) -> Result<f32, String> {
    number(v, 0.0, 255.0, " (0-255 on the light's relative scale, its brightest pixels = 255)").map(|x| x as f32)
}

/// `--memory`: bytes (K/M/G/T) or a percentage of the machine's memory.
pub fn memory(v: &str) -> Result<u64, String> {
    crate::memory::parse_budget(v, crate::memory::total())
}

/// `--build-threads`: 1-256, whole.
pub fn build_threads(v: &str) -> Result<usize, String> {
    threads(v, 1.0)
}

/// `--quiet-build-threads`: 0-256, whole.
pub fn quiet_build_threads(v: &str) -> Result<usize, String> {
    threads(v, 0.0)
}

/// A whole number of threads from `min` to 256.
fn threads(v: &str, min: f64) -> Result<usize, String> {
    number(v, min, 256.0, " threads")
        .and_then(|x| if x.fract() == 0.0 { Ok(x as usize) } else { Err("must be a whole number of threads".into()) })
}

/// `--width`/`--height`: 1-16384 pixels.
pub fn pixels(v: &str) -> Result<u32, String> {
    number(v, 1.0, 16384.0, " pixels")
        .and_then(|x| if x.fract() == 0.0 { Ok(x as u32) } else { Err("must be a whole number of pixels".into()) })
}

/// Bytes a light's photon map needs per stored photon (photon, k-d tree
/// node and irradiance cache share), for the `--photons` message.
const BYTES_PER_PHOTON: f64 = 64.0;
/// Most photons stored per light.
pub const MAX_PHOTONS: usize = 20_000_000;

/// `--photons`: 0-20,000,000 per light, with the memory it needs.
pub fn photons(v: &str) -> Result<usize, String> {
    let n: f64 = v.trim().parse().map_err(|_| "expected a whole number of photons".to_string())?;
    if !(n.is_finite() && n >= 0.0 && n.fract() == 0.0) {
        return Err("expected a whole number of photons (0 = direct light only)".into());
    }
    if n > MAX_PHOTONS as f64 {
        return Err(format!(
            "{n} photons per light would need about {:.1} GB per light; at most {MAX_PHOTONS} ({:.1} GB)",
            n * BYTES_PER_PHOTON / 1e9,
            MAX_PHOTONS as f64 * BYTES_PER_PHOTON / 1e9
        ));
    }
    Ok(n as usize)
}

/// `--estimate`: 2-10000 photons.
pub fn estimate(v: &str) -> Result<usize, String> {
    number(v, 2.0, 10_000.0, " photons").map(|x| x as usize)
}

/// `--depth`: 0-64 bounces.
pub fn depth(v: &str) -> Result<u32, String> {
    number(v, 0.0, 64.0, " bounces").map(|x| x as u32)
}

/// `--refine`: 0-1000 progressive passes.
pub fn refine(v: &str) -> Result<u32, String> {
    let x = number(v, 0.0, 1000.0, " passes")?;
    if x.fract() != 0.0 {
        return Err(format!("expected a whole number of passes, got {v}"));
    }
    Ok(x as u32)
}
/// `--festival-size WxH`, 16x16 to 3840x2160.
pub fn festival_size(v: &str) -> Result<(u32, u32), String> {
    let (w, h) = v.split_once(['x', 'X']).ok_or("expected WxH, e.g. 800x500")?;
    let parse = |s: &str, max: u32| s.trim().parse::<u32>().ok().filter(|n| (16..=max).contains(n));
    match (parse(w, 3840), parse(h, 2160)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err("expected WxH with W in 16..3840 and H in 16..2160".into()),
    }
}

/// `--festival-seconds`: 1 to 3600.
pub fn festival_seconds(v: &str) -> Result<f64, String> {
    v.trim()
        .parse::<f64>()
        .ok()
        .filter(|s| (1.0..=3600.0).contains(s))
        .ok_or_else(|| "expected 1 to 3600 seconds".into())
}
