//! Getting composited frames back to the CPU (for the HTTP preview, PNGs)
//! without waiting on the GPU more than necessary.
//!
//! Strategy: a small ring of `MAP_READ` staging buffers. Each submitted frame
//! copies the output into a free staging buffer in the same command buffer as
//! the composite and asks for it to be mapped (`map_async`); nothing waits.
//! [`GpuCompositor::try_frame`](crate::GpuCompositor::try_frame) polls the
//! device without blocking and hands out the newest frame whose copy has finished, dropping older finished ones (a
//! preview wants the latest picture, not a backlog). So a live loop that
//! submits frame n and then takes whatever is ready sees frame n−1 or n with
//! no stall, and the GPU works while the CPU encodes JPEG/PNG.
//!
//! Back-pressure: when every staging buffer holds a frame, the oldest finished
//! one is dropped and reused; only when all are still on the GPU does
//! [`GpuCompositor::submit`](crate::GpuCompositor::submit) wait, for the
//! oldest, which bounds the GPU's lead to the ring size instead of queueing
//! without limit. A std `AtomicU8` per slot
//! carries the map callback's result: the callback runs inside `device.poll`
//! on the calling thread, so no lock or channel is needed.

use crate::GpuError;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

const PENDING: u8 = 0;
const MAPPED: u8 = 1;
const FAILED: u8 = 2;

/// Identifies a submitted frame; increases by one per submission.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct FrameId(pub u64);

/// A composited frame as display pixels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    /// Which submission this is.
    pub id: FrameId,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// sRGB, 4 bytes per pixel (R, G, B, A = 255), row-major, no row padding.
    pub rgba8: Vec<u8>,
}

impl Frame {
    /// The pixels as RGB triplets (display.rs `to_srgb8` layout, for PNG).
    pub fn rgb8(&self) -> Vec<u8> {
        self.rgba8.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect()
    }
}

enum SlotState {
    Free,
    InFlight { frame: FrameId, submission: wgpu::SubmissionIndex, status: Arc<AtomicU8> },
}

struct Slot {
    buffer: wgpu::Buffer,
    state: SlotState,
}

/// The staging ring.
pub(crate) struct Readback {
    slots: Vec<Slot>,
    bytes: u64,
    width: u32,
    height: u32,
}

