//! Geometry cache: recent geometry states of each light keep their finished
//! buffers, so returning to a position preset (a focus cue, a pan/tilt
//! position) shows its converged picture at once instead of re-tracing.
//! Bounded by bytes; the least recently used entry goes first. The key is
//! the exact geometry state, compared with `==`.
//!
//! In haze (issue 15) an entry also holds the light's buffers at the density
//! knots ½ and 1 ([`crate::render::media::live`]), and its key includes the
//! haze ([`Medium`]: coefficients, g, box, multiple scattering), so a preset
//! recalled in haze shows its beam at once and no entry made in other air
//! is ever served.

use crate::Light;
use crate::render::LightBuffer;
use crate::render::buffer::SharedLayer;
use crate::render::media::Medium;
use std::collections::HashMap;
use std::sync::Arc;

/// A light's buffers at the haze density knots ½ and 1 (the knot 0 is its
/// buffer itself).
pub type Knots = [Arc<LightBuffer>; 2];

/// What a light showed when it finished: the value a cache entry keeps.
#[derive(Clone, Debug)]
pub struct Finished {
    /// Its buffer (a cell of a group: its own Whitted term).
    pub buffer: Arc<LightBuffer>,
    /// The group's shared indirect layer shown with it (issue 38), if any.
    pub shared: Option<SharedLayer>,
    /// In haze: its buffers at the density knots ½ and 1.
    pub knots: Option<Knots>,
}

impl Finished {
    /// A light's own finished buffer, no shared layer, no knots.
    pub fn alone(buffer: Arc<LightBuffer>) -> Self {
        Self { buffer, shared: None, knots: None }
    }

    /// Bytes it holds: the shared layer counted in full (the cache's own
    /// bound, an upper bound where other cells share the layer).
    fn bytes(&self) -> usize {
        self.buffer.bytes()
            + self.shared.as_ref().map_or(0, |l| l.buffer.bytes())
            + self.knots.as_ref().map_or(0, |k| k.iter().map(|b| b.bytes()).sum())
    }
}

struct Entry {
    /// The exact geometry state (the key: compared with `==`, so two
    /// states differing in any field never share a buffer).
    light: Light,
    /// The haze the entry was built in (part of the key; `None`: clear air).
    haze: Option<Medium>,
    finished: Finished,
    last_used: u64,
}

impl Entry {
    fn bytes(&self) -> usize {
        self.finished.bytes()
    }
}

/// LRU map from (light index, exact [`Light`]) to a finished buffer.
///
/// Why no hash: `Light` holds floats and beam tables, and a hash of its
/// Debug text (the first version) could collide and serve the wrong
/// buffer. A light has few cached states (the budget holds a few hundred
/// buffers in all), so a scan with `==` over that light's entries is both
/// exact and cheap.
pub struct GeometryCache {
    entries: HashMap<usize, Vec<Entry>>,
    bytes: usize,
    budget: usize,
    clock: u64,
}

impl GeometryCache {
    /// An empty cache holding at most `budget` bytes of buffers.
    pub fn new(budget: usize) -> Self {
        Self { entries: HashMap::new(), bytes: 0, budget, clock: 0 }
    }

    /// The finished buffer for this light index and exact geometry in clear
    /// air, if cached.
    pub fn get(&mut self, index: usize, light: &Light) -> Option<Arc<LightBuffer>> {
        self.get_in(index, light, None).map(|f| f.buffer)
    }

    /// What this light index showed finished (buffer, shared layer and, in
    /// haze, its knot buffers) for this exact geometry and exact `haze`
    /// (`None`: clear air), if cached.
    pub fn get_in(&mut self, index: usize, light: &Light, haze: Option<&Medium>) -> Option<Finished> {
        self.clock += 1;
        let clock = self.clock;
        let e = self.entries.get_mut(&index)?.iter_mut().find(|e| e.light == *light && e.haze.as_ref() == haze)?;
        e.last_used = clock;
        Some(e.finished.clone())
    }

    /// Evicts least recently used entries until at most `bytes` are held;
    /// returns the bytes freed (the memory budget's last resort).
    pub fn shrink_to(&mut self, bytes: usize) -> usize {
        let before = self.bytes;
        while self.bytes > bytes {
            let oldest = self
                .entries
                .iter()
                .flat_map(|(&i, list)| list.iter().enumerate().map(move |(pos, e)| (e.last_used, i, pos)))
                .min();
            let Some((_, i, pos)) = oldest else { break };
            if let Some(list) = self.entries.get_mut(&i) {
                self.bytes -= list.swap_remove(pos).bytes();
            }
        }
        before - self.bytes
    }

    /// Stores a finished buffer (clear air), evicting least recently used
    /// entries past the budget.
    pub fn insert(&mut self, index: usize, light: &Light, buffer: Arc<LightBuffer>) {
        self.insert_in(index, light, None, Finished::alone(buffer));
    }

