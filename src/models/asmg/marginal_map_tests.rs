use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::*;

fn normals(count: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|_| rng.sample::<f64, _>(StandardNormal))
        .collect()
}

fn moments(values: &[f64]) -> (f64, f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    let skew = values.iter().map(|v| (v - mean).powi(3)).sum::<f64>() / n / var.powf(1.5);
    (mean, var.sqrt(), skew)
}

#[test]
fn knots_by_hand_and_lines_beyond_them() {
    let map = MarginalMap {
        from: vec![0.0, 1.0, 2.0, 3.0, 4.0],
        to: vec![10.0, 20.0, 40.0, 70.0, 110.0],
    };
    assert_eq!(map.apply(1.5), 30.0);
    assert_eq!(map.apply(3.0), 70.0);
    // Below the first knot, along the line through it and the fourth (slope 20).
    assert_eq!(map.apply(-1.0), -10.0);
    // Above the last, along the line through the second and the last (slope 30).
    assert_eq!(map.apply(5.0), 140.0);
}

#[test]
fn the_map_is_monotone() {
    let drawn = normals(2000, 1);
    let training: Vec<f64> = normals(100, 2).iter().map(|z| (0.4 * z).exp()).collect();
    let map = MarginalMap::fit(&drawn, &training, &vec![1.0; 100]).unwrap();
    let mapped: Vec<f64> = (-600..600)
        .map(|k| map.apply(f64::from(k) / 100.0))
        .collect();
    assert!(mapped.windows(2).all(|w| w[1] > w[0]));
}

#[test]
fn symmetric_draws_take_the_skew_mean_and_sd_of_the_training_values() {
    // Training values skewed right (log-normal, skew about 1.3); draws symmetric.
    let training: Vec<f64> = normals(300, 3)
        .iter()
        .map(|z| 100.0 * (0.4 * z).exp())
        .collect();
    let drawn: Vec<f64> = normals(8000, 4).iter().map(|z| 100.0 + 10.0 * z).collect();
    let map = MarginalMap::fit(&drawn, &training, &vec![1.0; training.len()]).unwrap();
    let fresh: Vec<f64> = normals(4000, 5).iter().map(|z| 100.0 + 10.0 * z).collect();
    let mapped: Vec<f64> = fresh.iter().map(|x| map.apply(*x)).collect();
    let (t_mean, t_sd, t_skew) = moments(&training);
    let (m_mean, m_sd, m_skew) = moments(&mapped);
    assert!(t_skew > 0.8, "{t_skew}");
    assert!((m_mean / t_mean - 1.0).abs() < 0.01, "{m_mean} vs {t_mean}");
    assert!((m_sd / t_sd - 1.0).abs() < 0.05, "{m_sd} vs {t_sd}");
    assert!((m_skew - t_skew).abs() < 0.3, "{m_skew} vs {t_skew}");
}

#[test]
fn weights_pick_the_training_values_that_count() {
    // Two groups; weight only on the upper one.
    let training: Vec<f64> = normals(200, 6)
        .iter()
        .enumerate()
        .map(|(i, z)| if i % 2 == 0 { 50.0 + z } else { 150.0 + z })
        .collect();
    let weights: Vec<f64> = (0..200).map(|i| f64::from(i % 2 == 1)).collect();
    let drawn = normals(2000, 7);
    let map = MarginalMap::fit(&drawn, &training, &weights).unwrap();
    assert!((map.apply(0.0) - 150.0).abs() < 0.5, "{}", map.apply(0.0));
}

#[test]
fn degenerate_inputs_give_no_map() {
    let drawn = normals(100, 8);
    assert!(MarginalMap::fit(&drawn, &[5.0; 10], &[1.0; 10]).is_none());
    assert!(MarginalMap::fit(&[1.0; 100], &drawn, &vec![1.0; 100]).is_none());
    assert!(MarginalMap::fit(&drawn, &drawn[..2], &[1.0; 2]).is_none());
    assert!(MarginalMap::fit(&drawn, &drawn, &vec![0.0; 100]).is_none());
}
