//! Where the calibrated draws' volume mean leaves the training meshes': the uncalibrated
//! draws' mean against the calibration's own draws, the targets' mean, and how far the moves
//! land from their targets.

use cohortforge::eval::stats;
use cohortforge::mesh::Mesh;
use cohortforge::models::ShapeModel;
use cohortforge::models::asmg::biomarker_calibration::mesh_biomarkers;
use cohortforge::models::asmg::model::AsmgModel;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Prints the parts of the calibrated draws' (volume, area) bias for `draws` draws seeded
/// from `seed`, against the training meshes `meshes`.
pub fn print_bias(asmg: &AsmgModel, meshes: &[Mesh], draws: usize, seed: u64) {
    let Some(c) = &asmg.biomarker_calibration else {
        return;
    };
    let mut raw = asmg.clone();
    raw.biomarker_calibration = None;
    raw.spread_calibration = None;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let uncalibrated: Vec<Mesh> = (0..draws)
        .map(|_| raw.sample(&mut rng, Default::default()).unwrap().mesh)
        .collect();
    let b: Vec<[f64; 2]> = uncalibrated.iter().map(mesh_biomarkers).collect();
    let targets: Vec<[f64; 2]> = b.iter().map(|b| c.target(b)).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let calibrated: Vec<[f64; 2]> = (0..draws)
        .map(|_| mesh_biomarkers(&asmg.sample(&mut rng, Default::default()).unwrap().mesh))
        .collect();
    let training: Vec<[f64; 2]> = meshes.iter().map(mesh_biomarkers).collect();
    let latent = asmg.sizes.vae_latent;
    let volume_mean = |standard: &[Vec<f64>]| {
        let meshes = raw.decode_standard(0, standard).unwrap();
        stats::mean(
            &meshes
                .iter()
                .map(|m| mesh_biomarkers(m)[0])
                .collect::<Vec<_>>(),
        )
    };
    for antithetic in [false, true] {
        let means: Vec<f64> = (0..8)
            .map(|set| {
                let mut rng = ChaCha8Rng::seed_from_u64(seed + 1000 * (set + 1));
                let standard: Vec<Vec<f64>> = (0..draws / 2)
                    .flat_map(|_| {
                        let e: Vec<f64> = (0..latent)
                            .map(|_| rng.sample::<f64, _>(StandardNormal).clamp(-3.0, 3.0))
                            .collect();
                        let other: Vec<f64> = if antithetic {
                            e.iter().map(|v| -v).collect()
                        } else {
                            (0..latent)
                                .map(|_| rng.sample::<f64, _>(StandardNormal).clamp(-3.0, 3.0))
                                .collect()
                        };
                        [e, other]
                    })
                    .collect();
                volume_mean(&standard)
            })
            .collect();
        println!(
            "uncalibrated volume means of {draws} draws{}: {:?}, mean {:.3} sd {:.3}",
            if antithetic {
                " (antithetic pairs)"
            } else {
                ""
            },
            means
                .iter()
                .map(|m| (m * 100.0).round() / 100.0)
                .collect::<Vec<_>>(),
            stats::mean(&means),
            stats::sample_sd(&means)
        );
    }
    for k in 0..2 {
        let col = |rows: &[[f64; 2]]| rows.iter().map(|r| r[k]).collect::<Vec<_>>();
        let misses: Vec<f64> = calibrated
            .iter()
            .zip(&targets)
            .map(|(b, t)| (b[k] - t[k]) / t[k])
            .collect();
        let far = misses.iter().filter(|m| m.abs() > 1e-3).count();
        println!(
            "{}: training mean {:.2} sd {:.2}, target_mean {:.2}; uncalibrated draws mean \
             {:.2} sd {:.2} (calibration's draws {:.2}); targets mean {:.2} sd {:.2}; \
             calibrated mean {:.2} sd {:.2}; misses mean {:.2e}, {far} beyond 0.1%",
            ["volume", "area"][k],
            stats::mean(&col(&training)),
            stats::sample_sd(&col(&training)),
            c.target_mean[k],
            stats::mean(&col(&b)),
            stats::sample_sd(&col(&b)),
            c.drawn_mean[k],
            stats::mean(&col(&targets)),
            stats::sample_sd(&col(&targets)),
            stats::mean(&col(&calibrated)),
            stats::sample_sd(&col(&calibrated)),
            stats::mean(&misses),
        );
    }
}
