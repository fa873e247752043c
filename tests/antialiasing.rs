//! Adaptive anti-aliasing (Vierjahn 2010, section 3.4) against 9× oversampling.

use crate::common::*;
use footlight::bench::mse_display;
use footlight::render::display::Display;
use footlight::render::view::{AaParams, Sampling};
use glam::Vec3;

#[test]
fn adaptive_aa_beats_one_sample_against_nine_times_oversampling() {
    let scene = stage();
    let patch = paper_patch();
    let cam = scene.camera.unwrap();
    let display = Display::default();
    let (w, h) = (200, 125);
    let mut total = [[0f64; 3]; 3];
    for f in &patch.fixtures[..2] {
        let k_full = f.k_full();
        let aa = AaParams::new(20.0);
        let mut imgs = Vec::new();
        for sampling in [Sampling::One, Sampling::Adaptive, Sampling::Nine] {
            let v = view(&scene, cam, w, h, sampling, 5);
            let (buf, reshaded) = v.render_light(&scene, &f.light, Some(aa));
            if sampling == Sampling::Adaptive {
                assert!(reshaded > 0 && reshaded < (w * h) as usize, "adaptive re-shaded {reshaded} pixels");
            }
            imgs.push(buf.to_dense().iter().map(|v| *v * k_full).collect::<Vec<Vec3>>());
        }
        for (i, img) in imgs.iter().enumerate() {
            let m = mse_display(img, &imgs[2], &display);
            for c in 0..3 {
                total[i][c] += m[c];
            }
        }
    }
    let (one, adaptive) = (total[0], total[1]);
    for c in 0..3 {
        assert!(adaptive[c] < 0.5 * one[c], "channel {c}: adaptive MSE {} vs one-sample {}", adaptive[c], one[c]);
    }
    assert!(one.iter().sum::<f64>() > 0.0);
}

#[test]
fn reshaded_pixels_do_not_depend_on_exposure_or_dimmer() {
    // Issue 13.5: the decision is the light's own relative gradient, so the
    // set of re-shaded pixels is the same for the buffer at any scale
    // (exposure ×0.01 and ×100, any dimmer or k_i).
    let scene = stage();
    let patch = paper_patch();
    let cam = scene.camera.unwrap();
    let v = view(&scene, cam, 160, 100, Sampling::Adaptive, 5);
    let aa = AaParams::new(20.0);
    for f in &patch.fixtures[..2] {
        let (dense, _) = v.render_direct(&scene, &f.light, None);
        let at = |s: f32| v.gradient_flags(&scene, &dense.iter().map(|x| *x * s).collect::<Vec<_>>(), aa);
        let base = at(1.0);
        let n = base.iter().filter(|&&b| b).count();
        assert!(n > 0 && n < base.len() / 4, "{}: {n} pixels flagged", f.name);
        assert_eq!(at(0.01), base, "{}: exposure ×0.01 changed the re-shaded set", f.name);
        assert_eq!(at(100.0), base, "{}: exposure ×100 changed the re-shaded set", f.name);
        // The renderer's own count agrees.
        assert_eq!(v.render_direct(&scene, &f.light, Some(aa)).1, n);
    }
}

/// A Lambert floor (two triangles) with a Lambert block standing on it, a
/// spot grazing the block (a shadow edge on the floor), and a camera
/// looking down at both.
fn floor_and_block() -> (footlight::scene::Scene, footlight::Light, footlight::scene::Camera) {
    use footlight::fixture::{Beam, SpotBeam};
    let mut b = footlight::scene::SceneBuilder::new();
    let m = lambert(&mut b, 0.6);
    floor(&mut b, 4.0, 0.0, m);
    cube(&mut b, Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 0.8, 0.5), m);
    let light = footlight::Light::aimed(
        Vec3::new(-2.5, 3.0, 0.3),
        Vec3::new(1.0, 0.0, 0.0),
        Beam::Spot(SpotBeam::from_beam_field(50.0, 70.0)),
    );
    let cam = footlight::scene::Camera::look_at(Vec3::new(0.3, 4.0, 4.0), Vec3::new(0.2, 0.0, 0.0), 50f32.to_radians());
    (b.build(), light, cam)
}