impl Readback {
    /// `count` staging buffers for `width`×`height` RGBA8 frames.
    pub fn new(device: &wgpu::Device, count: usize, width: u32, height: u32) -> Self {
        let bytes = u64::from(width) * u64::from(height) * 4;
        let slots = (0..count.max(1))
            .map(|i| Slot {
                buffer: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(&format!("footlight readback {i}")),
                    size: bytes,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                }),
                state: SlotState::Free,
            })
            .collect();
        Self { slots, bytes, width, height }
    }

    /// A staging buffer to copy the next frame into (see the module doc for
    /// what happens when none is free).
    pub fn acquire(&mut self, device: &wgpu::Device) -> Result<usize, GpuError> {
        if let Some(i) = self.slots.iter().position(|s| matches!(s.state, SlotState::Free)) {
            return Ok(i);
        }
        device.poll(wgpu::PollType::Poll)?;
        let oldest = self.oldest_in_flight().expect("no free slot means all are in flight");
        if self.status(oldest) == PENDING {
            let SlotState::InFlight { submission, .. } = &self.slots[oldest].state else { unreachable!() };
            let submission = submission.clone();
            wait_for_map(device, submission, || self.status(oldest) != PENDING)?;
        }
        // Dropped unread: a newer frame is about to exist.
        self.release(oldest);
        Ok(oldest)
    }

    /// Records `slot` as holding `frame` (copied in `submission`) and starts
    /// mapping it.
    pub fn start(&mut self, slot: usize, frame: FrameId, submission: wgpu::SubmissionIndex) {
        let status = Arc::new(AtomicU8::new(PENDING));
        let done = Arc::clone(&status);
        self.slots[slot].buffer.map_async(wgpu::MapMode::Read, .., move |r| {
            done.store(if r.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
        });
        self.slots[slot].state = SlotState::InFlight { frame, submission, status };
    }

    /// The staging buffer of `slot`, for the copy.
    pub fn buffer(&self, slot: usize) -> &wgpu::Buffer {
        &self.slots[slot].buffer
    }

    /// Bytes per frame.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// The newest finished frame, if any, without blocking; older finished
    /// frames are dropped.
    pub fn try_take(&mut self, device: &wgpu::Device) -> Result<Option<Frame>, GpuError> {
        device.poll(wgpu::PollType::Poll)?;
        let mut finished: Vec<(FrameId, usize)> = (0..self.slots.len())
            .filter_map(|i| match &self.slots[i].state {
                SlotState::InFlight { frame, status, .. } if status.load(Ordering::Acquire) != PENDING => {
                    Some((*frame, i))
                }
                _ => None,
            })
            .collect();
        finished.sort_unstable();
        let Some(&(id, newest)) = finished.last() else { return Ok(None) };
        for &(_, i) in &finished[..finished.len() - 1] {
            self.release(i);
        }
        if self.status(newest) == FAILED {
            self.release(newest);
            return Err(GpuError::Map(wgpu::BufferAsyncError));
        }
        let rgba8 = {
            let view = self.slots[newest]
                .buffer
                .get_mapped_range(..)
                .map_err(|e| GpuError::Wgpu { during: "reading the frame back", message: e.to_string() })?;
            view.to_vec()
        };
        self.release(newest);
        Ok(Some(Frame { id, width: self.width, height: self.height, rgba8 }))
    }

    /// Blocks until the newest submitted frame is back and returns it; `None`
    /// when no frame is in flight.
    pub fn wait_newest(&mut self, device: &wgpu::Device) -> Result<Option<Frame>, GpuError> {
        let newest = (0..self.slots.len())
            .filter_map(|i| match &self.slots[i].state {
                SlotState::InFlight { frame, submission, .. } => Some((*frame, i, submission.clone())),
                SlotState::Free => None,
            })
            .max_by_key(|(frame, _, _)| *frame);
        let Some((_, slot, submission)) = newest else { return Ok(None) };
        wait_for_map(device, submission, || self.status(slot) != PENDING)?;
        self.try_take(device)
    }

    fn oldest_in_flight(&self) -> Option<usize> {
        (0..self.slots.len())
            .filter_map(|i| match &self.slots[i].state {
                SlotState::InFlight { frame, .. } => Some((*frame, i)),
                SlotState::Free => None,
            })
            .min()
            .map(|(_, i)| i)
    }

    fn status(&self, slot: usize) -> u8 {
        match &self.slots[slot].state {
            SlotState::InFlight { status, .. } => status.load(Ordering::Acquire),
            SlotState::Free => PENDING,
        }
    }

    /// Unmaps (if mapped) and frees `slot`.
    fn release(&mut self, slot: usize) {
        if self.status(slot) == MAPPED {
            self.slots[slot].buffer.unmap();
        }
        self.slots[slot].state = SlotState::Free;
    }
}

/// Waits for `submission` and then for its map callback (`mapped()` true).
///
/// The two are not the same moment when another thread polls the same
/// device: its poll may have collected our callback and not yet run it when
/// our wait returns. So this polls again until the callback has run, giving
/// up after 10 s (the callback runs even when the device is lost, with an
/// error, so that is never a normal outcome).
pub(crate) fn wait_for_map(
    device: &wgpu::Device,
    submission: wgpu::SubmissionIndex,
    mapped: impl Fn() -> bool,
) -> Result<(), GpuError> {
    device.poll(wgpu::PollType::Wait { submission_index: Some(submission), timeout: None })?;
    let start = std::time::Instant::now();
    while !mapped() {
        if start.elapsed() > std::time::Duration::from_secs(10) {
            return Err(GpuError::Wgpu {
                during: "reading a frame back",
                message: "no map callback after 10 s".into(),
            });
        }
        std::thread::yield_now();
        device.poll(wgpu::PollType::Poll)?;
    }
    Ok(())
}
