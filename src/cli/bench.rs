//! `cohortforge bench`: fits each model type on the same split of phantoms with known ground
//! truth, and measures quality (thesis tables 4.4–4.7), speed, memory and the fidelity of
//! the synthetic volume distribution to the generator's own.

use std::path::PathBuf;
use std::time::Instant;

use super::bench_clusters::ClusterBench;
use super::bench_conditional::bench_conditional;
use super::bench_models::{BenchModel, ModelEntry, bench_models, parse_model_entry};
use super::bench_privacy::held_out_privacy;
use super::bench_report::{
    BenchReport, BiomarkerDistance, CohortBench, FitBench, ModelBench, ReferenceFidelity,
    RenderBench, SpecificityBench, VolumeFidelity, print_markdown,
};
use super::memory::{self, StepMemory};
use super::progress::StderrProgress;
use super::{CliResult, write_json};
use crate::eval::SummaryStats;
use crate::eval::acceptance::joint_acceptance_rates;
use crate::eval::fidelity::Fidelity;
use crate::eval::gaussian_reference::{
    GAUSSIAN_REFERENCE_DRAWS, distance_quantile, gaussian_joint_acceptance,
};
use crate::geometry::pca::Sampling;
use crate::jobs::fit::fit_model;
use crate::mesh::measures::volume_ml;
use crate::mesh::{Mesh, phantom};
use crate::models::cohort::{CohortSpec, Criterion, TrainingIndex, sample_cohort};
use crate::models::evaluation::evaluate;
use crate::models::progress::Stages;
use crate::models::{FitInput, ModelError, ShapeModel};

/// Added to the bench seed for the fresh phantoms of the fidelity check, so that they are
/// not the training or test subjects.
pub const FIDELITY_SEED_OFFSET: u64 = 0xf1de_117e;

/// Times the cohort is drawn; the fastest counts.
const COHORT_TIMINGS: usize = 3;

/// Arguments of `cohortforge bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Phantom family: `lv`, `liver` or `mixed`.
    #[arg(long)]
    pub family: phantom::Family,
    /// Training phantoms.
    #[arg(long, default_value_t = 100)]
    pub train: usize,
    /// Test phantoms (held out from every fit).
    #[arg(long, default_value_t = 25)]
    pub test: usize,
    /// Models to compare, comma-separated: `TYPE` or `TYPE:LABEL` (e.g.
    /// `rsmp,asmg:sgcn,asmg:hgcn`); the label, else the type, names the model in the output.
    #[arg(long, value_delimiter = ',', value_parser = parse_model_entry, default_value = "rsmp")]
    pub models: Vec<ModelEntry>,
    /// Parameters as `LABEL=JSON` for one labelled model or `TYPE=JSON` for the models of a
    /// type without their own (repeatable; defaults otherwise).
    #[arg(long = "params", value_name = "KEY=JSON")]
    pub params: Vec<String>,
    /// Random seed of the phantoms, the fits and the samples.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Members of the cohort timed and judged for acceptance and fidelity.
    #[arg(long, default_value_t = 1000)]
    pub cohort_size: usize,
    /// Samples of the timed specificity evaluation against the training meshes.
    #[arg(long, default_value_t = 1000)]
    pub specificity_samples: usize,
    /// Fresh phantoms whose exact volumes stand for the generator's distribution.
    #[arg(long, default_value_t = 200)]
    pub fidelity_phantoms: usize,
    /// Simplify every phantom to about this many vertices first, as a dataset with
    /// `target_vertices` does on upload (fewer vertices: a smaller template or atlas).
    #[arg(long)]
    pub target_vertices: Option<usize>,
    /// JSON file to write every figure to.
    #[arg(long)]
    pub json: PathBuf,
}

/// The phantoms every model sees.
struct BenchData {
    training: Vec<Mesh>,
    test: Vec<Mesh>,
    /// Exact volumes of fresh phantoms, ml.
    fresh_volumes: Vec<f64>,
    /// Biomarkers of the fresh phantoms' meshes.
    fresh_biomarkers: Vec<crate::eval::biomarkers::Biomarkers>,
    /// Sub-population of each training phantom (labelled families).
    labels: Option<Vec<String>>,
}

