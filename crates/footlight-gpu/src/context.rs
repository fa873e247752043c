//! The wgpu device, created once per process (STYLE.md §11).
//!
//! [`GpuContext::new`] picks an adapter (a real GPU first, then a software
//! one such as Mesa's lavapipe) and asks for its full limits, so pool pages
//! can be as large as the device allows. When there is none it returns
//! [`GpuError::NoAdapter`], never a panic, and the caller keeps the CPU
//! compositor. Tests and embedders that already own a device wrap it with
//! [`GpuContext::from_device`] (the wgpu examples' `execute_gpu_inner` split);
//! everything else in the crate only takes `&wgpu::Device, &wgpu::Queue`.

use crate::GpuError;

/// A wgpu device and its queue, with what the adapter said about itself.
#[derive(Debug, Clone)]
pub struct GpuContext {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
}

impl GpuContext {
    /// Opens the preferred adapter on the primary native backends (Vulkan,
    /// Metal, DX12). OpenGL is left out unless asked for (a GL compute
    /// compositor would not beat the CPU one, and probing EGL costs start-up
    /// time). Known noise: on a headless Linux machine without
    /// `XDG_RUNTIME_DIR`, the Vulkan adapter probe still makes libwayland
    /// print "error: XDG_RUNTIME_DIR is invalid" twice. The usual wgpu environment
    /// variables apply: `WGPU_BACKEND` (e.g. `vulkan`, or `gl` to try
    /// OpenGL), `WGPU_ADAPTER_NAME`, `WGPU_POWER_PREF`.
    pub fn new() -> Result<Self, GpuError> {
        let backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY);
        Self::with_backends(backends)
    }

    /// Opens the preferred adapter among `backends` only. With no backend
    /// that has an adapter here (e.g. `Backends::empty()`, or Metal on
    /// Linux) this is [`GpuError::NoAdapter`].
    pub fn with_backends(backends: wgpu::Backends) -> Result<Self, GpuError> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        desc.backends = backends;
        let instance = wgpu::Instance::new(desc);
        let power_preference = wgpu::PowerPreference::from_env().unwrap_or(wgpu::PowerPreference::HighPerformance);
        let options = wgpu::RequestAdapterOptions { power_preference, ..Default::default() };
        let adapter =
            pollster::block_on(instance.request_adapter(&options)).map_err(|source| GpuError::NoAdapter { source })?;
        let info = adapter.get_info();
        let desc = wgpu::DeviceDescriptor {
            label: Some("footlight"),
            required_features: wgpu::Features::empty(),
            // The adapter's best limits: pool pages up to its real maximum
            // binding size instead of WebGPU's 128 MiB default.
            required_limits: adapter.limits(),
            ..Default::default()
        };
        let (device, queue) =
            pollster::block_on(adapter.request_device(&desc)).map_err(|source| GpuError::Device { source })?;
        tracing::info!(adapter = %info.name, backend = ?info.backend, kind = ?info.device_type, "GPU compositor");
        Ok(Self { device, queue, info })
    }

    /// Wraps a device the caller made (tests, or an app that also renders a
    /// window with it).
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Self {
        let info = device.adapter_info();
        Self { device, queue, info }
    }

    /// The device.
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// Its queue.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// Name, backend and kind of the adapter (e.g. "llvmpipe", Vulkan, Cpu).
    pub fn adapter_info(&self) -> &wgpu::AdapterInfo {
        &self.info
    }

    /// Whether the adapter is a software rasteriser (lavapipe/llvmpipe,
    /// WARP, SwiftShader). It runs on the same CPU cores as the tracer and is
    /// slower than footlight's CPU compositor, so the live daemon should keep
    /// the CPU compositor there; tests and CI use it to check the shader.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }
}

#[cfg(test)]
mod tests {
    /// The live daemon moves the compositor into its frame thread.
    #[test]
    fn context_and_compositor_can_move_between_threads() {
        fn send_sync<T: Send + Sync>() {}
        fn send<T: Send>() {}
        send_sync::<super::GpuContext>();
        send::<crate::GpuCompositor>();
    }
}
