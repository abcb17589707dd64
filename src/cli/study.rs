//! `cohortforge fit` and `cohortforge evaluate`: the fit jobs' code on directories of mesh
//! files, so that studies can be scripted and compared with other tools.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use super::laterality_file::LateralityFile;
use super::mesh_dir::{NamedMesh, read_mesh_dir};
use super::model_file::{FitInputs, ModelFile};
use super::progress::StderrProgress;
use super::tables::{DISTANCES, MATCHING, acceptance_table, distance_table};
use super::{CliResult, write_json};
use crate::eval::metrics::DistanceSummary;
use crate::geometry::pca::Sampling;
use crate::jobs::fit::fit_model;
use crate::jobs::split::holdout_split;
use crate::mesh::Mesh;
use crate::models::cohort::{CohortReport, CohortSpec, Criterion, TrainingIndex, sample_cohort};
use crate::models::evaluation::evaluate;
use crate::models::progress::Stages;
use crate::models::{Evaluation, FitInput, ModelParams, ModelType, StageTiming};

/// Column labels of the two ways distances are measured.
pub const DISTANCE_KINDS: [&str; 2] = ["vertex-to-vertex", "point-to-surface"];

/// Arguments of `cohortforge fit`.
#[derive(clap::Args, Debug)]
pub struct FitArgs {
    /// Directory of training meshes (every .obj, .stl, .ply, .vtk file, sorted by name).
    #[arg(long)]
    pub train: PathBuf,
    /// Model type, e.g. `rsmp`.
    #[arg(long, value_parser = parse_model_type)]
    pub model: ModelType,
    /// Model parameters as a JSON object (defaults fill the rest); a `template` names a
    /// mesh file (with or without its extension).
    #[arg(long)]
    pub params: Option<String>,
    /// Share of the meshes held out (seeded) to evaluate generalisation and matching.
    #[arg(long, default_value_t = 0.0)]
    pub holdout_fraction: f64,
    /// Random seed; the same seed and meshes give the same model.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Sides of paired-organ meshes: lines `mesh,left` or `mesh,right` (file name with or
    /// without extension). Models with `mirror` take them as given.
    #[arg(long)]
    pub laterality: Option<PathBuf>,
    /// Model file to write.
    #[arg(long)]
    pub out: PathBuf,
}

/// Arguments of `cohortforge evaluate`.
#[derive(clap::Args, Debug)]
pub struct EvaluateArgs {
    /// Model file written by `cohortforge fit`.
    #[arg(long)]
    pub model: PathBuf,
    /// Directory of test meshes (unseen by the fit).
    #[arg(long)]
    pub test: PathBuf,
    /// Samples for specificity and members of the cohort (default: as many as training
    /// meshes).
    #[arg(long)]
    pub samples: Option<usize>,
    /// Seed of the samples and the cohort (default: the model's seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// JSON file to write the results to.
    #[arg(long)]
    pub json: PathBuf,
    /// Sides of paired-organ meshes: lines `mesh,left` or `mesh,right` (file name with or
    /// without extension; names of other meshes, e.g. the training ones, are skipped). Models
    /// with `mirror` take them as given.
    #[arg(long)]
    pub laterality: Option<PathBuf>,
}

/// Parses a model type name for clap.
pub fn parse_model_type(s: &str) -> Result<ModelType, String> {
    ModelType::from_name(s).ok_or_else(|| {
        format!(
            "unknown model type '{s}': use one of {}",
            ModelType::names().join(", ")
        )
    })
}

/// Checks `params` (JSON text, or none for the defaults) for `model_type`.
pub fn parse_params(model_type: ModelType, params: Option<&str>) -> Result<ModelParams, String> {
    let json = match params {
        Some(text) => serde_json::from_str(text).map_err(|e| format!("--params: {e}"))?,
        None => serde_json::Value::Null,
    };
    model_type.parse_params(&json).map_err(|e| e.to_string())
}

/// The file name that `template` names: itself or a name whose stem it is.
fn resolve_template<'a>(template: &str, names: &'a [String]) -> Result<&'a str, String> {
    names
        .iter()
        .find(|n| *n == template || n.rsplit_once('.').is_some_and(|(stem, _)| stem == template))
        .map(String::as_str)
        .ok_or_else(|| format!("params.template: no mesh file named {template}"))
}

fn pick(meshes: &[NamedMesh], names: &[String]) -> Vec<Mesh> {
    names
        .iter()
        .filter_map(|n| meshes.iter().find(|m| &m.name == n))
        .map(|m| m.mesh.clone())
        .collect()
}

