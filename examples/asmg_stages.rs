//! Where ASMG loses (or keeps) the shape: the volume and matching quality of every stage.
//!
//! `cargo run --release --example asmg_stages -- [meshes] [seed] [epochs_graph] [epochs_vae]
//! [params JSON]` (defaults 40, 1, the default epochs, `{}`): aligns LV phantoms (cached
//! under the system temp directory), trains Ψ, then prints for several attention
//! temperatures the mean volume of the normalised shapes `h` and `h'` against the meshes, the
//! share of input vertices matched, and the matching distances; then runs the atlas loop and
//! the generator with the given params and prints the volumes of the atlas, of the
//! generator's reconstructions and of its random draws.

use std::path::PathBuf;
use std::time::Instant;

use cohortforge::geometry::distance::surface_distances;
use cohortforge::mesh::Mesh;
use cohortforge::mesh::codec;
use cohortforge::mesh::measures::volume_ml;
use cohortforge::mesh::phantom::{self, Family};
use cohortforge::models::alignment::median_resolution_index;
use cohortforge::models::alignment::simplified;
use cohortforge::models::asmg::model::{embed_mesh, embeddings_of, flatten_f32};
use cohortforge::models::asmg::registration::align;
use cohortforge::models::asmg::{
    AsmgParams, AtlasInit, Embeddings, ShapeInput, Smoother, Temperature, correspond,
    initial_atlas, learn_atlas,
};
use cohortforge::nn::{
    BetaVaeConfig, BetaVaeTraining, GraphSample, GraphVaeConfig, GraphVaeTraining, TrainedGraphVae,
    Unmonitored, train_beta_vae, train_graph_vae,
};

fn mean(v: impl IntoIterator<Item = f64>) -> f64 {
    let (s, n) = v
        .into_iter()
        .fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    s / n.max(1) as f64
}

fn aligned_meshes(count: usize, seed: u64, params: &AsmgParams) -> Vec<Mesh> {
    let dir = std::env::temp_dir().join(format!("asmg_stages_{count}_{seed}"));
    let path = |k: usize| -> PathBuf { dir.join(format!("{k}.mesh")) };
    if let Ok(cached) = (0..count)
        .map(|k| {
            let bytes = std::fs::read(path(k)).map_err(|e| e.to_string())?;
            codec::decode(&bytes).map_err(|e| e.to_string())
        })
        .collect::<Result<Vec<_>, _>>()
    {
        return cached;
    }
    let meshes: Vec<Mesh> = phantom::meshes(Family::Lv, count, seed);
    let started = Instant::now();
    let reference = simplified(
        &meshes[median_resolution_index(&meshes)],
        params.max_vertices,
    )
    .expect("reference");
    let alignment = params.alignment();
    let aligned: Vec<Mesh> = meshes
        .iter()
        .map(|m| {
            align(&reference, m, None, &alignment, params.max_vertices, &[])
                .expect("align")
                .0
        })
        .collect();
    println!("alignment: {:.1} s", started.elapsed().as_secs_f64());
    std::fs::create_dir_all(&dir).expect("cache dir");
    for (k, m) in aligned.iter().enumerate() {
        std::fs::write(path(k), codec::encode(m)).expect("cache");
    }
    aligned
}

fn train_psi(samples: &[GraphSample], params: &AsmgParams, seed: u64) -> TrainedGraphVae {
    let config = GraphVaeConfig::new().with_d_x(params.features.features().width());
    let cache = std::env::temp_dir().join(format!(
        "asmg_stages_psi_{}_{seed}_{:?}_{}_{}_{}_{}.bpk",
        samples.len(),
        params.features,
        params.epochs_graph,
        params.w_kl,
        params.lr,
        params.batch_size
    ));
    if let Some(t) = std::fs::read(&cache)
        .ok()
        .and_then(|b| TrainedGraphVae::from_bytes(&config, &b).ok())
    {
        return t;
    }
    let training = GraphVaeTraining {
        epochs: params.epochs_graph,
        batch_size: params.batch_size,
        lr: params.lr,
        w_kl: params.w_kl,
        w_norm: params.w_norm,
        seed,
    };
    let started = Instant::now();
    let trained = train_graph_vae(samples, &config, &training, &mut Unmonitored).expect("Ψ");
    println!(
        "Ψ: {} epochs in {:.1} s",
        params.epochs_graph,
        started.elapsed().as_secs_f64()
    );
    if let Ok(bytes) = trained.to_bytes() {
        let _ = std::fs::write(&cache, bytes);
    }
    trained
}

