use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::*;

const D: usize = 30;
const TRUE_VARIANCES: [f64; 4] = [25.0, 9.0, 4.0, 1.0];

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Four orthonormal modes in `R^30` by Gram–Schmidt on seeded random vectors.
fn true_modes(rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    let normal = Normal::new(0.0, 1.0).unwrap();
    let mut modes: Vec<Vec<f64>> = Vec::new();
    while modes.len() < 4 {
        let mut v: Vec<f64> = (0..D).map(|_| normal.sample(rng)).collect();
        for m in &modes {
            let p = dot(&v, m);
            v.iter_mut().zip(m).for_each(|(a, b)| *a -= p * b);
        }
        let n = dot(&v, &v).sqrt();
        modes.push(v.into_iter().map(|a| a / n).collect());
    }
    modes
}

fn synthetic(k: usize, noise_sd: f64, seed: u64) -> (Vec<f64>, Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let modes = true_modes(&mut rng);
    let mean: Vec<f64> = (0..D).map(|j| 10.0 + j as f64).collect();
    let unit = Normal::new(0.0, 1.0).unwrap();
    let samples = (0..k)
        .map(|_| {
            let mut x = mean.clone();
            for (m, l) in modes.iter().zip(TRUE_VARIANCES) {
                let b = l.sqrt() * unit.sample(&mut rng);
                x.iter_mut().zip(m).for_each(|(xj, u)| *xj += b * u);
            }
            x.iter_mut()
                .for_each(|xj| *xj += noise_sd * unit.sample(&mut rng));
            x
        })
        .collect();
    (mean, modes, samples)
}

#[test]
fn recovers_known_modes_and_variances() {
    let (_, truth, samples) = synthetic(2000, 0.05, 1);
    let model = PcaModel::fit(&samples).unwrap();
    for (i, t) in truth.iter().enumerate() {
        let d = dot(&model.modes[i], t).abs();
        assert!(d > 0.99, "mode {i}: |dot| = {d}");
        // Relative sampling error of a variance is about √(2/K) = 3%; allow 3.5 of those.
        let rel = (model.variances[i] - TRUE_VARIANCES[i]).abs() / TRUE_VARIANCES[i];
        assert!(
            rel < 0.11,
            "variance {i}: {} vs {}",
            model.variances[i],
            TRUE_VARIANCES[i]
        );
    }
    // Noise modes: variance ≈ 0.05² each, far below the signal.
    assert!(model.variances[4] < 0.01);
    for (i, a) in model.modes.iter().enumerate() {
        assert!((dot(a, a) - 1.0).abs() < 1e-10);
        for b in &model.modes[i + 1..] {
            assert!(dot(a, b).abs() < 1e-10);
        }
    }
}

#[test]
fn cumulative_explained_is_monotone_and_ends_at_one() {
    let (_, _, samples) = synthetic(200, 0.05, 2);
    let model = PcaModel::fit(&samples).unwrap();
    let c = &model.cumulative_explained;
    assert_eq!(c.len(), D.min(199));
    assert!(c.windows(2).all(|w| w[1] >= w[0]));
    assert!((c[c.len() - 1] - 1.0).abs() < 1e-12);
    // The four signal modes carry ≈ 39 of ≈ 39.075 units of variance.
    assert!(c[3] > 0.99 && c[2] < 0.99);
    let kept = PcaParams {
        n_modes: None,
        variance_target: Some(0.95),
    }
    .select(c);
    assert!(kept == 3 || kept == 4);
    let model = PcaModel::fit_with(
        &samples,
        &PcaParams {
            n_modes: Some(2),
            variance_target: Some(0.99),
        },
    )
    .unwrap();
    assert_eq!(model.n_modes(), 2);
    assert_eq!(model.variances.len(), 2);
    assert_eq!(model.cumulative_explained.len(), D);
}

#[test]
fn reconstruct_of_project_is_identity_in_the_span() {
    let (_, _, samples) = synthetic(50, 0.0, 3);
    let model = PcaModel::fit(&samples).unwrap();
    assert_eq!(model.n_modes(), 4);
    let x = model.reconstruct(&[3.0, -2.0, 1.0, 0.5]).unwrap();
    let b = model.project(&x).unwrap();
    assert_eq!(b.len(), 4);
    for (got, want) in b.iter().zip([3.0, -2.0, 1.0, 0.5]) {
        assert!((got - want).abs() < 1e-9);
    }
    let back = model.reconstruct(&b).unwrap();
    assert!(back.iter().zip(&x).all(|(a, c)| (a - c).abs() < 1e-9));
    // A training sample lies in the span too.
    let s = &samples[7];
    let r = model.reconstruct(&model.project(s).unwrap()).unwrap();
    assert!(r.iter().zip(s).all(|(a, c)| (a - c).abs() < 1e-9));
}

