//! `crease bench --deep`: the cost of DeepWrinkles inference per frame (issue 12 target: ≤ 50 ms at 256² on one
//! core, `--threads 1`), split into the two steps `crease deep apply` runs per frame — rasterising the coarse
//! mesh's normal map in UV space and the cGAN generator's forward pass — and the cGAN's training time per epoch.
//!
//! The generator's weights are freshly initialised, not trained: a forward pass costs the same whatever the
//! weights. The mesh is a training directory's captured frame (`--deep-data`), or by default a synthetic tube
//! with the sleeve's size (80 × 92 = 7,360 vertices). Separately, what `apply --coarse` does per frame with a
//! default model (no cGAN): the detail filter's map and writing the frame's OBJ and PNG.

use crate::bench::BenchArgs;
use anyhow::{bail, Context, Result};
use crease_core::mesh::io::open_sequence;
use crease_core::mesh::Topology;
use crease_core::vec3::V3;
use crease_deep::cgan::{Cgan, CganConfig};
use crease_deep::normal_map::bake_coarse;
use crease_deep::raster::TexelMap;
use crease_deep::uv::auto_atlas;
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// A tube of `na` × `nr` vertices; `ripple` adds folds around it (the "fine" mesh of the training pair).
fn tube(na: usize, nr: usize, ripple: f64) -> (Topology, Vec<V3>) {
    let mut tris = Vec::new();
    for j in 0..nr - 1 {
        for i in 0..na {
            let i1 = (i + 1) % na;
            let (a, b, c, d) = (j * na + i, j * na + i1, (j + 1) * na + i1, (j + 1) * na + i);
            tris.push([a as u32, b as u32, c as u32]);
            tris.push([a as u32, c as u32, d as u32]);
        }
    }
    let mut p = Vec::with_capacity(na * nr);
    for j in 0..nr {
        for i in 0..na {
            let phi = std::f64::consts::TAU * i as f64 / na as f64;
            let x = 0.6 * j as f64 / (nr - 1) as f64;
            let r = 0.07 + ripple * (7.0 * phi).sin() * (60.0 * x).cos();
            p.push([x, r * phi.cos(), r * phi.sin()]);
        }
    }
    (
        Topology::new(na * nr, tris).expect("a tube is a valid mesh"),
        p,
    )
}

/// Two consecutive frames of one mesh.
type FramePair = [Vec<V3>; 2];

/// Frames 0 and 1 of `dir/captured` and `dir/gt` (coarse, fine).
fn training_frames(dir: &Path) -> Result<(Topology, FramePair, FramePair)> {
    let c = open_sequence(&dir.join("captured"))?.source;
    let f = open_sequence(&dir.join("gt"))?.source;
    if c.n_frames() < 2 || f.n_frames() < 2 {
        bail!(
            "{}: --deep-data needs at least 2 frames in captured/ and gt/",
            dir.display()
        );
    }
    Ok((
        (**c.topology()).clone(),
        [c.read_frame(0)?, c.read_frame(1)?],
        [f.read_frame(0)?, f.read_frame(1)?],
    ))
}

fn median_ms(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    1e3 * v[v.len() / 2]
}

