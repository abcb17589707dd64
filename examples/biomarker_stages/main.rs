//! Where a model's members leave the training population in biomarker space.
//!
//! `cargo run --release --example biomarker_stages -- [model] [meshes] [seed] [draws]`
//! (defaults rsmp, 100, 1, 1000): fits the model to LV phantoms (or to the meshes of the
//! directory `MESHES`) and compares the six
//! biomarkers of the training shapes as the model reproduces them (what members are compared
//! with for privacy) and of its draws with those of the training meshes: mean and sd ratios,
//! joint A^μ (and each biomarker's A^μ), and the Mahalanobis distance of each shape's biomarkers from the training mean
//! (which sees a combination no patient has, such as a long axis too long for the volume,
//! where each biomarker alone is inside its interval). `PARAMS='{"beta": 30}'` sets the
//! model's parameters (JSON, as a fit request's `params`); for ASMG models,
//! `TEMPERATURES=1.2,1.5` adds draws whose standard latent coordinates are scaled by each,
//! and `VOLUME_STRETCH=0.95` those draws moved along the training shapes' regression on
//! volume (and on volume and area, and on all six) until their volume sd (and the covariance
//! of those biomarkers) is that share of the training meshes', and the volume-and-area ones
//! then matched rank for rank to a smoothed density of the training meshes' volume and area,
//! and the tempered draws matched rank for rank on volume, area and the extents (with and
//! without sphericity). For `rsmp`, `BANDWIDTHS=0,0.3,0.5` adds draws from a smoothed
//! bootstrap of the training shapes' coefficients and draws whose every mode takes a random
//! training shape's coefficient, each with that kernel width, and every rsmp stage prints its
//! share of near copies; `TRAILING=0.6,0.8` draws each mode up to that share of the variance
//! from its own random training shape and the remaining modes together from one. Last, for
//! each stage, how far the two ends of the long axis lie
//! from the centroid and how far each end's farthest vertex stands out of the next 20.
//! `DUMP=PREFIX` writes the six biomarkers of the training meshes, the reproduced shapes and
//! the draws, one shape a line, to `PREFIX-training.csv`, `PREFIX-reproduced.csv` and
//! `PREFIX-draws.csv`.

use cohortforge::cli::mesh_dir::read_mesh_dir;
use cohortforge::eval::biomarkers::{Biomarkers, ExtentAxes};
use cohortforge::eval::stats;
use cohortforge::mesh::Mesh;
use cohortforge::mesh::phantom::{self, Family};
use cohortforge::models::asmg::calibration::MAX_GAIN;
use cohortforge::models::asmg::model::AsmgModel;
use cohortforge::models::progress::Silent;
use cohortforge::models::rsmp::RsmpModel;
use cohortforge::models::{FitInput, ModelType, ShapeModel};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

mod bias;
mod bootstrap;
mod ends;
mod stretch;
use stretch::{biomarker_stretched, quantile_matched};

