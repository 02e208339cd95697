//! A sheet seen from above under a known lighting: the refinement puts back a fold the mesh lacks from the
//! image alone, and leaves a mesh that already matches its (noisy) image where it is.

use super::*;
use crate::folds::video::shading::sh_basis;
use crate::render::CalibratedCamera;

const W: u32 = 320;
const H: u32 = 240;

/// An `nx` × `ny` grid over 1 m × 0.8 m in the plane z = 0, with heights `z(x, y)`.
fn sheet(nx: usize, ny: usize, z: impl Fn(f64, f64) -> f64) -> (Topology, Vec<V3>) {
    let mut p = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let x = -0.5 + i as f64 / (nx - 1) as f64;
            let y = -0.4 + 0.8 * j as f64 / (ny - 1) as f64;
            p.push([x, y, z(x, y)]);
        }
    }
    let mut tris = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let a = (j * nx + i) as u32;
            let (b, c, d) = (a + 1, a + nx as u32, a + nx as u32 + 1);
            tris.push([a, b, d]);
            tris.push([a, d, c]);
        }
    }
    (Topology::new(p.len(), tris).unwrap(), p)
}

/// A camera 2 m above the sheet looking straight down at it (its image is 200 px across the sheet's metre).
fn camera() -> CalibratedCamera {
    CalibratedCamera {
        fx: 400.0,
        fy: 400.0,
        cx: (W as f64 - 1.0) / 2.0,
        cy: (H as f64 - 1.0) / 2.0,
        r: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        t: [0.0, 0.0, 2.0],
        width: W,
        height: H,
    }
}

/// Ambient light and a key light from the side: shading `sh_basis(n) · LIGHT` in linear grey levels.
const LIGHT: [f64; 9] = [110.0, 60.0, 25.0, -50.0, 0.0, 0.0, 0.0, 0.0, 0.0];

fn srgb(lin: f64) -> f32 {
    let c = (lin / 255.0).clamp(0.0, 1.0);
    let e = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (255.0 * e) as f32
}

/// The sheet rendered under [`LIGHT`] (sRGB grey), with `noise` grey levels of deterministic pseudo-random
/// noise added.
fn render(topo: &Topology, p: &[V3], cam: &CalibratedCamera, noise: f64) -> Photo {
    let surface = shading::surface_image(topo, p, cam);
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let gray: Vec<f32> = surface
        .iter()
        .map(|s| match s {
            Some((_, n)) => {
                let lin: f64 = sh_basis(*n).iter().zip(LIGHT).map(|(a, b)| a * b).sum();
                srgb(lin) + (noise * 3.46 * uniform()) as f32
            }
            None => 0.0,
        })
        .collect();
    Photo {
        width: W,
        height: H,
        rgb: gray.iter().map(|&g| [g; 3]).collect(),
        mask: surface.iter().map(|s| s.is_some()).collect(),
        gray,
        has_alpha: true,
    }
}

/// Mean angle (degrees) between the vertex normals of two shapes.
fn normal_error(topo: &Topology, a: &[V3], b: &[V3]) -> f64 {
    let (na, nb) = (
        geometry::vertex_normals(topo, a),
        geometry::vertex_normals(topo, b),
    );
    na.iter()
        .zip(&nb)
        .map(|(x, y)| vec3::dot(*x, *y).clamp(-1.0, 1.0).acos().to_degrees())
        .sum::<f64>()
        / na.len() as f64
}

/// The sheet's smooth shape: a shallow trough, so its normals vary enough for a lighting fit.
fn base(x: f64, y: f64) -> f64 {
    0.25 * x * x + 0.2 * y * y
}

/// A ridge 8 edges wide with 35° slopes across the middle of the sheet, on the trough.
fn fold(x: f64, y: f64) -> f64 {
    base(x, y) + ridge(x)
}

fn ridge(x: f64) -> f64 {
    let wavelength = 8.0 / 60.0;
    let amp = 0.7 * wavelength / (2.0 * std::f64::consts::PI);
    if x.abs() < wavelength {
        amp * 0.5 * (1.0 + (2.0 * std::f64::consts::PI * x / wavelength).cos())
    } else {
        0.0
    }
}