#[test]
fn surface_bins_merge_tessellation_edges_but_keep_geometry_edges() {
    // Issue 13 (AA cost): a pixel on the floor's diagonal (two coplanar
    // triangles of one material) is one surface and gets one bin; a pixel
    // on the block's outline (its top over the floor: same material, same
    // normal, 0.8 m apart; or its side against the floor) keeps two.
    use footlight::render::gbuffer::{NO_HIT, bin_samples, surface_bins};
    let (scene, _, cam) = floor_and_block();
    let v = view(&scene, cam, 160, 100, Sampling::Geometry, 0);
    let floor_tris = [0u32, 1];
    let (mut diagonal, mut outline) = (0, 0);
    for (i, s) in v.gbuffer.samples.iter().enumerate() {
        let tri = bin_samples(s);
        let surf = surface_bins(&scene, s);
        // The bins the G-buffer found when it traced the samples (what the
        // view shades) are these, bit for bit.
        assert_eq!(v.gbuffer.bins(i), surf.as_slice(), "pixel {i}");
        let total: f32 = surf.as_slice().iter().map(|b| b.weight).sum();
        assert!((total - 1.0).abs() < 1e-6, "weights sum to {total}");
        let tris: Vec<u32> = tri.as_slice().iter().map(|b| b.triangle).collect();
        assert!(!tris.contains(&NO_HIT) || surf.as_slice().iter().any(|b| b.triangle == NO_HIT));
        if tris.len() == 2 && tris.iter().all(|t| floor_tris.contains(t)) {
            diagonal += 1;
            assert_eq!(surf.as_slice().len(), 1, "floor diagonal pixel kept {} bins", surf.as_slice().len());
        } else if tris.len() >= 2
            && tris.iter().any(|t| floor_tris.contains(t))
            && tris.iter().any(|t| *t >= 2 && *t != NO_HIT)
        {
            outline += 1;
            assert!(surf.as_slice().len() >= 2, "block outline pixel merged into one bin");
        }
    }
    assert!(diagonal > 20 && outline > 50, "diagonal {diagonal}, outline {outline} pixels");
}

/// Two upright Lambert cylinders (24 facets of 15°, radius 8 cm) side by
/// side: the left one smooth-shaded (neighbouring facets share each edge's
/// radial vertex normal), the right one flat-shaded (a crease at every
/// edge), and a wide spot from above the camera lighting both. Returns the
/// scene, the light, the camera and the first triangle of the flat one.
fn smooth_and_flat_cylinders() -> (footlight::scene::Scene, footlight::Light, footlight::scene::Camera, u32) {
    use footlight::fixture::{Beam, SpotBeam};
    let mut b = footlight::scene::SceneBuilder::new();
    let m = lambert(&mut b, 0.7);
    let mut first_flat = 0;
    for (centre, smooth) in [(Vec3::new(-0.2, 0.0, 0.0), true), (Vec3::new(0.2, 0.0, 0.0), false)] {
        if !smooth {
            first_flat = b.triangle_count() as u32;
        }
        let n = |k: usize| {
            let a = std::f32::consts::TAU * k as f32 / 24.0;
            Vec3::new(a.cos(), 0.0, a.sin())
        };
        for k in 0..24 {
            let (n0, n1) = (n(k), n(k + 1));
            let (b0, b1) = (centre + 0.08 * n0, centre + 0.08 * n1);
            let (t0, t1) = (b0 + Vec3::Y, b1 + Vec3::Y);
            // Counter-clockwise seen from outside: the winding's normal points out.
            let normals = |x: [Vec3; 3]| smooth.then_some(x);
            b.add_triangle([b0, t0, b1], normals([n0, n0, n1]), m);
            b.add_triangle([b1, t0, t1], normals([n1, n0, n1]), m);
        }
    }
    let light = footlight::Light::aimed(
        Vec3::new(0.3, 2.5, 3.0),
        Vec3::new(0.0, 0.5, 0.0),
        Beam::Spot(SpotBeam::from_beam_field(60.0, 80.0)),
    );
    let cam = footlight::scene::Camera::look_at(Vec3::new(0.0, 0.5, 2.5), Vec3::new(0.0, 0.5, 0.0), 40f32.to_radians());
    (b.build(), light, cam, first_flat)
}

