//! Every fixture type in patch/fixtures, and the paper's rig.

use super::{gels, root};
use footlight_fixture::fixture_type::load_type;
use footlight_fixture::{Attribute, BeamSampler, Patch};
use glam::Vec3;

#[test]
fn every_fixture_type_loads_and_every_channel_gives_finite_k_and_a_valid_beam() {
    let lib = gels();
    let dir = root().join("patch/fixtures");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        count += 1;
        let ty = load_type(&path, Some(&lib)).unwrap_or_else(|e| panic!("{e}"));
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("source"), "{}: values must name their source or say estimated", path.display());
        for mode in &ty.modes {
            for channel in &mode.channels {
                for value in [0u8, 127, 255] {
                    // Every other slot at its default, this channel's slots at `value`.
                    let mut slots = vec![0u8; usize::from(mode.footprint)];
                    for c in &mode.channels {
                        for (o, v) in c.slots_for(c.default) {
                            slots[usize::from(o)] = v;
                        }
                    }
                    slots[usize::from(channel.offset)] = value;
                    if let Some(f) = channel.fine {
                        slots[usize::from(f)] = value;
                    }
                    let s = ty.decode(mode, &Default::default(), &|o| slots.get(usize::from(o)).copied().unwrap_or(0));
                    let what = format!("{} mode {} {} = {value}", ty.name, mode.name, channel.name);
                    let beam = ty.beam(&s);
                    assert_eq!(beam.pattern(Vec3::NEG_Z), 1.0, "{what}: peak 1 on the axis");
                    let cut = beam.cos_cutoff();
                    assert!((-1.0..1.0).contains(&cut), "{what}: cut-off {cut}");
                    for i in 0..=180 {
                        let a = (i as f32).to_radians();
                        let p = beam.pattern(Vec3::new(a.sin(), 0.0, -a.cos()));
                        assert!((0.0..=1.0).contains(&p), "{what}: pattern {p} at {i} deg");
                        if a.cos() < cut - 1e-6 {
                            assert_eq!(p, 0.0, "{what}: light past the cut-off at {i} deg");
                        }
                    }
                    let sampler = BeamSampler::new(&beam);
                    assert!(sampler.flux() > 0.0 && sampler.flux().is_finite(), "{what}");
                    let intensity = ty.intensity(&s);
                    assert!(intensity > 0.0 && intensity.is_finite(), "{what}: Î {intensity}");
                    // k_i through the photometry crate, with the mode's scroller if any.
                    let mix = match mode.channel(Attribute::Scroller).and_then(|c| c.scroller.as_ref()) {
                        Some(sc) => sc.at(&lib, s.frame).expect("frames are in the library"),
                        None => footlight_photometry::GelMix::OPEN,
                    };
                    let k = footlight_photometry::k(&ty.lamp_for(&s), s.v, &mix, intensity);
                    assert!(k.is_finite() && k.min_element() >= 0.0, "{what}: k {k}");
                    if s.v == 0.0 {
                        assert_eq!(k, Vec3::ZERO, "{what}: v = 0 is exactly black");
                    }
                }
            }
        }
    }
    assert!(count >= 6, "the library has the paper's rig and the generic types ({count} files)");
}