fn check(args: &BenchArgs) -> CliResult {
    let positive = [
        ("--train", args.train),
        ("--cohort-size", args.cohort_size),
        ("--specificity-samples", args.specificity_samples),
        ("--fidelity-phantoms", args.fidelity_phantoms),
        ("--models", args.models.len()),
    ];
    match positive.iter().find(|(_, n)| *n == 0) {
        Some((flag, _)) => Err(format!("{flag} must be at least 1")),
        None => Ok(()),
    }
}

/// Runs `cohortforge bench`.
pub fn run(args: &BenchArgs) -> CliResult {
    check(args)?;
    let started = Instant::now();
    let benched = bench_models(&args.models, &args.params)?;
    eprintln!(
        "generating {} + {} {} phantoms (seed {})",
        args.train, args.test, args.family, args.seed
    );
    let mut phantoms = simplified(
        phantom::generate(args.family, args.train + args.test, args.seed),
        args.target_vertices,
    )?;
    let test_phantoms = phantoms.split_off(args.train.min(phantoms.len()));
    let fidelity_seed = args.seed.wrapping_add(FIDELITY_SEED_OFFSET);
    let fresh = simplified(
        phantom::generate(args.family, args.fidelity_phantoms, fidelity_seed),
        args.target_vertices,
    )?;
    let labels: Option<Vec<String>> = phantoms
        .iter()
        .map(|p| match &p.params.shape {
            phantom::ShapeParams::Mixed(m) => Some(m.sub_population().as_str().to_owned()),
            _ => None,
        })
        .collect();
    let data = BenchData {
        labels,
        training: phantoms.iter().map(|p| p.mesh.clone()).collect(),
        test: test_phantoms.into_iter().map(|p| p.mesh).collect(),
        fresh_volumes: fresh.iter().map(|p| p.params.volume_ml).collect(),
        fresh_biomarkers: fresh
            .iter()
            .map(|p| crate::eval::biomarkers::Biomarkers::from_mesh(&p.mesh))
            .collect::<Result<_, _>>()
            .map_err(|e| e.to_string())?,
    };
    drop(fresh);
    let exact: Vec<f64> = phantoms.iter().map(|p| p.params.volume_ml).collect();
    let measured: Vec<f64> = data.training.iter().map(volume_ml).collect();
    let text = |e: crate::eval::EvalError| e.to_string();
    let reference = ReferenceFidelity {
        phantoms: args.fidelity_phantoms,
        seed: fidelity_seed,
        volumes: SummaryStats::from_values(&data.fresh_volumes).map_err(text)?,
        training_exact_volumes: SummaryStats::from_values(&exact).map_err(text)?,
        training_measured_volumes: SummaryStats::from_values(&measured).map_err(text)?,
        training_exact: Fidelity::between(&exact, &data.fresh_volumes).map_err(text)?,
        training_measured: Fidelity::between(&measured, &data.fresh_volumes).map_err(text)?,
    };
    drop(phantoms);
    let mut models = Vec::new();
    let mut peak_mib = memory::resident().map_or(0.0, |r| r.peak_mib);
    for model in &benched {
        let bench = bench_model(model, &data, args)?;
        let steps = [
            bench.fit.memory,
            bench.cohort.memory,
            bench.specificity.memory,
        ];
        for m in steps.iter().flatten() {
            peak_mib = peak_mib.max(m.peak_mib);
        }
        models.push(bench);
    }
    let report = BenchReport {
        family: args.family.as_str().to_owned(),
        train: data.training.len(),
        test: data.test.len(),
        seed: args.seed,
        vertex_counts: vertex_range(&data.training, &data.test),
        fidelity_reference: reference,
        models,
        process_peak_mib: memory::resident().map(|r| r.peak_mib.max(peak_mib)),
        total_seconds: started.elapsed().as_secs_f64(),
    };
    write_json(&args.json, &report)?;
    print_markdown(&report);
    Ok(())
}

