//! No adapter: `GpuContext` returns `NoAdapter` (the caller falls back to the
//! CPU compositor with a log line), never a panic. Runs everywhere: asking
//! for no backend, or for one this platform cannot have, finds no adapter
//! whatever hardware is present.

use footlight_gpu::{GpuContext, GpuError};

fn assert_no_adapter(backends: footlight_gpu::wgpu::Backends) {
    match GpuContext::with_backends(backends) {
        Err(e @ GpuError::NoAdapter { .. }) => {
            assert!(e.is_unavailable());
            let line = e.to_string();
            assert!(line.contains("CPU compositor"), "the log line says what happens next: {line}");
            eprintln!("as expected: {line}");
        }
        Err(other) => panic!("expected NoAdapter for {backends:?}, got {other}"),
        Ok(ctx) => panic!("expected NoAdapter for {backends:?}, got {:?}", ctx.adapter_info()),
    }
}

#[test]
fn no_backend_means_no_adapter() {
    assert_no_adapter(footlight_gpu::wgpu::Backends::empty());
}

#[test]
fn a_backend_this_platform_lacks_means_no_adapter() {
    // Metal exists only on Apple platforms, DX12 only on Windows.
    let missing = if cfg!(target_vendor = "apple") {
        footlight_gpu::wgpu::Backends::DX12
    } else {
        footlight_gpu::wgpu::Backends::METAL
    };
    assert_no_adapter(missing);
}
