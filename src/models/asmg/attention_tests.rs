use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::*;
use crate::mesh::phantom::{Family, subject};

fn random_embeddings(rows: usize, dim: usize, seed: u64) -> Embeddings {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let data = (0..rows * dim)
        .map(|_| StandardNormal.sample(&mut rng))
        .collect();
    Embeddings::new(rows, dim, data).unwrap()
}

fn emb(rows: usize, dim: usize, values: &[f64]) -> Embeddings {
    Embeddings::from_f64(rows, dim, values).unwrap()
}

#[test]
fn two_input_vertices_split_by_hand() {
    // Scores 1 and 0; λ = ln 3 gives weights 3/4 and 1/4.
    let atlas = emb(1, 2, &[2.0, 0.0]);
    let shape = emb(2, 2, &[1.0, 0.0, 0.0, 5.0]);
    let positions = [[4.0, 0.0, 0.0], [0.0, 8.0, 0.0]];
    let c = correspond(&atlas, &shape, &positions, Temperature::Fixed(3f64.ln())).unwrap();
    let h = c.normalised[0];
    assert!((h[0] - 3.0).abs() < 1e-6 && (h[1] - 2.0).abs() < 1e-6 && h[2] == 0.0);
    assert_eq!(c.matches[0].index, 0);
    assert!((c.matches[0].weight - 0.75).abs() < 1e-6);
}

#[test]
fn moments_and_inverse_variance_by_hand() {
    // Cosine scores 1, 0, −1, 0: mean 0, variance 1/2.
    let atlas = emb(1, 2, &[1.0, 0.0]);
    let shape = emb(4, 2, &[1.0, 0.0, 0.0, 1.0, -3.0, 0.0, 0.0, 2.0]);
    let m = score_moments(&atlas, &shape).unwrap();
    assert_eq!(m.count, 4);
    assert!(m.mean.abs() < 1e-7);
    assert!((m.variance - 0.5).abs() < 1e-7);
    let t = Temperature::InverseVariance { multiplier: 2.0 };
    assert!((inverse_temperature(&atlas, &shape, t).unwrap() - 4.0).abs() < 1e-6);
    assert_eq!(
        inverse_temperature(&atlas, &shape, Temperature::Fixed(7.0)).unwrap(),
        7.0
    );
}

#[test]
fn attention_rows_sum_to_one() {
    let atlas = random_embeddings(40, 8, 1);
    let shape = random_embeddings(70, 8, 2);
    for temperature in [
        Temperature::InverseVariance { multiplier: 1.0 },
        Temperature::default(),
        Temperature::Fixed(500.0),
    ] {
        let lambda = inverse_temperature(&atlas, &shape, temperature).unwrap();
        let phi = attention_rows(&atlas, &shape, lambda, 0..40).unwrap();
        assert_eq!(phi.len(), 40 * 70);
        for row in phi.chunks_exact(70) {
            let sum: f64 = row.iter().sum();
            assert!((sum - 1.0).abs() < 1e-12, "row sum {sum}");
            assert!(row.iter().all(|&w| (0.0..=1.0).contains(&w)));
        }
    }
    // A sharper temperature concentrates the rows.
    let mean_row_max = |lambda: f64| {
        let phi = attention_rows(&atlas, &shape, lambda, 0..40).unwrap();
        phi.chunks_exact(70)
            .map(|r| r.iter().copied().fold(0.0, f64::max))
            .sum::<f64>()
            / 40.0
    };
    let soft = inverse_temperature(
        &atlas,
        &shape,
        Temperature::InverseVariance { multiplier: 1.0 },
    )
    .unwrap();
    assert!(mean_row_max(soft) < 0.5 * mean_row_max(500.0));
}

#[test]
fn normalised_shape_is_the_attention_weighted_mean() {
    // Large enough to run on several threads; compared with a dense f64 computation.
    let atlas = random_embeddings(200, 16, 3);
    let shape = random_embeddings(300, 16, 4);
    let positions: Vec<[f64; 3]> = (0..300)
        .map(|i| [i as f64, (i * i % 17) as f64, -(i as f64) / 3.0])
        .collect();
    let t = Temperature::InverseVariance { multiplier: 5.0 };
    let c = correspond(&atlas, &shape, &positions, t).unwrap();
    let phi = attention_rows(&atlas, &shape, c.lambda, 0..200).unwrap();
    for (j, row) in phi.chunks_exact(300).enumerate() {
        let mut h = [0.0; 3];
        for (w, x) in row.iter().zip(&positions) {
            for d in 0..3 {
                h[d] += w * x[d];
            }
        }
        for (a, b) in h.iter().zip(c.normalised[j]) {
            assert!((a - b).abs() < 1e-9);
        }
        let best = row
            .iter()
            .enumerate()
            .fold(0, |b, (i, w)| if *w > row[b] { i } else { b });
        assert_eq!(c.matches[j].index as usize, best);
        assert!((c.matches[j].weight - row[best]).abs() < 1e-12);
    }
    // Same inputs, same result, bit for bit.
    assert_eq!(c, correspond(&atlas, &shape, &positions, t).unwrap());
}

