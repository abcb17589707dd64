//! Checks of FeaStConv against an independent per-edge loop, finite differences and vertex
//! permutations.

use burn::module::Param;
use burn::tensor::{DType, Device, Tensor, TensorData};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::*;
use crate::nn::device::{STREAM_INIT, inference_device, rng, training_device};
use crate::nn::graph::{GraphBatch, GraphSample, PositionScaling};
use crate::nn::init::standard_normal;

/// A random graph on `n` nodes (each pair joined with probability 0.4; the last node has no
/// neighbours) with standard-normal positions.
fn random_graph(n: usize, rng: &mut ChaCha8Rng) -> GraphSample {
    let mut edges = Vec::new();
    for a in 0..n.saturating_sub(1) as u32 {
        for b in a + 1..n.saturating_sub(1) as u32 {
            if rng.random::<f64>() < 0.4 {
                edges.push([a, b]);
            }
        }
    }
    let p = standard_normal(3 * n, rng);
    GraphSample {
        positions: p.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
        normals: None,
        edges,
    }
}

/// A tensor of `values` in double precision.
fn f64_tensor<const D: usize>(values: Vec<f64>, shape: [usize; D], device: &Device) -> Tensor<D> {
    Tensor::from_data(TensorData::new(values, shape), (device, DType::F64))
}

fn values<const D: usize>(t: Tensor<D>) -> Vec<f64> {
    t.into_data().iter::<f64>().collect()
}

/// The layer with every parameter converted to double precision on `device`.
fn to_f64(layer: &FeaStConv, device: &Device) -> FeaStConv {
    FeaStConv {
        weight: Param::from_tensor(f64_tensor(
            values(layer.weight.val()),
            layer.weight.shape().dims(),
            device,
        )),
        steer: Param::from_tensor(f64_tensor(
            values(layer.steer.val()),
            layer.steer.shape().dims(),
            device,
        )),
        steer_offset: Param::from_tensor(f64_tensor(
            values(layer.steer_offset.val()),
            layer.steer_offset.shape().dims(),
            device,
        )),
        bias: Param::from_tensor(f64_tensor(
            values(layer.bias.val()),
            layer.bias.shape().dims(),
            device,
        )),
    }
}

/// The batch's slots and degrees in double precision (`1/|N(i)|` computed in f64).
fn f64_graph(batch: &GraphBatch, device: &Device) -> GraphTensors {
    let mut g = batch.tensors(device);
    let mut count = vec![0.0f64; batch.node_count()];
    for &t in &batch.targets {
        count[t as usize] += 1.0;
    }
    let n = count.len();
    g.inv_degree = f64_tensor(count.iter().map(|c| 1.0 / c).collect(), [n, 1], device);
    g.slot_mask = g.slot_mask.cast(DType::F64);
    g
}

/// Plain per-edge evaluation of the FeaStConv formula, independent of the tensor code.
fn naive(layer: &FeaStConv, x: &[f64], batch: &GraphBatch) -> Vec<f64> {
    let (h, d_in, d_out) = layer.dims();
    let w = values(layer.weight.val());
    let u = values(layer.steer.val());
    let c = values(layer.steer_offset.val());
    let b = values(layer.bias.val());
    let n = batch.node_count();
    let mut sum = vec![0.0; n * d_out];
    let mut count = vec![0usize; n];
    for (&j, &i) in batch.sources.iter().zip(&batch.targets) {
        let (i, j) = (i as usize, j as usize);
        let logits: Vec<f64> = (0..h)
            .map(|m| {
                c[m] + (0..d_in)
                    .map(|k| u[k * h + m] * (x[j * d_in + k] - x[i * d_in + k]))
                    .sum::<f64>()
            })
            .collect();
        let top = logits.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let z: f64 = logits.iter().map(|l| (l - top).exp()).sum();
        for m in 0..h {
            let q = (logits[m] - top).exp() / z;
            for o in 0..d_out {
                let wx: f64 = (0..d_in)
                    .map(|k| x[j * d_in + k] * w[(k * h + m) * d_out + o])
                    .sum();
                sum[i * d_out + o] += q * wx;
            }
        }
        count[i] += 1;
    }
    (0..n * d_out)
        .map(|t| sum[t] / count[t / d_out] as f64 + b[t % d_out])
        .collect()
}

