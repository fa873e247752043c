//! Memory a picture needs, and what the machine has: the check behind
//! `--width`/`--height` (a size that cannot fit is refused when the command
//! line is parsed, naming the flags and the memory, instead of aborting on a
//! failed allocation once the scene is loaded).

/// Bytes one pixel of a picture costs before any photon map: the 9-sample
/// G-buffer (108 bytes: 9 × 12), the Whitted paths' shading vertices, the
/// per-light buffers of a small rig and the composite. Measured: peak RSS of
/// `footlight render --patch patch/paper-rig.toml --photons 0` (6 lights) at
/// 400×250, 800×500 and 1600×1000 was 56, 130 and 458 MB: 246 and 273 bytes
/// per added pixel; 250 is taken, so the estimate is a floor, not a promise.
pub const PICTURE_BYTES_PER_PIXEL: u64 = 250;

/// The memory a `width` × `height` picture needs at least (see
/// [`PICTURE_BYTES_PER_PIXEL`]).
pub fn picture_bytes(width: u32, height: u32) -> u64 {
    u64::from(width) * u64::from(height) * PICTURE_BYTES_PER_PIXEL
}

/// Memory available to a new allocation now, in bytes: Linux's
/// `MemAvailable` (`/proc/meminfo`); `None` where it cannot be read.
pub fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_meminfo_available(&text)
}

/// The `MemAvailable:` line of a `/proc/meminfo` text, in bytes.
fn parse_meminfo_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find_map(|l| l.strip_prefix("MemAvailable:"))?;
    let kib: u64 = line.trim().strip_suffix("kB")?.trim().parse().ok()?;
    kib.checked_mul(1024)
}

/// Refuses a picture size that cannot fit in `available` bytes, with a
/// message naming the flags, the memory needed and the largest size of the
/// same shape that fits. `None` when it fits (or nothing is known).
pub fn picture_too_big(width: u32, height: u32, available: Option<u64>) -> Option<String> {
    let available = available?;
    let need = picture_bytes(width, height);
    if need <= available {
        return None;
    }
    let scale = (available as f64 / need as f64).sqrt();
    let (w, h) = ((f64::from(width) * scale).floor().max(1.0), (f64::from(height) * scale).floor().max(1.0));
    Some(format!(
        "--width {width} --height {height}: a {width}×{height} picture needs at least {:.1} GB \
         ({PICTURE_BYTES_PER_PIXEL} bytes per pixel before any photon map), but only {:.1} GB of memory \
         is available; the largest picture of that shape that fits is about {w}×{h}",
        need as f64 / 1e9,
        available as f64 / 1e9,
    ))
}

/// The machine's memory, in bytes: Linux's `MemTotal` (`/proc/meminfo`);
/// `None` where it cannot be read.
pub fn total() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find_map(|l| l.strip_prefix("MemTotal:"))?;
    let kib: u64 = line.trim().strip_suffix("kB")?.trim().parse().ok()?;
    kib.checked_mul(1024)
}

/// The default share of the machine's memory the live daemon's buffers,
/// photon maps and caches may hold (`footlight run --memory`).
pub const DEFAULT_BUDGET_PERCENT: f64 = 50.0;

/// The budget where the machine's memory cannot be read: 4 GiB.
pub const FALLBACK_BUDGET: u64 = 4 << 30;

/// The default memory budget: [`DEFAULT_BUDGET_PERCENT`] of `MemTotal`,
/// else [`FALLBACK_BUDGET`].
pub fn default_budget() -> u64 {
    total().map_or(FALLBACK_BUDGET, |t| (t as f64 * DEFAULT_BUDGET_PERCENT / 100.0) as u64)
}

/// Parses a memory budget: bytes with an optional `K`, `M`, `G` or `T`
/// suffix (binary: `1G` = 2^30 bytes; a trailing `B`/`iB` is allowed), or a
/// percentage of `total` (`50%`; of 8 GiB when `total` is unknown). At
/// least 1 MiB.
pub fn parse_budget(v: &str, total: Option<u64>) -> Result<u64, String> {
    let v = v.trim();
    let bytes = if let Some(p) = v.strip_suffix('%') {
        let p: f64 = p.trim().parse().map_err(|_| format!("{v}: expected a percentage such as 50%"))?;
        if !(p > 0.0 && p <= 100.0) {
            return Err(format!("{v}: a percentage of the machine's memory must be above 0 and at most 100"));
        }
        // Unknown memory: a percentage of twice the fallback (50% is the fallback).
        let total = total.unwrap_or(2 * FALLBACK_BUDGET);
        (total as f64 * p / 100.0) as u64
    } else {
        let upper = v.to_ascii_uppercase();
        let number = upper.trim_end_matches("IB").trim_end_matches('B');
        let (digits, scale) = match number.chars().last() {
            Some('K') => (&number[..number.len() - 1], 1u64 << 10),
            Some('M') => (&number[..number.len() - 1], 1 << 20),
            Some('G') => (&number[..number.len() - 1], 1 << 30),
            Some('T') => (&number[..number.len() - 1], 1 << 40),
            _ => (number, 1),
        };
        let x: f64 =
            digits.trim().parse().map_err(|_| format!("{v}: expected bytes (4G, 512M) or a percentage (50%)"))?;
        if !(x.is_finite() && x >= 0.0) {
            return Err(format!("{v}: expected a positive size"));
        }
        (x * scale as f64) as u64
    };
    if bytes < 1 << 20 {
        return Err(format!("{v}: at least 1M"));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meminfo_available_is_read_in_bytes() {
        let text = "MemTotal:       24576000 kB\nMemFree:        1000 kB\nMemAvailable:   23456789 kB\n";
        assert_eq!(parse_meminfo_available(text), Some(23_456_789 * 1024));
        assert_eq!(parse_meminfo_available("MemTotal: 1 kB\n"), None);
        assert_eq!(parse_meminfo_available("MemAvailable: lots\n"), None);
    }

    #[test]
    fn a_picture_that_cannot_fit_is_refused_with_the_size_that_fits() {
        let gb = 1_000_000_000;
        assert_eq!(picture_too_big(800, 500, Some(24 * gb)), None);
        assert_eq!(picture_too_big(16384, 16384, None), None, "nothing known, nothing refused");
        let msg = picture_too_big(16384, 16384, Some(24 * gb)).expect("67 GB does not fit in 24");
        assert!(msg.contains("--width 16384 --height 16384") && msg.contains("67.1 GB"), "{msg}");
        // The suggested size fits, and is within a pixel of the largest that does.
        let fit = msg.rsplit("about ").next().unwrap();
        let (w, h) = fit.split_once('×').unwrap();
        let (w, h): (u32, u32) = (w.parse().unwrap(), h.parse().unwrap());
        assert_eq!(w, h);
        assert!(picture_bytes(w, h) <= 24 * gb && picture_bytes(w + 1, h + 1) > 24 * gb, "{w}×{h}");
    }
}
