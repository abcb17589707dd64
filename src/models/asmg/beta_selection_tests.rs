use super::*;
use crate::models::progress::Silent;

#[test]
fn folds_are_seeded_and_nearly_equal() {
    let folds = fold_of_each_shape(10, 3);
    assert_eq!(folds, fold_of_each_shape(10, 3));
    let sizes: Vec<usize> = (0..FOLDS)
        .map(|f| folds.iter().filter(|&&x| x == f).count())
        .collect();
    // 10 shapes in 4 folds: 3, 3, 2, 2.
    assert_eq!(sizes.iter().sum::<usize>(), 10);
    assert!(sizes.iter().all(|&s| (2..=3).contains(&s)), "{sizes:?}");
    let split = Split::of(&folds, 0);
    assert_eq!(split.held_out.len() + split.training.len(), 10);
    assert!(split.held_out.iter().all(|&k| folds[k] == 0));
    assert!(split.training.iter().all(|&k| folds[k] != 0));
}

#[test]
fn the_search_stops_once_a_larger_beta_generalises_no_better() {
    let c = |beta, near_copy_fraction, holdout_error_mm| BetaCandidate {
        beta,
        near_copy_fraction,
        holdout_error_mm,
    };
    assert!(!stop_after(&[c(1.0, 0.0, 1.0)]));
    assert!(stop_after(&[c(1.0, 0.0, 1.0), c(3.0, 0.0, 1.2)]));
    // Still improving, or the one before copied patients: go on.
    assert!(!stop_after(&[c(1.0, 0.0, 1.0), c(3.0, 0.0, 0.9)]));
    assert!(!stop_after(&[c(1.0, 0.3, 1.0), c(3.0, 0.0, 1.2)]));
}

/// Shapes of 12 vertices: a common shape plus a random offset per shape, mm.
fn population(count: usize, seed: u64) -> Vec<Vec<f32>> {
    use rand::Rng;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|_| {
            let scale: f32 = rng.random_range(0.8..1.2);
            (0..36)
                .map(|i| scale * (i as f32).sin() * 10.0 + rng.random_range(-0.5..0.5))
                .collect()
        })
        .collect()
}

fn small_generator() -> (BetaVaeConfig, BetaVaeTraining) {
    let config = BetaVaeConfig::new(36)
        .with_hidden(vec![32, 16])
        .with_latent(4);
    let training = BetaVaeTraining {
        epochs: 20,
        batch_size: 4,
        beta: 0.5,
        seed: 7,
        ..BetaVaeTraining::default()
    };
    (config, training)
}

fn chosen(shapes: &[Vec<f32>]) -> Option<BetaChoice> {
    let (config, training) = small_generator();
    let mut stages = Stages::new(&[("generator", 1.0)]);
    stages.enter("generator");
    let data = SelectionData {
        shapes,
        weights: None,
        cluster: None,
        measured: &[],
        faces: &[],
        calibration: None,
    };
    choose_beta(&data, &config, &training, &stages, &mut Silent).unwrap()
}

#[test]
fn a_few_shapes_get_beta_chosen_on_folds_reproducibly() {
    let shapes = population(10, 1);
    let choice = chosen(&shapes).expect("10 shapes are few enough to choose on");
    let betas: Vec<f64> = choice.candidates.iter().map(|c| c.beta).collect();
    // Candidates start at the β asked for and grow; the search may stop early.
    assert_eq!(betas[0], 0.5);
    assert!(betas.windows(2).all(|w| w[1] > w[0]), "{betas:?}");
    assert!(betas.contains(&choice.chosen));
    for c in &choice.candidates {
        assert!((0.0..=1.0).contains(&c.near_copy_fraction), "{c:?}");
        assert!(
            c.holdout_error_mm.is_finite() && c.holdout_error_mm > 0.0,
            "{c:?}"
        );
    }
    assert_eq!(
        (choice.folds, choice.draws_per_fold),
        (FOLDS, DRAWS_PER_FOLD)
    );
    assert_eq!(Some(choice), chosen(&shapes), "same seed, same choice");
}

#[test]
fn too_few_or_enough_shapes_keep_beta_as_given() {
    assert!(chosen(&population(CHOOSE_FROM - 1, 2)).is_none());
    assert!(chosen(&population(CHOOSE_BELOW, 2)).is_none());
}
