//! Merging sources per patch universe and slot (DESIGN.md "Merge"; OLA
//! `Universe`/`DmxSource`). Knows priorities, HTP/LTP and timeouts; knows no
//! sockets, protocols or clocks (`now` is an argument).
//!
//! A universe holds its sources (id, priority, 512 levels, when each slot last
//! changed, when the source was last heard, its timeout) and the merged
//! [`UniverseFrame`]. The rules:
//! - Only sources at the highest priority present take part (sACN 0-200;
//!   Art-Net and USB Pro count as 100).
//! - Among those, each slot is the highest value (HTP), or on slots the
//!   [`SlotMask`] marks LTP the value of the source that changed that slot
//!   last (a source that joins counts as changing the slots where it differs
//!   from the output). Ties go to the source that joined last.
//! - A source not heard for its timeout (sACN 2.5 s, Art-Net 10 s, USB Pro
//!   2.5 s) leaves. When the last source leaves, the frame holds its last
//!   values and is marked stale.
//! - At most [`MergeConfig::max_sources`] sources per universe (default 8; a
//!   further source is refused and counted as dropped until one leaves) and
//!   [`MergeConfig::max_universes`] universes.
//!
//! Steady state allocates nothing: sources and frames live in vectors that
//! only grow when a source or universe first appears.

use std::collections::BTreeMap;
use std::time::Duration;

use tokio::time::Instant;

use crate::source::{Levels, SLOTS, SourceId};

/// One merged patch universe, as the patch decodes it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UniverseFrame {
    /// Patch universe, 1-based.
    pub universe: u16,
    /// Slot values; DMX address A is `slots[A - 1]`.
    pub slots: [u8; SLOTS],
    /// When the frame last changed (a source's levels arrived or left).
    pub at: Instant,
    /// No source is left: these are the last values, held.
    pub stale: bool,
}

/// A per-slot flag set; the merge reads it as "this slot merges LTP".
/// Addresses are 1-based DMX addresses (1-512).
#[derive(Clone, Default, PartialEq, Eq)]
pub struct SlotMask([u64; SLOTS / 64]);

impl SlotMask {
    /// No slot set (all HTP).
    pub fn none() -> Self {
        SlotMask::default()
    }

    /// Every slot set.
    pub fn all() -> Self {
        SlotMask([u64::MAX; SLOTS / 64])
    }

    /// The given 1-based addresses set (others out of range are ignored).
    pub fn from_addresses(addresses: impl IntoIterator<Item = u16>) -> Self {
        let mut mask = SlotMask::none();
        for a in addresses {
            mask.set(a);
        }
        mask
    }

    /// Sets address `address` (1-512).
    pub fn set(&mut self, address: u16) {
        if (1..=SLOTS as u16).contains(&address) {
            let i = usize::from(address - 1);
            self.0[i / 64] |= 1 << (i % 64);
        }
    }

    /// Whether address `address` (1-512) is set.
    pub fn contains(&self, address: u16) -> bool {
        (1..=SLOTS as u16).contains(&address) && {
            let i = usize::from(address - 1);
            self.0[i / 64] & (1 << (i % 64)) != 0
        }
    }

    /// True when no slot is set.
    pub fn is_empty(&self) -> bool {
        self.0.iter().all(|w| *w == 0)
    }

    /// The set slots as 0-based indices.
    fn indices(&self) -> impl Iterator<Item = usize> + '_ {
        self.0.iter().enumerate().flat_map(|(w, &bits)| {
            let mut bits = bits;
            std::iter::from_fn(move || {
                (bits != 0).then(|| {
                    let b = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    w * 64 + b
                })
            })
        })
    }
}

impl std::fmt::Debug for SlotMask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_set().entries(self.indices().map(|i| i + 1)).finish()
    }
}

/// Merge limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MergeConfig {
    /// Sources merged per universe (E1.31 asks receivers to declare it).
    pub max_sources: usize,
    /// Patch universes tracked.
    pub max_universes: usize,
}

impl Default for MergeConfig {
    fn default() -> Self {
        MergeConfig { max_sources: 8, max_universes: 512 }
    }
}

/// Why the merge refused levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MergeError {
    /// Patch universes count from 1.
    #[error("patch universe 0 does not exist")]
    UniverseZero,
    /// [`MergeConfig::max_universes`] universes are already tracked.
    #[error("too many universes (limit {0})")]
    TooManyUniverses(usize),
    /// [`MergeConfig::max_sources`] sources already feed this universe.
    #[error("too many sources on universe {universe} (limit {limit})")]
    TooManySources {
        /// The patch universe.
        universe: u16,
        /// The limit.
        limit: usize,
    },
}

