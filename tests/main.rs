//! Integration tests, one binary (ripgrep's tests/tests.rs layout).
//! Every reference here comes from an independent path: closed forms, the
//! single-pass eq. 1 renderer, or the 9× oversampled render.

mod common;

// Closed forms: point light over a Lambert plane, candela -> lux -> display.
mod analytic;
// Eq. 5 composite == single-pass eq. 1 render, for random k_i.
mod linearity;
// Mirror, glass and the recursion depth limit against closed forms.
mod recursion;
// Adaptive anti-aliasing against 9× oversampling on the bundled stage.
mod antialiasing;
// The rim of a hard-edged beam: nine samples and adaptive AA against a box-filtered reference.
mod beam_rim;
// Edge pixels (rims, shutter cuts, gobos, geometry) supersampled to the box filter.
mod edges;
// NaN vertices, zero-area triangles, empty scenes, lights and cameras inside geometry.
mod degenerate;
// Full-size golden image of the default render (guards against change).
mod golden;
// Per-light photon maps: energy, linearity, caustics, progressive refinement.
mod photons;
// The live daemon: frame clock, staged rebuilds, cache, HTTP preview, the status's patch fields.
mod live;
// The preview page's light table at 1280×800 in headless Chromium (issue 37).
mod light_table;
// Haze: single scattering vs quadrature, extinction, wedges, density, linearity.
mod haze;
// Numerical stress matrix: extremes stay finite and bounded.
mod stress;
// GPU compositor == CPU compositor (lavapipe in CI).
mod gpu;
// Recorded DMX end to end, cues vs golden, packet flood, browser preview.
mod replay;
// The command line as a user runs it.
mod cli;
// Hostile and broken glTF files: cycles, budgets, buffer URIs, accessors.
mod scene_import;
// Seeded property-based fuzzing of the glTF importer and the patch loader.
mod fuzz_import;
// The preview server under hostile clients: timeouts, limits, Host check, shared encodes.
mod serve;
// The browser stream: Chromium composites like the server; slow, malformed and picture clients.
mod stream;
// Fixture bodies from the GDTF model: silhouettes against the projected model dimensions.
mod bodies;
// Walking the stage: camera moves keep photon maps, cached views, orbit with DMX, write policy.
mod views;
// Gobos, framing shutters, prism and frost: floor cut vs its projection, golden image, spin rate.
mod gate;
// Pixel cells of MVR pixel bars against the eq. 1 renderer.
mod pixels;
// LED rigs without GDTF emitters: white at full under --white-balance auto, one note per type.
mod led_white;
// The attributes real GDTFs use: check lists none as not modelled, a dimmer-less bar goes dark.
mod gdtf_attributes;
// The tracer supervised (a panicking build, a dead worker) and within its memory budget.
mod tracer;
// Emitter groups: a pixel bar's cells grouped (low-rank tiles) vs per emitter, within issue 38's bound.
mod groups;