pub(crate) fn row(mesh: &Mesh) -> [f64; 6] {
    let b = Biomarkers::measure(mesh, ExtentAxes::Surface).expect("biomarkers");
    [
        b.volume_ml.abs(),
        b.area_cm2,
        b.sphericity,
        b.extent_major_mm,
        b.extent_middle_mm,
        b.extent_minor_mm,
    ]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let model = args.get(1).map(String::as_str).unwrap_or("rsmp");
    let count: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(100);
    let seed: u64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1);
    let draws: usize = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(1000);
    // MESHES=DIR: the meshes of a directory (the first `count`, by name) instead of phantoms.
    let meshes: Vec<Mesh> = match std::env::var("MESHES") {
        Ok(dir) => read_mesh_dir(std::path::Path::new(&dir))
            .expect("a directory of meshes")
            .into_iter()
            .take(count)
            .map(|m| m.mesh)
            .collect(),
        Err(_) => {
            // FAMILY=liver: liver phantoms instead of LV ones.
            let family =
                std::env::var("FAMILY").map_or(Family::Lv, |f| f.parse().expect("a family"));
            phantom::meshes(family, count, seed)
        }
    };
    let input = FitInput {
        training: &meshes,
        holdout: &[],
        training_laterality: &[],
        holdout_laterality: &[],
        template_indices: &[],
        seed,
    };
    let json = std::env::var("PARAMS").map_or(serde_json::Value::Null, |text| {
        serde_json::from_str(&text).expect("PARAMS is JSON")
    });
    let params = ModelType::parse_name(model)
        .unwrap()
        .parse_params(&json)
        .unwrap();
    let outcome = params.fit(&input, &mut Silent).unwrap();
    let stored = &outcome.model;
    let faces = &stored.model.atlases()[0].faces;
    let reproduced: Vec<Mesh> = stored.training.normalised_f64()[0]
        .iter()
        .map(|v| Mesh::new(v.clone(), faces.clone()))
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let drawn: Vec<Mesh> = (0..draws)
        .map(|_| {
            stored
                .model
                .sample(&mut rng, Default::default())
                .unwrap()
                .mesh
        })
        .collect();
    let reference = Reference::new(&meshes.iter().map(row).collect::<Vec<_>>());
    let mean_shape = Mesh::new(
        (0..vertex_count(&reproduced))
            .map(|i| {
                let sum = reproduced.iter().fold([0.0; 3], |s, m| {
                    [
                        s[0] + m.vertices[i][0],
                        s[1] + m.vertices[i][1],
                        s[2] + m.vertices[i][2],
                    ]
                });
                sum.map(|x| x / reproduced.len() as f64)
            })
            .collect(),
        faces.clone(),
    );
    let (_, mean_axis) = major_axis(&mean_shape);
    println!(
        "{model}, {} meshes (seed {seed}); ratios to the training meshes for \
         volume, area, sphericity, major, middle, minor extent; tilt: angle of a shape's long \
         axis to that of the mean reproduced shape",
        meshes.len()
    );
    // The training meshes keep their own poses: no tilt for them.
    reference.print("training meshes", &meshes, None);
    reference.print("reproduced", &reproduced, Some(&mean_axis));
    reference.print("draws", &drawn, Some(&mean_axis));
    // DUMP=PREFIX: the six biomarkers of each stage's shapes as PREFIX-{stage}.csv.
    if let Ok(prefix) = std::env::var("DUMP") {
        for (stage, shapes) in [
            ("training", &meshes),
            ("reproduced", &reproduced),
            ("draws", &drawn),
        ] {
            let text: String = shapes
                .iter()
                .map(|m| row(m).map(|x| x.to_string()).join(",") + "\n")
                .collect();
            std::fs::write(format!("{prefix}-{stage}.csv"), text).expect("DUMP is writable");
        }
    }
    // Draws no farther from the training mean, in biomarker space, than the farthest mesh.
    let farthest = meshes
        .iter()
        .map(|m| reference.radius(&row(m)))
        .fold(0.0, f64::max);
    let within: Vec<Mesh> = drawn
        .iter()
        .filter(|m| reference.radius(&row(m)) <= farthest)
        .cloned()
        .collect();
    reference.print("  within", &within, Some(&mean_axis));
    // The training meshes keep their own poses: either end is "top".
    ends::print_ends("training meshes", &meshes, None);
    ends::print_ends("reproduced", &reproduced, Some(&mean_axis));
    ends::print_ends("draws", &drawn, Some(&mean_axis));
    if let Some(rsmp) = stored.model.as_any().downcast_ref::<RsmpModel>() {
        let near_copies = bootstrap::NearCopies::new(rsmp, &stored.training.normalised_f64()[0]);
        println!("draws near copies {:.1}%", near_copies.percent(&drawn));
        let bandwidths = env_list::<f64>("BANDWIDTHS");
        match bootstrap::standard_coefficients(rsmp) {
            Some(coefficients) => {
                let modes = rsmp.pca.n_modes();
                for h in bandwidths {
                    for (label, independent) in [("bootstrap", 0), ("modewise", modes)] {
                        let d = bootstrap::bootstrap_draws(
                            rsmp,
                            &coefficients,
                            (h, independent),
                            draws,
                            seed,
                        );
                        reference.print(&format!("{label} h {h}"), &d, Some(&mean_axis));
                        println!("  near copies {:.1}%", near_copies.percent(&d));
                    }
                }
                // Modes beyond a share of the variance taken together from one patient.
                for share in env_list::<f64>("TRAILING") {
                    let independent = rsmp
                        .pca
                        .cumulative_explained
                        .iter()
                        .position(|c| *c >= share)
                        .map_or(modes, |k| k + 1);
                    let d = bootstrap::bootstrap_draws(
                        rsmp,
                        &coefficients,
                        (0.0, independent),
                        draws,
                        seed,
                    );
                    let label = format!("modes {independent} of {modes} apart, rest joint");
                    reference.print(&label, &d, Some(&mean_axis));
                    ends::print_ends(&label, &d, Some(&mean_axis));
                    println!("  near copies {:.1}%", near_copies.percent(&d));
                }
            }
            None if !bandwidths.is_empty() => {
                println!("BANDWIDTHS needs a model that stores its training coefficients")
            }
            None => {}
        }
    }
    if let Some(asmg) = stored.model.as_any().downcast_ref::<AsmgModel>() {
        if let Some(d) = affine_draws(asmg, draws, seed) {
            reference.print("draws, affine targets", &d, Some(&mean_axis));
        }
        bias::print_bias(asmg, &meshes, draws, seed);
        for t in env_list::<f32>("TEMPERATURES") {
            let tempered = tempered_draws(asmg, t, draws, seed);
            reference.print(&format!("draws, latent x{t}"), &tempered, Some(&mean_axis));
            if let Some(share) = std::env::var("VOLUME_STRETCH")
                .ok()
                .and_then(|v| v.parse::<f64>().ok())
            {
                let stretched = biomarker_stretched(&reproduced, &tempered, &meshes, share, &[0]);
                reference.print("  volume-stretched", &stretched, Some(&mean_axis));
                let both = biomarker_stretched(&reproduced, &tempered, &meshes, share, &[0, 1]);
                reference.print("  volume+area-stretched", &both, Some(&mean_axis));
                let all = biomarker_stretched(
                    &reproduced,
                    &tempered,
                    &meshes,
                    share,
                    &[0, 1, 2, 3, 4, 5],
                );
                reference.print("  all-six-stretched", &all, Some(&mean_axis));
                let matched = quantile_matched(&reproduced, &both, &meshes, &[0, 1]);
                reference.print("  +quantile-matched", &matched, Some(&mean_axis));
                for columns in [&[0, 1, 3, 4, 5][..], &[0, 1, 2, 3, 4, 5]] {
                    let matched = quantile_matched(&reproduced, &tempered, &meshes, columns);
                    reference.print(
                        &format!("  matched {columns:?}"),
                        &matched,
                        Some(&mean_axis),
                    );
                }
            }
        }
    }
    if let Some(asmg) = stored.model.as_any().downcast_ref::<AsmgModel>()
        && let Some(c) = &asmg.spread_calibration
    {
        let eigenvalues: Vec<f64> = c.transform.as_ref().map_or_else(
            || c.gain.iter().map(|g| f64::from(*g)).collect(),
            |t| {
                let k = t.len();
                DMatrix::from_fn(k, k, |a, b| f64::from(t[a][b]))
                    .symmetric_eigenvalues()
                    .iter()
                    .copied()
                    .collect()
            },
        );
        let (low, high) = eigenvalues
            .iter()
            .fold((f64::MAX, 0.0_f64), |(l, h), e| (l.min(*e), h.max(*e)));
        let bounded = eigenvalues
            .iter()
            .filter(|e| **e >= MAX_GAIN * 0.999)
            .count();
        println!(
            "spread calibration: {} modes, map eigenvalues {low:.2}-{high:.2} ({bounded} at \
                 the bound {MAX_GAIN}), residual gain {:.2}",
            c.mode_count(),
            c.residual_gain
        );
    }
}