/// The sides a `--laterality` file gives (none without one), checked against the mesh
/// files `names`.
fn laterality_of(path: Option<&Path>, names: &[String]) -> Result<LateralityFile, String> {
    let file = path.map_or_else(|| Ok(LateralityFile::default()), LateralityFile::read)?;
    file.check_names(names)?;
    Ok(file)
}

/// Runs `cohortforge fit`.
pub fn fit(args: &FitArgs) -> CliResult {
    let params = parse_params(args.model, args.params.as_deref())?;
    if !(0.0..1.0).contains(&args.holdout_fraction) {
        return Err("--holdout-fraction must be in [0, 1)".to_owned());
    }
    let meshes = read_mesh_dir(&args.train)?;
    let names: Vec<String> = meshes.iter().map(|m| m.name.clone()).collect();
    let templates = params
        .template_mesh_ids()
        .into_iter()
        .map(|t| resolve_template(t, &names))
        .collect::<Result<Vec<_>, _>>()?;
    let (training_names, holdout_names) =
        holdout_split(&names, args.holdout_fraction, args.seed, &templates);
    let (training, holdout) = (
        pick(&meshes, &training_names),
        pick(&meshes, &holdout_names),
    );
    let template_indices: Vec<usize> = templates
        .iter()
        .filter_map(|t| training_names.iter().position(|n| n == t))
        .collect();
    eprintln!(
        "fitting {} on {} meshes ({} held out)",
        args.model.as_str(),
        training.len(),
        holdout.len()
    );
    let started = Instant::now();
    let mut progress = StderrProgress::new(args.model.as_str());
    let sides = laterality_of(args.laterality.as_deref(), &names)?;
    let input = FitInput {
        training: &training,
        holdout: &holdout,
        training_laterality: &sides.sides_of(&training_names),
        holdout_laterality: &sides.sides_of(&holdout_names),
        template_indices: &template_indices,
        seed: args.seed,
    };
    let outcome = fit_model(&params, &input, &mut progress).map_err(|e| e.to_string())?;
    let inputs = FitInputs {
        training_names: &training_names,
        holdout_names: &holdout_names,
        training_faces: training.iter().map(|m| m.faces.as_slice()).collect(),
    };
    let file = ModelFile::new(&params, args.seed, &outcome, &inputs).map_err(|e| e.to_string())?;
    file.save(&args.out).map_err(|e| e.to_string())?;
    println!(
        "{}",
        evaluation_markdown(&[(args.model.as_str().to_owned(), &outcome.summary.evaluation)])
    );
    if let Some(f) = &outcome.summary.fidelity {
        println!("{}", fidelity_markdown(f));
    }
    for choice in &outcome.summary.beta_choices {
        println!("{}\n", choice.sentence());
    }
    if let Some(c) = &outcome.summary.clusters {
        println!("{}", clusters_markdown(c, &training_names, &holdout_names));
    }
    if !outcome.summary.mirrored_training.is_empty() {
        println!(
            "{}\n",
            mirrored_sentence(
                &outcome.summary.mirrored_training,
                &training_names,
                outcome.summary.laterality
            )
        );
    }
    println!(
        "fitted {} in {:.1} s ({} modes); wrote {}",
        args.model.as_str(),
        started.elapsed().as_secs_f64(),
        outcome
            .summary
            .n_modes
            .map_or("n/a".to_owned(), |n| n.to_string()),
        args.out.display()
    );
    Ok(())
}

/// Which training meshes were registered as their mirror images.
fn mirrored_sentence(
    positions: &[usize],
    names: &[String],
    laterality: Option<crate::mesh::Laterality>,
) -> String {
    let side = laterality.map_or(String::new(), |s| format!(" (the patient's {s}, as given)"));
    let listed: Vec<&str> = positions
        .iter()
        .filter_map(|k| names.get(*k).map(String::as_str))
        .collect();
    format!(
        "{} of the {} training meshes were registered as their mirror images, to the side of \
         the alignment reference{side}, which every member takes: {}.",
        listed.len(),
        names.len(),
        listed.join(", ")
    )
}

