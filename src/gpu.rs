//! The GPU side of the real-time update (Vierjahn 2010, section 3.3): an
//! adapter from the renderer's sparse [`LightBuffer`]s to the
//! `footlight-gpu` compute compositor. Per-light buffers are uploaded only
//! when a light was rebuilt (its generation changed); each frame sends only
//! the k_i. The CPU compositor ([`crate::render::composite`]) is the
//! reference it matches, and the fallback when no adapter exists.

use crate::render::Display;
use crate::render::composite::CompositeInput;
use footlight_gpu::{CompositorOptions, DisplayParams, GpuCompositor, GpuContext, GpuError, LightTiles};

/// Which compositor the daemon uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum CompositorChoice {
    /// The GPU when a hardware adapter exists, else the CPU (with a log line).
    Auto,
    /// Always the CPU.
    Cpu,
    /// The GPU, software adapters (lavapipe) included; an error without one.
    Gpu,
}

/// Whether the machine has a GPU device node (Linux: a DRM render node or
/// an NVIDIA device); elsewhere assumed yes, and the adapter probe decides.
fn gpu_device_node_present() -> bool {
    if !cfg!(target_os = "linux") {
        return true;
    }
    let render = std::fs::read_dir("/dev/dri")
        .map(|d| d.flatten().any(|e| e.file_name().to_string_lossy().starts_with("renderD")))
        .unwrap_or(false);
    render || std::path::Path::new("/dev/nvidia0").exists()
}

/// The shader's display uniforms from the CPU reference's settings: the
/// same scale and the same roll-off constants (display.rs owns the curve).
pub fn display_params(display: &Display) -> DisplayParams {
    DisplayParams {
        exposure: display.exposure,
        white_balance: display.white_balance.to_array(),
        rolloff: display.rolloff.map(|r| r.uniforms()),
    }
}

/// GPU compositor plus the generations of the buffers it holds.
pub struct GpuFrames {
    context: GpuContext,
    compositor: GpuCompositor,
    generations: Vec<Option<u64>>,
    display: DisplayParams,
}

impl GpuFrames {
    /// Opens an adapter (honouring `choice`) and a compositor of `width`×`height`.
    /// `Ok(None)` means: use the CPU compositor (and the reason was logged).
    pub fn open(choice: CompositorChoice, width: u32, height: u32, display: Display) -> Result<Option<Self>, GpuError> {
        if choice == CompositorChoice::Cpu {
            return Ok(None);
        }
        if choice == CompositorChoice::Auto && !gpu_device_node_present() {
            // No GPU device at all: probing Vulkan would only find a
            // software rasteriser (which `auto` declines anyway) and, on a
            // headless machine, makes libwayland print errors on stderr.
            tracing::info!("no GPU device (/dev/dri/renderD*, /dev/nvidia*); compositing on the CPU");
            return Ok(None);
        }
        let context = match GpuContext::new() {
            Ok(c) => c,
            Err(e) if choice == CompositorChoice::Auto => {
                tracing::info!("no GPU adapter ({e}); compositing on the CPU");
                return Ok(None);
            }
            Err(e) => return Err(e),
        };
        if choice == CompositorChoice::Auto && context.is_software() {
            tracing::info!(
                "GPU adapter {:?} is a software rasteriser; compositing on the CPU (faster here)",
                context.adapter_info().name
            );
            return Ok(None);
        }
        let compositor =
            GpuCompositor::new(context.device(), context.queue(), width, height, CompositorOptions::default())?;
        tracing::info!("compositing on the GPU: {}", context.adapter_info().name);
        Ok(Some(Self { context, compositor, generations: Vec::new(), display: display_params(&display) }))
    }

    /// Changes exposure, white balance and roll-off from the next frame on
    /// (uniforms only: nothing is rebuilt or re-uploaded).
    pub fn set_display(&mut self, display: &Display) {
        self.display = display_params(display);
    }

    /// Adapter name, for the status page.
    pub fn adapter(&self) -> &str {
        &self.context.adapter_info().name
    }

    /// Uploads the lights rebuilt since the last call (their generation
    /// changed) and returns the k_i vector for the shader.
    fn upload(&mut self, lights: &[CompositeInput]) -> Result<Vec<[f32; 3]>, GpuError> {
        if self.generations.len() != lights.len() {
            self.generations = vec![None; lights.len()];
        }
        for (i, l) in lights.iter().enumerate() {
            if self.generations[i] != Some(l.generation) {
                let (tiles, slots) = l.buffer.raw();
                self.compositor.set_light(i, LightTiles { tiles: bytemuck::cast_slice(&tiles), slots })?;
                self.generations[i] = Some(l.generation);
            }
        }
        Ok(lights.iter().map(|l| l.k.to_array()).collect())
    }

    /// Uploads rebuilt lights, composites with the current k_i and returns
    /// the frame as 8-bit sRGB RGB, waiting for the GPU (tests, bench).
    pub fn frame(&mut self, lights: &[CompositeInput]) -> Result<Vec<u8>, GpuError> {
        let k = self.upload(lights)?;
        Ok(self.compositor.composite(&k, &self.display)?.rgb8())
    }

    /// The live path: submits this frame's composite and returns the newest
    /// frame whose readback has finished, without waiting (the readback
    /// ring, `footlight_gpu::readback`). `None`: nothing new is ready yet
    /// (the caller shows the previous picture). A change therefore reaches
    /// the picture one or two frames later than on the CPU path, and the
    /// frame clock never blocks on the GPU.
    pub fn submit_frame(&mut self, lights: &[CompositeInput]) -> Result<Option<Vec<u8>>, GpuError> {
        let k = self.upload(lights)?;
        self.compositor.submit(&k, &self.display)?;
        Ok(self.compositor.try_frame()?.map(|f| f.rgb8()))
    }
}