#[test]
fn surface_bins_merge_a_smooth_lambert_surface_however_it_curves_and_keep_creases() {
    // Issue 13 (AA cost): on a smooth-shaded Lambert surface the normal
    // field is continuous across a tessellation edge, so a pixel across it
    // is one surface even where its bins' normals are more than 8° apart
    // (the bundled stage's pleated curtains); a flat-shaded crease of the
    // same angle keeps its bins. A merged pixel is shaded once at its
    // centre sample, as in 1-sample rendering, so it gives up the surface's
    // curvature inside the pixel (second order in the normals' spread):
    // checked against the 9-sample render, the image's error stays under
    // 1 % of the 1-sample render's and no lit merged pixel is off by 5 %.
    use footlight::render::RecursionLimits;
    use footlight::render::gbuffer::{Bin, NO_HIT, SAME_SURFACE_COS, bin_samples, surface_bins};
    use footlight::render::reference::render_eq1;
    use footlight::render::view::SampleSet;
    use footlight::scene::Hit;
    let (scene, light, cam, first_flat) = smooth_and_flat_cylinders();
    let v = view(&scene, cam, 160, 100, Sampling::Geometry, 0);
    let limits = RecursionLimits { max_depth: 0, min_weight: 0.0 };
    let lights = [light];
    let render = |set| render_eq1(&scene, &v.gbuffer, &lights, &[Vec3::ONE], set, limits);
    let (nine, binned, one) = (render(SampleSet::All), render(SampleSet::Binned), render(SampleSet::Centre));
    let peak = nine.iter().map(|x| x.x).fold(0.0, f32::max);
    let normal = |b: &Bin| scene.surface(&Hit { triangle: b.triangle, t: 0.0, u: b.u, v: b.v }).shading_normal;
    let facet = |b: &Bin| (b.triangle - first_flat) / 2;
    let (mut merged_wide, mut creases, mut merged_err) = (0, 0, 0f32);
    for (i, s) in v.gbuffer.samples.iter().enumerate() {
        assert_eq!(v.gbuffer.bins(i), surface_bins(&scene, s).as_slice(), "pixel {i}");
        let tri = bin_samples(s);
        let tris = tri.as_slice();
        if tris.len() >= 2 && tris.iter().all(|b| b.triangle < first_flat) {
            assert_eq!(v.gbuffer.bins(i).len(), 1, "smooth pixel {i} kept {} bins", v.gbuffer.bins(i).len());
            if tris.iter().any(|a| tris.iter().any(|b| normal(a).dot(normal(b)) < SAME_SURFACE_COS)) {
                merged_wide += 1;
            }
            if nine[i].x > 0.2 * peak {
                merged_err = merged_err.max((binned[i].x - nine[i].x).abs() / nine[i].x);
            }
        }
        // Two facets of the flat cylinder (not the two halves of one facet).
        if tris.iter().all(|b| b.triangle >= first_flat && b.triangle != NO_HIT)
            && tris.iter().any(|b| facet(b) != facet(&tris[0]))
        {
            creases += 1;
            assert!(v.gbuffer.bins(i).len() >= 2, "crease pixel {i} merged");
        }
    }
    assert!(merged_wide > 10 && creases > 30, "{merged_wide} wide merged pixels, {creases} crease pixels");
    assert!(merged_err < 0.05, "a lit merged pixel is off its 9-sample value by {merged_err}");
    let relative = |x: &[Vec3]| x.iter().map(|y| *y / peak).collect::<Vec<_>>();
    let display = Display::default();
    let (mse_bins, mse_one) = (
        mse_display(&relative(&binned), &relative(&nine), &display),
        mse_display(&relative(&one), &relative(&nine), &display),
    );
    for c in 0..3 {
        assert!(mse_bins[c] < 0.01 * mse_one[c], "channel {c}: bins {} against 1 sample {}", mse_bins[c], mse_one[c]);
    }
}