/// The same draws with the calibration's affine targets only (no quantile maps), when the
/// model has maps.
fn affine_draws(asmg: &AsmgModel, draws: usize, seed: u64) -> Option<Vec<Mesh>> {
    let mut affine = asmg.clone();
    affine.biomarker_calibration.as_mut()?.shape_maps.take()?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Some(
        (0..draws)
            .map(|_| affine.sample(&mut rng, Default::default()).unwrap().mesh)
            .collect(),
    )
}

/// The comma-separated values of the environment variable `name` (none when unset).
fn env_list<T: std::str::FromStr>(name: &str) -> Vec<T> {
    std::env::var(name).map_or_else(
        |_| Vec::new(),
        |text| {
            text.split(',')
                .filter_map(|t| t.trim().parse().ok())
                .collect()
        },
    )
}

/// ASMG draws whose standard latent coordinates are scaled by `t` before the latent prior
/// (the calibration, if the model has one, applies after decoding).
fn tempered_draws(asmg: &AsmgModel, t: f32, draws: usize, seed: u64) -> Vec<Mesh> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let latent = asmg.sizes.vae_latent;
    let codes: Vec<Vec<f32>> = (0..draws)
        .map(|_| {
            let standard: Vec<f32> = (0..latent)
                .map(|_| t * rng.sample::<f32, _>(StandardNormal).clamp(-3.0, 3.0))
                .collect();
            match &asmg.latent_prior {
                Some(prior) => prior.code(&standard),
                None => standard,
            }
        })
        .collect();
    asmg.decode(&codes).unwrap()
}

pub(crate) fn vertex_count(meshes: &[Mesh]) -> usize {
    meshes.first().map_or(0, |m| m.vertices.len())
}