/// A star: vertex 0 joined to the 8 others, and a path 1-2-3; its hub needs several rows of
/// message slots.
fn star() -> GraphSample {
    let mut edges: Vec<[u32; 2]> = (1..9).map(|j| [0, j]).collect();
    edges.extend([[1, 2], [2, 3]]);
    let p = standard_normal(27, &mut rng(4, 4));
    GraphSample {
        positions: p.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
        normals: None,
        edges,
    }
}

/// A layer with 3 heads, a random 7-vertex graph (or the 9-vertex star) and input features.
fn setup(
    d_in: usize,
    d_out: usize,
    seed: u64,
    use_star: bool,
) -> (FeaStConv, GraphBatch, Vec<f64>) {
    let mut r = rng(seed, STREAM_INIT);
    let layer = FeaStConfig::new(d_in, d_out)
        .with_heads(3)
        .init(&mut r, &inference_device());
    let g = if use_star {
        star()
    } else {
        random_graph(7, &mut r)
    };
    let batch = GraphBatch::new(&[&g], &PositionScaling::IDENTITY);
    let x: Vec<f64> = standard_normal(batch.node_count() * d_in, &mut r)
        .into_iter()
        .map(f64::from)
        .collect();
    (layer, batch, x)
}

#[test]
fn output_equals_the_per_edge_loop() {
    for (d_in, d_out, use_star) in [(3, 5, false), (5, 3, false), (4, 4, true)] {
        let device = inference_device();
        let (layer, batch, x) = setup(d_in, d_out, 11, use_star);
        let n = batch.node_count();
        if use_star {
            assert!(
                batch.tensors(&device).row_sources.is_some(),
                "the hub has several rows"
            );
        }
        let layer = to_f64(&layer, &device);
        let y = layer.forward(
            f64_tensor(x.clone(), [n, d_in], &device),
            &f64_graph(&batch, &device),
        );
        let expected = naive(&layer, &x, &batch);
        let got = values(y);
        assert_eq!(got.len(), n * d_out);
        for (g, e) in got.iter().zip(&expected) {
            assert!((g - e).abs() < 1e-12, "{d_in}->{d_out}: {g} vs {e}");
        }
    }
}

#[test]
fn single_precision_matches_the_loop() {
    let device = inference_device();
    let (layer, batch, x) = setup(4, 6, 5, false);
    let xs: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    let y = layer.forward(
        Tensor::from_data(TensorData::new(xs, [7, 4]), &device),
        &batch.tensors(&device),
    );
    for (g, e) in values(y).iter().zip(naive(&layer, &x, &batch)) {
        assert!((g - e).abs() < 1e-5, "{g} vs {e}");
    }
}

/// Loss `Σ r ⊙ y` of the layer at input `x`, in double precision on the plain device.
fn weighted_output(layer: &FeaStConv, x: &[f64], batch: &GraphBatch, r: &[f64]) -> f64 {
    let device = inference_device();
    let d_in = layer.dims().1;
    let y = layer.forward(
        f64_tensor(x.to_vec(), [x.len() / d_in, d_in], &device),
        &f64_graph(batch, &device),
    );
    values(y).iter().zip(r).map(|(a, b)| a * b).sum()
}

/// Replaces entry `k` of the named parameter (0 weight, 1 steer, 2 offset, 3 bias).
fn nudged(layer: &FeaStConv, which: usize, k: usize, delta: f64) -> FeaStConv {
    let device = inference_device();
    let mut out = to_f64(layer, &device);
    let bump = |t: Vec<f64>| {
        let mut t = t;
        t[k] += delta;
        t
    };
    match which {
        0 => {
            out.weight = Param::from_tensor(f64_tensor(
                bump(values(layer.weight.val())),
                layer.weight.shape().dims(),
                &device,
            ))
        }
        1 => {
            out.steer = Param::from_tensor(f64_tensor(
                bump(values(layer.steer.val())),
                layer.steer.shape().dims(),
                &device,
            ))
        }
        2 => {
            out.steer_offset = Param::from_tensor(f64_tensor(
                bump(values(layer.steer_offset.val())),
                layer.steer_offset.shape().dims(),
                &device,
            ))
        }
        _ => {
            out.bias = Param::from_tensor(f64_tensor(
                bump(values(layer.bias.val())),
                layer.bias.shape().dims(),
                &device,
            ))
        }
    }
    out
}

