use super::*;

fn sd(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

/// Points on a line through (10, 0) along x: training sd 2 mm, draws sd 1 mm around 11.
fn line(values: &[f64], offset: f64) -> Vec<Vec<f32>> {
    values
        .iter()
        .map(|v| vec![(10.0 + offset + v) as f32, 0.0])
        .collect()
}

#[test]
fn narrow_draws_get_the_training_mean_and_spread_along_its_mode() {
    let training = line(&[-2.0, 2.0, -2.0, 2.0, 0.0, 0.0], 0.0);
    let (_, train_sd) = sd(&training.iter().map(|x| f64::from(x[0])).collect::<Vec<_>>());
    let drawn = line(&[-1.0, 1.0, -1.0, 1.0, 0.0, 0.0], 1.0);
    let c = SpreadCalibration::fit(&training, None, &drawn).unwrap();
    assert_eq!(c.mode_count(), 1);
    let calibrated: Vec<f64> = drawn
        .iter()
        .map(|d| {
            let mut d = d.clone();
            c.apply(&mut d);
            assert!(d[1].abs() < 1e-5, "nothing moves off the mode");
            f64::from(d[0])
        })
        .collect();
    let (mean, spread) = sd(&calibrated);
    assert!((mean - 10.0).abs() < 1e-4, "mean {mean}");
    assert!(
        (spread - train_sd).abs() < 1e-4,
        "sd {spread} vs {train_sd}"
    );
}

/// Training shapes vary along x (var 8/3 mm²) and y (var 2/3), uncorrelated; the draws
/// vary along x − y and x + y, so a per-mode gain gives every mode the right sd but
/// leaves the coordinates correlated (cov −0.8), and x + y (a stand-in for a volume)
/// then varies less than in the training shapes: 1.32 against 1.83.
#[test]
fn correlated_draws_get_the_training_covariance_on_the_modes() {
    let points = |p: &[(f32, f32)]| p.iter().map(|&(x, y)| vec![x, y]).collect::<Vec<_>>();
    let training = points(&[(-2.0, 0.0), (2.0, 0.0), (0.0, -1.0), (0.0, 1.0)]);
    let drawn = points(&[(1.0, -1.0), (-1.0, 1.0), (0.5, 0.5), (-0.5, -0.5)]);
    let c = SpreadCalibration::fit(&training, None, &drawn).unwrap();
    assert_eq!(c.mode_count(), 2);
    let calibrated: Vec<Vec<f64>> = drawn
        .iter()
        .map(|d| {
            let mut d = d.clone();
            c.apply(&mut d);
            d.iter().map(|&v| f64::from(v)).collect()
        })
        .collect();
    let n = calibrated.len() as f64;
    let cov = |a: usize, b: usize| {
        let (ma, mb) = (
            calibrated.iter().map(|p| p[a]).sum::<f64>() / n,
            calibrated.iter().map(|p| p[b]).sum::<f64>() / n,
        );
        calibrated
            .iter()
            .map(|p| (p[a] - ma) * (p[b] - mb))
            .sum::<f64>()
            / (n - 1.0)
    };
    assert!((cov(0, 0) - 8.0 / 3.0).abs() < 1e-4, "{}", cov(0, 0));
    assert!((cov(1, 1) - 2.0 / 3.0).abs() < 1e-4, "{}", cov(1, 1));
    assert!(cov(0, 1).abs() < 1e-4, "{}", cov(0, 1));
    let sums: Vec<f64> = calibrated.iter().map(|p| p[0] + p[1]).collect();
    let (_, spread) = sd(&sums);
    assert!((spread - (10.0f64 / 3.0).sqrt()).abs() < 1e-4, "{spread}");
    // Models stored before the transform existed scale each mode by its gain.
    let per_mode = SpreadCalibration {
        transform: None,
        ..c
    };
    let mut shape = drawn[0].clone();
    per_mode.apply(&mut shape);
    let expected = [per_mode.gain[0], per_mode.gain[1]];
    let along: Vec<f32> = per_mode
        .modes
        .iter()
        .map(|u| u[0] * shape[0] + u[1] * shape[1])
        .collect();
    for (got, want) in along.iter().zip(expected) {
        assert!(
            (got.abs() - want.abs()).abs() < 1e-4,
            "{along:?} vs {expected:?}"
        );
    }
}

/// A calibration stored before the transform existed reads back without one (and so
/// keeps calibrating by per-mode gains).
#[test]
fn calibrations_stored_without_a_transform_still_read() {
    #[derive(Serialize)]
    struct Stored {
        mean: Vec<f32>,
        modes: Vec<Vec<f32>>,
        drawn_mean: Vec<f32>,
        gain: Vec<f32>,
        residual_gain: f32,
    }
    let stored = Stored {
        mean: vec![1.0, 2.0],
        modes: vec![vec![1.0, 0.0]],
        drawn_mean: vec![0.5],
        gain: vec![2.0],
        residual_gain: 0.5,
    };
    let bytes = crate::models::stored::encode_named(&stored).unwrap();
    let read: SpreadCalibration = crate::models::stored::decode_named(&bytes).unwrap();
    assert_eq!(read.transform, None);
    assert_eq!(read.gain, vec![2.0]);
    let mut shape = vec![2.0f32, 3.0];
    read.apply(&mut shape);
    // x: 1 + (1 − 0.5)·2 = 2; y: what lies off the mode, 1 from the mean, halved.
    assert_eq!(shape, vec![2.0, 2.5]);
}

#[test]
fn what_lies_off_the_modes_is_left_as_drawn() {
    let training = line(&[-2.0, 2.0, -1.0, 1.0], 0.0);
    let drawn = line(&[-1.0, 1.0, 0.0], 0.0);
    let c = SpreadCalibration::fit(&training, None, &drawn).unwrap();
    let mut off = vec![10.0f32, 3.0];
    c.apply(&mut off);
    assert!((off[1] - 3.0).abs() < 1e-6);
    // Draws that vary off the modes more than the training shapes are pulled in: the
    // training shapes vary only along x.
    let noisy: Vec<Vec<f32>> = [(-1.0, 1.0), (1.0, -1.0), (0.0, 0.0), (0.5, 2.0)]
        .iter()
        .map(|(x, y)| vec![10.0 + x, *y])
        .collect();
    let c = SpreadCalibration::fit(&training, None, &noisy).unwrap();
    assert!(c.residual_gain < 1e-3, "{}", c.residual_gain);
    let mut shape = noisy[3].clone();
    c.apply(&mut shape);
    assert!(shape[1].abs() < 1e-2, "{shape:?}");
    // A shape of another width is not touched.
    let mut other = vec![1.0f32; 3];
    c.apply(&mut other);
    assert_eq!(other, vec![1.0; 3]);
}

#[test]
fn weights_choose_whose_spread_is_matched_and_gains_are_bounded() {
    // Heavy weights on the two outer shapes: a wider weighted spread than equal weights.
    let training = line(&[-3.0, 3.0, -0.5, 0.5], 0.0);
    let drawn = line(&[-1.0, 1.0, 0.0], 0.0);
    let equal = SpreadCalibration::fit(&training, None, &drawn).unwrap();
    let outer = SpreadCalibration::fit(&training, Some(&[1.0, 1.0, 0.01, 0.01]), &drawn).unwrap();
    assert!(outer.gain[0] > equal.gain[0]);
    let still = line(&[0.0, 0.0, 0.0], 0.0);
    let flat = SpreadCalibration::fit(&training, None, &still).unwrap();
    assert_eq!(flat.gain[0], MAX_GAIN as f32);
    assert!(SpreadCalibration::fit(&training[..2], None, &drawn).is_none());
}
