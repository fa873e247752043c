//! The real-time update of Vierjahn 2010, section 3.3, on the GPU:
//! I = Σ_i k_i ⊙ buffer_i (eq. 5), then white balance, exposure, clipping and
//! sRGB, in one compute pipeline (the top-level `shaders/composite.wgsl`).
//!
//! # Where the data lives
//! * **Tile pool** (one or more storage buffers, "pages", each within
//!   `max_storage_buffer_binding_size`): every light's occupied 16×16 tiles,
//!   uploaded only by [`GpuCompositor::set_light`], i.e. when the tracer
//!   rebuilds the light. Nothing dense per light ever exists on the GPU: 600
//!   lights reaching 5 % of a 1920×1080 frame each take ~750 MB as f32,
//!   ~375 MB as f16 ([`TileFormat::F16`]), instead of 15 GB.
//! * **Per-page index**, rebuilt on the CPU after lights change (not per
//!   frame): for each screen tile, the (light, slot) entries of the lights that
//!   reach it, in light order (CSR: `offsets` + `entries`).
//! * **Per frame** only the weights (16 bytes per light) and a 32-byte
//!   `Params` per page are written.
//!
//! # Per frame
//! One workgroup per screen tile walks the tile's entries; entries of lights
//! with k_i = 0 are skipped without reading their tiles, and pages that hold
//! no active light are not dispatched at all. With several pages the running
//! sum is carried in a linear f32 image between dispatches; with one page
//! (the usual case on a real GPU) the frame is a single dispatch that writes
//! only RGBA8. The frame is recomputed whole each time: on a GPU that is
//! cheaper than the CPU path's dirty-tile tracking, and it cannot drift.
//!
//! Readback: see [`crate::readback`].

use crate::pool::{Run, TileAllocator};
use crate::readback::{Frame, FrameId, Readback};
use crate::{
    CompositorOptions, DisplayParams, EMPTY_SLOT, GpuError, LightTiles, MAX_LIGHTS, TILE, TILE_PIXELS, TileFormat,
};
use bytemuck::{Pod, Zeroable};

/// Start from the running sum (composite.wgsl `READ_ACC`).
const READ_ACC: u32 = 1;
/// Store the sum in the linear image (composite.wgsl `WRITE_ACC`).
const WRITE_ACC: u32 = 2;
/// Encode to RGBA8 (composite.wgsl `WRITE_DISPLAY`).
const WRITE_DISPLAY: u32 = 4;
/// Skip the entry lists (composite.wgsl `NO_LIGHTS`).
const NO_LIGHTS: u32 = 8;

/// First page size in tiles (grows by doubling up to the binding limit).
const INITIAL_PAGE_TILES: u32 = 256;

/// Storage buffers the shader binds (weights, offsets, entries, tiles, linear, rgba8).
const STORAGE_BINDINGS: u32 = 6;

/// The shader's `Params` uniform, byte for byte.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub(crate) struct Params {
    /// white_balance × exposure in xyz; w unused.
    scale: [f32; 4],
    width: u32,
    height: u32,
    tiles_x: u32,
    flags: u32,
    /// Highlight roll-off: knee, white, 1 = on / 0 = off, unused.
    rolloff: [f32; 4],
}

// The WGSL struct is vec4<f32> + 4 × u32 + vec4<f32> = 48 bytes, no padding.
const _: () = assert!(std::mem::size_of::<Params>() == 48);

/// Where one tile of a light sits.
#[derive(Clone, Copy, Debug)]
struct Placed {
    /// Screen tile index, row-major.
    screen_tile: u32,
    page: u32,
    slot: u32,
}

/// A light's place in the pool.
#[derive(Debug)]
struct LightSlot {
    runs: Vec<Run>,
    /// One per occupied screen tile, in screen-tile order.
    placed: Vec<Placed>,
    /// Pages holding any of its tiles, sorted.
    pages: Vec<u32>,
}

