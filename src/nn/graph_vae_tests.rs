//! Checks of Ψ: shapes on a batch of different-sized graphs, the loss formula, training,
//! reproducibility and the weight round trip.

use super::*;
use crate::mesh::fixtures::{cube, uv_sphere};
use crate::nn::device::{STREAM_INIT, inference_device, rng};
use crate::nn::graph::{Features, GraphBatch, GraphSample};
use crate::nn::graph_vae_train::{GraphVaeTraining, TrainedGraphVae, train_graph_vae};
use crate::nn::train::{Flow, Monitor, Unmonitored};

fn small_config(d_x: usize) -> GraphVaeConfig {
    GraphVaeConfig::new()
        .with_d_x(d_x)
        .with_hidden(vec![8, 12])
        .with_d_z(4)
        .with_heads(2)
}

/// Spheres of different radii and resolutions, off-centre.
fn toy_shapes(features: Features) -> Vec<GraphSample> {
    [(10.0, 4, 6), (12.0, 5, 6), (9.0, 4, 8), (11.0, 5, 7)]
        .iter()
        .map(|&(r, rings, segments)| {
            GraphSample::from_mesh(&uv_sphere(r, [5.0, 0.0, -3.0], rings, segments), features)
        })
        .collect()
}

fn values(t: Tensor<2>) -> Vec<f32> {
    t.into_data().iter::<f32>().collect()
}

#[test]
fn a_batch_of_two_graphs_of_different_sizes_has_the_right_shapes() {
    let device = inference_device();
    let (a, b) = (
        GraphSample::from_mesh(&cube(), Features::Spatial),
        GraphSample::from_mesh(&uv_sphere(5.0, [0.0; 3], 3, 5), Features::Spatial),
    );
    let batch = GraphBatch::new(&[&a, &b], &PositionScaling::IDENTITY);
    assert_eq!(batch.node_count(), 8 + 12);
    let config = small_config(3);
    let model = config.init(PositionScaling::IDENTITY, &mut rng(1, STREAM_INIT), &device);
    let g = batch.tensors(&device);
    let (mu, log_sigma) = model.encode(batch.feature_tensor(&device), &g);
    assert_eq!(mu.dims(), [20, 4]);
    assert_eq!(log_sigma.dims(), [20, 4]);
    let x_hat = model.decode(mu, &g);
    assert_eq!(x_hat.dims(), [20, 3]);
    assert_eq!(model.encoder.len(), 2);
    assert_eq!(model.decoder.len(), 2);
    assert_eq!(model.decoder[0].conv.dims(), (2, 4, 12));
    assert_eq!(model.output.dims(), (2, 8, 3));
}

#[test]
fn loss_is_the_documented_sum() {
    // With zero noise z = μ, so the loss can be recomputed from encode and decode.
    let device = inference_device();
    let samples = toy_shapes(Features::Hybrid);
    let batch = GraphBatch::new(&[&samples[0], &samples[1]], &PositionScaling::IDENTITY);
    let model = small_config(6).init(PositionScaling::IDENTITY, &mut rng(2, STREAM_INIT), &device);
    let g = batch.tensors(&device);
    let x = batch.feature_tensor(&device);
    let n = batch.node_count();
    let weights = LossWeights {
        kl: 0.3,
        normals: 0.7,
    };
    let loss = model.loss(x.clone(), &g, Tensor::zeros([n, 4], &device), 2, weights);
    let loss = f64::from(loss.into_scalar::<f32>());

    let (mu, ls) = model.encode(x.clone(), &g);
    let x_hat = values(model.decode(mu.clone(), &g));
    let (mu, ls, x) = (values(mu), values(ls), values(x));
    let rec: f64 = x_hat
        .iter()
        .zip(&x)
        .map(|(a, b)| 0.5 * f64::from(a - b).powi(2))
        .sum();
    let kl: f64 = mu
        .iter()
        .zip(&ls)
        .map(|(&m, &l)| {
            let (m, l) = (f64::from(m), f64::from(l));
            -l + 0.5 * (m * m + (2.0 * l).exp()) - 0.5
        })
        .sum();
    let normal: f64 = x_hat
        .chunks(6)
        .map(|r| 1.0 - r[3..].iter().map(|v| f64::from(*v).powi(2)).sum::<f64>())
        .sum();
    let expected = (rec + 0.3 * kl + 0.7 * normal) / 2.0;
    assert!(
        (loss - expected).abs() < 1e-4 * expected.abs().max(1.0),
        "{loss} vs {expected}"
    );
}

fn quick(epochs: usize, seed: u64) -> GraphVaeTraining {
    GraphVaeTraining {
        epochs,
        batch_size: 2,
        lr: 5e-3,
        seed,
        ..GraphVaeTraining::default()
    }
}