#[test]
fn reshaded_pixels_equal_nine_samples_in_a_lambert_scene() {
    // Every re-shaded pixel equals the independent eq. 1 renderer with all
    // 9 samples (`render::reference`), and every other pixel equals it with
    // the surface bins (the merged bins are the same in both).
    use footlight::render::RecursionLimits;
    use footlight::render::reference::render_eq1;
    use footlight::render::view::SampleSet;
    let (scene, light, cam) = floor_and_block();
    let v = view(&scene, cam, 160, 100, Sampling::Adaptive, 5);
    // The shipped rule: a one-bin pixel whose probed corners disagree is
    // reconstructed from them and its base (`Reshading::reconstruct`), a
    // pixel of several bins takes all 9 samples.
    let aa = AaParams::new(20.0);
    let (base, _) = v.render_direct(&scene, &light, None);
    let flags = v.gradient_flags(&scene, &base, aa);
    let (adaptive, n) = v.render_direct(&scene, &light, Some(aa));
    let limits = RecursionLimits { max_depth: 5, min_weight: 0.0 };
    let lights = [light.clone()];
    let nine = render_eq1(&scene, &v.gbuffer, &lights, &[Vec3::ONE], SampleSet::All, limits);
    let binned = render_eq1(&scene, &v.gbuffer, &lights, &[Vec3::ONE], SampleSet::Binned, limits);
    assert!(n > 50 && n < base.len() / 4, "{n} pixels re-shaded");
    let corners = CornerProbes::new(&scene, &v, &lights, limits, &base, aa);
    let rebuilt = (0..base.len()).filter(|&i| corners.reconstruct[i] && flags[i]).count();
    let several = (0..base.len()).filter(|&i| !corners.reconstruct[i] && flags[i]).count();
    let (changed, kept) = check_reshaded(&adaptive, &base, &flags, &[], &nine, &binned, &corners);
    assert!(changed > 20 && kept > 0 && rebuilt > 20, "{changed} changed, {kept} kept, {rebuilt} one-bin pixels");
    assert!(several > 0, "some marked pixels hold several bins");
    // The whole re-shade (what a highlight pixel takes): every marked pixel
    // listed as whole is the 9-sample render.
    let mut decision = v.aa_decision(&scene, &light, &base, aa);
    assert_eq!(decision.flags, flags, "no highlight pixels in a Lambert scene");
    let every = (0..base.len()).filter(|&i| flags[i]).collect::<Vec<_>>();
    decision.highlights = every.clone();
    let mut whole = base.clone();
    assert_eq!(v.reshade(&scene, &light, &mut whole, decision.reshading()), n);
    assert_eq!(check_reshaded(&whole, &base, &flags, &every, &nine, &binned, &corners).1, 0);
}

/// Each pixel's 4 corner samples ([`corner_renders`]) and which of them it
/// probes ([`facing_masks`], from the light's pairs over the threshold).
struct CornerProbes {
    values: Vec<Vec<Vec3>>,
    facing: Vec<u8>,
    /// Pixels reconstructed from their probed corners when these disagree
    /// (one bin of all 9 samples).
    reconstruct: Vec<bool>,
}

impl CornerProbes {
    fn new(
        scene: &footlight::scene::Scene,
        v: &footlight::render::View,
        lights: &[footlight::Light],
        limits: footlight::render::RecursionLimits,
        base: &[Vec3],
        aa: AaParams,
    ) -> Self {
        let facing = facing_masks(&v.gradient_pairs(scene, base, aa), base.len());
        // The renderer reconstructs every one-bin pixel (`AaParams::new`).
        let reconstruct = (0..base.len()).map(|i| matches!(v.gbuffer.bins(i), [b] if b.weight >= 1.0)).collect();
        Self { values: corner_renders(scene, &v.gbuffer, lights, limits), facing, reconstruct }
    }

    /// Pixel `i` rebuilt on its 3×3 grid, written out from the sample
    /// grid: the probed corners at their own values, the centre and the
    /// other corners at the base's (`base`), each edge midpoint the mean of
    /// its two corners; all 9 weighted 1/9.
    fn rebuilt(&self, i: usize, base: Vec3) -> Vec3 {
        // Row-major 3×3 grid; corner j of `values` is grid sample 0, 2, 6, 8.
        let mut grid = [base; 9];
        for (j, &s) in [0, 2, 6, 8].iter().enumerate() {
            if self.facing[i] & (1 << j) != 0 {
                grid[s] = self.values[j][i];
            }
        }
        for (m, a, b) in [(1, 0, 2), (3, 0, 6), (5, 2, 8), (7, 6, 8)] {
            grid[m] = (grid[a] + grid[b]) / 2.0;
        }
        grid[4] = base;
        grid.iter().sum::<Vec3>() / 9.0
    }
}

/// Which of the 4 corner samples (bit j: the j-th of 0, 2, 6, 8 of the
/// row-major 3×3 grid) each pixel probes first: for every neighbour pair
/// over the threshold, the two corners of each pixel on the side facing
/// the other; all 4 for a pixel in no pair.
fn facing_masks(pairs: &[(usize, usize)], n: usize) -> Vec<u8> {
    let mut mask = vec![0u8; n];
    for &(a, b) in pairs {
        let (right, left, down, up) = (0b1010, 0b0101, 0b1100, 0b0011);
        let (ma, mb) = if b == a + 1 { (right, left) } else { (down, up) };
        mask[a] |= ma;
        mask[b] |= mb;
    }
    mask.iter().map(|&m| if m == 0 { 0b1111 } else { m }).collect()
}