/// One pool page and the buffers that go with it.
struct Page {
    tiles: wgpu::Buffer,
    params: wgpu::Buffer,
    offsets: wgpu::Buffer,
    entries: wgpu::Buffer,
    /// Entries `entries` can hold.
    entries_capacity: u64,
    bind_group: Option<wgpu::BindGroup>,
}

/// How much of the pool is in use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PoolStats {
    /// Storage buffers in the pool.
    pub pages: usize,
    /// Tiles the pool can hold without growing.
    pub capacity_tiles: u64,
    /// Tiles holding light data.
    pub used_tiles: u64,
    /// GPU bytes of the pool.
    pub bytes: u64,
    /// Largest page, in tiles (from the device limit or the options).
    pub max_page_tiles: u32,
}

/// What the last composite did (for status output and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameStats {
    /// Lights with k_i ≠ 0 and at least one tile.
    pub active_lights: usize,
    /// Tiles of those lights, each read once (dark lights' tiles are not read).
    pub tiles_read: u64,
    /// Dispatches: pool pages holding an active light (1 when none does).
    pub passes: usize,
}

/// The GPU compositor: per-light tiles on the GPU, one composite per frame.
///
/// Made for one image size; a new camera resolution needs a new compositor.
pub struct GpuCompositor {
    device: wgpu::Device,
    queue: wgpu::Queue,
    width: u32,
    height: u32,
    tiles_x: u32,
    tiles_y: u32,
    format: TileFormat,
    max_page_tiles: u32,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    alloc: TileAllocator,
    /// Parallel to `alloc`'s pages.
    pages: Vec<Page>,
    /// Indexed by light; `None` is a light without a buffer (contributes 0).
    lights: Vec<Option<LightSlot>>,
    /// Lights changed since the index was built.
    index_dirty: bool,
    /// A buffer behind a bind group was replaced.
    bind_groups_dirty: bool,
    weights: wgpu::Buffer,
    weights_capacity: usize,
    /// Running sum between pages, and the linear readback.
    linear: wgpu::Buffer,
    rgba8: wgpu::Buffer,
    readback: Readback,
    linear_staging: Option<wgpu::Buffer>,
    next_frame: u64,
    /// Reused for f16 conversion on upload.
    half_scratch: Vec<u16>,
    last_stats: FrameStats,
}

