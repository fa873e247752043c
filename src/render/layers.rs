//! The sum of the shared indirect layers, off the frame clock (issue 38).
//!
//! A fixture's cells show one shared indirect layer A_g with the summed
//! weight K_g = Σ_{i∈g} k_i ([`super::buffer::SharedLayer`]), so eq. 5 is
//! Σ_i k_i W_i + Σ_g K_g A_g. The W_i are tile-sparse and the compositor
//! recomposes only the tiles a change touches; the A_g cover the whole
//! frame (indirect light reaches every surface), so any change of one K_g
//! or A_g makes every tile dirty and a full recomposite sums every dense
//! layer: on the festival show, 250 layers made a pixel chase 24 Hz and
//! put 50-75 ms frames into the clock while leaders published their
//! refinement passes.
//!
//! [`LayerSum`] keeps S = Σ_g K_g A_g as one dense image that the
//! compositor adds before encoding ([`super::composite::Compositor::set_overlay`]):
//!
//! * up to [`LayerSum::SYNC_LAYERS`] layers with k ≠ 0 are summed on the
//!   calling thread at once (exact in every frame: a bar or two lit);
//! * more are summed on a thread of their own at the lowest OS priority;
//!   the frame shows the last finished sum until the next lands, so the
//!   indirect light of a change follows one sum later (on 2 cores about
//!   50-100 ms for 250 layers) while the direct light and every W_i are
//!   exact in the very frame. A weight change (a fader, a chase) starts a
//!   new sum as soon as none is running; a new layer with unchanged
//!   weights (a leader's next refinement pass) waits until
//!   [`LayerSum::REFRESH`] has passed since the last sum started, so
//!   refinement does not take the build thread's core;
//! * when no layer has k ≠ 0 there is no sum (a blackout is exact at once).
//!
//! Every sum is recomputed from the layers (never updated by deltas), so
//! nothing drifts; a sum whose layers and weights equal the frame's is
//! exactly what [`super::composite::composite`] gives for those entries.

use super::buffer::LightBuffer;
use super::composite::{composite, lowest_priority_pool};
use glam::Vec3;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::{Duration, Instant};

/// What a sum was made from: per layer with k ≠ 0, its id and k.
type Key = Vec<(u64, Vec3)>;

/// The running sum of the shared layers (module doc).
pub struct LayerSum {
    width: u32,
    height: u32,
    /// The sum on screen: what it was made from, its generation, its pixels.
    shown: Option<(Key, u64, Arc<Vec<Vec3>>)>,
    /// The key of the sum being made on the sum thread.
    in_flight: Option<Key>,
    /// When the last sum on the sum thread started.
    last_start: Option<Instant>,
    generation: u64,
    tx: Sender<(Key, Vec<Vec3>)>,
    rx: Receiver<(Key, Vec<Vec3>)>,
    pool: Option<Arc<rayon::ThreadPool>>,
    /// Sums started on the sum thread.
    pub background_sums: u64,
    /// Sums made on the calling thread.
    pub sync_sums: u64,
}

impl LayerSum {
    /// At most this many layers with k ≠ 0 are summed on the calling thread.
    pub const SYNC_LAYERS: usize = 4;
    /// A new layer with unchanged weights starts a sum at most this often.
    pub const REFRESH: Duration = Duration::from_millis(250);

    /// An empty sum for a frame of `width`×`height`; the sum thread starts
    /// with the first sum it makes.
    pub fn new(width: u32, height: u32) -> Self {
        let (tx, rx) = channel();
        Self {
            width,
            height,
            shown: None,
            in_flight: None,
            last_start: None,
            generation: 0,
            tx,
            rx,
            pool: None,
            background_sums: 0,
            sync_sums: 0,
        }
    }

