//! `crease bench --deep`: the cost of DeepWrinkles inference per frame (the aim: ≤ 50 ms at 256² on one core,
//! `--threads 1`), split into the steps `crease deep apply --coarse` runs per frame — the detail model's fine
//! shape drawn into the map, the cGAN generator's forward pass, writing the frame — and the cGAN's training
//! time.
//!
//! Weights are made up or freshly initialised, not trained: a forward pass costs the same whatever the
//! weights. The mesh is a training directory's first gt frames (`--deep-data`; a random capture of them is the
//! coarse input), or by default a synthetic tube with the sleeve's size (80 × 92 = 7,360 vertices). Also timed:
//! writing the frame's OBJ and PNG (bytes, files, sync apart), the PNG encoder's settings against each other,
//! and every `--deep-filters` size.

use super::args::BenchArgs;
use anyhow::{bail, Context, Result};
use crease_core::mesh::io::open_sequence;
use crease_core::mesh::Topology;
use crease_core::vec3::V3;
use crease_deep::cgan::data::TrainingSet;
use crease_deep::cgan::{Cgan, CganConfig};
use crease_deep::nn::seed::Rng;
use crease_deep::normal_maps::raster::TexelMap;
use crease_deep::normal_maps::uv::auto_atlas;
use crease_deep::normal_maps::{bake_coarse, world_from_vertex_normals};
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

/// Frames 0 and 1 of `dir/gt` (fine) and a random capture of each (coarse).
fn training_frames(dir: &Path) -> Result<(Topology, FramePair, FramePair)> {
    let f = open_sequence(&dir.join("gt"))?.source;
    if f.n_frames() < 2 {
        bail!(
            "{}: --deep-data needs at least 2 frames in gt/",
            dir.display()
        );
    }
    let topo = (**f.topology()).clone();
    let fine = [f.read_frame(0)?, f.read_frame(1)?];
    let capture = |t: usize| {
        let h = crease_core::shape::mean_edge_length(&topo, &fine[t]);
        crease_deep::detail::training_capture(&topo, &fine[t], h, 1, 0, t, 0).0
    };
    let coarse = [capture(0), capture(1)];
    Ok((topo, coarse, fine))
}

fn median_ms(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    1e3 * v[v.len() / 2]
}

/// Median milliseconds of `repeats` calls of `f`.
fn time_ms(repeats: usize, mut f: impl FnMut() -> Result<()>) -> Result<f64> {
    let mut v = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let t = Instant::now();
        f()?;
        v.push(t.elapsed().as_secs_f64());
    }
    Ok(median_ms(v))
}

fn verdict(ms: f64) -> &'static str {
    if ms <= 50.0 {
        "met"
    } else {
        "not met"
    }
}

/// One generator size: forward pass per frame and (unless `train_steps` is 0) a training step.
struct GeneratorTimes {
    filters: usize,
    forward_ms: f64,
    train_step_ms: Option<f64>,
}

