//! Cohort sampling throughput with and without the privacy guard's nearest-training search.
//!
//! `cargo run --release --example cohort_timing -- [training meshes] [members] [seed]`
//! (defaults 100, 1000, 1): fits RSMP on LV phantoms (quick registration), then times
//! drawing the members with their biomarkers alone, and a full cohort (biomarkers,
//! acceptance and nearest training shape).

use std::time::Instant;

use cohortforge::mesh::measures::volume_ml;

use cohortforge::eval::biomarkers::Biomarkers;
use cohortforge::geometry::Sampling;
use cohortforge::mesh::phantom::{self, Family};
use cohortforge::models::cohort::{CohortSpec, Criterion, TrainingIndex, draw_rng, sample_cohort};
use cohortforge::models::progress::Silent;
use cohortforge::models::rsmp::RsmpParams;
use cohortforge::models::{FitInput, ModelType};

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let (count, size, seed) = (
        args.first().copied().unwrap_or(100),
        args.get(1).copied().unwrap_or(1000),
        args.get(2).copied().unwrap_or(1) as u64,
    );
    let meshes: Vec<_> = phantom::meshes(Family::Lv, count, seed);
    let params = RsmpParams {
        cpd_max_iterations: 40,
        ..RsmpParams::default()
    };
    let started = Instant::now();
    let params = ModelType::parse_name("rsmp")
        .and_then(|t| t.parse_params(&serde_json::to_value(&params).expect("params")))
        .expect("params");
    let input = FitInput {
        training: &meshes,
        holdout: &[],
        training_laterality: &[],
        holdout_laterality: &[],
        template_indices: &[],
        seed,
    };
    let outcome = params.fit(&input, &mut Silent).expect("fit");
    println!(
        "fit of {count} meshes: {:.1} s",
        started.elapsed().as_secs_f64()
    );
    let stored = outcome.model;
    let model = stored.model.as_ref();
    let atlas = &model.atlases()[0];
    let faces = atlas.faces.clone();
    let h_volumes: Vec<f64> = stored
        .training
        .normalised_f64()
        .swap_remove(0)
        .into_iter()
        .map(|h| volume_ml(&cohortforge::mesh::Mesh::new(h, faces.clone())))
        .collect();
    let raw: f64 = meshes.iter().map(volume_ml).sum::<f64>() / meshes.len() as f64;
    println!(
        "training volume: meshes {raw:.1} ml, normalised shapes {:.1} ml, atlas {:.1} ml",
        h_volumes.iter().sum::<f64>() / h_volumes.len() as f64,
        volume_ml(atlas)
    );

    let started = Instant::now();
    for draw in 0..size as u64 {
        let mesh = model
            .sample(&mut draw_rng(seed, draw), Sampling::Gaussian)
            .expect("sample")
            .mesh;
        Biomarkers::from_mesh(&mesh).expect("biomarkers");
    }
    let plain = started.elapsed().as_secs_f64();

    let shapes = stored.training.normalised_f64();
    let started = Instant::now();
    let training = TrainingIndex::new(&shapes, &stored.training.privacy).expect("shapes");
    let spec = CohortSpec {
        size,
        seed,
        sampling: Sampling::Gaussian,
        criterion: Criterion::Mean,
        only_accepted: false,
        exclude_near_copies: false,
        max_draws: size,
    };
    let (members, report) =
        sample_cohort(model, &outcome.reference, &training, &spec).expect("cohort");
    let full = started.elapsed().as_secs_f64();
    let volume = |name: &str| {
        report
            .biomarkers
            .get(name)
            .map(|b| (b.reference.mean, b.synthetic.mean))
    };
    if let Some((training, cohort)) = volume("volume_ml") {
        println!(
            "volume_ml: training mean {training:.1}, cohort mean {cohort:.1}; joint acceptance A^r {:.3} A^M {:.3} A^mean {:.3}",
            report.acceptance.range, report.acceptance.mode, report.acceptance.mean
        );
    }
    println!(
        "{size} members: draws + biomarkers {plain:.2} s ({:.0}/s, one thread); full cohort {full:.2} s ({:.0}/s); {} near copies (threshold {:.2} mm)",
        size as f64 / plain,
        members.len() as f64 / full,
        report.privacy.near_copies,
        report.privacy.threshold_mm
    );
}