/// The value of each corner sample (0, 2, 6, 8 of the 3×3 grid) of every
/// pixel, from the independent eq. 1 renderer: a G-buffer whose 9 samples
/// are all that corner, rendered with all 9.
fn corner_renders(
    scene: &footlight::scene::Scene,
    gbuffer: &footlight::render::gbuffer::GBuffer,
    lights: &[footlight::Light],
    limits: footlight::render::RecursionLimits,
) -> Vec<Vec<Vec3>> {
    use footlight::render::reference::render_eq1;
    use footlight::render::view::SampleSet;
    [0, 2, 6, 8]
        .iter()
        .map(|&s| {
            let mut g = gbuffer.clone();
            for px in g.samples.iter_mut() {
                *px = [px[s]; 9];
            }
            render_eq1(scene, &g, lights, &[Vec3::ONE], SampleSet::All, limits)
        })
        .collect()
}

/// What the re-shaded pixels must be, from independent renders: an
/// unmarked pixel is the eq. 1 binned render; a highlight pixel the 9-sample
/// render; any other marked pixel exactly its base value when each of its
/// corner samples that face its pairs' partners (`corners`,
/// [`corner_renders`], chosen by `facing`, [`facing_masks`]) lies within
/// `CORNER_AGREEMENT` codes of it (the light's relative codes, reference
/// level = 255), else the 9-sample render, or where `corners.reconstruct`
/// its grid rebuilt from those corners and its base
/// ([`CornerProbes::rebuilt`]; a pixel within one code of the limit may
/// be either). All within 1e-5 of the peak. Returns how many marked pixels
/// took that value where it differs from the base, and how many kept
/// their base while it differs.
fn check_reshaded(
    adaptive: &[Vec3],
    base: &[Vec3],
    flags: &[bool],
    highlights: &[usize],
    nine: &[Vec3],
    binned: &[Vec3],
    corners: &CornerProbes,
) -> (usize, usize) {
    use footlight::render::display::srgb8;
    use footlight::render::view::{CORNER_AGREEMENT, reference_level};
    let scale = nine.iter().map(|x| x.max_element()).fold(0.0f32, f32::max);
    let near = |a: Vec3, b: Vec3| (a - b).abs().max_element() <= 1e-5 * scale;
    let level = reference_level(base).unwrap();
    let code = |x: Vec3| srgb8(x / level);
    let (mut changed, mut kept) = (0, 0);
    for i in 0..base.len() {
        if !flags[i] {
            assert!(near(adaptive[i], binned[i]), "pixel {i}: {} vs binned {}", adaptive[i], binned[i]);
            continue;
        }
        let whole = highlights.contains(&i) || !corners.reconstruct[i];
        let full = if whole { nine[i] } else { corners.rebuilt(i, base[i]) };
        let took_full = near(adaptive[i], full);
        if highlights.contains(&i) {
            assert!(took_full, "highlight pixel {i}: {} vs 9 samples {}", adaptive[i], nine[i]);
        } else {
            let own = code(base[i]);
            // Only the corners that face the pixel's pairs' partners.
            let off = corners
                .values
                .iter()
                .enumerate()
                .filter(|(j, _)| corners.facing[i] & (1 << j) != 0)
                .flat_map(|(_, c)| {
                    let c = code(c[i]);
                    (0..3).map(move |k| (f32::from(c[k]) - f32::from(own[k])).abs())
                })
                .fold(0.0f32, f32::max);
            if off <= CORNER_AGREEMENT - 1.0 {
                assert_eq!(adaptive[i], base[i], "pixel {i}: corners within {off} codes, not its base");
            } else if off > CORNER_AGREEMENT + 1.0 {
                assert!(took_full, "pixel {i}: corners {off} codes off, {} vs {full} (whole: {whole})", adaptive[i]);
            }
        }
        if !near(full, base[i]) {
            if took_full {
                changed += 1;
            } else {
                assert_eq!(adaptive[i], base[i], "pixel {i}: neither {full} (whole: {whole}) nor its base");
                kept += 1;
            }
        }
    }
    (changed, kept)
}

