//! Normal maps (Lähner et al. §4.1): UV layouts, rasterisation, coarse and fine maps, spaces, PNG.

mod support;

use crease_core::mesh::geometry::vertex_normals;
use crease_deep::normal_maps::bake::map_normal_error;
use crease_deep::normal_maps::raster::TexelMap;
use crease_deep::normal_maps::uv::{auto_atlas, read_obj_uv, write_obj_with_uv};
use crease_deep::normal_maps::{
    angle_deg, bake_coarse, bake_fine, convert_space, sample_vertex_normals, FineSurface, NormalMap,
};

#[test]
fn auto_atlas_of_a_tube_samples_back_its_own_normals() {
    // A bumpy tube without texture coordinates: every vertex sampled from the coarse map must get its own
    // normal back, which fails if charts overlap or the atlas leaves vertices out.
    let (topo, p) = support::tube(40, 24, |phi, x| {
        0.07 + 0.004 * (3.0 * phi).sin() * (20.0 * x).cos()
    });
    let layout = auto_atlas(&topo, &p, 0.01).unwrap();
    layout.check(&topo, "tube").unwrap();
    assert!(layout
        .uv
        .iter()
        .all(|q| (0.0..=1.0).contains(&q[0]) && (0.0..=1.0).contains(&q[1])));
    assert!(
        layout.uv.len() > topo.n_vertices(),
        "a closed-around tube needs seams"
    );
    let texels = TexelMap::new(&layout, 256, 256);
    assert!(
        texels.coverage() > 0.4,
        "atlas uses {:.2} of the map",
        texels.coverage()
    );
    let map = bake_coarse(&texels, &topo, &p);
    let sampled = sample_vertex_normals(&map, &topo, &layout);
    let (err, reached) = map_normal_error(&sampled, &topo, &p);
    assert_eq!(reached, 1.0);
    assert!(
        err < 1.5,
        "coarse map reproduces the mesh normals to {err:.3} degrees"
    );
}

#[test]
fn fine_map_carries_the_folds_the_coarse_mesh_lacks() {
    let (topo, flat) = support::sheet(61, |_, _| 0.0);
    let (_, folded) = support::sheet(61, |x, _| 0.01 * (std::f64::consts::TAU * 5.0 * x).sin());
    let layout = auto_atlas(&topo, &flat, 0.01).unwrap();
    let texels = TexelMap::new(&layout, 256, 256);
    let fine = FineSurface::new(&topo, &folded).unwrap();
    let hr = bake_fine(&texels, &topo, &flat, &fine, 0.05);
    let lr = bake_coarse(&texels, &topo, &flat);
    let (hr_err, hr_reach) =
        map_normal_error(&sample_vertex_normals(&hr, &topo, &layout), &topo, &folded);
    let (lr_err, _) = map_normal_error(&sample_vertex_normals(&lr, &topo, &layout), &topo, &folded);
    assert!(hr_reach > 0.99);
    assert!(lr_err > 10.0, "flat sheet against 17° folds: {lr_err:.2}");
    assert!(
        hr_err < 2.0,
        "fine map error {hr_err:.2}° (coarse {lr_err:.2}°)"
    );
    // A texel whose ray meets nothing within the distance stays uncovered.
    let (_, far) = support::sheet(61, |_, _| 0.2);
    let none = bake_fine(
        &texels,
        &topo,
        &flat,
        &FineSurface::new(&topo, &far).unwrap(),
        0.05,
    );
    assert!(none.covered.iter().all(|c| !c));
}

#[test]
fn tangent_space_of_a_coarse_map_is_up_and_converts_back() {
    let (topo, p) = support::tube(32, 16, |phi, _| 0.07 + 0.003 * (2.0 * phi).cos());
    let layout = auto_atlas(&topo, &p, 0.01).unwrap();
    let texels = TexelMap::new(&layout, 128, 128);
    let world = bake_coarse(&texels, &topo, &p);
    let tangent = convert_space(&world, &texels, &topo, &p, &layout, true);
    let mut worst = 0.0f64;
    for k in 0..tangent.n.len() {
        if tangent.covered[k] {
            worst = worst.max(angle_deg(tangent.n[k], [0.0, 0.0, 1.0]));
        }
    }
    assert!(
        worst < 0.01,
        "coarse normals in their own tangent frame deviate {worst}°"
    );
    // A folded map survives the round trip.
    let (_, bumpy) = support::tube(32, 16, |phi, x| {
        0.07 + 0.006 * (6.0 * phi).sin() * (30.0 * x).sin()
    });
    let detail = bake_fine(
        &texels,
        &topo,
        &p,
        &FineSurface::new(&topo, &bumpy).unwrap(),
        0.03,
    );
    let back = convert_space(
        &convert_space(&detail, &texels, &topo, &p, &layout, true),
        &texels,
        &topo,
        &p,
        &layout,
        false,
    );
    assert!(
        detail.mean_angle_deg(&back) < 0.05,
        "round trip {}",
        detail.mean_angle_deg(&back)
    );
    assert!(
        detail.mean_angle_deg(&world) > 2.0,
        "the detail map differs from the coarse one"
    );
}

#[test]
fn png_is_16_bit_rgba_and_round_trips() {
    let (topo, p) = support::tube(24, 12, |_, _| 0.07);
    let layout = auto_atlas(&topo, &p, 0.01).unwrap();
    let texels = TexelMap::new(&layout, 64, 64);
    let map = bake_coarse(&texels, &topo, &p);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.png");
    map.write_png(&path).unwrap();
    let img = image::open(&path).unwrap();
    assert_eq!(img.color(), image::ColorType::Rgba16);
    let back = NormalMap::read_png(&path).unwrap();
    assert_eq!(
        back.covered, map.covered,
        "alpha marks exactly the covered texels"
    );
    assert!(map.mean_angle_deg(&back) < 0.01);
    assert!(NormalMap::read_png(&dir.path().join("missing.png")).is_err());
}

#[test]
fn obj_with_uv_round_trips_and_mismatches_are_named() {
    let (topo, p) = support::tube(16, 8, |_, _| 0.07);
    let layout = auto_atlas(&topo, &p, 0.01).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.obj");
    write_obj_with_uv(&path, &topo, &p, &layout).unwrap();
    let back = read_obj_uv(&path, &topo).unwrap().expect("vt present");
    assert_eq!(back.corners, layout.corners);
    for (a, b) in back.uv.iter().zip(&layout.uv) {
        assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12);
    }
    // No vt: None. Other topology: an error naming the file.
    let plain = dir.path().join("plain.obj");
    crease_core::mesh::io::write_obj(&plain, &topo, &p).unwrap();
    assert!(read_obj_uv(&plain, &topo).unwrap().is_none());
    let (other, _) = support::tube(16, 9, |_, _| 0.07);
    let err = read_obj_uv(&path, &other).unwrap_err().to_string();
    assert!(
        err.contains("t.obj") && err.contains("do not match"),
        "{err}"
    );
    let _ = vertex_normals(&topo, &p);
}