    /// The sum to show for these layers (k, layer id, buffer; places with
    /// k = 0 or an empty buffer count for nothing): its generation (new
    /// whenever the pixels are new) and pixels, `None` when no layer
    /// counts. Never waits for the sum thread (module doc).
    pub fn update(&mut self, layers: &[(Vec3, u64, &Arc<LightBuffer>)]) -> Option<(u64, Arc<Vec<Vec3>>)> {
        while let Ok((key, sum)) = self.rx.try_recv() {
            if self.in_flight.as_ref() == Some(&key) {
                self.in_flight = None;
            }
            self.generation += 1;
            self.shown = Some((key, self.generation, Arc::new(sum)));
        }
        let counted: Vec<&(Vec3, u64, &Arc<LightBuffer>)> =
            layers.iter().filter(|(k, _, b)| *k != Vec3::ZERO && b.occupied_tiles() > 0).collect();
        let key: Key = counted.iter().map(|(k, id, _)| (*id, *k)).collect();
        if key.is_empty() {
            self.shown = None;
            return None;
        }
        if let Some((shown, g, sum)) = &self.shown
            && *shown == key
        {
            return Some((*g, sum.clone()));
        }
        let k: Vec<Vec3> = counted.iter().map(|(k, ..)| *k).collect();
        if key.len() <= Self::SYNC_LAYERS {
            let refs: Vec<&LightBuffer> = counted.iter().map(|(.., b)| &***b).collect();
            let sum = composite(&refs, &k, self.width, self.height);
            self.sync_sums += 1;
            self.generation += 1;
            self.shown = Some((key, self.generation, Arc::new(sum)));
            return self.shown.as_ref().map(|(_, g, s)| (*g, s.clone()));
        }
        let weights_changed = self
            .shown
            .as_ref()
            .is_none_or(|(shown, ..)| shown.len() != key.len() || shown.iter().zip(&key).any(|(a, b)| a.1 != b.1));
        let due = weights_changed || self.last_start.is_none_or(|t| t.elapsed() >= Self::REFRESH);
        if self.in_flight.is_none() && due {
            let buffers = counted.iter().map(|(.., b)| Arc::clone(b)).collect();
            self.start(key, buffers, k);
        }
        self.shown.as_ref().map(|(_, g, s)| (*g, s.clone()))
    }

    /// Starts a sum of `buffers` with weights `k` on the sum thread.
    fn start(&mut self, key: Key, buffers: Vec<Arc<LightBuffer>>, k: Vec<Vec3>) {
        let pool = self.pool.get_or_insert_with(|| Arc::new(lowest_priority_pool("footlight-layer-sum")));
        let (tx, w, h) = (self.tx.clone(), self.width, self.height);
        self.in_flight = Some(key.clone());
        self.last_start = Some(Instant::now());
        self.background_sums += 1;
        pool.spawn(move || {
            let refs: Vec<&LightBuffer> = buffers.iter().map(|b| &**b).collect();
            // The receiver may be gone (the clock ended): nothing to deliver to.
            let _ = tx.send((key, composite(&refs, &k, w, h)));
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(w: u32, h: u32, v: f32) -> Arc<LightBuffer> {
        let dense: Vec<Vec3> = (0..w * h).map(|i| Vec3::new(v, v * 0.5 + i as f32 * 1e-3, 0.25)).collect();
        Arc::new(LightBuffer::from_dense(w, h, &dense))
    }

    /// Few layers: exact at once. Many: the sum thread's sum arrives and
    /// equals the composite of the same entries; meanwhile the last sum
    /// stays; a blackout is no sum at once; unchanged input keeps the
    /// generation.
    #[test]
    fn few_layers_at_once_many_on_the_sum_thread_equal_to_the_composite() {
        let (w, h) = (37u32, 21u32);
        let layers: Vec<Arc<LightBuffer>> = (0..7).map(|i| layer(w, h, 1.0 + i as f32)).collect();
        let k = |i: usize, t: f32| Vec3::new(1.0 + i as f32 * t, 2.0, 0.5 * t);
        let input = |n: usize, t: f32| -> Vec<(Vec3, u64, &Arc<LightBuffer>)> {
            layers.iter().take(n).enumerate().map(|(i, b)| (k(i, t), i as u64 + 1, b)).collect()
        };
        let expect = |n: usize, t: f32| {
            let refs: Vec<&LightBuffer> = layers.iter().take(n).map(|b| &**b).collect();
            let ks: Vec<Vec3> = (0..n).map(|i| k(i, t)).collect();
            composite(&refs, &ks, w, h)
        };
        let mut sum = LayerSum::new(w, h);
        let (g1, s) = sum.update(&input(3, 1.0)).expect("three layers count");
        assert_eq!(*s, expect(3, 1.0), "few layers: summed at once");
        assert_eq!(sum.update(&input(3, 1.0)).unwrap().0, g1, "nothing changed: same generation");
        // Seven layers: the last sum stays until the sum thread's lands.
        let shown = sum.update(&input(7, 2.0)).expect("the last sum meanwhile");
        assert_eq!(shown.0, g1);
        let t = Instant::now();
        let s = loop {
            let (g, s) = sum.update(&input(7, 2.0)).unwrap();
            if g != g1 {
                break s;
            }
            assert!(t.elapsed() < Duration::from_secs(30), "the sum thread never delivered");
            std::thread::sleep(Duration::from_millis(1));
        };
        assert_eq!(*s, expect(7, 2.0), "the sum thread's sum is the composite of the same entries");
        assert_eq!(sum.background_sums, 1);
        let dark: Vec<_> = input(7, 2.0).into_iter().map(|(_, id, b)| (Vec3::ZERO, id, b)).collect();
        assert!(sum.update(&dark).is_none(), "every layer dark: no sum, at once");
    }
}
