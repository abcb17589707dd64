//! Seeded split of a dataset's meshes into training and held-out sets.

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

/// Holds out `round(fraction · n)` of `ids` chosen by `seed` (never one of `keep`, e.g. the
/// template or the atlases). Both parts keep the order of `ids`.
pub fn holdout_split(
    ids: &[String],
    fraction: f64,
    seed: u64,
    keep: &[&str],
) -> (Vec<String>, Vec<String>) {
    let candidates: Vec<usize> = (0..ids.len())
        .filter(|&i| !keep.contains(&ids[i].as_str()))
        .collect();
    let wanted = ((fraction * ids.len() as f64).round() as usize).min(candidates.len());
    let mut shuffled = candidates;
    shuffled.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let held: std::collections::HashSet<usize> = shuffled.into_iter().take(wanted).collect();
    let (mut training, mut holdout) = (Vec::new(), Vec::new());
    for (i, id) in ids.iter().enumerate() {
        if held.contains(&i) {
            holdout.push(id.clone())
        } else {
            training.push(id.clone())
        }
    }
    (training, holdout)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ids(n: usize) -> Vec<String> {
        (0..n).map(|i| format!("m{i}")).collect()
    }

    #[test]
    fn split_sizes_order_and_seed() {
        let (train, hold) = holdout_split(&ids(20), 0.25, 7, &[]);
        assert_eq!((train.len(), hold.len()), (15, 5));
        let mut all: Vec<String> = train.iter().chain(&hold).cloned().collect();
        all.sort();
        let mut expected = ids(20);
        expected.sort();
        assert_eq!(all, expected);
        assert!(
            train
                .windows(2)
                .all(|w| w[0][1..].parse::<u32>().unwrap() < w[1][1..].parse::<u32>().unwrap())
        );
        assert_eq!(
            holdout_split(&ids(20), 0.25, 7, &[]),
            (train.clone(), hold.clone())
        );
        assert_ne!(holdout_split(&ids(20), 0.25, 8, &[]).1, hold);
    }

    #[test]
    fn kept_mesh_stays_in_training() {
        for seed in 0..20 {
            let (train, _) = holdout_split(&ids(4), 0.75, seed, &["m2"]);
            assert!(train.contains(&"m2".to_owned()));
        }
        assert_eq!(holdout_split(&ids(5), 0.0, 1, &[]).1.len(), 0);
    }
}