impl GpuCompositor {
    /// A compositor for `width`×`height` frames with no lights (frames are
    /// black until [`Self::set_light`]). Checks the device's limits.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        width: u32,
        height: u32,
        options: CompositorOptions,
    ) -> Result<Self, GpuError> {
        let limits = device.limits();
        let bad_size = |why: String| GpuError::BadSize { width, height, why };
        if width == 0 || height == 0 {
            return Err(bad_size("empty image".into()));
        }
        let (tiles_x, tiles_y) = (width.div_ceil(TILE), height.div_ceil(TILE));
        if tiles_x.max(tiles_y) > limits.max_compute_workgroups_per_dimension {
            return Err(bad_size(format!(
                "{} tiles on a side, the device dispatches at most {}",
                tiles_x.max(tiles_y),
                limits.max_compute_workgroups_per_dimension
            )));
        }
        let binding_limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        let linear_bytes = u64::from(width) * u64::from(height) * 12;
        if linear_bytes > binding_limit {
            return Err(bad_size(format!("{linear_bytes} bytes of linear image, the device binds {binding_limit}")));
        }
        check_limit("storage buffers per shader stage", STORAGE_BINDINGS, limits.max_storage_buffers_per_shader_stage)?;
        check_limit("invocations per workgroup", TILE * TILE, limits.max_compute_invocations_per_workgroup)?;
        check_limit("workgroup size x", TILE, limits.max_compute_workgroup_size_x)?;
        check_limit("workgroup size y", TILE, limits.max_compute_workgroup_size_y)?;

        let page_bytes = binding_limit.min(options.max_page_bytes.unwrap_or(u64::MAX));
        // Word indices in the shader are u32: slot × (words per tile) must fit.
        let words_per_tile = options.tile_format.tile_bytes() / 4;
        let max_page_tiles = (page_bytes / options.tile_format.tile_bytes()).min(u64::from(u32::MAX) / words_per_tile);
        if max_page_tiles == 0 {
            return Err(GpuError::Unsupported {
                what: format!("a pool page of {page_bytes} bytes cannot hold one {}-byte tile", words_per_tile * 4),
            });
        }
        let max_page_tiles = max_page_tiles as u32;

        let scope = ErrorScopes::push(device);
        let (pipeline, layout) = create_pipeline(device, options.tile_format);
        let storage = wgpu::BufferUsages::STORAGE;
        let linear = create_buffer(device, "footlight linear", linear_bytes, storage | wgpu::BufferUsages::COPY_SRC);
        let rgba8 = create_buffer(device, "footlight rgba8", linear_bytes / 3, storage | wgpu::BufferUsages::COPY_SRC);
        let weights_capacity = 64;
        let weights = create_weights(device, weights_capacity);
        let readback = Readback::new(device, options.readback_slots, width, height);
        let mut c = Self {
            device: device.clone(),
            queue: queue.clone(),
            width,
            height,
            tiles_x,
            tiles_y,
            format: options.tile_format,
            max_page_tiles,
            pipeline,
            layout,
            alloc: TileAllocator::default(),
            pages: Vec::new(),
            lights: Vec::new(),
            index_dirty: true,
            bind_groups_dirty: true,
            weights,
            weights_capacity,
            linear,
            rgba8,
            readback,
            linear_staging: None,
            next_frame: 0,
            half_scratch: Vec::new(),
            last_stats: FrameStats::default(),
        };
        c.add_page(INITIAL_PAGE_TILES.min(max_page_tiles));
        scope.pop("creating the compositor")?;
        Ok(c)
    }

    /// Frame width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Frame height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Length of the light table: one more than the highest index ever set.
    /// [`Self::composite`] needs at least this many weights.
    pub fn light_count(&self) -> usize {
        self.lights.len()
    }

    /// Pool usage, for status output and tests.
    pub fn pool_stats(&self) -> PoolStats {
        let capacity_tiles: u64 = (0..self.alloc.pages()).map(|p| u64::from(self.alloc.capacity(p))).sum();
        PoolStats {
            pages: self.alloc.pages(),
            capacity_tiles,
            used_tiles: self.alloc.used_tiles(),
            bytes: capacity_tiles * self.format.tile_bytes(),
            max_page_tiles: self.max_page_tiles,
        }
    }

    /// What the last composite did.
    pub fn last_frame_stats(&self) -> FrameStats {
        self.last_stats
    }

    /// Uploads light `index`'s buffer, replacing any earlier one (call when
    /// the tracer has rebuilt the light). The input is checked first (slot
    /// table size, slots in range and unique, values finite and
    /// non-negative); a bad input changes nothing. If the pool cannot grow
    /// (out of GPU memory) the error is returned and the light is left empty.
    pub fn set_light(&mut self, index: usize, light: LightTiles<'_>) -> Result<(), GpuError> {
        if index >= MAX_LIGHTS {
            return Err(GpuError::LightIndex { index, max: MAX_LIGHTS });
        }
        self.validate(index, light)?;
        let n = (light.tiles.len() / TILE_PIXELS) as u32;

        // Free first, so a rebuilt light can reuse its own space.
        self.remove_light(index);
        if self.lights.len() <= index {
            self.lights.resize_with(index + 1, || None);
        }
        let runs = self.allocate(n)?;

        // Upload, one write per run.
        let scope = ErrorScopes::push(&self.device);
        let mut first = 0usize;
        let mut slot_of = Vec::with_capacity(n as usize);
        for run in &runs {
            let tiles = &light.tiles[first * TILE_PIXELS..(first + run.len as usize) * TILE_PIXELS];
            let offset = u64::from(run.start) * self.format.tile_bytes();
            let buffer = &self.pages[run.page as usize].tiles;
            match self.format {
                TileFormat::F32 => self.queue.write_buffer(buffer, offset, bytemuck::cast_slice(tiles)),
                TileFormat::F16 => {
                    to_half(tiles, &mut self.half_scratch);
                    self.queue.write_buffer(buffer, offset, bytemuck::cast_slice(&self.half_scratch));
                }
            }
            slot_of.extend((run.start..run.start + run.len).map(|s| (run.page, s)));
            first += run.len as usize;
        }
        if let Err(e) = scope.pop("uploading a light") {
            self.alloc.free(&runs);
            return Err(e);
        }

        let placed: Vec<Placed> = light
            .slots
            .iter()
            .enumerate()
            .filter(|(_, s)| **s != EMPTY_SLOT)
            .map(|(t, &s)| {
                let (page, slot) = slot_of[s as usize];
                Placed { screen_tile: t as u32, page, slot }
            })
            .collect();
        let mut pages: Vec<u32> = placed.iter().map(|p| p.page).collect();
        pages.sort_unstable();
        pages.dedup();
        self.lights[index] = Some(LightSlot { runs, placed, pages });
        self.index_dirty = true;
        Ok(())
    }

    /// Drops light `index`'s buffer (it then contributes nothing); returns
    /// whether it had one. Its index stays valid.
    pub fn remove_light(&mut self, index: usize) -> bool {
        let Some(old) = self.lights.get_mut(index).and_then(Option::take) else { return false };
        self.alloc.free(&old.runs);
        self.index_dirty = true;
        true
    }

    /// Composites with weights `k` (k\[i\] for light i; at least
    /// [`Self::light_count`] of them, extra ones are lights without a buffer)
    /// and waits for the frame: the simple, blocking form of
    /// [`Self::submit`] + [`Self::wait_frame`].
    pub fn composite(&mut self, k: &[[f32; 3]], display: &DisplayParams) -> Result<Frame, GpuError> {
        let id = self.submit(k, display)?;
        match self.readback.wait_newest(&self.device)? {
            Some(frame) if frame.id == id => Ok(frame),
            other => Err(GpuError::Wgpu {
                during: "reading the frame back",
                message: format!("expected frame {id:?}, got {:?}", other.map(|f| f.id)),
            }),
        }
    }

    /// Starts compositing a frame and returns at once; collect it with
    /// [`Self::try_frame`] (non-blocking) or [`Self::wait_frame`].
    pub fn submit(&mut self, k: &[[f32; 3]], display: &DisplayParams) -> Result<FrameId, GpuError> {
        if !display.is_valid() {
            return Err(GpuError::BadDisplay(*display));
        }
        // Before taking a readback slot, which may drop an unread frame.
        self.check_weights(k)?;
        let scope = ErrorScopes::push(&self.device);
        let slot = self.readback.acquire(&self.device)?;
        let mut encoder = self.encode(k, display.scale(), display.rolloff_uniform(), WRITE_DISPLAY)?;
        encoder.copy_buffer_to_buffer(&self.rgba8, 0, self.readback.buffer(slot), 0, self.readback.bytes());
        let submission = self.queue.submit([encoder.finish()]);
        let id = FrameId(self.next_frame);
        self.next_frame += 1;
        self.readback.start(slot, id, submission);
        scope.pop("compositing")?;
        Ok(id)
    }

    /// The newest finished frame, if any, without blocking (older finished
    /// frames are dropped).
    pub fn try_frame(&mut self) -> Result<Option<Frame>, GpuError> {
        self.readback.try_take(&self.device)
    }

    /// Waits for the newest submitted frame; `None` if none is in flight.
    pub fn wait_frame(&mut self) -> Result<Option<Frame>, GpuError> {
        self.readback.wait_newest(&self.device)
    }

    /// The linear composite I = Σ k_i ⊙ buffer_i (cd/m², row-major RGB),
    /// read back in f32 (for stills and tests; blocks until done).
    pub fn composite_linear(&mut self, k: &[[f32; 3]]) -> Result<Vec<[f32; 3]>, GpuError> {
        let scope = ErrorScopes::push(&self.device);
        let bytes = u64::from(self.width) * u64::from(self.height) * 12;
        let staging = self.linear_staging.get_or_insert_with(|| {
            create_buffer(
                &self.device,
                "footlight linear readback",
                bytes,
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            )
        });
        let staging = staging.clone();
        let mut encoder = self.encode(k, [1.0; 3], [0.0; 4], WRITE_ACC)?;
        encoder.copy_buffer_to_buffer(&self.linear, 0, &staging, 0, bytes);
        let submission = self.queue.submit([encoder.finish()]);
        let status = std::sync::Arc::new(std::sync::Mutex::new(None));
        let done = std::sync::Arc::clone(&status);
        staging.map_async(wgpu::MapMode::Read, .., move |r| *done.lock().expect("map status lock") = Some(r));
        crate::readback::wait_for_map(&self.device, submission, || status.lock().expect("map status lock").is_some())?;
        let mapped = status.lock().expect("map status lock").take();
        match mapped {
            Some(Ok(())) => {}
            Some(Err(e)) => return Err(GpuError::Map(e)),
            None => return Err(GpuError::Map(wgpu::BufferAsyncError)),
        }
        let out = {
            let view = staging
                .get_mapped_range(..)
                .map_err(|e| GpuError::Wgpu { during: "reading the linear image back", message: e.to_string() })?;
            bytemuck::pod_collect_to_vec::<u8, [f32; 3]>(&view)
        };
        staging.unmap();
        scope.pop("compositing the linear image")?;
        Ok(out)
    }

    /// Checks a light's input against the image and the buffer.rs contract.
    fn validate(&self, light: usize, input: LightTiles<'_>) -> Result<(), GpuError> {
        let expected = (self.tiles_x * self.tiles_y) as usize;
        if input.slots.len() != expected {
            return Err(GpuError::SlotTableLength {
                light,
                got: input.slots.len(),
                expected,
                width: self.width,
                height: self.height,
            });
        }
        if !input.tiles.len().is_multiple_of(TILE_PIXELS) {
            return Err(GpuError::TileDataLength { light, len: input.tiles.len() });
        }
        let n = input.tiles.len() / TILE_PIXELS;
        let mut used = vec![false; n];
        for (t, &s) in input.slots.iter().enumerate().filter(|(_, s)| **s != EMPTY_SLOT) {
            if s as usize >= n || std::mem::replace(&mut used[s as usize], true) {
                return Err(GpuError::BadSlot { light, tile: t, slot: s, tiles: n });
            }
            let tile = &input.tiles[s as usize * TILE_PIXELS..(s as usize + 1) * TILE_PIXELS];
            if let Some(p) = tile.iter().position(|v| v.iter().any(|c| !c.is_finite() || *c < 0.0)) {
                let x = (t as u32 % self.tiles_x) * TILE + p as u32 % TILE;
                let y = (t as u32 / self.tiles_x) * TILE + p as u32 / TILE;
                return Err(GpuError::BadValue { light, x, y, value: tile[p] });
            }
        }
        Ok(())
    }

    /// One finite, non-negative k_i per light with a slot.
    fn check_weights(&self, k: &[[f32; 3]]) -> Result<(), GpuError> {
        if k.len() < self.lights.len() {
            return Err(GpuError::WeightCount { lights: self.lights.len(), got: k.len() });
        }
        match k.iter().position(|v| v.iter().any(|c| !c.is_finite() || *c < 0.0)) {
            Some(i) => Err(GpuError::BadWeight { light: i, value: k[i] }),
            None => Ok(()),
        }
    }

    /// Takes `n` pool slots, growing the pool as needed.
    fn allocate(&mut self, n: u32) -> Result<Vec<Run>, GpuError> {
        loop {
            if let Some(runs) = self.alloc.alloc(n) {
                return Ok(runs);
            }
            let shortage = u64::from(n) - self.alloc.free_tiles();
            let scope = ErrorScopes::push(&self.device);
            let last = self.alloc.pages() - 1;
            let cap = self.alloc.capacity(last);
            if cap < self.max_page_tiles {
                let want = u64::from(cap) * 2;
                let new_cap = want.max(u64::from(cap) + shortage).min(u64::from(self.max_page_tiles)) as u32;
                self.grow_last_page(new_cap);
            } else {
                self.add_page(shortage.max(u64::from(INITIAL_PAGE_TILES)).min(u64::from(self.max_page_tiles)) as u32);
            }
            scope.pop("growing the tile pool")?;
        }
    }

    /// Adds a pool page of `capacity` tiles.
    fn add_page(&mut self, capacity: u32) {
        let d = &self.device;
        let n_tiles = u64::from(self.tiles_x * self.tiles_y);
        let page = Page {
            tiles: create_tiles(d, capacity, self.format),
            params: create_buffer(
                d,
                "footlight params",
                std::mem::size_of::<Params>() as u64,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
            offsets: create_buffer(
                d,
                "footlight offsets",
                (n_tiles + 1) * 4,
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ),
            entries: create_entries(d, 64),
            entries_capacity: 64,
            bind_group: None,
        };
        tracing::debug!(page = self.pages.len(), tiles = capacity, "GPU tile pool: new page");
        self.pages.push(page);
        self.alloc.add_page(capacity);
        self.bind_groups_dirty = true;
    }

    /// Replaces the last page's buffer with one of `capacity` tiles, copying
    /// the old contents on the GPU.
    fn grow_last_page(&mut self, capacity: u32) {
        let last = self.pages.len() - 1;
        let old_cap = self.alloc.capacity(last);
        let tiles = create_tiles(&self.device, capacity, self.format);
        let mut encoder =
            self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("footlight pool grow") });
        let used = u64::from(old_cap) * self.format.tile_bytes();
        if used > 0 {
            encoder.copy_buffer_to_buffer(&self.pages[last].tiles, 0, &tiles, 0, used);
        }
        self.queue.submit([encoder.finish()]);
        tracing::debug!(page = last, from = old_cap, to = capacity, "GPU tile pool: page grown");
        self.pages[last].tiles = tiles;
        self.alloc.grow_last(capacity);
        self.bind_groups_dirty = true;
    }

    /// Rebuilds every page's screen-tile → (light, slot) lists.
    fn rebuild_index(&mut self) {
        let n_tiles = (self.tiles_x * self.tiles_y) as usize;
        let n_pages = self.pages.len();
        // Count, prefix-sum, fill: entries of a tile come out in light order.
        let mut offsets = vec![vec![0u32; n_tiles + 1]; n_pages];
        for light in self.lights.iter().flatten() {
            for p in &light.placed {
                offsets[p.page as usize][p.screen_tile as usize + 1] += 1;
            }
        }
        for page in &mut offsets {
            for t in 0..n_tiles {
                page[t + 1] += page[t];
            }
        }
        let mut cursor: Vec<Vec<u32>> = offsets.iter().map(|o| o[..n_tiles].to_vec()).collect();
        let mut entries: Vec<Vec<[u32; 2]>> = offsets.iter().map(|o| vec![[0; 2]; o[n_tiles] as usize]).collect();
        for (i, light) in self.lights.iter().enumerate() {
            for p in light.iter().flat_map(|l| &l.placed) {
                let c = &mut cursor[p.page as usize][p.screen_tile as usize];
                entries[p.page as usize][*c as usize] = [i as u32, p.slot];
                *c += 1;
            }
        }
        for (p, page) in self.pages.iter_mut().enumerate() {
            let len = entries[p].len() as u64;
            if len > page.entries_capacity {
                page.entries_capacity = len.next_power_of_two();
                page.entries = create_entries(&self.device, page.entries_capacity);
                self.bind_groups_dirty = true;
            }
            self.queue.write_buffer(&page.offsets, 0, bytemuck::cast_slice(&offsets[p]));
            if len > 0 {
                self.queue.write_buffer(&page.entries, 0, bytemuck::cast_slice(&entries[p]));
            }
        }
        self.index_dirty = false;
    }

    /// Validates `k`, uploads weights and per-page params, and records the
    /// composite passes; the last pass gets `last_flags`.
    fn encode(
        &mut self,
        k: &[[f32; 3]],
        scale: [f32; 3],
        rolloff: [f32; 4],
        last_flags: u32,
    ) -> Result<wgpu::CommandEncoder, GpuError> {
        self.check_weights(k)?;
        if self.index_dirty {
            self.rebuild_index();
        }

        // Weights: lights without a buffer get 0 (their entries do not exist anyway).
        let n = self.lights.len().max(1);
        if n > self.weights_capacity {
            self.weights_capacity = n.next_power_of_two();
            self.weights = create_weights(&self.device, self.weights_capacity);
            self.bind_groups_dirty = true;
        }
        let w: Vec<[f32; 4]> = (0..n).map(|i| k.get(i).map_or([0.0; 4], |v| [v[0], v[1], v[2], 0.0])).collect();
        self.queue.write_buffer(&self.weights, 0, bytemuck::cast_slice(&w));

        // Skip what cannot contribute: pages holding no light with k ≠ 0.
        let mut active = vec![false; self.pages.len()];
        let mut stats = FrameStats::default();
        for (light, kv) in self.lights.iter().zip(k) {
            if let Some(l) = light.as_ref().filter(|l| *kv != [0.0; 3] && !l.placed.is_empty()) {
                l.pages.iter().for_each(|&p| active[p as usize] = true);
                stats.active_lights += 1;
                stats.tiles_read += l.placed.len() as u64;
            }
        }
        let mut passes: Vec<(usize, u32)> =
            active.iter().enumerate().filter(|(_, a)| **a).map(|(p, _)| (p, 0)).collect();
        if passes.is_empty() {
            passes.push((0, NO_LIGHTS));
        }
        stats.passes = passes.len();
        self.last_stats = stats;
        let last = passes.len() - 1;
        for (i, (p, flags)) in passes.iter_mut().enumerate() {
            *flags |= if i > 0 { READ_ACC } else { 0 } | if i < last { WRITE_ACC } else { last_flags };
            let params = Params {
                scale: [scale[0], scale[1], scale[2], 0.0],
                width: self.width,
                height: self.height,
                tiles_x: self.tiles_x,
                flags: *flags,
                rolloff,
            };
            self.queue.write_buffer(&self.pages[*p].params, 0, bytemuck::bytes_of(&params));
        }

        if self.bind_groups_dirty {
            self.rebuild_bind_groups();
        }
        let mut encoder =
            self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("footlight composite") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("footlight composite"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            for (p, _) in &passes {
                pass.set_bind_group(0, self.pages[*p].bind_group.as_ref(), &[]);
                pass.dispatch_workgroups(self.tiles_x, self.tiles_y, 1);
            }
        }
        Ok(encoder)
    }

    fn rebuild_bind_groups(&mut self) {
        for page in &mut self.pages {
            let entries = [
                page.params.as_entire_binding(),
                self.weights.as_entire_binding(),
                page.offsets.as_entire_binding(),
                page.entries.as_entire_binding(),
                page.tiles.as_entire_binding(),
                self.linear.as_entire_binding(),
                self.rgba8.as_entire_binding(),
            ];
            let entries: Vec<wgpu::BindGroupEntry> = entries
                .into_iter()
                .enumerate()
                .map(|(i, resource)| wgpu::BindGroupEntry { binding: i as u32, resource })
                .collect();
            page.bind_group = Some(self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("footlight composite"),
                layout: &self.layout,
                entries: &entries,
            }));
        }
        self.bind_groups_dirty = false;
    }
}

