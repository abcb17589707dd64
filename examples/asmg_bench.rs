//! Fit benchmark of a shape model on phantoms, without the HTTP layer: time by stage and
//! per network epoch, evaluation, and acceptance of a cohort as large as the training set.
//!
//! `cargo run --release --example asmg_bench -- [model] [family] [train] [test] [seed] [params]`
//! (defaults: `asmg lv 100 25 1 {}`; `model` is `asmg` or `rsmp`, `family` `lv` or `liver`,
//! `params` a JSON object of job parameters). Run under `/usr/bin/time -v` for peak memory.

use std::time::Instant;

use cohortforge::eval::metrics::{DistanceSummary, IndexedShapes};
use cohortforge::jobs::params::ModelParams;
use cohortforge::mesh::Mesh;
use cohortforge::mesh::measures::volume_ml;
use cohortforge::mesh::phantom::{self, Family};
use cohortforge::models::cohort::{CohortSpec, Criterion, TrainingIndex, sample_cohort};
use cohortforge::models::progress::{Cancelled, Progress, ProgressUpdate};
use cohortforge::models::{FitOutcome, ModelType, asmg, rsmp};

/// Prints every epoch and atlas step with the time since the last one.
struct Printer {
    last: Instant,
    stage: &'static str,
}

impl Progress for Printer {
    fn report(&mut self, u: ProgressUpdate) -> Result<(), Cancelled> {
        let epoch_like = u.message.contains("epoch") || u.message.starts_with("atlas step");
        if epoch_like || u.stage != self.stage {
            eprintln!(
                "[{:>10}] {:7.2} s  {}",
                u.stage,
                self.last.elapsed().as_secs_f64(),
                u.message
            );
            self.last = Instant::now();
            self.stage = u.stage;
        }
        Ok(())
    }
}

fn row(name: &str, d: Option<DistanceSummary>) {
    if let Some(d) = d {
        println!(
            "| {name} | {:.2} ± {:.2} | {:.2} ± {:.2} | {:.2} ± {:.2} | {:.2} |",
            d.hd.mean, d.hd.std, d.ed.mean, d.ed.std, d.ed_star.mean, d.ed_star.std, d.cd.mean
        );
    }
}

fn fit(
    model: ModelType,
    training: &[Mesh],
    holdout: &[Mesh],
    params: &str,
    seed: u64,
) -> FitOutcome {
    let json: serde_json::Value = serde_json::from_str(params).expect("params must be JSON");
    let parsed = ModelParams::parse(model, &json).expect("valid params");
    let mut printer = Printer {
        last: Instant::now(),
        stage: "",
    };
    match parsed {
        ModelParams::Rsmp(p) => rsmp::fit(training, holdout, &p, None, seed, &mut printer),
        ModelParams::Asmg(p) => asmg::fit(training, holdout, &p, None, seed, &mut printer),
    }
    .expect("fit")
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or_else(|| default.into());
    let model = ModelType::from_name(&arg(0, "asmg")).expect("model: asmg or rsmp");
    let family = match arg(1, "lv").as_str() {
        "liver" => Family::Liver,
        _ => Family::Lv,
    };
    let train: usize = arg(2, "100").parse().expect("train count");
    let test: usize = arg(3, "25").parse().expect("test count");
    let seed: u64 = arg(4, "1").parse().expect("seed");
    let params = arg(5, "{}");
    let meshes: Vec<Mesh> = phantom::generate(family, train + test, seed)
        .into_iter()
        .map(|p| p.mesh)
        .collect();
    let (training, holdout) = meshes.split_at(train);
    let started = Instant::now();
    let outcome = fit(model, training, holdout, &params, seed);
    let total = started.elapsed().as_secs_f64();
    println!(
        "## {} on {} {} phantoms ({train} train / {test} holdout, seed {seed}, params {params})\n",
        model.as_str(),
        family.as_str(),
        train + test
    );
    println!("fit {total:.1} s\n\n| stage | seconds |\n|---|---|");
    for t in &outcome.summary.timings {
        println!("| {} | {:.1} |", t.stage, t.seconds);
    }
    println!(
        "\natlas vertices {}\n\n| metric (mm) | HD | ED | ED* | CD |\n|---|---|---|---|---|",
        outcome.summary.atlas.vertex_count
    );
    let e = &outcome.summary.evaluation;
    row("generalisation", e.generalisation);
    row("specificity", Some(e.specificity));
    row("matching", e.matching);

    let stored = &outcome.model;
    let shapes = stored.training.to_f64();
    let index = TrainingIndex {
        shapes: IndexedShapes::new(&shapes).expect("index"),
        privacy: &stored.training.privacy,
    };
    let spec = CohortSpec {
        size: train,
        seed: 7,
        sampling: Default::default(),
        criterion: Criterion::Mean,
        only_accepted: false,
        exclude_near_copies: false,
        max_draws: train,
    };
    let (members, report) = sample_cohort(
        stored.model.shape_model(),
        &outcome.reference,
        &index,
        &spec,
    )
    .expect("cohort");
    let volumes: Vec<f64> = members.iter().map(|m| volume_ml(&m.mesh)).collect();
    let reference_volumes: Vec<f64> = training.iter().map(volume_ml).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    println!(
        "\ncohort of {}: joint acceptance A^r {:.3} A^M {:.3} A^mu {:.3}; volume {:.1} ml \
         (training {:.1} ml)",
        members.len(),
        report.acceptance.range,
        report.acceptance.mode,
        report.acceptance.mean,
        mean(&volumes),
        mean(&reference_volumes)
    );
    if let Some(v) = report.biomarkers.get("volume_ml") {
        println!(
            "volume acceptance A^r {:.3} A^M {:.3} A^mu {:.3}",
            v.acceptance.range, v.acceptance.mode, v.acceptance.mean
        );
    }
}