/// The phantoms with their meshes simplified to about `target` vertices (unchanged without
/// a target); their exact volumes stay those of the generator.
fn simplified(
    phantoms: Vec<phantom::Phantom>,
    target: Option<usize>,
) -> Result<Vec<phantom::Phantom>, String> {
    let Some(target) = target else {
        return Ok(phantoms);
    };
    let meshes = crate::eval::metrics::parallel_map(&phantoms, |p| {
        crate::mesh::simplify::simplify(&p.mesh, target).map(|s| s.mesh)
    });
    phantoms
        .into_iter()
        .zip(meshes)
        .map(|(p, mesh)| {
            Ok(phantom::Phantom {
                mesh: mesh.map_err(|e| format!("simplifying a phantom: {e}"))?,
                ..p
            })
        })
        .collect()
}

fn vertex_range(training: &[Mesh], test: &[Mesh]) -> [usize; 2] {
    let counts = training.iter().chain(test).map(Mesh::vertex_count);
    let min = counts.clone().min().unwrap_or(0);
    [min, counts.max().unwrap_or(0)]
}

fn bench_model(
    benched: &BenchModel,
    data: &BenchData,
    args: &BenchArgs,
) -> Result<ModelBench, String> {
    let (name, params) = (benched.name.as_str(), &benched.params);
    eprintln!("fitting {name} on {} meshes", data.training.len());
    let mut progress = StderrProgress::new(name);
    let started = Instant::now();
    let (outcome, fit_memory) = memory::measure(|| {
        let input = FitInput::new(&data.training, &data.test, args.seed);
        fit_model(params, &input, &mut progress)
    });
    let outcome = outcome.map_err(|e| e.to_string())?;
    let fit = FitBench {
        seconds: started.elapsed().as_secs_f64(),
        stages: outcome.summary.timings.clone(),
        epochs: progress.epoch_timings(),
        memory: fit_memory,
    };
    let stored = &outcome.model;
    let model = stored.model.as_ref();
    let aligned = stored.training.to_f64();

    eprintln!("{name}: sampling a cohort of {}", args.cohort_size);
    let spec = CohortSpec {
        size: args.cohort_size,
        seed: args.seed,
        sampling: Sampling::Gaussian,
        criterion: Criterion::Mean,
        only_accepted: false,
        exclude_near_copies: false,
        max_draws: 20 * args.cohort_size,
    };
    let normalised = stored.training.normalised_f64();
    let draw = || -> Result<_, ModelError> {
        let index = TrainingIndex::new(&normalised, &stored.training.privacy)?;
        sample_cohort(model, &outcome.reference, &index, &spec)
    };
    let started = Instant::now();
    let (cohort, cohort_memory) = memory::measure(draw);
    let (members, report) = cohort.map_err(|e| e.to_string())?;
    // The same cohort twice more: the fastest of three runs is the least disturbed by
    // whatever else the machine does.
    let mut seconds = started.elapsed().as_secs_f64();
    for _ in 1..COHORT_TIMINGS {
        let started = Instant::now();
        draw().map_err(|e| e.to_string())?;
        seconds = seconds.min(started.elapsed().as_secs_f64());
    }
    let volumes: Vec<f64> = members.iter().map(|m| m.biomarkers.volume_ml).collect();
    let render = members.first().map(|m| time_render(&m.mesh));
    let conditional = bench_conditional(
        model,
        &outcome.reference,
        &normalised,
        &stored.training.privacy,
        &spec,
        &members,
    );
    let clusters = outcome.summary.clusters.as_ref().map(|c| {
        let biomarkers: Vec<_> = members.iter().map(|m| m.biomarkers).collect();
        ClusterBench::new(
            c,
            data.labels.as_deref(),
            &outcome.reference.values,
            &biomarkers,
            &data.fresh_biomarkers,
        )
    });
    let member_columns =
        crate::models::cohort::columns(&members.iter().map(|m| &m.biomarkers).collect::<Vec<_>>());
    drop(members);
    eprintln!(
        "{name}: {} held-out meshes against the near-copy threshold",
        data.test.len()
    );
    let held_out_privacy =
        held_out_privacy(model, &data.test, &normalised, &stored.training.privacy)?;
    let text = |e: crate::eval::EvalError| e.to_string();
    let fresh_columns =
        crate::models::cohort::columns(&data.fresh_biomarkers.iter().collect::<Vec<_>>());
    let intervals = outcome.reference.intervals();
    let fidelity = VolumeFidelity {
        synthetic: SummaryStats::from_values(&volumes).map_err(text)?,
        fidelity: Fidelity::between(&volumes, &data.fresh_volumes).map_err(text)?,
        fresh_acceptance: joint_acceptance_rates(&intervals, &fresh_columns).map_err(text)?,
        training_acceptance: joint_acceptance_rates(&intervals, &outcome.reference.values)
            .map_err(text)?,
        gaussian_acceptance: gaussian_joint_acceptance(
            &intervals,
            &outcome.reference.values,
            GAUSSIAN_REFERENCE_DRAWS,
            args.seed,
        )
        .map_err(text)?,
        distance: BiomarkerDistance {
            cohort: distance_quantile(&outcome.reference.values, &member_columns, 0.95)
                .map_err(text)?,
            fresh: distance_quantile(&outcome.reference.values, &fresh_columns, 0.95)
                .map_err(text)?,
            training: distance_quantile(&outcome.reference.values, &outcome.reference.values, 0.95)
                .map_err(text)?,
        },
    };
    let cohort = CohortBench {
        size: args.cohort_size,
        seconds,
        members_per_second: args.cohort_size as f64 / seconds.max(f64::MIN_POSITIVE),
        memory: cohort_memory,
        report,
        render,
        conditional,
    };
    let faces: Vec<&[[u32; 3]]> = data.training.iter().map(|m| m.faces.as_slice()).collect();
    let specificity = time_specificity(model, &aligned, &faces, args)?;
    Ok(ModelBench {
        model: name.to_owned(),
        model_type: benched.model_type.as_str().to_owned(),
        params: params.to_json(),
        n_modes: outcome.summary.n_modes,
        fit,
        evaluation: outcome.summary.evaluation,
        cohort,
        fidelity,
        held_out_privacy,
        specificity,
        clusters,
    })
}