#[test]
fn two_shapes_by_hand() {
    // One point at ±1 on x: mean 0, one mode (1, 0, 0), λ = (1² + 1²)/(2 − 1) = 2.
    let model = PcaModel::fit(&[vec![1.0, 0.0, 0.0], vec![-1.0, 0.0, 0.0]]).unwrap();
    assert_eq!(model.mean, vec![0.0, 0.0, 0.0]);
    assert_eq!(model.n_modes(), 1);
    assert!((model.variances[0] - 2.0).abs() < 1e-12);
    assert!((model.modes[0][0] - 1.0).abs() < 1e-12);
    assert_eq!(model.cumulative_explained, vec![1.0]);
}

#[test]
fn sampling_respects_limits_and_seed() {
    let (_, _, samples) = synthetic(100, 0.0, 4);
    let model = PcaModel::fit(&samples).unwrap();
    for sampling in [Sampling::Gaussian, Sampling::Uniform] {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut second_moment = [0.0; 4];
        let n = 4000;
        for _ in 0..n {
            let b = model.sample_coefficients(&mut rng, sampling);
            for (i, (bi, l)) in b.iter().zip(&model.variances).enumerate() {
                assert!(bi.abs() <= 3.0 * l.sqrt() + 1e-12);
                second_moment[i] += bi * bi / n as f64;
            }
        }
        // Gaussian clipped at 3σ keeps ≈ 98.9% of λ; uniform on ±3√λ has variance 3λ.
        let expected = if sampling == Sampling::Gaussian {
            0.989
        } else {
            3.0
        };
        for (m, l) in second_moment.iter().zip(&model.variances) {
            assert!(
                (m / l - expected).abs() < 0.08 * expected,
                "{sampling:?}: {}",
                m / l
            );
        }
        let a = model.sample(&mut ChaCha8Rng::seed_from_u64(5), sampling);
        let b = model.sample(&mut ChaCha8Rng::seed_from_u64(5), sampling);
        assert_eq!(a, b);
        assert_eq!(a.len(), D);
    }
}

#[test]
fn rejects_bad_input() {
    assert_eq!(
        PcaModel::fit(&[vec![1.0; 3]]).unwrap_err().code(),
        "geometry.too_few_shapes"
    );
    assert_eq!(
        PcaModel::fit(&[vec![1.0; 3], vec![1.0; 6]])
            .unwrap_err()
            .code(),
        "geometry.dimension_mismatch"
    );
    assert_eq!(
        PcaModel::fit(&[vec![1.0; 3], vec![1.0; 3]])
            .unwrap_err()
            .code(),
        "geometry.degenerate_input"
    );
    assert!(
        PcaParams {
            n_modes: Some(0),
            variance_target: None
        }
        .check()
        .is_err()
    );
    assert!(
        PcaParams {
            n_modes: None,
            variance_target: Some(1.5)
        }
        .check()
        .is_err()
    );
    let model = PcaModel::fit(&[vec![1.0, 0.0, 0.0], vec![-1.0, 0.0, 0.0]]).unwrap();
    assert!(model.project(&[0.0; 6]).is_err());
    assert!(model.reconstruct(&[0.0, 1.0]).is_err());
}

#[test]
fn combining_modes_gives_the_same_bits_on_every_cpu_path() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let normal = Normal::new(0.0, 3.0).unwrap();
    let mean: Vec<f64> = (0..301).map(|_| normal.sample(&mut rng)).collect();
    let modes: Vec<Vec<f64>> = (0..7)
        .map(|_| (0..301).map(|_| normal.sample(&mut rng)).collect())
        .collect();
    let b: Vec<f64> = (0..7).map(|_| normal.sample(&mut rng)).collect();
    let plain = combine_baseline(&mean, &modes, &b);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        let wide = unsafe { combine_avx2(&mean, &modes, &b) };
        assert!(
            wide.iter()
                .zip(&plain)
                .all(|(w, p)| w.to_bits() == p.to_bits())
        );
    }
    let expected: f64 = mean[5] + (0..7).map(|i| b[i] * modes[i][5]).sum::<f64>();
    assert!((plain[5] - expected).abs() < 1e-9);
}