/// One source's contribution to a universe.
struct MergeSource {
    id: SourceId,
    priority: u8,
    levels: [u8; SLOTS],
    /// Per slot, the universe stamp of this source's last change (for LTP).
    changed: [u32; SLOTS],
    seen: Instant,
    timeout: Option<Duration>,
}

impl MergeSource {
    fn expired(&self, now: Instant) -> bool {
        self.timeout.is_some_and(|t| now.saturating_duration_since(self.seen) >= t)
    }
}

/// One patch universe: its sources and merged output.
struct UniverseState {
    frame: UniverseFrame,
    ltp: SlotMask,
    sources: Vec<MergeSource>,
    /// Counts level updates; LTP compares these stamps.
    stamp: u32,
}

impl UniverseState {
    /// Recomputes the output from the sources at the top priority. With no
    /// source the frame holds.
    fn recompute(&mut self) {
        let Some(top) = self.sources.iter().map(|s| s.priority).max() else { return };
        let out = &mut self.frame.slots;
        let mut contenders = 0;
        for s in self.sources.iter().filter(|s| s.priority == top) {
            if contenders == 0 {
                *out = s.levels;
            } else {
                // HTP on every slot first; LTP slots are overwritten below.
                for (o, l) in out.iter_mut().zip(&s.levels) {
                    *o = (*o).max(*l);
                }
            }
            contenders += 1;
        }
        if contenders > 1 {
            for i in self.ltp.indices() {
                let latest = self.sources.iter().filter(|s| s.priority == top).max_by_key(|s| s.changed[i]);
                if let Some(s) = latest {
                    out[i] = s.levels[i];
                }
            }
        }
    }
}

/// The merge of every patch universe.
pub struct Merge {
    config: MergeConfig,
    /// Sorted by universe number (binary search; a show has a handful).
    universes: Vec<UniverseState>,
    /// LTP masks, also for universes that have not appeared yet.
    policies: BTreeMap<u16, SlotMask>,
}

impl Merge {
    /// An empty merge.
    pub fn new(config: MergeConfig) -> Self {
        Merge { config, universes: Vec::new(), policies: BTreeMap::new() }
    }

    /// Marks which slots of `universe` merge LTP (the rest merge HTP).
    pub fn set_ltp(&mut self, universe: u16, mask: SlotMask) {
        if let Ok(i) = self.find(universe) {
            let u = &mut self.universes[i];
            u.ltp = mask.clone();
            u.recompute();
        }
        self.policies.insert(universe, mask);
    }

    fn find(&self, universe: u16) -> Result<usize, usize> {
        self.universes.binary_search_by_key(&universe, |u| u.frame.universe)
    }

    fn find_or_insert(&mut self, universe: u16, now: Instant) -> Result<usize, MergeError> {
        if universe == 0 {
            return Err(MergeError::UniverseZero);
        }
        match self.find(universe) {
            Ok(i) => Ok(i),
            Err(_) if self.universes.len() >= self.config.max_universes => {
                Err(MergeError::TooManyUniverses(self.config.max_universes))
            }
            Err(i) => {
                let ltp = self.policies.get(&universe).cloned().unwrap_or_default();
                let frame = UniverseFrame { universe, slots: [0; SLOTS], at: now, stale: false };
                self.universes.insert(i, UniverseState { frame, ltp, sources: Vec::new(), stamp: 0 });
                Ok(i)
            }
        }
    }