/// Times specificity of `args.specificity_samples` samples against the training meshes,
/// vertex-to-vertex and point-to-surface.
fn time_specificity(
    model: &dyn ShapeModel,
    aligned: &[Vec<[f64; 3]>],
    faces: &[&[[u32; 3]]],
    args: &BenchArgs,
) -> Result<SpecificityBench, String> {
    let n = args.specificity_samples;
    eprintln!(
        "specificity of {n} samples against {} training meshes",
        aligned.len()
    );
    let mut stages = Stages::new(&[("specificity", 1.0)]);
    stages.enter("specificity");
    let mut progress = StderrProgress::new("specificity");
    let started = Instant::now();
    let (evaluation, memory): (_, Option<StepMemory>) = memory::measure(|| {
        evaluate(
            model,
            aligned,
            faces,
            &[],
            &[],
            n,
            args.seed,
            &stages,
            &mut progress,
        )
    });
    let evaluation = evaluation.map_err(|e| e.to_string())?;
    Ok(SpecificityBench {
        samples: n,
        training_meshes: aligned.len(),
        seconds: started.elapsed().as_secs_f64(),
        memory,
        vertex_to_vertex: evaluation.specificity,
        point_to_surface: evaluation.point_to_surface.map(|s| s.specificity),
    })
}

/// Milliseconds per view of one picture of `mesh` (240 px panels), averaged over the views.
fn time_render(mesh: &Mesh) -> RenderBench {
    use crate::report::render::{View, pictures};
    let started = Instant::now();
    for view in View::ALL {
        let _ = pictures::members(
            "bench",
            &[(0, mesh)],
            Some(view),
            pictures::DEFAULT_PANEL_PX,
        );
    }
    RenderBench {
        vertices: mesh.vertex_count(),
        ms_per_view: 1e3 * started.elapsed().as_secs_f64() / View::ALL.len() as f64,
    }
}