/// The spread of the fit's own cohort against the training meshes.
fn fidelity_markdown(f: &crate::models::spread::FidelitySummary) -> String {
    let header = [
        "biomarker",
        "training",
        "cohort",
        "mean ratio",
        "sd ratio",
        "KS D",
    ]
    .map(String::from);
    let rows: Vec<Vec<String>> = f
        .biomarkers
        .iter()
        .map(|(name, s)| {
            vec![
                name.clone(),
                format!("{:.2} ± {:.2}", s.training_mean, s.training_sd),
                format!("{:.2} ± {:.2}", s.synthetic_mean, s.synthetic_sd),
                format!("{:.3}", s.mean_ratio),
                format!("{:.3}", s.sd_ratio),
                format!("{:.3}", s.ks_statistic),
            ]
        })
        .collect();
    let mut out = format!(
        "### Spread of a cohort of {} against the training meshes ({} near copies)\n\n{}",
        f.members,
        f.near_copies,
        super::tables::table(&header, &rows)
    );
    if let Some(sentence) = f.acceptance_sentence() {
        out.push_str(&format!("\n{sentence}.\n"));
    }
    if let Some(sentence) = f.folding_sentence() {
        out.push_str(&format!("\n{sentence}.\n"));
    }
    for warning in [f.near_copy_sentence(), f.folding_warning()]
        .into_iter()
        .flatten()
    {
        out.push_str(&format!("\n{warning}.\n"));
    }
    if let Some(note) = &f.population_note {
        out.push_str(&format!("\nSmall population: {note}.\n"));
    }
    out
}

/// The clusters of a multi-atlas fit: the priors, then each mesh's weights and cluster.
fn clusters_markdown(
    c: &crate::models::ClusterSummary,
    training: &[String],
    holdout: &[String],
) -> String {
    let priors: Vec<String> = c.priors.iter().map(|p| format!("{p:.3}")).collect();
    let effective: Vec<String> = c
        .effective_meshes()
        .iter()
        .map(|e| format!("{e:.1}"))
        .collect();
    let mut out = format!(
        "Clusters (priors {}; effective training meshes, Kish {}):\n\n",
        priors.join(" / "),
        effective.join(" / ")
    );
    if let Some(note) = c.thin_cluster_note() {
        out.push_str(&format!("Few meshes per cluster: {note}.\n\n"));
    }
    out.push_str("| mesh | set | cluster | weights |\n|---|---|---|---|\n");
    let rows = (training.iter().zip(&c.training).map(|r| (r, "training")))
        .chain(holdout.iter().zip(&c.holdout).map(|r| (r, "held out")));
    for ((name, weights), set) in rows {
        let w: Vec<String> = weights.iter().map(|w| format!("{w:.3}")).collect();
        out.push_str(&format!(
            "| {name} | {set} | {} | {} |\n",
            crate::models::clusters::winning_cluster(weights),
            w.join(" / ")
        ));
    }
    out
}

/// Matching, generalisation and specificity tables of one or more models, each with
/// vertex-to-vertex and point-to-surface rows.
pub fn evaluation_markdown(models: &[(String, &Evaluation)]) -> String {
    type Part = fn(&Evaluation) -> [Option<DistanceSummary>; 2];
    let parts: [(&str, &[_], Part); 3] = [
        (
            "Matching quality: held-out meshes against their normalised shapes (mm)",
            &MATCHING,
            |e| {
                let s = e.point_to_surface.as_ref();
                [e.matching, s.and_then(|s| s.matching)]
            },
        ),
        (
            "Generalisation: reconstructions of held-out meshes against the originals (mm)",
            &DISTANCES,
            |e| {
                let s = e.point_to_surface.as_ref();
                [e.generalisation, s.and_then(|s| s.generalisation)]
            },
        ),
        (
            "Specificity: samples against their closest training mesh (mm)",
            &DISTANCES,
            |e| {
                let s = e.point_to_surface.as_ref();
                [Some(e.specificity), s.map(|s| s.specificity)]
            },
        ),
    ];
    let mut out = String::new();
    for (title, metrics, part) in parts {
        let columns: Vec<(String, Vec<Option<DistanceSummary>>)> = models
            .iter()
            .map(|(name, e)| (name.clone(), part(e).to_vec()))
            .collect();
        out.push_str(&format!(
            "### {title}\n\n{}\n",
            distance_table(metrics, &DISTANCE_KINDS, &columns)
        ));
    }
    out
}