#[test]
fn the_paper_rig_loads_with_its_look() {
    let patch = Patch::load(&root().join("patch/paper-rig.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(patch.fixtures.len(), 6);
    let dmx: Vec<_> = patch.fixtures.iter().map(|f| f.dmx).collect();
    assert_eq!(dmx, (1..=6).map(|a| Some((1, a))).collect::<Vec<_>>());
    // 100 %, 100 %, then four at 50 % (DMX 128 on a linear curve).
    let v: Vec<f32> = patch.fixtures.iter().map(|f| f.look.v).collect();
    assert_eq!(&v[..2], &[1.0, 1.0]);
    assert!(v[2..].iter().all(|&x| (x - 128.0 / 255.0).abs() < 1e-6));
    let frame = patch.look_universes.get(1).unwrap();
    assert_eq!(&frame[..6], &[255, 255, 128, 128, 128, 128]);
    // Colours: the HPZ is warm tungsten, the Castor through LEE 201 is bluer, the HMIs through LEE 136 are lavender.
    let k: Vec<Vec3> = patch.default_k();
    assert!(k[0].x > k[0].y && k[0].y > k[0].z, "3200 K is warm: {}", k[0]);
    assert!(k[1].z / k[1].x > k[0].z / k[0].x, "LEE 201 is bluer: {}", k[1]);
    assert!(k[2].x > k[2].y && k[2].z > k[2].y, "LEE 136 is pink/lavender: {}", k[2]);
    for f in &patch.fixtures {
        assert!(f.k().is_finite() && f.k().min_element() > 0.0);
        assert!((f.k_full() - f.k() / f.look.v).abs().max_element() < 1e-2 * f.k_full().max_element());
        assert!(f.light.axis().y < 0.0, "{}: aimed down at the stage", f.name);
    }
    assert!(patch.camera.is_none());
    assert!(patch.gels.is_some());
}

#[test]
fn the_built_in_spot_patch_takes_its_colours_from_the_gel_library() {
    let patch = Patch::load(&root().join("patch/builtin-spots.toml")).unwrap();
    assert_eq!(patch.fixtures.len(), 6);
    assert_eq!(patch.fixtures[0].k(), Vec3::splat(60000.0), "open white");
    // LEE 136 (pale lavender) on tungsten: red and blue pass more than green,
    // and the light loses some of its flux; at level 0.5, k is half of k_full.
    let k = patch.fixtures[2].k_full() / 120000.0;
    assert!(k.x > k.y && k.z > k.y && k.max_element() <= 1.0 && k.min_element() > 0.2, "{k}");
    assert!((patch.fixtures[2].k() - patch.fixtures[2].k_full() * 0.5).abs().max_element() < 1e-3);
    // LEE 201 (full CT blue) on tungsten: blue passes most, red least.
    let b = patch.fixtures[1].k_full();
    assert!(b.z > b.y && b.y > b.x, "{b}");
}

/// The default patch is the paper's rig (same fixtures, addresses and look)
/// plus colour and moving heads a desk can play: every fixture addressed on
/// universe 1, footprints apart, and DMX on the documented addresses drives
/// the PARs' colour and the spots' pan/tilt.
#[test]
fn the_default_patch_is_the_paper_rig_plus_colour_and_moving_heads() {
    let default = Patch::load(&root().join("patch/default.toml")).unwrap_or_else(|e| panic!("{e}"));
    let paper = Patch::load(&root().join("patch/paper-rig.toml")).unwrap();
    assert_eq!(default.fixtures.len(), 10);
    for (d, p) in default.fixtures.iter().zip(&paper.fixtures) {
        assert_eq!((d.id, &d.name, d.dmx), (p.id, &p.name, p.dmx));
        assert_eq!(d.light.position, p.light.position);
        assert_eq!(d.k(), p.k(), "{}: the paper's look", d.name);
    }
    // The addresses the file's header table documents, and no overlap.
    let starts: Vec<_> = default.fixtures.iter().map(|f| f.dmx).collect();
    let want = [1, 2, 3, 4, 5, 6, 7, 13, 21, 41].map(|a| Some((1u16, a)));
    assert_eq!(starts, want);
    let mut used = [false; 512];
    for f in &default.fixtures {
        let (_, a) = f.dmx.unwrap();
        for s in a..a + f.footprint() {
            assert!(!used[usize::from(s) - 1], "slot {s} used twice");
            used[usize::from(s) - 1] = true;
        }
    }
    assert_eq!(default.fixtures[6].footprint(), 6);
    assert_eq!(default.fixtures[8].footprint(), 13);
    // The extras wait dark.
    assert!(default.fixtures[6..].iter().all(|f| f.k() == Vec3::ZERO));
    // A desk's levels on the documented slots (1-based as desks show them).
    let mut slots = [0u8; 512];
    let mut set =
        |address: usize, values: &[u8]| slots[address - 1..address - 1 + values.len()].copy_from_slice(values);
    set(7, &[255, 255, 255, 0, 0, 0]); // PAR SR: full, red only
    set(13, &[255, 255, 0, 0, 255, 0]); // PAR SL: full, blue only
    set(21, &[0x80, 0, 0x80, 0, 0, 0, 0, 0, 0, 0, 255, 255, 255]); // spot SR: centre, full
    set(41, &[0xC0, 0, 0x80, 0, 0, 0, 0, 0, 0, 0, 255, 255, 255]); // spot SL: panned
    let states: Vec<_> = default.fixtures.iter().map(|f| f.decode(&slots)).collect();
    let red = default.fixtures[6].k_of(&states[6]);
    let blue = default.fixtures[7].k_of(&states[7]);
    assert!(red.x > 10.0 * red.y.max(red.z), "a red PAR: {red}");
    assert!(blue.z > 3.0 * blue.x.max(blue.y), "a blue PAR: {blue}");
    let centre = default.fixtures[8].light_of(&states[8]);
    assert!(centre.axis().y < -0.99, "at the DMX centre the spot points straight down: {}", centre.axis());
    let panned = default.fixtures[9].light_of(&states[9]);
    assert!(panned.axis().y < -0.99, "pan alone turns a hanging head's beam about the vertical: {}", panned.axis());
    assert!((states[9].pan - states[8].pan - 540.0 * 0.25).abs() < 1.0, "a quarter of the 540° pan range");
    let tilted = {
        let mut s = slots;
        s[20 + 2] = 0xC0; // spot SR tilt to 3/4
        default.fixtures[8].light_of(&default.fixtures[8].decode(&s))
    };
    assert!(tilted.axis().y > -0.75, "tilt swings the beam off the vertical: {}", tilted.axis());
    assert!(default.fixtures[8].k_of(&states[8]).min_element() > 0.0, "the spot's shutter is open and lit");
}