#[test]
fn training_lowers_the_loss() {
    let samples = toy_shapes(Features::Spatial);
    let trained =
        train_graph_vae(&samples, &small_config(3), &quick(40, 3), &mut Unmonitored).unwrap();
    assert_eq!(trained.losses.len(), 40);
    let (first, last) = (trained.losses[0], trained.losses[39]);
    assert!(last < 0.5 * first, "loss {first} -> {last}");
    let z = trained.embed(&samples[1]).unwrap();
    assert_eq!(z.len(), samples[1].vertex_count() * 4);
    assert!(z.iter().all(|v| v.is_finite()));
}

#[test]
fn same_seed_same_weights_and_losses() {
    let samples = toy_shapes(Features::Hybrid);
    let config = small_config(6);
    let a = train_graph_vae(&samples, &config, &quick(3, 7), &mut Unmonitored).unwrap();
    let b = train_graph_vae(&samples, &config, &quick(3, 7), &mut Unmonitored).unwrap();
    let c = train_graph_vae(&samples, &config, &quick(3, 8), &mut Unmonitored).unwrap();
    assert_eq!(a.losses, b.losses);
    assert_eq!(a.to_bytes().unwrap(), b.to_bytes().unwrap());
    assert_ne!(a.losses, c.losses);
    assert_ne!(a.to_bytes().unwrap(), c.to_bytes().unwrap());
}

#[test]
fn weights_round_trip_through_bytes() {
    let samples = toy_shapes(Features::Spatial);
    let config = small_config(3);
    let trained = train_graph_vae(&samples, &config, &quick(2, 1), &mut Unmonitored).unwrap();
    let bytes = trained.to_bytes().unwrap();
    let loaded = TrainedGraphVae::from_bytes(&config, &bytes).unwrap();
    assert_eq!(loaded.to_bytes().unwrap(), bytes);
    assert_eq!(
        loaded.embed(&samples[2]).unwrap(),
        trained.embed(&samples[2]).unwrap()
    );
    assert_eq!(
        loaded.reconstruct(&samples[0]).unwrap(),
        trained.reconstruct(&samples[0]).unwrap()
    );

    let wider = config.clone().with_d_z(5);
    assert_eq!(
        TrainedGraphVae::from_bytes(&wider, &bytes)
            .unwrap_err()
            .code(),
        "nn.weights"
    );
    assert_eq!(
        TrainedGraphVae::from_bytes(&config, &bytes[..bytes.len() / 2])
            .unwrap_err()
            .code(),
        "nn.weights"
    );
}

#[test]
fn embedding_many_equals_embedding_one_by_one() {
    // Eval-mode batch norm uses running statistics, so graphs do not influence each other.
    let samples = toy_shapes(Features::Spatial);
    let trained =
        train_graph_vae(&samples, &small_config(3), &quick(2, 4), &mut Unmonitored).unwrap();
    let many = trained.embed_many(&samples).unwrap();
    for (s, z) in samples.iter().zip(&many) {
        let one = trained.embed(s).unwrap();
        for (a, b) in one.iter().zip(z) {
            assert!((a - b).abs() < 1e-5);
        }
    }
}

struct CancelAfter(usize);

impl Monitor for CancelAfter {
    fn batch(&mut self) -> Flow {
        self.0 = self.0.saturating_sub(1);
        if self.0 == 0 {
            Flow::Cancel
        } else {
            Flow::Continue
        }
    }
    fn epoch(&mut self, _: usize, _: usize, _: f64) -> Flow {
        Flow::Continue
    }
}

#[test]
fn bad_input_and_cancellation_are_errors() {
    let samples = toy_shapes(Features::Spatial);
    let err =
        train_graph_vae(&samples, &small_config(6), &quick(1, 0), &mut Unmonitored).unwrap_err();
    assert_eq!(err.code(), "nn.dimension_mismatch");
    let err = train_graph_vae(&[], &small_config(3), &quick(1, 0), &mut Unmonitored).unwrap_err();
    assert_eq!(err.code(), "nn.empty_dataset");
    let err = train_graph_vae(
        &samples,
        &small_config(3).with_hidden(vec![]),
        &quick(1, 0),
        &mut Unmonitored,
    )
    .unwrap_err();
    assert_eq!(err.code(), "nn.invalid_config");
    let err = train_graph_vae(
        &samples,
        &small_config(3),
        &quick(3, 0),
        &mut CancelAfter(3),
    )
    .unwrap_err();
    assert_eq!(err, NnError::Cancelled);
}

#[test]
fn trained_networks_can_be_shared_between_threads() {
    fn shareable<T: Send + Sync>() {}
    shareable::<TrainedGraphVae>();
    shareable::<crate::nn::TrainedBetaVae>();
}