/// What `cohortforge evaluate` writes.
#[derive(Debug, Serialize)]
pub struct EvaluateReport {
    /// The model file.
    pub model_file: String,
    /// Model type.
    pub model_type: String,
    /// The model's parameters.
    pub params: serde_json::Value,
    /// Training meshes of the model.
    pub training_count: usize,
    /// Test mesh file names.
    pub test_meshes: Vec<String>,
    /// Specificity samples and cohort members.
    pub samples: usize,
    /// Seed of the samples and the cohort.
    pub seed: u64,
    /// Generalisation and matching on the test meshes, specificity of the samples.
    pub evaluation: Evaluation,
    /// Criterion of the cohort's acceptance flags.
    pub cohort_criterion: String,
    /// The cohort's acceptance and privacy report.
    pub cohort: CohortReport,
    /// Wall-clock seconds per step.
    pub timings: Vec<StageTiming>,
}

fn timing(stage: &str, started: Instant) -> StageTiming {
    StageTiming {
        stage: stage.to_owned(),
        seconds: started.elapsed().as_secs_f64(),
    }
}

/// Runs `cohortforge evaluate`.
pub fn evaluate_model(args: &EvaluateArgs) -> CliResult {
    let started = Instant::now();
    let file = ModelFile::load(&args.model).map_err(|e| e.to_string())?;
    let stored = file.stored_model().map_err(|e| e.to_string())?;
    let reference = file.reference().map_err(|e| e.to_string())?;
    let mut timings = vec![timing("load_model", started)];
    let step = Instant::now();
    let test = read_mesh_dir(&args.test)?;
    timings.push(timing("read_test_meshes", step));
    let samples = args.samples.unwrap_or(file.training_faces.len());
    if samples == 0 {
        return Err("--samples must be at least 1".to_owned());
    }
    let seed = args.seed.unwrap_or(file.seed);
    let model = stored.model.as_ref();
    let aligned = stored.training.to_f64();
    let faces: Vec<&[[u32; 3]]> = file.training_faces.iter().map(Vec::as_slice).collect();
    let test_meshes: Vec<Mesh> = test.iter().map(|m| m.mesh.clone()).collect();
    let test_names: Vec<String> = test.iter().map(|m| m.name.clone()).collect();
    // The file may list the training meshes too: names not among the test meshes are skipped.
    let test_sides = match &args.laterality {
        Some(path) => LateralityFile::read(path)?.sides_of(&test_names),
        None => Vec::new(),
    };

    let step = Instant::now();
    let mut stages = Stages::new(&[("evaluation", 1.0)]);
    stages.enter("evaluation");
    let mut progress = StderrProgress::new("evaluate");
    let evaluation = evaluate(
        model,
        &aligned,
        &faces,
        &test_meshes,
        &test_sides,
        samples,
        seed,
        &stages,
        &mut progress,
    )
    .map_err(|e| e.to_string())?;
    timings.push(timing("evaluation", step));

    let step = Instant::now();
    let normalised = stored.training.normalised_f64();
    let index =
        TrainingIndex::new(&normalised, &stored.training.privacy).map_err(|e| e.to_string())?;
    let spec = CohortSpec {
        size: samples,
        seed,
        sampling: Sampling::Gaussian,
        criterion: Criterion::Mean,
        only_accepted: false,
        exclude_near_copies: false,
        max_draws: 20 * samples,
    };
    let (_, cohort) = sample_cohort(model, &reference, &index, &spec).map_err(|e| e.to_string())?;
    timings.push(timing("cohort", step));
    timings.push(timing("total", started));

    let report = EvaluateReport {
        model_file: args.model.display().to_string(),
        model_type: file.model_type.clone(),
        params: file.params_value(),
        training_count: file.training_faces.len(),
        test_meshes: test.iter().map(|m| m.name.clone()).collect(),
        samples,
        seed,
        evaluation,
        cohort_criterion: Criterion::Mean.as_str().to_owned(),
        cohort,
        timings,
    };
    write_json(&args.json, &report)?;
    print_evaluation(&report);
    Ok(())
}

fn print_evaluation(report: &EvaluateReport) {
    println!(
        "## {} model, {} test meshes, {} samples (seed {})\n",
        report.model_type,
        report.test_meshes.len(),
        report.samples,
        report.seed
    );
    println!(
        "{}",
        evaluation_markdown(&[(report.model_type.clone(), &report.evaluation)])
    );
    println!(
        "### Clinical acceptance of a cohort of {} (%)\n\n{}",
        report.samples,
        acceptance_table(&report.cohort)
    );
    let rows: Vec<Vec<String>> = report
        .timings
        .iter()
        .map(|t| vec![t.stage.clone(), format!("{:.2}", t.seconds)])
        .collect();
    println!(
        "### Timings\n\n{}",
        super::tables::table(&["step".to_owned(), "seconds".to_owned()], &rows)
    );
}