/// Chrome balls (Phong exponent 10,000, no mirror recursion) on a Lambert
/// floor under an omni light: each ball's highlight is a spot far smaller
/// than a pixel, which a pixel's one shade per bin misses and some of its 9
/// samples hit.
fn chrome_balls() -> (footlight::scene::Scene, footlight::Light, footlight::scene::Camera) {
    use footlight::scene::Material;
    let mut b = footlight::scene::SceneBuilder::new();
    let m = lambert(&mut b, 0.5);
    floor(&mut b, 6.0, 0.0, m);
    let chrome = b.add_material(Material {
        specular: Vec3::splat(0.9),
        exponent: 10_000.0,
        ..Material::lambert("chrome", Vec3::ZERO)
    });
    // UV spheres with smooth normals, at a few sub-pixel offsets.
    for k in 0..7 {
        let centre = Vec3::new(-1.8 + 0.6 * k as f32 + 0.013 * k as f32, 0.3 + 0.007 * k as f32, 0.05 * k as f32);
        b.add_uv_sphere(centre, 0.25, 24, 48, chrome);
    }
    let light = omni(Vec3::new(0.4, 3.0, 2.5));
    let cam = footlight::scene::Camera::look_at(Vec3::new(0.0, 1.2, 6.0), Vec3::new(0.0, 0.3, 0.0), 40f32.to_radians());
    (b.build(), light, cam)
}

#[test]
fn sub_pixel_highlights_are_re_shaded_with_nine_samples() {
    // Issue 13 (AA cost and error): a highlight smaller than a pixel is
    // invisible to the base shade and to every neighbour jump; the
    // highlight test (`View::glint_pixels`) finds it from the 9 G-buffer
    // samples. Against the independent eq. 1 renderer: every pixel whose
    // 9-sample value is brighter than its binned value by more than the
    // threshold (the light's relative codes) is re-shaded, the light-free
    // jump test alone misses some of them, and every re-shaded pixel equals
    // the 9-sample render (every other one the binned render) within 1e-5.
    use footlight::render::RecursionLimits;
    use footlight::render::display::srgb8;
    use footlight::render::reference::render_eq1;
    use footlight::render::view::{CORNER_AGREEMENT, SampleSet, reference_level};
    let (scene, light, cam) = chrome_balls();
    let v = view(&scene, cam, 160, 100, Sampling::Adaptive, 5);
    let aa = AaParams::new(footlight::render::view::AA_THRESHOLD);
    let (base, _) = v.render_direct(&scene, &light, None);
    let decision = v.aa_decision(&scene, &light, &base, aa);
    let flags = decision.flags.clone();
    let jumps_only = v.gradient_flags(&scene, &base, aa);
    let (adaptive, n) = v.render_direct(&scene, &light, Some(aa));
    assert_eq!(n, flags.iter().filter(|&&f| f).count());
    let limits = RecursionLimits { max_depth: 5, min_weight: 0.0 };
    let lights = [light.clone()];
    let nine = render_eq1(&scene, &v.gbuffer, &lights, &[Vec3::ONE], SampleSet::All, limits);
    let binned = render_eq1(&scene, &v.gbuffer, &lights, &[Vec3::ONE], SampleSet::Binned, limits);
    let level = reference_level(&base).unwrap();
    let code = |x: Vec3| srgb8(x / level);
    let brighter = |i: usize| {
        let (a, b) = (code(nine[i]), code(binned[i]));
        (0..3).any(|c| f32::from(a[c]) - f32::from(b[c]) > aa.threshold)
    };
    let hidden: Vec<usize> = (0..base.len()).filter(|&i| brighter(i)).collect();
    assert!(hidden.iter().any(|&i| !jumps_only[i]), "some highlight is missed by the jump test: {hidden:?}");
    for &i in &hidden {
        assert!(flags[i], "pixel {i}: 9 samples {} vs binned {}, not re-shaded", nine[i], binned[i]);
    }
    // Every hidden highlight found by the highlight test takes its 9
    // samples; one marked by a pair only is rebuilt from its probed corners
    // (checked with every other pixel below); none keeps its base (which is
    // more than the threshold darker).
    let peak = nine.iter().map(|x| x.max_element()).fold(0.0f32, f32::max);
    let mut whole = 0;
    for &i in &hidden {
        assert_ne!(adaptive[i], base[i], "pixel {i}: 9 samples {}, kept its base", nine[i]);
        if decision.highlights.contains(&i) {
            whole += 1;
            let off = (adaptive[i] - nine[i]).abs().max_element();
            assert!(off <= 1e-5 * peak, "highlight pixel {i}: {} vs {}", adaptive[i], nine[i]);
        }
    }
    assert!(whole > 0, "no hidden highlight found by the highlight test");
    let corners = CornerProbes::new(&scene, &v, &lights, limits, &base, aa);
    check_reshaded(&adaptive, &base, &flags, &decision.highlights, &nine, &binned, &corners);
    // Highlights between the corners: from these light positions some
    // highlight pixels' 4 corner samples agree with the base (within the
    // corner agreement) while their 9 samples are brighter by more than
    // the threshold. They take all 9 samples: kept at the corners, they
    // would lose the highlight.
    for k in [9, 12] {
        let a = k as f32 * 0.7;
        let light = omni(Vec3::new(2.5 * a.cos(), 2.0 + 0.05 * k as f32, 2.5 * a.sin() + 1.0));
        let lights = [light.clone()];
        let (base, _) = v.render_direct(&scene, &light, None);
        let decision = v.aa_decision(&scene, &light, &base, aa);
        let (adaptive, _) = v.render_direct(&scene, &light, Some(aa));
        let nine = render_eq1(&scene, &v.gbuffer, &lights, &[Vec3::ONE], SampleSet::All, limits);
        let binned = render_eq1(&scene, &v.gbuffer, &lights, &[Vec3::ONE], SampleSet::Binned, limits);
        let corners = CornerProbes::new(&scene, &v, &lights, limits, &base, aa);
        check_reshaded(&adaptive, &base, &decision.flags, &decision.highlights, &nine, &binned, &corners);
        let level = reference_level(&base).unwrap();
        let code = |x: Vec3| srgb8(x / level);
        let steps = |a: Vec3, b: Vec3| {
            let (a, b) = (code(a), code(b));
            [0, 1, 2].map(|c| f32::from(a[c]) - f32::from(b[c]))
        };
        let between = decision
            .highlights
            .iter()
            .filter(|&&i| {
                steps(nine[i], base[i]).iter().any(|&d| d > aa.threshold)
                    && corners.values.iter().all(|c| steps(c[i], base[i]).iter().all(|d| d.abs() < CORNER_AGREEMENT))
            })
            .count();
        assert!(between > 0, "light {k}: no highlight between the corners");
    }
}

