//! FeaStConv and graph-VAE benchmark.
//!
//! `cargo run --release --example feast_bench [-- --dump-phantom FILE]`
//! (`--features ndarray` for the burn-ndarray backend).
//!
//! 1. One FeaStConv layer, forward + backward, 64 → 64 channels, 8 heads, on a 30 × 50
//!    triangulated torus grid: 1,500 vertices, 9,000 directed edges (+ 1,500 self-loops).
//! 2. Ψ (default sizes, spatial features) forward + backward on one LV phantom, and one full
//!    training step (with Adam).
//!
//! Each figure is the median of 30 runs after 5 warm-up runs. `--dump-phantom` writes the
//! phantom's vertices and edges so `scripts/feast_pyg_bench.py` can time the same graph.

use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams};
use burn::tensor::{Tensor, TensorData};
use cohortforge::mesh::phantom::{self, Family};
use cohortforge::nn::device::{backend_name, training_device};
use cohortforge::nn::graph_vae::LossWeights;
use cohortforge::nn::{
    FeaStConfig, Features, GraphBatch, GraphSample, GraphVaeConfig, PositionScaling,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

const WARM_UP: usize = 5;
const RUNS: usize = 30;
const GRID: (u32, u32) = (30, 50);

/// Median wall time of `f` in ms.
fn median_ms(mut f: impl FnMut()) -> f64 {
    for _ in 0..WARM_UP {
        f();
    }
    let mut times: Vec<f64> = (0..RUNS)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[RUNS / 2]
}

/// A triangulated torus grid: vertex (i, j) joined to (i+1, j), (i, j+1) and (i+1, j+1).
fn torus_grid() -> GraphSample {
    let (a, b) = GRID;
    let id = |i: u32, j: u32| (i % a) * b + (j % b);
    let edges = (0..a)
        .flat_map(|i| {
            (0..b).flat_map(move |j| {
                [
                    [id(i, j), id(i + 1, j)],
                    [id(i, j), id(i, j + 1)],
                    [id(i, j), id(i + 1, j + 1)],
                ]
            })
        })
        .collect();
    GraphSample {
        positions: vec![[0.0; 3]; (a * b) as usize],
        normals: None,
        edges,
    }
}

fn normal(n: usize, rng: &mut ChaCha8Rng) -> Vec<f32> {
    (0..n)
        .map(|_| {
            let v: f64 = StandardNormal.sample(rng);
            v as f32
        })
        .collect()
}

fn bench_layer() {
    let device = training_device();
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let grid = torus_grid();
    let batch = GraphBatch::new(&[&grid], &PositionScaling::IDENTITY);
    let graph = batch.tensors(&device);
    let layer = FeaStConfig::new(64, 64)
        .with_heads(8)
        .init(&mut rng, &device);
    let n = grid.vertex_count();
    let x = Tensor::<2>::from_data(TensorData::new(normal(n * 64, &mut rng), [n, 64]), &device);
    let ms = median_ms(|| {
        let x = x.clone().detach().require_grad();
        let y = layer.forward(x.clone(), &graph);
        let grads = y.sum().backward();
        let g = layer.weight.val().grad(&grads).expect("weight gradient");
        let _ = g.into_data();
        let _ = x.grad(&grads).expect("input gradient").into_data();
    });
    println!(
        "feast_layer backend={} vertices={} edges={} (+{} self-loops) channels=64 heads=8 fwd+bwd median={ms:.2} ms",
        backend_name(),
        n,
        batch.edge_count() - n,
        n
    );
}

fn bench_psi(dump: Option<&str>) {
    let device = training_device();
    let lv = phantom::subject(Family::Lv, 1, 0);
    let sample = GraphSample::from_mesh(&lv.mesh, Features::Spatial);
    if let Some(path) = dump {
        let mut text = String::new();
        for p in &sample.positions {
            text.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
        }
        for e in &sample.edges {
            text.push_str(&format!("e {} {}\n", e[0], e[1]));
        }
        std::fs::write(path, text).expect("write the phantom graph");
    }
    let scaling = PositionScaling::fit(std::slice::from_ref(&sample));
    let batch = GraphBatch::new(&[&sample], &scaling);
    let graph = batch.tensors(&device);
    let config = GraphVaeConfig::new();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut model = config.init(scaling, &mut rng, &device);
    let n = batch.node_count();
    let noise = Tensor::<2>::from_data(
        TensorData::new(normal(n * config.d_z, &mut rng), [n, config.d_z]),
        &device,
    );
    let weights = LossWeights {
        kl: 1e-3,
        normals: 1e-2,
    };
    let x = batch.feature_tensor(&device);
    let fwd_bwd = median_ms(|| {
        let loss = model.loss(x.clone(), &graph, noise.clone(), 1, weights);
        let grads = loss.backward();
        let _ = model
            .output
            .bias
            .val()
            .grad(&grads)
            .expect("gradient")
            .into_data();
    });
    let mut optimizer = AdamConfig::new().init();
    let step = median_ms(|| {
        let loss = model.loss(x.clone(), &graph, noise.clone(), 1, weights);
        let grads = GradientsParams::from_grads(loss.backward(), &model);
        model = optimizer.step(1e-3, model.clone(), grads);
        let _ = model.output.bias.val().into_data();
    });
    println!(
        "psi backend={} lv_phantom vertices={} edges={} params={} fwd+bwd median={fwd_bwd:.1} ms, train step (with Adam) median={step:.1} ms",
        backend_name(),
        n,
        sample.edges.len() * 2,
        model.num_params()
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dump = args
        .iter()
        .position(|a| a == "--dump-phantom")
        .and_then(|i| args.get(i + 1));
    bench_layer();
    bench_psi(dump.map(String::as_str));
}
