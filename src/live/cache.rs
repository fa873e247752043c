//! Geometry cache: recent geometry states of each light keep their finished
//! buffers, so returning to a position preset (a focus cue, a pan/tilt
//! position) shows its converged picture at once instead of re-tracing.
//! Bounded by bytes; the least recently used entry goes first.

use crate::Light;
use crate::render::LightBuffer;
use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::sync::Arc;

/// Key of a light's geometry state: every field of its [`Light`] (position,
/// orientation, beam parameters). DMX-driven states repeat bit for bit, so
/// the exact value is the right key.
pub fn geometry_key(light: &Light) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    format!("{light:?}").hash(&mut h);
    h.finish()
}

struct Entry {
    buffer: Arc<LightBuffer>,
    last_used: u64,
}

/// LRU map from (light index, geometry key) to a finished buffer.
pub struct GeometryCache {
    entries: HashMap<(usize, u64), Entry>,
    bytes: usize,
    budget: usize,
    clock: u64,
}

impl GeometryCache {
    /// An empty cache holding at most `budget` bytes of buffers.
    pub fn new(budget: usize) -> Self {
        Self { entries: HashMap::new(), bytes: 0, budget, clock: 0 }
    }

    /// The finished buffer for this light and geometry, if cached.
    pub fn get(&mut self, light: usize, key: u64) -> Option<Arc<LightBuffer>> {
        self.clock += 1;
        let clock = self.clock;
        self.entries.get_mut(&(light, key)).map(|e| {
            e.last_used = clock;
            e.buffer.clone()
        })
    }

    /// Stores a finished buffer, evicting least recently used entries past the budget.
    pub fn insert(&mut self, light: usize, key: u64, buffer: Arc<LightBuffer>) {
        let size = buffer.bytes();
        if size > self.budget {
            return;
        }
        self.clock += 1;
        if let Some(old) = self.entries.insert((light, key), Entry { buffer, last_used: self.clock }) {
            self.bytes -= old.buffer.bytes();
        }
        self.bytes += size;
        while self.bytes > self.budget {
            let Some((&oldest, _)) = self.entries.iter().min_by_key(|(_, e)| e.last_used) else { break };
            if let Some(e) = self.entries.remove(&oldest) {
                self.bytes -= e.buffer.bytes();
            }
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    /// Entries held.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn evicts_least_recently_used_within_budget() {
        let buf = |v: f32| Arc::new(LightBuffer::from_dense(16, 16, &vec![Vec3::splat(v); 256]));
        let one = buf(1.0).bytes();
        let mut c = GeometryCache::new(2 * one);
        c.insert(0, 1, buf(1.0));
        c.insert(0, 2, buf(2.0));
        assert!(c.get(0, 1).is_some()); // 1 is now more recent than 2
        c.insert(1, 1, buf(3.0));
        assert_eq!(c.len(), 2);
        assert!(c.get(0, 2).is_none(), "least recently used evicted");
        assert_eq!(c.get(0, 1).unwrap().get(0, 0), Vec3::ONE);
        assert!(c.bytes() <= 2 * one);
    }
}