#[test]
fn lights_built_together_re_shade_the_same_highlights_as_alone() {
    // Cells built together (`render::build::together`) find sub-pixel highlights on
    // their window as a light alone finds them on the whole frame: same
    // pixels re-shaded, same buffers (1e-6 of the peak), on the chrome balls.
    use footlight::render::build::BuildSettings;
    use footlight::render::view::reference_level;
    let (scene, light, cam) = chrome_balls();
    let lights = vec![light.clone(), omni(Vec3::new(-1.2, 2.5, 1.5)), omni(Vec3::new(1.5, 2.0, -0.5))];
    let v = view(&scene, cam, 160, 100, Sampling::Adaptive, 5);
    let settings = BuildSettings { photons: None, ..BuildSettings::default() };
    let aa = AaParams::new(settings.aa_threshold);
    let (base, _) = v.render_direct(&scene, &light, None);
    let glints = v.glint_pixels(&scene, &light, &base, reference_level(&base).unwrap(), aa.threshold);
    assert!(!glints.is_empty(), "the chrome balls hold sub-pixel highlights");
    crate::common::assert_together_equals_alone(&scene, &v, &lights, settings);
}

/// A Lambert floor seen through, and reflected in, a vertical glass pane
/// (k_T 0.9, k_R 0.04), under a spot whose beam edge crosses the floor on
/// both sides of the pane.
fn floor_behind_glass() -> (footlight::scene::Scene, footlight::Light, footlight::scene::Camera) {
    use footlight::fixture::{Beam, SpotBeam};
    use footlight::scene::Material;
    let mut b = footlight::scene::SceneBuilder::new();
    let m = lambert(&mut b, 0.6);
    floor(&mut b, 4.0, 0.0, m);
    let glass = b.add_material(Material {
        k_r: Vec3::splat(0.04),
        k_t: Vec3::splat(0.9),
        ior: 1.5,
        ..Material::lambert("glass", Vec3::ZERO)
    });
    let (a, c) = (Vec3::new(-1.5, 0.05, 0.0), Vec3::new(1.5, 1.6, 0.0));
    b.add_quad(a, Vec3::new(c.x, a.y, 0.0), c, Vec3::new(a.x, c.y, 0.0), glass);
    let light = footlight::Light::aimed(
        Vec3::new(0.0, 3.0, 0.5),
        Vec3::new(0.4, 0.0, -0.3),
        Beam::Spot(SpotBeam::from_beam_field(50.0, 70.0)),
    );
    let cam =
        footlight::scene::Camera::look_at(Vec3::new(0.0, 1.0, 3.5), Vec3::new(0.0, 0.4, -1.0), 50f32.to_radians());
    (b.build(), light, cam)
}