/// Least-squares slope of `v` on `x`: 1 when the shapes' volumes follow the meshes', 0 when
/// they all keep the atlas's.
fn slope(v: &[f64], x: &[f64]) -> f64 {
    let (mv, mx) = (mean(v.iter().copied()), mean(x.iter().copied()));
    let cov: f64 = v.iter().zip(x).map(|(a, b)| (a - mv) * (b - mx)).sum();
    let var: f64 = x.iter().map(|b| (b - mx).powi(2)).sum();
    cov / var.max(f64::MIN_POSITIVE)
}

/// Volumes of h and h', coverage and matching distances of every shape for one temperature.
fn report_temperature(
    label: &str,
    atlas: &Mesh,
    atlas_z: &Embeddings,
    meshes: &[Mesh],
    embeddings: &[Embeddings],
    temperature: Temperature,
    smoother: &Smoother,
) {
    let (mut vh, mut vs, mut cover, mut cd, mut hd, mut weight, mut lambda) =
        (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
    for (m, z) in meshes.iter().zip(embeddings) {
        let c = correspond(atlas_z, z, &m.vertices, temperature).expect("attention");
        let smoothed = smoother
            .smooth(&c.normalised, &atlas.vertices)
            .expect("smooth");
        vh.push(volume_ml(&Mesh::new(
            c.normalised.clone(),
            atlas.faces.clone(),
        )));
        vs.push(volume_ml(&Mesh::new(smoothed.clone(), atlas.faces.clone())));
        let mut used: Vec<u32> = c.matches.iter().map(|m| m.index).collect();
        used.sort_unstable();
        used.dedup();
        cover.push(used.len() as f64 / m.vertex_count() as f64);
        weight.push(mean(c.matches.iter().map(|m| m.weight)));
        let d = surface_distances(&smoothed, &m.vertices).expect("distances");
        cd.push(d.cd);
        hd.push(d.hd);
        lambda.push(c.lambda);
    }
    let mesh_volumes: Vec<f64> = meshes.iter().map(volume_ml).collect();
    println!(
        "| {label} | {:.0} | {:.1} ({:.2}) | {:.1} ({:.2}) | {:.2} | {:.2} | {:.2} | {:.2} |",
        mean(lambda),
        mean(vh.iter().copied()),
        slope(&vh, &mesh_volumes),
        mean(vs.iter().copied()),
        slope(&vs, &mesh_volumes),
        mean(cover),
        mean(weight),
        mean(hd),
        mean(cd)
    );
}

/// Hard nearest-neighbour matches by Euclidean embedding distance and by position.
fn report_hard_matches(
    atlas: &Mesh,
    atlas_z: &Embeddings,
    meshes: &[Mesh],
    embeddings: &[Embeddings],
) {
    let d = atlas_z.dim;
    for by_position in [false, true] {
        let (mut vol, mut cover, mut cd) = (vec![], vec![], vec![]);
        for (m, z) in meshes.iter().zip(embeddings) {
            let mut used = Vec::new();
            let h: Vec<[f64; 3]> = (0..atlas.vertex_count())
                .map(|j| {
                    let cost = |i: usize| -> f64 {
                        if by_position {
                            let (a, b) = (atlas.vertices[j], m.vertices[i]);
                            (0..3).map(|c| (a[c] - b[c]).powi(2)).sum()
                        } else {
                            (0..d)
                                .map(|c| {
                                    f64::from(atlas_z.data[j * d + c] - z.data[i * d + c]).powi(2)
                                })
                                .sum()
                        }
                    };
                    let best = (0..m.vertex_count())
                        .min_by(|&a, &b| cost(a).total_cmp(&cost(b)))
                        .unwrap_or(0);
                    used.push(best);
                    m.vertices[best]
                })
                .collect();
            used.sort_unstable();
            used.dedup();
            cover.push(used.len() as f64 / m.vertex_count() as f64);
            vol.push(volume_ml(&Mesh::new(h.clone(), atlas.faces.clone())));
            cd.push(surface_distances(&h, &m.vertices).expect("distances").cd);
        }
        println!(
            "hard match by {}: vol h {:.1} ml, coverage {:.2}, CD {:.2}",
            if by_position {
                "position"
            } else {
                "euclidean embedding"
            },
            mean(vol),
            mean(cover),
            mean(cd)
        );
    }
}

/// RMS vertex distance (mm) between two flattened shapes with the same vertices.
fn rms_distance(a: &[f32], b: &[f32]) -> f64 {
    let sum: f64 = a.iter().zip(b).map(|(x, y)| f64::from(x - y).powi(2)).sum();
    (sum / a.len() as f64 * 3.0).sqrt()
}

/// How close the draws come to the training shapes: mean distance to the nearest, and the
/// share nearer than the 5th percentile of the training shapes' own nearest-neighbour
/// distances (a stand-in for the privacy guard's `near_copy`).
fn report_draw_novelty(shapes: &[Vec<f32>], draws: &[Vec<f32>]) {
    let nearest = |s: &[f32], skip: Option<usize>| -> f64 {
        shapes
            .iter()
            .enumerate()
            .filter(|(k, _)| Some(*k) != skip)
            .map(|(_, t)| rms_distance(s, t))
            .fold(f64::INFINITY, f64::min)
    };
    let mut own: Vec<f64> = (0..shapes.len())
        .map(|k| nearest(&shapes[k], Some(k)))
        .collect();
    own.sort_by(f64::total_cmp);
    let threshold = own[own.len() / 20];
    let to_training: Vec<f64> = draws.iter().map(|d| nearest(d, None)).collect();
    let near = to_training.iter().filter(|&&d| d < threshold).count();
    println!(
        "draws: nearest training shape {:.2} mm on average (training among themselves {:.2}); {near} of {} nearer than {threshold:.2} mm",
        mean(to_training.iter().copied()),
        mean(own.iter().copied()),
        draws.len()
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let num = |i: usize, d: usize| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(d);
    let mut params: AsmgParams =
        serde_json::from_str(args.get(4).map_or("{}", String::as_str)).expect("params JSON");
    let (count, seed) = (num(0, 40), num(1, 1) as u64);
    params.epochs_graph = num(2, params.epochs_graph);
    params.epochs_vae = num(3, params.epochs_vae);
    let meshes = aligned_meshes(count, seed, &params);
    println!(
        "meshes: {count}, mean volume {:.1} ml, {:.0} vertices",
        mean(meshes.iter().map(volume_ml)),
        mean(meshes.iter().map(|m| m.vertex_count() as f64))
    );
    let samples: Vec<GraphSample> = meshes
        .iter()
        .map(|m| GraphSample::from_mesh(m, params.features.features()))
        .collect();
    let psi = train_psi(&samples, &params, seed);
    let embeddings = embeddings_of(&psi, &samples, 8).expect("embeddings");
    let nearest = initial_atlas(
        &AtlasInit::Auto {
            target_vertices: params.atlas_vertices,
        },
        &meshes,
    )
    .expect("atlas");
    let atlas = simplified(&nearest, params.atlas_vertices).expect("atlas");
    let atlas_z = embed_mesh(&psi, &atlas, &params).expect("atlas embeddings");
    let smoother = Smoother::new(&atlas, params.smoothing()).expect("smoother");
    println!("initial atlas: {:.1} ml\n", volume_ml(&atlas));
    println!(
        "| temperature | λ | vol h ml (slope on the meshes') | vol h' ml (slope) | coverage | match weight | HD h'–X | CD h'–X |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let temperatures = [
        ("1/var ×1", Temperature::InverseVariance { multiplier: 1.0 }),
        (
            "1/var ×30",
            Temperature::InverseVariance { multiplier: 30.0 },
        ),
        (
            "1/var ×120",
            Temperature::InverseVariance { multiplier: 120.0 },
        ),
        (
            "1/var ×300",
            Temperature::InverseVariance { multiplier: 300.0 },
        ),
        ("fixed 1e3", Temperature::Fixed(1e3)),
        ("fixed 1e4", Temperature::Fixed(1e4)),
    ];
    for (label, t) in temperatures {
        report_temperature(label, &atlas, &atlas_z, &meshes, &embeddings, t, &smoother);
    }

    report_hard_matches(&atlas, &atlas_z, &meshes, &embeddings);

    let inputs: Vec<ShapeInput<'_>> = embeddings
        .iter()
        .zip(&meshes)
        .map(|(e, m)| ShapeInput {
            embeddings: e,
            positions: &m.vertices,
        })
        .collect();
    let started = Instant::now();
    let learned = learn_atlas(
        atlas.clone(),
        &inputs,
        &params.atlas_loop(),
        |a| embed_mesh(&psi, a, &params),
        |s| {
            println!(
                "atlas step {}: moved {:.3} mm (max {:.3}), match weight {:.3}",
                s.step, s.movement_mm, s.max_movement_mm, s.mean_match_weight
            );
            Ok(())
        },
    )
    .expect("atlas loop");
    let faces = &learned.atlas.faces;
    let volume_of = |v: &[[f64; 3]]| volume_ml(&Mesh::new(v.to_vec(), faces.clone()));
    println!(
        "atlas loop {:.1} s: atlas {:.1} ml, h' {:.1} ml",
        started.elapsed().as_secs_f64(),
        volume_ml(&learned.atlas),
        mean(learned.smoothed.iter().map(|h| volume_of(h)))
    );

    let shapes: Vec<Vec<f32>> = learned.smoothed.iter().map(|h| flatten_f32(h)).collect();
    let config =
        BetaVaeConfig::new(3 * learned.atlas.vertex_count()).with_latent(params.latent_dim);
    let unflatten = |s: &Vec<f32>| -> Vec<[f64; 3]> {
        s.chunks_exact(3)
            .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
            .collect()
    };
    let spread = |v: &[f64]| {
        let m = mean(v.iter().copied());
        (m, mean(v.iter().map(|x| (x - m).powi(2))).sqrt())
    };
    let h_volumes: Vec<f64> = learned.smoothed.iter().map(|h| volume_of(h)).collect();
    let (hm, hs) = spread(&h_volumes);
    let mesh_volumes: Vec<f64> = meshes.iter().map(volume_ml).collect();
    let (mm, ms) = spread(&mesh_volumes);
    println!(
        "h' volumes {hm:.1} ± {hs:.1} ml (meshes {mm:.1} ± {ms:.1} ml; slope on the meshes' {:.2})",
        slope(&h_volumes, &mesh_volumes)
    );
    let betas: Vec<f64> = std::env::var("BETAS")
        .ok()
        .map(|b| b.split(',').filter_map(|x| x.parse().ok()).collect())
        .unwrap_or_else(|| vec![params.beta]);
    for beta in betas {
        let training = BetaVaeTraining {
            epochs: std::env::var("EPOCHS_VAE")
                .ok()
                .and_then(|e| e.parse().ok())
                .unwrap_or(params.epochs_vae),
            batch_size: params.batch_size_vae,
            lr: params.lr,
            beta,
            seed,
            ..BetaVaeTraining::default()
        };
        let started = Instant::now();
        let generator = train_beta_vae(&shapes, &config, &training, &mut Unmonitored).expect("VAE");
        let recon = generator.reconstruct(&shapes).expect("reconstruct");
        let rms: f64 = mean(recon.iter().zip(&shapes).map(|(r, s)| {
            (r.iter()
                .zip(s)
                .map(|(a, b)| f64::from(a - b).powi(2))
                .sum::<f64>()
                / s.len() as f64
                * 3.0)
                .sqrt()
        }));
        let prior = generator.aggregate_prior(&shapes).expect("prior");
        let codes: Vec<Vec<f32>> = generator
            .sample_codes(count.max(100), seed)
            .iter()
            .map(|e| prior.code(e))
            .collect();
        let draws = generator.decode(&codes).expect("decode");
        let independent = cohortforge::nn::LatentPrior {
            mixing: Vec::new(),
            ..prior.clone()
        };
        let independent_codes: Vec<Vec<f32>> = generator
            .sample_codes(count.max(100), seed)
            .iter()
            .map(|e| independent.code(e))
            .collect();
        let independent_draws = generator.decode(&independent_codes).expect("decode");
        let iv: Vec<f64> = independent_draws
            .iter()
            .map(|s| volume_of(&unflatten(s)))
            .collect();
        let (im, is) = spread(&iv);
        println!("draws with independent latent dimensions: {im:.1} ± {is:.1} ml");
        report_draw_novelty(&shapes, &independent_draws);
        let rv: Vec<f64> = recon.iter().map(|s| volume_of(&unflatten(s))).collect();
        let dv: Vec<f64> = draws.iter().map(|s| volume_of(&unflatten(s))).collect();
        let ((rm, rs), (dm, ds)) = (spread(&rv), spread(&dv));
        report_draw_novelty(&shapes, &draws);
        println!(
            "β {beta:e}, {} epochs, batch {}: {:.1} s, final loss {:.3}; reconstruction RMS {rms:.2} mm, volumes {rm:.1} ± {rs:.1} ml; draws {dm:.1} ± {ds:.1} ml",
            training.epochs,
            params.batch_size_vae,
            started.elapsed().as_secs_f64(),
            generator.losses.last().copied().unwrap_or(f64::NAN)
        );
    }
}
