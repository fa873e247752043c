//! Geometry cache: recent geometry states of each light keep their finished
//! buffers, so returning to a position preset (a focus cue, a pan/tilt
//! position) shows its converged picture at once instead of re-tracing.
//! Bounded by bytes; the least recently used entry goes first. The key is
//! the exact geometry state, compared with `==`.

use crate::Light;
use crate::render::LightBuffer;
use std::collections::HashMap;
use std::sync::Arc;

struct Entry {
    /// The exact geometry state (the key: compared with `==`, so two
    /// states differing in any field never share a buffer).
    light: Light,
    buffer: Arc<LightBuffer>,
    last_used: u64,
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

    /// The finished buffer for this light index and exact geometry, if cached.
    pub fn get(&mut self, index: usize, light: &Light) -> Option<Arc<LightBuffer>> {
        self.clock += 1;
        let clock = self.clock;
        let e = self.entries.get_mut(&index)?.iter_mut().find(|e| e.light == *light)?;
        e.last_used = clock;
        Some(e.buffer.clone())
    }

    /// Stores a finished buffer, evicting least recently used entries past the budget.
    pub fn insert(&mut self, index: usize, light: &Light, buffer: Arc<LightBuffer>) {
        let size = buffer.bytes();
        if size > self.budget {
            return;
        }
        self.clock += 1;
        let list = self.entries.entry(index).or_default();
        if let Some(pos) = list.iter().position(|e| e.light == *light) {
            self.bytes -= list.swap_remove(pos).buffer.bytes();
        }
        list.push(Entry { light: light.clone(), buffer, last_used: self.clock });
        self.bytes += size;
        while self.bytes > self.budget {
            let oldest = self
                .entries
                .iter()
                .flat_map(|(&i, list)| list.iter().enumerate().map(move |(pos, e)| (e.last_used, i, pos)))
                .min();
            let Some((_, i, pos)) = oldest else { break };
            if let Some(list) = self.entries.get_mut(&i) {
                self.bytes -= list.swap_remove(pos).buffer.bytes();
            }
        }
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
}