/// RGB f32 tiles to packed IEEE halves, saturating at 65504 (values are
/// already checked finite and non-negative).
fn to_half(tiles: &[[f32; 3]], out: &mut Vec<u16>) {
    let max = half::f16::MAX.to_f32();
    out.clear();
    out.extend(tiles.iter().flatten().map(|&v| half::f16::from_f32(v.min(max)).to_bits()));
}

fn check_limit(what: &str, need: u32, have: u32) -> Result<(), GpuError> {
    if have < need {
        return Err(GpuError::Unsupported { what: format!("{what}: need {need}, the device has {have}") });
    }
    Ok(())
}

/// The compute pipeline and its bind group layout (bindings as in composite.wgsl).
fn create_pipeline(device: &wgpu::Device, format: TileFormat) -> (wgpu::ComputePipeline, wgpu::BindGroupLayout) {
    let module = device.create_shader_module(wgpu::include_wgsl!("../../../shaders/composite.wgsl"));
    let storage = |read_only| wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only },
        has_dynamic_offset: false,
        min_binding_size: None,
    };
    let uniform = wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: false,
        min_binding_size: None,
    };
    let types = [uniform, storage(true), storage(true), storage(true), storage(true), storage(false), storage(false)];
    let entries: Vec<wgpu::BindGroupLayoutEntry> = types
        .into_iter()
        .enumerate()
        .map(|(i, ty)| wgpu::BindGroupLayoutEntry {
            binding: i as u32,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty,
            count: None,
        })
        .collect();
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("footlight composite"),
        entries: &entries,
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("footlight composite"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let constants = [("TILE_F16", if format == TileFormat::F16 { 1.0 } else { 0.0 })];
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("footlight composite"),
        layout: Some(&pipeline_layout),
        module: &module,
        entry_point: Some("composite"),
        compilation_options: wgpu::PipelineCompilationOptions { constants: &constants, ..Default::default() },
        cache: None,
    });
    (pipeline, layout)
}