fn assert_close(analytic: &[f64], numeric: &[f64], what: &str) {
    assert_eq!(analytic.len(), numeric.len(), "{what}");
    for (k, (a, n)) in analytic.iter().zip(numeric).enumerate() {
        let tol = 1e-6 * (1.0 + a.abs().max(n.abs()));
        assert!(
            (a - n).abs() < tol,
            "{what}[{k}]: autodiff {a} vs finite difference {n}"
        );
    }
}

#[test]
fn gradients_match_central_finite_differences() {
    const STEP: f64 = 1e-5;
    for (d_in, d_out, use_star) in [(3, 5, false), (5, 3, true)] {
        let (layer, batch, x) = setup(d_in, d_out, 23, use_star);
        let n = batch.node_count();
        let plain = inference_device();
        let layer = to_f64(&layer, &plain);
        let r: Vec<f64> = standard_normal(n * d_out, &mut rng(2, STREAM_INIT))
            .into_iter()
            .map(f64::from)
            .collect();

        // Autodiff gradients.
        let ad = training_device();
        let ad_layer = to_f64(&layer, &ad);
        let xt = f64_tensor(x.clone(), [n, d_in], &ad).require_grad();
        let y = ad_layer.forward(xt.clone(), &f64_graph(&batch, &ad));
        let loss = (y * f64_tensor(r.clone(), [n, d_out], &ad)).sum();
        let grads = loss.backward();
        let gx = values(xt.grad(&grads).unwrap());
        let gparams = [
            values(ad_layer.weight.val().grad(&grads).unwrap()),
            values(ad_layer.steer.val().grad(&grads).unwrap()),
            values(ad_layer.steer_offset.val().grad(&grads).unwrap()),
            values(ad_layer.bias.val().grad(&grads).unwrap()),
        ];

        // Central differences.
        let fx: Vec<f64> = (0..x.len())
            .map(|k| {
                let (mut up, mut down) = (x.clone(), x.clone());
                up[k] += STEP;
                down[k] -= STEP;
                (weighted_output(&layer, &up, &batch, &r)
                    - weighted_output(&layer, &down, &batch, &r))
                    / (2.0 * STEP)
            })
            .collect();
        assert_close(&gx, &fx, "d/dx");
        for (which, analytic) in gparams.iter().enumerate() {
            let numeric: Vec<f64> = (0..analytic.len())
                .map(|k| {
                    let up = weighted_output(&nudged(&layer, which, k, STEP), &x, &batch, &r);
                    let down = weighted_output(&nudged(&layer, which, k, -STEP), &x, &batch, &r);
                    (up - down) / (2.0 * STEP)
                })
                .collect();
            assert_close(analytic, &numeric, ["dW", "du", "dc", "db"][which]);
        }
    }
}

#[test]
fn permuting_vertices_permutes_the_output() {
    let device = inference_device();
    let (layer, _, _) = setup(3, 4, 31, false);
    let g = random_graph(9, &mut rng(31, 9));
    // New vertex k is old vertex perm[k].
    let perm = [4usize, 0, 8, 2, 7, 1, 6, 3, 5];
    let mut inverse = [0u32; 9];
    for (k, &old) in perm.iter().enumerate() {
        inverse[old] = k as u32;
    }
    let permuted = GraphSample {
        positions: perm.iter().map(|&old| g.positions[old]).collect(),
        normals: None,
        edges: g
            .edges
            .iter()
            .map(|e| e.map(|v| inverse[v as usize]))
            .collect(),
    };
    let run = |s: &GraphSample| {
        let b = GraphBatch::new(&[s], &PositionScaling::IDENTITY);
        values(layer.forward(b.feature_tensor(&device), &b.tensors(&device)))
    };
    let (y, yp) = (run(&g), run(&permuted));
    for (k, &old) in perm.iter().enumerate() {
        for o in 0..4 {
            assert!((yp[k * 4 + o] - y[old * 4 + o]).abs() < 1e-5);
        }
    }
    // The isolated vertex (old 8) sees only itself: y = b + Σ_m q_m W_m x (q from c alone).
    assert!(y.iter().all(|v| v.is_finite()));
}