#[test]
fn reshaded_samples_take_their_weak_branches_from_the_base() {
    // Issue 13 (AA cost): a re-shaded pixel whose base is one bin of all 9
    // samples follows its samples' branches only down to
    // RESHADE_MIN_BRANCH (relative path weight); the base's branches below
    // it stand in for theirs. Against the independent eq. 1 renderer: such
    // a pixel is the 9-sample render cut at that weight plus the binned
    // render's part below it; any other re-shaded pixel is the full
    // 9-sample render. Fails without the base's part (the glass's k_R =
    // 0.04 reflections of the lit floor) or with the samples followed to
    // the end.
    use footlight::render::RecursionLimits;
    use footlight::render::reference::render_eq1;
    use footlight::render::view::{RESHADE_MIN_BRANCH, SampleSet};
    let (scene, light, cam) = floor_behind_glass();
    let v = view(&scene, cam, 160, 100, Sampling::Adaptive, 5);
    let aa = AaParams::new(20.0);
    let (base, _) = v.render_direct(&scene, &light, None);
    // Every marked pixel re-shaded whole, as a highlight pixel is.
    let mut decision = v.aa_decision(&scene, &light, &base, aa);
    let flags = decision.flags.clone();
    let highlights = std::mem::replace(&mut decision.highlights, (0..base.len()).filter(|&i| flags[i]).collect());
    let mut adaptive = base.clone();
    let n = v.reshade(&scene, &light, &mut adaptive, decision.reshading());
    let lights = [light.clone()];
    let eq1 = |set, min_weight| {
        render_eq1(&scene, &v.gbuffer, &lights, &[Vec3::ONE], set, RecursionLimits { max_depth: 5, min_weight })
    };
    let nine = eq1(SampleSet::All, 0.0);
    let nine_strong = eq1(SampleSet::All, RESHADE_MIN_BRANCH / 9.0);
    let binned = eq1(SampleSet::Binned, 0.0);
    let binned_strong = eq1(SampleSet::Binned, RESHADE_MIN_BRANCH);
    let scale = nine.iter().map(|x| x.max_element()).fold(0.0f32, f32::max);
    let near = |a: Vec3, b: Vec3| (a - b).abs().max_element() <= 1e-5 * scale;
    // The shipped rule: a one-bin pixel whose probed corners disagree is
    // rebuilt from its base's strong part and its corners cut at the same
    // weight, plus the base's weak part; a pixel of several bins whose
    // corners disagree takes the same value as when re-shaded whole.
    let (shipped, _) = v.render_direct(&scene, &light, Some(aa));
    let strong = RecursionLimits { max_depth: 5, min_weight: RESHADE_MIN_BRANCH / 9.0 };
    let probes = CornerProbes::new(&scene, &v, &lights, strong, &base, aa);
    let (mut pruned, mut weak_lit, mut differs, mut rebuilt) = (0, 0, 0, 0);
    for i in (0..base.len()).filter(|&i| flags[i]) {
        let one_bin = matches!(v.gbuffer.bins(i), [b] if b.weight >= 1.0);
        let weak = binned[i] - binned_strong[i];
        let expected = if one_bin { nine_strong[i] + weak } else { nine[i] };
        assert!(near(adaptive[i], expected), "pixel {i} (one bin: {one_bin}): {} vs {expected}", adaptive[i]);
        let grid =
            if one_bin && !highlights.contains(&i) { probes.rebuilt(i, base[i] - weak) + weak } else { expected };
        assert!(shipped[i] == base[i] || near(shipped[i], grid), "pixel {i}: {} vs rebuilt {grid}", shipped[i]);
        rebuilt += usize::from(one_bin && shipped[i] != base[i] && !near(grid, expected));
        if one_bin && nine_strong[i] != nine[i] {
            pruned += 1;
            weak_lit += usize::from((binned[i] - binned_strong[i]).max_element() > 1e-3 * scale);
            differs += usize::from(!near(expected, nine[i]));
        }
    }
    assert!(n > 50, "{n} pixels re-shaded");
    assert!(
        pruned > 20 && weak_lit > 20 && differs > 5,
        "{pruned} pruned, {weak_lit} with lit weak branches, {differs} off 9 samples"
    );
    assert!(rebuilt > 5, "{rebuilt} pixels rebuilt from their corners, off their 9 samples");
}