    /// Stores what a light showed finished, built in `haze` (its knot
    /// buffers and shared layer counted against the budget too), evicting
    /// least recently used entries past the budget.
    pub fn insert_in(&mut self, index: usize, light: &Light, haze: Option<Medium>, finished: Finished) {
        let entry = Entry { light: light.clone(), haze, finished, last_used: 0 };
        let size = entry.bytes();
        if size > self.budget {
            return;
        }
        self.clock += 1;
        let list = self.entries.entry(index).or_default();
        if let Some(pos) = list.iter().position(|e| e.light == *light && e.haze == haze) {
            self.bytes -= list.swap_remove(pos).bytes();
        }
        list.push(Entry { last_used: self.clock, ..entry });
        self.bytes += size;
        self.shrink_to(self.budget);
    }

    /// Drops every entry (their buffers belong to a view that was replaced).
    pub fn clear(&mut self) {
        self.entries.clear();
        self.bytes = 0;
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    /// Entries held.
    pub fn len(&self) -> usize {
        self.entries.values().map(Vec::len).sum()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixture::{Beam, SpotBeam};
    use glam::Vec3;

    fn buf(v: f32) -> Arc<LightBuffer> {
        Arc::new(LightBuffer::from_dense(16, 16, &vec![Vec3::splat(v); 256]))
    }

    fn light(x: f32) -> Light {
        Light::aimed(Vec3::new(x, 5.0, 0.0), Vec3::ZERO, Beam::Spot(SpotBeam::from_beam_field(20.0, 30.0)))
    }

    #[test]
    fn evicts_least_recently_used_within_budget() {
        let one = buf(1.0).bytes();
        let mut c = GeometryCache::new(2 * one);
        c.insert(0, &light(1.0), buf(1.0));
        c.insert(0, &light(2.0), buf(2.0));
        assert!(c.get(0, &light(1.0)).is_some()); // 1 is now more recent than 2
        c.insert(1, &light(1.0), buf(3.0));
        assert_eq!(c.len(), 2);
        assert!(c.get(0, &light(2.0)).is_none(), "least recently used evicted");
        assert_eq!(c.get(0, &light(1.0)).unwrap().get(0, 0), Vec3::ONE);
        assert!(c.bytes() <= 2 * one);
    }

    #[test]
    fn lights_differing_in_one_field_never_share_a_buffer() {
        let mut c = GeometryCache::new(1 << 20);
        let a = light(1.0);
        let mut b = a.clone();
        b.position.x = f32::from_bits(a.position.x.to_bits() + 1); // one ulp away
        let mut beam = a.clone();
        beam.beam = Beam::Spot(SpotBeam::from_beam_field(20.0, 31.0));
        c.insert(0, &a, buf(1.0));
        assert!(c.get(0, &b).is_none(), "position differs by one ulp");
        assert!(c.get(0, &beam).is_none(), "field angle differs");
        assert!(c.get(1, &a).is_none(), "another light index");
        c.insert(0, &b, buf(2.0));
        assert_eq!(c.get(0, &a).unwrap().get(0, 0), Vec3::ONE);
        assert_eq!(c.get(0, &b).unwrap().get(0, 0), Vec3::splat(2.0));
    }

    #[test]
    fn haze_is_part_of_the_key_and_knots_count_against_the_budget() {
        let one = buf(1.0).bytes();
        let mut c = GeometryCache::new(6 * one);
        let haze = Medium::new(0.03, 0.003, 0.7, Vec3::ZERO, Vec3::ONE).unwrap();
        let thicker = Medium { sigma_s: 0.031, ..haze };
        let a = light(1.0);
        c.insert_in(0, &a, Some(haze), Finished { knots: Some([buf(0.5), buf(0.25)]), ..Finished::alone(buf(1.0)) });
        assert_eq!(c.bytes(), 3 * one, "buffer and both knots");
        assert!(c.get(0, &a).is_none(), "an entry made in haze is not served in clear air");
        assert!(c.get_in(0, &a, Some(&thicker)).is_none(), "nor in other haze");
        let Finished { buffer: b, knots, .. } = c.get_in(0, &a, Some(&haze)).expect("same light, same haze");
        assert_eq!(b.get(0, 0), Vec3::ONE);
        let knots = knots.expect("knots kept");
        assert_eq!((knots[0].get(0, 0), knots[1].get(0, 0)), (Vec3::splat(0.5), Vec3::splat(0.25)));
        // The same light in clear air and in the thicker haze: entries of their own.
        c.insert(0, &a, buf(2.0));
        c.insert_in(0, &a, Some(thicker), Finished { knots: Some([buf(3.0), buf(3.0)]), ..Finished::alone(buf(3.0)) });
        assert_eq!(c.len(), 2, "budget 6 buffers: the least recently used hazy entry went");
        assert_eq!(c.get(0, &a).unwrap().get(0, 0), Vec3::splat(2.0));
        assert_eq!(c.get_in(0, &a, Some(&thicker)).unwrap().buffer.get(0, 0), Vec3::splat(3.0));
        assert!(c.bytes() <= 6 * one);
    }
}
