//! Integration tests of the GPU compositor, one binary (STYLE.md §12).
//!
//! Every test that needs a device gets the shared one from
//! [`support::context`] and skips, with a message, when the machine has no
//! adapter (CI has Mesa's lavapipe: Debian `mesa-vulkan-drivers` + `libvulkan1`,
//! and sets `FOOTLIGHT_REQUIRE_GPU=1` so a missing adapter fails there).

// Shared: device, seeded random sparse buffers, the CPU reference (a copy of
// footlight's composite.rs + display.rs).
mod support;

// GPU frames against the CPU reference: light counts, odd sizes, edge tiles, pages.
mod matches_cpu;
// Light lifecycle: k = 0, re-upload, removal, pool growth, input errors.
mod lights;
// f16 tile storage: measured error, saturation.
mod half;
// Pipelined readback: submit ahead, newest frame wins, bounded ring.
mod readback;
// No adapter: a clean error, never a panic.
mod no_adapter;
// Timings on whatever adapter is here (ignored; run with --ignored --nocapture).
mod bench;
