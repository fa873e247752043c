//! Pixel cells of an MVR pixel bar (issue 14): each emitting cell of the
//! GDTF's `GeometryReference`s is its own light with its own channels.
//! Known answer: the split-mode bar of `tests/data/mvr/features.mvr` (bar
//! master dimmer on universe 1 slot 201, the cells' R, G, B on DMX break 2
//! = universe 2 from slot 1) with cell 3's red at full lights exactly what
//! the single-pass eq. 1 renderer (`render::reference`) gives for cell 3
//! alone, red only, centred under cell 3.

use crate::common::*;
use footlight::fixture::Universes;
use footlight::render::RecursionLimits;
use footlight::render::buffer::LightBuffer;
use footlight::render::composite;
use footlight::render::reference::render_eq1;
use footlight::render::view::Sampling;
use footlight::scene::{Camera, SceneBuilder};
use glam::Vec3;

#[test]
fn cell_three_red_lights_only_cell_three() {
    let import = footlight_mvr::load_mvr(&root().join("tests/data/mvr/features.mvr")).unwrap();
    let cells: Vec<_> = import.patch.fixtures.iter().filter(|f| f.id == 301).collect();
    assert_eq!(cells.len(), 8, "one light per cell");
    assert_eq!(cells[2].name, "Bar split / SplitCell3");
    // Cells 125 mm apart along the bar (GDTF X = stage X here), all at the bar's height.
    for w in cells.windows(2) {
        let d = w[1].light.position - w[0].light.position;
        assert!((d - Vec3::new(0.125, 0.0, 0.0)).length() < 1e-4, "{d}");
    }
    let mut u = Universes::new();
    u.set_slot(1, 201, 255); // the bar's master dimmer (break 1)
    u.set_slot(2, 7, 255); // cell 3's red: break 2 offset 7 (Break DMXOffset 7 + channel offset 1 − 1)
    let states: Vec<_> = cells.iter().map(|f| f.decode_universes(&u)).collect();
    let k: Vec<Vec3> = cells.iter().zip(&states).map(|(f, s)| f.k_of(s)).collect();
    for (i, k) in k.iter().enumerate() {
        if i == 2 {
            // The red emitter (xy 0.70, 0.299 in the generator) in linear RGB: red, a trace of blue.
            assert!(k.x > 0.0 && k.y < 0.02 * k.x && k.z < 0.02 * k.x, "cell 3 is red: {k}");
        } else {
            assert_eq!(*k, Vec3::ZERO, "cell {} stays dark", i + 1);
        }
    }
    // Master dimmer at 0: cell 3 goes dark too (the bar's dimmer multiplies every cell).
    let mut off = u.clone();
    off.set_slot(1, 201, 0);
    assert_eq!(cells[2].k_of(&cells[2].decode_universes(&off)), Vec3::ZERO);

    // A floor under the bar, seen from above.
    let mut b = SceneBuilder::new();
    let m = lambert(&mut b, 0.5);
    let centre = cells[2].light.position;
    floor(&mut b, 30.0, 0.0, m);
    let scene = b.build();
    let cam = Camera::look_at(
        Vec3::new(centre.x, 14.0, centre.z + 0.01),
        Vec3::new(centre.x, 0.0, centre.z),
        40f32.to_radians(),
    );
    let (w, h) = (96, 64);
    let v = view(&scene, cam, w, h, Sampling::Geometry, 0);
    let lights: Vec<_> = cells.iter().zip(&states).map(|(f, s)| f.light_of(s)).collect();
    let buffers: Vec<LightBuffer> = lights.iter().map(|l| v.render_light(&scene, l, None).0).collect();
    let comp = composite(&buffers.iter().collect::<Vec<_>>(), &k, w, h);
    let limits = RecursionLimits { max_depth: 0, min_weight: 0.0 };
    let alone = render_eq1(&scene, &v.gbuffer, &lights[2..3], &k[2..3], Sampling::Geometry.base_set(), limits);
    assert_finite(&comp, "composite");
    let peak = alone.iter().map(|p| p.x).fold(0.0f32, f32::max);
    assert!(peak > 0.0);
    let (mut lit, mut sum, mut weight) = (0, 0.0f64, 0.0f64);
    for (i, (a, e)) in comp.iter().zip(&alone).enumerate() {
        assert!((*a - *e).abs().max_element() <= 1e-5 * peak, "pixel {i}: composite {a} vs eq. 1 of cell 3 alone {e}");
        assert!(a.y <= 0.02 * a.x.max(peak * 1e-6) && a.z <= 0.02 * a.x.max(peak * 1e-6), "pixel {i} is red: {a}");
        if a.x > 0.0 {
            lit += 1;
            let s = v.gbuffer.samples[i][footlight::render::gbuffer::CENTRE_SAMPLE];
            if let Some(p) = v.gbuffer.position(&scene, &s) {
                sum += f64::from(a.x) * f64::from(p.x);
                weight += f64::from(a.x);
            }
        }
    }
    assert!(lit > 200, "cell 3's pool is in the picture: {lit} pixels");
    // The pool is centred under cell 3, not under its neighbours 125 mm away.
    let cx = (sum / weight) as f32;
    assert!((cx - centre.x).abs() < 0.04, "pool centre x {cx} vs cell 3 at {}", centre.x);
}