pub fn bench_deep(a: &BenchArgs) -> Result<()> {
    if a.repeats == 0 || a.deep_train_steps == 0 {
        bail!("--repeats and --deep-train-steps must be at least 1");
    }
    let threads = rayon::current_num_threads();
    // candle sizes its own parallel loops from RAYON_NUM_THREADS: make it use the pool `--threads` set.
    std::env::set_var("RAYON_NUM_THREADS", threads.to_string());
    let res = a.deep_resolution;
    let config = CganConfig {
        resolution: res,
        filters: a.deep_filters,
        disc_filters: a.deep_filters,
        seed: 1,
        ..Default::default()
    };
    config.validate()?;
    let (topo, coarse, fine, source) = match &a.deep_data {
        Some(dir) => {
            let (t, c, f) = training_frames(dir)?;
            (t, c, f, dir.display().to_string())
        }
        None => {
            let (t, c) = tube(80, 92, 0.0);
            let (_, f0) = tube(80, 92, 0.003);
            let (_, f1) = tube(80, 92, 0.0035);
            (t, [c.clone(), c], [f0, f1], "synthetic tube".to_string())
        }
    };
    println!(
        "crease bench --deep: {} ({} vertices, {} triangles), {res}² maps, generator {} filters, {threads} thread(s), median of {} runs",
        source,
        topo.n_vertices(),
        topo.n_triangles(),
        a.deep_filters,
        a.repeats
    );
    let layout = auto_atlas(&topo, &coarse[0], 0.01).context("UV layout")?;
    let t = Instant::now();
    let texels = TexelMap::new(&layout, res, res);
    let texel_setup_ms = 1e3 * t.elapsed().as_secs_f64();

    let mut raster = Vec::new();
    let mut map = bake_coarse(&texels, &topo, &coarse[0]);
    for _ in 0..a.repeats {
        let t = Instant::now();
        map = bake_coarse(&texels, &topo, &coarse[0]);
        raster.push(t.elapsed().as_secs_f64());
    }
    let mut gan = Cgan::new(config.clone())?;
    gan.enhance(&map)?; // first call allocates; not counted
    let mut forward = Vec::new();
    for _ in 0..a.repeats {
        let t = Instant::now();
        let out = gan.enhance(&map)?;
        forward.push(t.elapsed().as_secs_f64());
        if out.n.len() != map.n.len() {
            bail!("the generator returned a map of another size");
        }
    }
    // What `crease deep apply --coarse` does per frame with a default model (no cGAN): the detail filter's
    // fine shape (degree 40; its cost does not depend on the weights) drawn into the map, then the frame's OBJ
    // and 16-bit PNG written (the output contract), into a scratch directory removed afterwards.
    let op = crease_deep::detail_filter::Umbrella::new(&topo);
    let degree = crease_deep::detail_filter::DEFAULT_DEGREE;
    let filter = crease_deep::detail_filter::DetailFilter {
        degree,
        interior: (0..=degree).map(|j| 0.1 / (1.0 + j as f64)).collect(),
        boundary: (0..=degree).map(|j| 0.05 / (1.0 + j as f64)).collect(),
    };
    let mut detail = Vec::new();
    let mut dmap = map.clone();
    for _ in 0..a.repeats {
        let t = Instant::now();
        dmap = crease_deep::apply::detail_map(&texels, &topo, &op, &filter, &coarse[0]);
        detail.push(t.elapsed().as_secs_f64());
    }
    let scratch = std::env::temp_dir().join(format!("crease-bench-deep-{}", std::process::id()));
    crease_deep::contract::prepare(&scratch)?;
    let mut write = Vec::new();
    for r in 0..a.repeats {
        let t = Instant::now();
        crease_deep::contract::write_frame(&scratch, r, &topo, &coarse[0], &layout, &dmap)?;
        write.push(t.elapsed().as_secs_f64());
    }
    let _ = std::fs::remove_dir_all(&scratch);
    let (detail_ms, write_ms) = (median_ms(detail), median_ms(write));
    println!("  apply --coarse without a cGAN (the default model), per frame: detail filter + map {detail_ms:.1} ms + write OBJ and PNG {write_ms:.1} ms = {:.1} ms", detail_ms + write_ms);
    let (raster_ms, forward_ms) = (median_ms(raster), median_ms(forward));
    println!(
        "  texel map set-up (once per model): {texel_setup_ms:.1} ms; the surface covers {:.0}% of the texels",
        100.0 * texels.coverage()
    );
    println!("  per frame: rasterise coarse normal map {raster_ms:.1} ms + generator forward {forward_ms:.1} ms = {:.1} ms (target ≤ 50 ms at 256² on one core)", raster_ms + forward_ms);

    // Training: one step (discriminator + generator, batch 1) per training frame.
    let pairs = crease_deep::cgan_data::map_pairs(
        &topo,
        &texels,
        &[coarse[0].clone(), coarse[1].clone()],
        &[fine[0].clone(), fine[1].clone()],
        8.0,
    )?;
    let samples = crease_deep::cgan_data::samples(&pairs);
    gan.step(&[&samples[1]])?; // warm-up
    let mut steps = Vec::new();
    for i in 0..a.deep_train_steps {
        let t = Instant::now();
        gan.step(&[&samples[i % samples.len()]])?;
        steps.push(t.elapsed().as_secs_f64());
    }
    let step_ms = median_ms(steps);
    let epoch_frames = a.deep_epoch_frames;
    let epoch_s = step_ms * 1e-3 * epoch_frames as f64;
    println!(
        "  training: {step_ms:.0} ms per step (batch 1, median of {}) → {epoch_s:.0} s per epoch of {epoch_frames} frames",
        a.deep_train_steps
    );
    if let Some(path) = &a.json {
        let doc = json!({ "deep": {
            "source": source,
            "vertices": topo.n_vertices(),
            "triangles": topo.n_triangles(),
            "resolution": res,
            "filters": a.deep_filters,
            "threads": threads,
            "repeats": a.repeats,
            "texel_setup_ms": texel_setup_ms,
            "coverage": texels.coverage(),
            "raster_ms": raster_ms,
            "forward_ms": forward_ms,
            "per_frame_ms": raster_ms + forward_ms,
            "detail_map_ms": detail_ms,
            "write_frame_ms": write_ms,
            "apply_coarse_default_ms": detail_ms + write_ms,
            "train_step_ms": step_ms,
            "epoch_frames": epoch_frames,
            "epoch_s": epoch_s,
        }});
        crease_core::fsutil::write_atomic(path, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    }
    Ok(())
}