    /// Merges a source's new levels into `universe` and returns the frame.
    pub fn apply(
        &mut self,
        universe: u16,
        source: SourceId,
        priority: u8,
        timeout: Option<Duration>,
        levels: &Levels,
        now: Instant,
    ) -> Result<&UniverseFrame, MergeError> {
        let max_sources = self.config.max_sources;
        let i = self.find_or_insert(universe, now)?;
        let u = &mut self.universes[i];
        u.stamp = u.stamp.wrapping_add(1);
        let stamp = u.stamp;
        let new = levels.slots();
        match u.sources.iter().position(|s| s.id == source) {
            Some(i) => {
                let s = &mut u.sources[i];
                for ((old, new), changed) in s.levels.iter_mut().zip(new).zip(s.changed.iter_mut()) {
                    if old != new {
                        *old = *new;
                        *changed = stamp;
                    }
                }
                (s.priority, s.seen, s.timeout) = (priority, now, timeout);
            }
            None if u.sources.len() >= max_sources => {
                return Err(MergeError::TooManySources { universe, limit: max_sources });
            }
            None => {
                let mut changed = [0; SLOTS];
                for ((c, new), out) in changed.iter_mut().zip(new).zip(&u.frame.slots) {
                    if new != out {
                        *c = stamp;
                    }
                }
                u.sources.push(MergeSource { id: source, priority, levels: *new, changed, seen: now, timeout });
            }
        }
        u.recompute();
        u.frame.at = now;
        u.frame.stale = false;
        Ok(&u.frame)
    }

    /// Notes that a source is alive without new levels (data held for sync).
    pub fn keep_alive(&mut self, universe: u16, source: SourceId, now: Instant) {
        if let Ok(i) = self.find(universe)
            && let Some(s) = self.universes[i].sources.iter_mut().find(|s| s.id == source)
        {
            s.seen = now;
        }
    }

    /// Removes a source from `universe`; returns the changed frame, if it was there.
    pub fn remove(&mut self, universe: u16, source: SourceId, now: Instant) -> Option<&UniverseFrame> {
        let i = self.find(universe).ok()?;
        let u = &mut self.universes[i];
        let before = u.sources.len();
        u.sources.retain(|s| s.id != source);
        (u.sources.len() != before).then(|| Self::after_leave(u, now))
    }

    fn after_leave(u: &mut UniverseState, now: Instant) -> &UniverseFrame {
        if u.sources.is_empty() {
            u.frame.stale = true;
        } else {
            u.recompute();
        }
        u.frame.at = now;
        &u.frame
    }

    /// Drops sources whose timeout has passed; calls `changed` with each frame that changed.
    pub fn expire(&mut self, now: Instant, mut changed: impl FnMut(&UniverseFrame)) {
        for u in &mut self.universes {
            let before = u.sources.len();
            u.sources.retain(|s| !s.expired(now));
            if u.sources.len() != before {
                changed(Self::after_leave(u, now));
            }
        }
    }

    /// When the next source times out, if any will.
    pub fn next_deadline(&self) -> Option<Instant> {
        let sources = self.universes.iter().flat_map(|u| &u.sources);
        sources.filter_map(|s| s.timeout.map(|t| s.seen + t)).min()
    }

    /// The frame of `universe`, if any source ever fed it.
    pub fn frame(&self, universe: u16) -> Option<&UniverseFrame> {
        self.find(universe).ok().map(|i| &self.universes[i].frame)
    }

    /// All frames, by universe number.
    pub fn frames(&self) -> impl Iterator<Item = &UniverseFrame> {
        self.universes.iter().map(|u| &u.frame)
    }