pub fn bench_deep(a: &BenchArgs) -> Result<()> {
    if a.repeats == 0 {
        bail!("--repeats must be at least 1");
    }
    if a.deep_filters.is_empty() || a.deep_filters.contains(&0) {
        bail!("--deep-filters needs one or more sizes of at least 1");
    }
    let threads = rayon::current_num_threads();
    // candle sizes its own parallel loops from RAYON_NUM_THREADS: make it use the pool `--threads` set.
    std::env::set_var("RAYON_NUM_THREADS", threads.to_string());
    let res = a.deep_resolution;
    let configs: Vec<CganConfig> = a
        .deep_filters
        .iter()
        .map(|&filters| CganConfig {
            filters,
            disc_filters: filters,
            seed: 1,
            ..Default::default()
        })
        .collect();
    for c in &configs {
        c.validate()?;
        c.check_resolution(res)?;
    }
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
    let filters_list: Vec<String> = a.deep_filters.iter().map(|f| f.to_string()).collect();
    println!(
        "crease bench --deep: {} ({} vertices, {} triangles), {res}² maps, generator {} filters, {threads} thread(s), median of {} runs",
        source,
        topo.n_vertices(),
        topo.n_triangles(),
        filters_list.join(" and "),
        a.repeats
    );
    let layout = auto_atlas(&topo, &coarse[0], 0.01).context("UV layout")?;
    let t = Instant::now();
    let texels = TexelMap::new(&layout, res, res);
    let texel_setup_ms = 1e3 * t.elapsed().as_secs_f64();
    println!(
        "  texel map set-up (once per model): {texel_setup_ms:.1} ms; the surface covers {:.0}% of the texels",
        100.0 * texels.coverage()
    );

    // Inference of the default model's detail (`apply --coarse`): the detail model's fine shape at the default
    // degree (its cost does not depend on the weights; the guard is wide open so every frame runs the filter)
    // drawn into the map, with the scale check apply makes.
    let detail = bench_detail_model();
    let h = detail.check_scale(&topo, &coarse[0], "bench")?;
    let mut dmap = world_from_vertex_normals(
        &texels,
        &topo,
        &detail
            .normals(&topo, &coarse[0], h, crease_deep::detail::SurfaceGate::OPEN)
            .0,
    );
    let detail_ms = time_ms(a.repeats, || {
        let h = detail.check_scale(&topo, &coarse[0], "bench")?;
        dmap = world_from_vertex_normals(
            &texels,
            &topo,
            &detail
                .normals(&topo, &coarse[0], h, crease_deep::detail::SurfaceGate::OPEN)
                .0,
        );
        Ok(())
    })?;
    // `apply --pose`'s map: the coarse mesh's own normals (no detail model).
    let mut map = bake_coarse(&texels, &topo, &coarse[0]);
    let raster_ms = time_ms(a.repeats, || {
        map = bake_coarse(&texels, &topo, &coarse[0]);
        Ok(())
    })?;

    // Writing the frame (the output contract): the bytes of the OBJ and the PNG, then the files (written and
    // renamed into place), then their sync to the device (apply syncs once at the end; here per frame, to time
    // it), into a scratch directory removed afterwards.
    let writer = crease_deep::contract::FrameWriter::new(&topo, &layout);
    let mut files = crease_deep::contract::FrameScratch::default();
    let scratch_dir =
        std::env::temp_dir().join(format!("crease-bench-deep-{}", std::process::id()));
    crease_deep::contract::prepare(&scratch_dir)?;
    let written = (|| -> Result<(f64, f64, f64, usize)> {
        let mut bytes = 0;
        let encode_ms = time_ms(a.repeats, || {
            let (obj, png) =
                writer.encode(&scratch_dir, 0, &coarse[0], &dmap, "bench", &mut files)?;
            bytes = obj.len() + png.len();
            Ok(())
        })?;
        let mut frame = 0;
        let files_ms = time_ms(a.repeats, || {
            writer.write(&scratch_dir, frame, &coarse[0], &dmap, "bench", &mut files)?;
            frame += 1;
            Ok(())
        })?;
        let mut frame = 0;
        let sync_ms = time_ms(a.repeats, || {
            crease_deep::contract::sync_frames(&scratch_dir, frame..frame + 1)?;
            frame += 1;
            Ok(())
        })?;
        // The OBJ tail (vt and f lines) is the same for every frame: add its share to the byte count.
        Ok((
            encode_ms,
            files_ms,
            sync_ms,
            bytes + writer.constant_obj_bytes(),
        ))
    })();
    let _ = std::fs::remove_dir_all(&scratch_dir);
    let (encode_ms, files_ms, sync_ms, frame_bytes) = written?;
    println!(
        "  inference, the detail model's map (apply --coarse without a cGAN): {detail_ms:.2} ms per frame"
    );
    println!(
        "  inference, apply --pose's map (rasterise the coarse normals): {raster_ms:.2} ms per frame"
    );
    println!(
        "  writing a frame: OBJ + PNG bytes {encode_ms:.2} ms, files written and renamed {files_ms:.2} ms (both: {:.2} ms, {:.2} MB), synced to the device {sync_ms:.2} ms",
        encode_ms + files_ms,
        frame_bytes as f64 / 1e6
    );
    println!(
        "  default apply --coarse per frame: inference + writing {:.2} ms (+ {sync_ms:.2} ms sync)",
        detail_ms + encode_ms + files_ms
    );

    // PNG encoder settings (the bytes differ, the pixels do not): what the default costs against the others.
    let mut png_variants = Vec::new();
    {
        use crease_deep::normal_maps::{PngScratch, PngSettings};
        use image::codecs::png::{CompressionType as C, FilterType as F};
        let mut ps = PngScratch::default();
        let mut line = Vec::new();
        for (name, compression, filter) in [
            ("default (fast, adaptive)", C::Fast, F::Adaptive),
            ("balanced (zlib level 6), adaptive", C::Default, F::Adaptive),
            ("fast, up", C::Fast, F::Up),
            ("fast, sub", C::Fast, F::Sub),
            ("uncompressed, no filter", C::Uncompressed, F::NoFilter),
        ] {
            let settings = PngSettings {
                compression,
                filter,
            };
            let mut size = 0;
            let ms = time_ms(a.repeats, || {
                size = dmap
                    .encode_png(Path::new("bench.png"), settings, &mut ps)?
                    .len();
                Ok(())
            })?;
            line.push(format!("{name} {ms:.2} ms {:.0} KB", size as f64 / 1e3));
            png_variants.push(json!({"settings": name, "encode_ms": ms, "bytes": size}));
        }
        println!("  PNG encoding (dilation included): {}", line.join("; "));
    }

    let mut generators = Vec::new();
    for config in &configs {
        let mut gan = Cgan::new(config.clone())?;
        gan.enhance(&map)?; // first call allocates; not counted
        let forward_ms = time_ms(a.repeats, || {
            let out = gan.enhance(&map)?;
            if out.n.len() != map.n.len() {
                bail!("the generator returned a map of another size");
            }
            Ok(())
        })?;
        println!(
            "  generator forward, {} filters: {forward_ms:.1} ms per frame; with the detail model's map {:.1} ms (target ≤ 50 ms at 256² on one core: {})",
            config.filters,
            forward_ms + detail_ms,
            verdict(forward_ms + detail_ms)
        );
        let train_step_ms = if a.deep_train_steps == 0 {
            None
        } else {
            // Training: one step (discriminator + generator) on a batch of random crops.
            let normals = crease_deep::cgan::data::shape_normals(&topo, &coarse[..], &fine[..]);
            let set = TrainingSet::new(&topo, &texels, vec![normals], config.crop);
            let mut rng = Rng::new(1);
            let mut step = || -> Result<()> {
                let batch = set.batch(&mut rng, config.batch, config.crop)?;
                gan.train_step(&batch)?;
                Ok(())
            };
            step()?; // warm-up
            let step_ms = time_ms(a.deep_train_steps, step)?;
            println!(
                "  training, {} filters: {step_ms:.0} ms per step (batch {} of {}² crops, median of {}) → {:.0} s for the default {} steps",
                config.filters,
                config.batch,
                config.crop,
                a.deep_train_steps,
                step_ms * 1e-3 * config.steps as f64,
                config.steps
            );
            Some(step_ms)
        };
        generators.push(GeneratorTimes {
            filters: config.filters,
            forward_ms,
            train_step_ms,
        });
    }

    if let Some(path) = &a.json {
        let first = &generators[0];
        let train_s = |ms: Option<f64>| ms.map(|ms| ms * 1e-3 * configs[0].steps as f64);
        let doc = json!({ "deep": {
            "source": source,
            "vertices": topo.n_vertices(),
            "triangles": topo.n_triangles(),
            "resolution": res,
            "filters": first.filters,
            "threads": threads,
            "repeats": a.repeats,
            "texel_setup_ms": texel_setup_ms,
            "coverage": texels.coverage(),
            "raster_ms": raster_ms,
            "forward_ms": first.forward_ms,
            "per_frame_ms": detail_ms + first.forward_ms,
            "detail_map_ms": detail_ms,
            "encode_frame_ms": encode_ms,
            "write_files_ms": files_ms,
            "write_frame_ms": encode_ms + files_ms,
            "sync_frame_ms": sync_ms,
            "frame_bytes": frame_bytes,
            "apply_coarse_default_ms": detail_ms + encode_ms + files_ms,
            "png_encoders": png_variants,
            "generators": generators.iter().map(|g| json!({
                "filters": g.filters,
                "forward_ms": g.forward_ms,
                "train_step_ms": g.train_step_ms,
                "training_s": train_s(g.train_step_ms),
            })).collect::<Vec<_>>(),
            "train_step_ms": first.train_step_ms,
            "training_steps": configs[0].steps,
            "training_s": train_s(first.train_step_ms),
        }});
        crease_core::fsutil::write_atomic(path, serde_json::to_string_pretty(&doc)?.as_bytes())?;
    }
    Ok(())
}

/// A detail model of the default degree with made-up weights and a guard that lets every frame through: what
/// the benchmark times does not depend on the values.
fn bench_detail_model() -> crease_deep::detail::DetailModel {
    use crease_deep::detail::{DetailModel, DetailSpec, Guard, DEFAULT_DEGREE, SIGNATURE_LEN};
    let n = (DEFAULT_DEGREE + 1) * (SIGNATURE_LEN + 1);
    DetailModel {
        spec: DetailSpec {
            degree: DEFAULT_DEGREE,
            ridge: 1e-6,
            captures_per_frame: 1,
            seed: 1,
            signature_mean: vec![0.0; SIGNATURE_LEN],
            signature_std: vec![1.0; SIGNATURE_LEN],
            guard: Guard {
                edge_length: [1e-9, 1e9],
                max_signature_distance: f64::INFINITY,
                max_detail: f64::INFINITY,
                lost_surface: None,
            },
            held_out_capture_deg: 0.0,
            held_out_model_deg: 0.0,
            coarse: None,
        },
        interior: (0..n).map(|j| 0.1 / (1.0 + j as f64)).collect(),
        boundary: (0..n).map(|j| 0.05 / (1.0 + j as f64)).collect(),
    }
}