#[test]
fn a_fold_the_mesh_lacks_comes_back_from_the_image() {
    let (topo, truth) = sheet(61, 49, fold);
    let (_, flat) = sheet(61, 49, base);
    let cam = camera();
    let photo = render(&topo, &truth, &cam, 0.0);
    let views = vec![RefineView {
        camera: &cam,
        photo: &photo,
    }];
    let r = refine_frame(&topo, &flat, views, &ShadingRefineParams::default()).unwrap();
    let before = normal_error(&topo, &flat, &truth);
    let after = normal_error(&topo, &r.positions, &truth);
    assert!(
        after < 0.6 * before,
        "normal error {before:.2}° → {after:.2}°: the image's fold did not come back"
    );
    // The fold is where the image has it: the offsets correlate with the true heights.
    let h: Vec<f64> = truth.iter().map(|p| ridge(p[0])).collect();
    let (mh, mo) = (
        h.iter().sum::<f64>() / h.len() as f64,
        r.offsets.iter().sum::<f64>() / h.len() as f64,
    );
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in h.iter().zip(&r.offsets) {
        sxy += (a - mh) * (b - mo);
        sxx += (a - mh) * (a - mh);
        syy += (b - mo) * (b - mo);
    }
    let corr = sxy / (sxx * syy).sqrt();
    assert!(corr > 0.7, "offsets correlate {corr:.3} with the fold");
    assert!(r.residual_last < r.residual_first);
    assert_eq!(r.views_used, 1);
}

#[test]
fn a_mesh_that_matches_its_noisy_image_stays_put() {
    let (topo, truth) = sheet(61, 49, fold);
    let cam = camera();
    let photo = render(&topo, &truth, &cam, 4.0);
    let views = vec![RefineView {
        camera: &cam,
        photo: &photo,
    }];
    let r = refine_frame(&topo, &truth, views, &ShadingRefineParams::default()).unwrap();
    let err = normal_error(&topo, &r.positions, &truth);
    assert!(err < 1.0, "image noise moved the normals by {err:.2}°");
}

#[test]
fn no_usable_view_gives_the_frame_back() {
    let (topo, truth) = sheet(21, 17, fold);
    let cam = camera();
    let mut small = cam;
    small.width = 10;
    let photo = render(&topo, &truth, &cam, 0.0);
    let views = vec![RefineView {
        camera: &small,
        photo: &photo,
    }];
    let r = refine_frame(&topo, &truth, views, &ShadingRefineParams::default()).unwrap();
    assert_eq!(r.positions, truth);
    assert_eq!(r.views_used, 0);
}

#[test]
fn bad_settings_and_inputs_are_named() {
    let p = ShadingRefineParams {
        stay: 0.0,
        ..ShadingRefineParams::default()
    };
    assert!(p.validate().unwrap_err().to_string().contains("stay"));
    let p = ShadingRefineParams {
        smoothness: f64::NAN,
        ..ShadingRefineParams::default()
    };
    assert!(p.validate().unwrap_err().to_string().contains("smoothness"));
    let (topo, truth) = sheet(5, 5, |_, _| 0.0);
    let e = refine_frame(&topo, &truth[..3], vec![], &ShadingRefineParams::default());
    assert!(e.unwrap_err().to_string().contains("positions"));
}