    /// The ids of the sources feeding `universe` (no allocation).
    pub fn source_ids(&self, universe: u16) -> impl Iterator<Item = SourceId> + Clone + '_ {
        let sources = self.find(universe).ok().map_or(&[][..], |i| &self.universes[i].sources[..]);
        sources.iter().map(|s| s.id)
    }

    /// The sources feeding `universe` with their priorities.
    pub fn sources(&self, universe: u16) -> Vec<(SourceId, u8)> {
        let Ok(i) = self.find(universe) else { return Vec::new() };
        self.universes[i].sources.iter().map(|s| (s.id, s.priority)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::{IpAddr, Ipv4Addr};

    fn art(last: u8) -> SourceId {
        SourceId::ArtNet { ip: IpAddr::V4(Ipv4Addr::new(10, 0, 0, last)), physical: 0 }
    }
    fn sacn(n: u8) -> SourceId {
        SourceId::Sacn { cid: [n; 16] }
    }
    const T: Option<Duration> = Some(Duration::from_millis(2500));

    #[test]
    fn htp_takes_the_highest_value_per_slot() {
        let now = Instant::now();
        let mut m = Merge::new(MergeConfig::default());
        m.apply(1, art(1), 100, T, &Levels::new(&[10, 200, 0]), now).unwrap();
        let f = m.apply(1, art(2), 100, T, &Levels::new(&[50, 100]), now).unwrap();
        assert_eq!(f.slots[..4], [50, 200, 0, 0]);
        assert!(!f.stale);
    }

    #[test]
    fn highest_priority_wins_the_whole_universe() {
        let now = Instant::now();
        let mut m = Merge::new(MergeConfig::default());
        m.apply(1, sacn(1), 100, T, &Levels::new(&[255, 255]), now).unwrap();
        let f = m.apply(1, sacn(2), 150, T, &Levels::new(&[1]), now).unwrap();
        assert_eq!(f.slots[..2], [1, 0]);
        // Art-Net counts as 100: loses to 150, merges HTP with 100.
        let f = m.apply(1, art(1), 100, T, &Levels::new(&[9, 9]), now).unwrap();
        assert_eq!(f.slots[..2], [1, 0]);
    }

    #[test]
    fn ltp_slots_follow_the_last_change() {
        let t0 = Instant::now();
        let mut m = Merge::new(MergeConfig::default());
        m.set_ltp(1, SlotMask::from_addresses([2]));
        m.apply(1, art(1), 100, T, &Levels::new(&[10, 200]), t0).unwrap();
        // B joins with a lower pan: it differs from the output, so it takes slot 2.
        let f = m.apply(1, art(2), 100, T, &Levels::new(&[20, 50]), t0).unwrap();
        assert_eq!(f.slots[..2], [20, 50]);
        // A repeats itself: no change, B keeps slot 2.
        let f = m.apply(1, art(1), 100, T, &Levels::new(&[10, 200]), t0).unwrap();
        assert_eq!(f.slots[..2], [20, 50]);
        // A moves: A takes slot 2 again, slot 1 stays HTP.
        let f = m.apply(1, art(1), 100, T, &Levels::new(&[10, 120]), t0).unwrap();
        assert_eq!(f.slots[..2], [20, 120]);
    }

    #[test]
    fn timeout_leaves_and_last_source_leaving_holds_stale() {
        let t0 = Instant::now();
        let mut m = Merge::new(MergeConfig::default());
        m.apply(1, sacn(1), 100, T, &Levels::new(&[100]), t0).unwrap();
        m.apply(1, art(1), 100, Some(Duration::from_secs(10)), &Levels::new(&[50]), t0).unwrap();
        assert_eq!(m.next_deadline(), Some(t0 + Duration::from_millis(2500)));
        let mut changed = Vec::new();
        m.expire(t0 + Duration::from_millis(2499), |f| changed.push(f.clone()));
        assert!(changed.is_empty());
        m.expire(t0 + Duration::from_millis(2500), |f| changed.push(f.clone()));
        assert_eq!((changed[0].slots[0], changed[0].stale), (50, false));
        m.expire(t0 + Duration::from_secs(10), |f| changed.push(f.clone()));
        assert_eq!((changed[1].slots[0], changed[1].stale), (50, true));
        assert_eq!(m.next_deadline(), None);
        let f = m.apply(1, sacn(1), 100, T, &Levels::new(&[7]), t0 + Duration::from_secs(11)).unwrap();
        assert_eq!((f.slots[0], f.stale), (7, false));
    }

    #[test]
    fn limits_are_errors_not_panics() {
        let now = Instant::now();
        let mut m = Merge::new(MergeConfig { max_sources: 2, max_universes: 1 });
        let l = Levels::new(&[1]);
        assert_eq!(m.apply(0, art(1), 100, T, &l, now).unwrap_err(), MergeError::UniverseZero);
        m.apply(1, art(1), 100, T, &l, now).unwrap();
        m.apply(1, art(2), 100, T, &l, now).unwrap();
        assert!(matches!(m.apply(1, art(3), 100, T, &l, now), Err(MergeError::TooManySources { .. })));
        assert_eq!(m.apply(2, art(1), 100, T, &l, now).unwrap_err(), MergeError::TooManyUniverses(1));
        assert!(m.remove(1, art(1), now).is_some());
        assert!(m.remove(1, art(1), now).is_none());
        m.apply(1, art(3), 100, T, &l, now).unwrap();
    }

    #[test]
    fn slot_mask_addresses_are_one_based() {
        let m = SlotMask::from_addresses([1, 64, 65, 512, 0, 513]);
        assert!(m.contains(1) && m.contains(64) && m.contains(65) && m.contains(512));
        assert!(!m.contains(2) && !m.contains(0) && !m.contains(513));
        assert_eq!(m.indices().collect::<Vec<_>>(), vec![0, 63, 64, 511]);
        assert_eq!(SlotMask::all().indices().count(), 512);
    }
}