/// Centroid and unit long axis of a surface (eigenvector of the area-weighted covariance of
/// its triangles with the largest eigenvalue), as the extents are measured.
fn major_axis(mesh: &Mesh) -> (Vector3<f64>, Vector3<f64>) {
    let v = |i: u32| Vector3::from(mesh.vertices[i as usize]);
    let (mut area, mut centroid) = (0.0, Vector3::zeros());
    for f in &mesh.faces {
        let (a, b, c) = (v(f[0]), v(f[1]), v(f[2]));
        let w = 0.5 * (b - a).cross(&(c - a)).norm();
        area += w;
        centroid += w * (a + b + c) / 3.0;
    }
    centroid /= area;
    let mut covariance = Matrix3::zeros();
    for f in &mesh.faces {
        let (a, b, c) = (v(f[0]), v(f[1]), v(f[2]));
        let w = 0.5 * (b - a).cross(&(c - a)).norm();
        for p in [a, b, c] {
            let d = p - centroid;
            covariance += w * d * d.transpose();
        }
    }
    let e = covariance.symmetric_eigen();
    let k = e.eigenvalues.imax();
    (centroid, e.eigenvectors.column(k).into_owned())
}

/// The training meshes' biomarker mean, sd and covariance.
struct Reference {
    mean: DVector<f64>,
    sd: DVector<f64>,
    precision: DMatrix<f64>,
}

impl Reference {
    fn new(rows: &[[f64; 6]]) -> Self {
        let n = rows.len() as f64;
        let x = DMatrix::from_fn(rows.len(), 6, |i, j| rows[i][j]);
        let mean = DVector::from_fn(6, |j, _| x.column(j).sum() / n);
        let centred = DMatrix::from_fn(rows.len(), 6, |i, j| x[(i, j)] - mean[j]);
        let covariance = centred.transpose() * &centred / (n - 1.0);
        let sd = covariance.diagonal().map(f64::sqrt);
        let precision = covariance.try_inverse().expect("invertible covariance");
        Self {
            mean,
            sd,
            precision,
        }
    }

    /// Mahalanobis distance of a biomarker row from the training mean.
    fn radius(&self, r: &[f64; 6]) -> f64 {
        let d = DVector::from_fn(6, |j, _| r[j] - self.mean[j]);
        (d.transpose() * &self.precision * &d)[(0, 0)].sqrt()
    }

    fn print(&self, stage: &str, shapes: &[Mesh], mean_axis: Option<&Vector3<f64>>) {
        let rows: Vec<[f64; 6]> = shapes.iter().map(row).collect();
        let n = rows.len() as f64;
        let column = |j: usize| rows.iter().map(|r| r[j]).collect::<Vec<_>>();
        let ratios = |f: &dyn Fn(&[f64]) -> f64, of: &DVector<f64>| -> String {
            (0..6)
                .map(|j| format!("{:.3}", f(&column(j)) / of[j]))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let inside = rows
            .iter()
            .filter(|r| (0..6).all(|j| (r[j] - self.mean[j]).abs() <= 2.0 * self.sd[j]))
            .count() as f64;
        let per_biomarker = (0..6)
            .map(|j| {
                let kept = rows
                    .iter()
                    .filter(|r| (r[j] - self.mean[j]).abs() <= 2.0 * self.sd[j])
                    .count() as f64;
                format!("{:.1}", 100.0 * kept / n)
            })
            .collect::<Vec<_>>()
            .join(" ");
        let radii = stats::sorted(&rows.iter().map(|r| self.radius(r)).collect::<Vec<_>>());
        let tilt = mean_axis.map_or_else(
            || "-".to_owned(),
            |axis| {
                let tilts = stats::sorted(
                    &shapes
                        .iter()
                        .map(|m| major_axis(m).1.dot(axis).abs().min(1.0).acos().to_degrees())
                        .collect::<Vec<_>>(),
                );
                format!(
                    "mean {:.1}, 90th {:.1} deg",
                    stats::mean(&tilts),
                    stats::quantile_sorted(&tilts, 0.9)
                )
            },
        );
        println!(
            "{stage:15} n {:4}  joint A^mu {:5.1}%  mean {}  sd {}  radius mean {:.2}, 95th \
             {:.2}  tilt {tilt}  A^mu each {per_biomarker}",
            rows.len(),
            100.0 * inside / n,
            ratios(&stats::mean, &self.mean),
            ratios(&stats::sample_sd, &self.sd),
            stats::mean(&radii),
            stats::quantile_sorted(&radii, 0.95),
        );
    }
}