#[test]
fn where_the_capture_erased_the_fold_the_images_are_followed_further() {
    let (topo, truth) = sheet(61, 49, fold);
    let (_, flat) = sheet(61, 49, base);
    let cam = camera();
    let photo = render(&topo, &truth, &cam, 0.0);
    let views = || {
        vec![RefineView {
            camera: &cam,
            photo: &photo,
        }]
    };
    // The band of the ridge lost surface and the relief gave none of it back (rest areas far above the
    // captured ones there); elsewhere nothing was lost (no rest area to compare with).
    let band = |p: &V3| p[0].abs() < 8.0 / 60.0;
    let rest = flat
        .iter()
        .map(|p| if band(p) { 1.0 } else { 0.0 })
        .collect();
    let areas = crate::spacetime::shape::lost_area::RestAreas::from_areas(&topo, rest, 0.0);
    let trace = areas.trace(&topo, &flat, &flat).unwrap();
    assert_eq!(trace.share(), Some(0.0));
    let params = ShadingRefineParams::default();
    assert!(params.erased_stay < params.stay && params.stay < params.kept_stay);
    // Per vertex: the erased band at the lowest stay, where nothing was lost the plain stay, and where the relief
    // gives back all that was lost (here a relief that doubles the sheet) the highest.
    let n = flat.len();
    let weights = stay_weights(&params, Some(&trace), n);
    let doubled: Vec<V3> = flat.iter().map(|p| vec3::scale(*p, 2.0)).collect();
    let full = areas.trace(&topo, &flat, &doubled).unwrap();
    let kept = stay_weights(&params, Some(&full), n);
    for v in 0..n {
        let (want_erased, want_kept) = if band(&flat[v]) {
            (params.erased_stay, params.kept_stay)
        } else {
            (params.stay, params.stay)
        };
        assert!(
            (weights[v] - want_erased).abs() < 1e-9 * want_erased,
            "vertex {v}"
        );
        assert!((kept[v] - want_kept).abs() < 1e-9 * want_kept, "vertex {v}");
    }
    assert_eq!(stay_weights(&params, None, n), vec![params.stay; n]);
    assert_eq!(
        stay_weights(&params, Some(&trace), n - 1),
        vec![params.stay; n - 1]
    );
    let held = refine_frame(&topo, &flat, views(), &params).unwrap();
    let erased = refine_frame_traced(&topo, &flat, views(), &params, Some(&trace)).unwrap();
    let (e_held, e_erased) = (
        normal_error(&topo, &held.positions, &truth),
        normal_error(&topo, &erased.positions, &truth),
    );
    assert!(
        e_erased < e_held - 0.05,
        "normal error {e_held:.3}° held, {e_erased:.3}° with the erased band's lower stay"
    );
    // The crest comes up further towards the true ridge's (the refinement stays below it either way).
    let crest = |h: &dyn Fn(usize) -> f64| {
        (0..flat.len())
            .filter(|&v| flat[v][0].abs() < 1.0 / 60.0)
            .map(h)
            .sum::<f64>()
    };
    let (true_crest, held_crest, erased_crest) = (
        crest(&|v| ridge(flat[v][0])),
        crest(&|v| held.offsets[v]),
        crest(&|v| erased.offsets[v]),
    );
    assert!(
        held_crest < erased_crest && erased_crest < true_crest,
        "crest offsets {held_crest:.4} held, {erased_crest:.4} erased, {true_crest:.4} true"
    );
    // Off (a share of 0, or the same stay everywhere), the trace changes nothing, bit for bit.
    for off in [
        ShadingRefineParams {
            erased_share: 0.0,
            ..params.clone()
        },
        ShadingRefineParams {
            erased_stay: params.stay,
            kept_stay: params.stay,
            ..params.clone()
        },
    ] {
        let a = refine_frame(&topo, &flat, views(), &off).unwrap();
        let b = refine_frame_traced(&topo, &flat, views(), &off, Some(&trace)).unwrap();
        assert_eq!(a.positions, b.positions);
    }
    let bad = ShadingRefineParams {
        erased_share: 1.5,
        ..params.clone()
    };
    assert!(bad
        .validate()
        .unwrap_err()
        .to_string()
        .contains("erased_share"));
}

/// How much of the ridge's height the offsets give back: their projection onto the true heights.
fn height_recovered(truth: &[V3], offsets: &[f64]) -> f64 {
    let h: Vec<f64> = truth.iter().map(|p| ridge(p[0])).collect();
    let hh: f64 = h.iter().map(|a| a * a).sum();
    h.iter().zip(offsets).map(|(a, b)| a * b).sum::<f64>() / hh
}

#[test]
fn the_same_sheet_meshed_finer_is_refined_alike_at_the_same_detail_scale() {
    let cam = camera();
    let refine = |n: usize, detail_scale: f64| {
        let (topo, truth) = sheet(60 * n + 1, 48 * n + 1, fold);
        let (_, flat) = sheet(60 * n + 1, 48 * n + 1, base);
        let photo = render(&topo, &truth, &cam, 0.0);
        let views = vec![RefineView {
            camera: &cam,
            photo: &photo,
        }];
        let params = ShadingRefineParams {
            detail_scale,
            ..ShadingRefineParams::default()
        };
        let r = refine_frame(&topo, &flat, views, &params).unwrap();
        height_recovered(&truth, &r.offsets)
    };
    // Five coarse edges, in metres: the fold's own scale, whatever the mesh.
    let detail = 5.0 / 60.0;
    let coarse = refine(1, detail);
    let fine = refine(2, detail);
    let fine_by_edges = refine(2, 0.0);
    assert!(
        coarse > 0.2,
        "the coarse sheet got back {coarse:.3} of the ridge"
    );
    assert!(
        (fine - coarse).abs() < 0.25 * coarse,
        "same detail scale: coarse {coarse:.3}, fine {fine:.3} of the ridge"
    );
    // Measured in the fine mesh's own edges the stay holds it back: the detail scale is what keeps it alike.
    assert!(
        fine_by_edges < 0.8 * fine,
        "fine mesh at five of its own edges {fine_by_edges:.3}, at the physical scale {fine:.3}"
    );
}