#[test]
fn a_permuted_copy_is_unpermuted_with_a_sharp_temperature() {
    let mesh = subject(Family::Lv, 5, 0).mesh;
    let n = mesh.vertex_count();
    let atlas = random_embeddings(n, 32, 6);
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(7));
    // Input vertex i is atlas vertex order[i], with its embedding.
    let mut data = Vec::with_capacity(n * 32);
    for &o in &order {
        data.extend_from_slice(&atlas.data[o * 32..(o + 1) * 32]);
    }
    let shape = Embeddings::new(n, 32, data).unwrap();
    let positions: Vec<[f64; 3]> = order.iter().map(|&o| mesh.vertices[o]).collect();
    let c = correspond(&atlas, &shape, &positions, Temperature::Fixed(2000.0)).unwrap();
    let mut inverse = vec![0; n];
    for (i, &o) in order.iter().enumerate() {
        inverse[o] = i;
    }
    for (j, (m, h)) in c.matches.iter().zip(&c.normalised).enumerate() {
        assert_eq!(m.index as usize, inverse[j]);
        assert!(m.weight > 1.0 - 1e-9);
        for (a, b) in h.iter().zip(mesh.vertices[j]) {
            assert!((a - b).abs() < 1e-6);
        }
    }
}

#[test]
fn identical_embeddings_give_the_centroid() {
    let atlas = emb(2, 3, &[1.0, 1.0, 0.0, 1.0, 1.0, 0.0]);
    let shape = emb(3, 3, &[2.0, 2.0, 0.0, 2.0, 2.0, 0.0, 3.0, 3.0, 0.0]);
    let positions = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 6.0, 3.0]];
    let c = correspond(&atlas, &shape, &positions, Temperature::default()).unwrap();
    assert_eq!(c.lambda, 0.0);
    for h in &c.normalised {
        assert!((h[0] - 1.0).abs() < 1e-12 && (h[1] - 2.0).abs() < 1e-12);
        assert!((h[2] - 1.0).abs() < 1e-12);
    }
}

#[test]
fn mismatched_inputs_are_errors() {
    let atlas = random_embeddings(4, 3, 8);
    let shape = random_embeddings(5, 3, 9);
    let other = random_embeddings(5, 4, 9);
    let p = vec![[0.0; 3]; 5];
    let t = Temperature::default();
    assert!(matches!(
        correspond(&atlas, &other, &p, t),
        Err(ModelError::InvalidInput(_))
    ));
    assert!(correspond(&atlas, &shape, &p[..4], t).is_err());
    assert!(correspond(&atlas, &shape, &p, Temperature::Fixed(-1.0)).is_err());
    let t0 = Temperature::InverseVariance { multiplier: 0.0 };
    assert!(correspond(&atlas, &shape, &p, t0).is_err());
    assert!(attention_rows(&atlas, &shape, 1.0, 2..5).is_err());
}

/// Time of attention + h for N_μ = 1,000, N_k = 2,000, d = 128 (run with `--ignored`).
#[test]
#[ignore = "timing report, not a check"]
fn time_attention_1000_by_2000() {
    let atlas = random_embeddings(1000, 128, 10);
    let shape = random_embeddings(2000, 128, 11);
    let positions: Vec<[f64; 3]> = (0..2000).map(|i| [i as f64, 0.0, 1.0]).collect();
    let best_ms = |f: &dyn Fn()| {
        (0..5)
            .map(|_| {
                let start = std::time::Instant::now();
                f();
                start.elapsed().as_secs_f64() * 1e3
            })
            .fold(f64::MAX, f64::min)
    };
    let moments = best_ms(&|| {
        assert!(score_moments(&atlas, &shape).unwrap().variance > 0.0);
    });
    println!("score moments pass, 1000 x 2000 x 128: {moments:.1} ms (best of 5)");
    for temperature in [Temperature::default(), Temperature::Fixed(30.0)] {
        let ms = best_ms(&|| {
            let c = correspond(&atlas, &shape, &positions, temperature).unwrap();
            assert_eq!(c.normalised.len(), 1000);
        });
        println!("attention + h, 1000 x 2000 x 128, {temperature:?}: {ms:.1} ms (best of 5)");
    }
}