fn create_buffer(device: &wgpu::Device, label: &str, size: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size.max(4),
        usage,
        mapped_at_creation: false,
    })
}

fn create_tiles(device: &wgpu::Device, capacity: u32, format: TileFormat) -> wgpu::Buffer {
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC;
    create_buffer(device, "footlight tile pool", u64::from(capacity.max(1)) * format.tile_bytes(), usage)
}

fn create_entries(device: &wgpu::Device, capacity: u64) -> wgpu::Buffer {
    create_buffer(
        device,
        "footlight entries",
        capacity.max(1) * 8,
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
    )
}

fn create_weights(device: &wgpu::Device, capacity: usize) -> wgpu::Buffer {
    create_buffer(
        device,
        "footlight weights",
        capacity.max(1) as u64 * 16,
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
    )
}

/// Out-of-memory and validation error scopes around a group of wgpu calls,
/// so a failure becomes a [`GpuError::Wgpu`] instead of reaching wgpu's
/// default handler (which panics).
struct ErrorScopes {
    // Field order is drop order: the inner scope (pushed last) first.
    validation: wgpu::ErrorScopeGuard,
    oom: wgpu::ErrorScopeGuard,
}

impl ErrorScopes {
    fn push(device: &wgpu::Device) -> Self {
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        Self { validation, oom }
    }

    /// Pops both scopes (innermost first) and returns the first error.
    fn pop(self, during: &'static str) -> Result<(), GpuError> {
        let validation = pollster::block_on(self.validation.pop());
        let oom = pollster::block_on(self.oom.pop());
        match validation.or(oom) {
            None => Ok(()),
            Some(e) => Err(GpuError::Wgpu { during, message: e.to_string() }),
        }
    }
}
