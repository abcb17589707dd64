//! Checks of the beta-VAE: training, reproducibility, sampling and the weight round trip.

use super::*;
use crate::nn::train::Unmonitored;

/// 12 ellipses of 20 points (z = 0.5·x) with semi-axes 20–31 mm and 10–15 mm, in mm.
fn toy_shapes() -> Vec<Vec<f32>> {
    (0..12)
        .map(|k| {
            let (a, b) = (20.0 + k as f32, 10.0 + 0.5 * (k % 11) as f32);
            (0..20)
                .flat_map(|i| {
                    let t = i as f32 * std::f32::consts::TAU / 20.0;
                    [a * t.cos(), b * t.sin(), 0.5 * a * t.cos()]
                })
                .collect()
        })
        .collect()
}

fn config() -> BetaVaeConfig {
    BetaVaeConfig::new(60)
        .with_hidden(vec![32, 16])
        .with_latent(2)
}

fn quick(epochs: usize, seed: u64) -> BetaVaeTraining {
    BetaVaeTraining {
        epochs,
        batch_size: 4,
        lr: 3e-3,
        lr_step: 40,
        beta: 1e-3,
        seed,
        ..BetaVaeTraining::default()
    }
}

#[test]
fn training_lowers_the_loss_and_reconstructs() {
    let shapes = toy_shapes();
    let trained = train_beta_vae(&shapes, &config(), &quick(120, 1), &mut Unmonitored).unwrap();
    let (first, last) = (trained.losses[0], *trained.losses.last().unwrap());
    assert!(last < 0.2 * first, "loss {first} -> {last}");
    let rec = trained.reconstruct(&shapes[3..4]).unwrap();
    let rms = (rec[0]
        .iter()
        .zip(&shapes[3])
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f32>()
        / 60.0)
        .sqrt();
    assert!(rms < 3.0, "reconstruction rms {rms} mm");
    let z = trained.encode_mean(&shapes).unwrap();
    assert_eq!((z.len(), z[0].len()), (12, 2));
}

#[test]
fn same_seed_same_model_and_samples() {
    let shapes = toy_shapes();
    let a = train_beta_vae(&shapes, &config(), &quick(4, 9), &mut Unmonitored).unwrap();
    let b = train_beta_vae(&shapes, &config(), &quick(4, 9), &mut Unmonitored).unwrap();
    let c = train_beta_vae(&shapes, &config(), &quick(4, 10), &mut Unmonitored).unwrap();
    assert_eq!(a.losses, b.losses);
    assert_eq!(a.to_bytes().unwrap(), b.to_bytes().unwrap());
    assert_ne!(a.to_bytes().unwrap(), c.to_bytes().unwrap());
    assert_eq!(a.sample(3, 5), b.sample(3, 5));
    assert_ne!(a.sample(3, 5), a.sample(3, 6));
    let s = a.sample(3, 5);
    assert_eq!((s.len(), s[0].len()), (3, 60));
}

#[test]
fn weights_round_trip_through_bytes() {
    let shapes = toy_shapes();
    let trained = train_beta_vae(&shapes, &config(), &quick(3, 2), &mut Unmonitored).unwrap();
    let bytes = trained.to_bytes().unwrap();
    let loaded = TrainedBetaVae::from_bytes(&config(), &bytes).unwrap();
    assert_eq!(loaded.to_bytes().unwrap(), bytes);
    assert_eq!(loaded.sample(2, 1), trained.sample(2, 1));
    assert_eq!(
        loaded.encode_mean(&shapes[..2]).unwrap(),
        trained.encode_mean(&shapes[..2]).unwrap()
    );
    let other = config().with_latent(3);
    assert_eq!(
        TrainedBetaVae::from_bytes(&other, &bytes)
            .unwrap_err()
            .code(),
        "nn.weights"
    );
}

#[test]
fn bad_input_is_rejected() {
    let mut shapes = toy_shapes();
    assert_eq!(
        train_beta_vae(&[], &config(), &quick(1, 0), &mut Unmonitored)
            .unwrap_err()
            .code(),
        "nn.empty_dataset"
    );
    shapes[2].pop();
    let err = train_beta_vae(&shapes, &config(), &quick(1, 0), &mut Unmonitored).unwrap_err();
    assert_eq!(err.code(), "nn.dimension_mismatch");
    let bad = BetaVaeTraining {
        beta: -1.0,
        ..quick(1, 0)
    };
    assert_eq!(
        train_beta_vae(&toy_shapes(), &config(), &bad, &mut Unmonitored)
            .unwrap_err()
            .code(),
        "nn.invalid_config"
    );
}

#[test]
fn a_latent_prior_maps_standard_draws_to_codes() {
    let prior = LatentPrior {
        centre: vec![1.0, 2.0],
        spread: vec![2.0, 0.5],
        mixing: Vec::new(),
    };
    assert_eq!(prior.code(&[1.0, -2.0]), vec![3.0, 1.0]);
    assert_eq!(LatentPrior::standard(2).code(&[0.3, -1.0]), vec![0.3, -1.0]);
}

#[test]
fn a_latent_prior_with_a_covariance_keeps_the_correlation() {
    // var 4 and 1, correlation 0.9: the Cholesky factor is [[2, 0], [0.9, √0.19]].
    let covariance = nalgebra::DMatrix::from_row_slice(2, 2, &[4.0, 1.8, 1.8, 1.0]);
    let prior = LatentPrior::with_covariance(vec![1.0, -1.0], &covariance);
    assert_eq!(prior.spread, vec![2.0, 1.0]);
    let code = prior.code(&[1.0, 1.0]);
    assert!((code[0] - 3.0).abs() < 1e-6, "{code:?}");
    assert!(
        (code[1] - (-1.0 + 0.9 + 0.19f32.sqrt())).abs() < 1e-6,
        "{code:?}"
    );
}

/// Standard deviation of the largest `x` (the semi-axis `a`) over flattened shapes.
fn spread_of_semi_axis(shapes: &[Vec<f32>]) -> f64 {
    let a: Vec<f64> = shapes
        .iter()
        .map(|s| {
            s.chunks_exact(3)
                .map(|p| f64::from(p[0]))
                .fold(f64::MIN, f64::max)
        })
        .collect();
    let mean = a.iter().sum::<f64>() / a.len() as f64;
    (a.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
}

#[test]
fn draws_through_the_fitted_prior_vary_like_the_training_shapes() {
    let shapes = toy_shapes();
    let trained = train_beta_vae(&shapes, &config(), &quick(120, 1), &mut Unmonitored).unwrap();
    let prior = trained.aggregate_prior(&shapes).unwrap();
    let means = trained.encode_mean(&shapes).unwrap();
    for d in 0..2 {
        let centre = means.iter().map(|z| z[d]).sum::<f32>() / means.len() as f32;
        assert!((prior.centre[d] - centre).abs() < 1e-4, "dimension {d}");
        assert!(prior.spread[d] > 0.0);
    }
    let codes: Vec<Vec<f32>> = trained
        .sample_codes(200, 3)
        .iter()
        .map(|e| prior.code(e))
        .collect();
    let draws = trained.decode(&codes).unwrap();
    let (training, generated) = (spread_of_semi_axis(&shapes), spread_of_semi_axis(&draws));
    assert!(
        generated > 0.5 * training && generated < 2.0 * training,
        "semi-axis sd {generated:.2} mm against {training:.2} mm in training"
    );
}
