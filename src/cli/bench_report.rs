//! What `cohortforge bench` measures, as JSON and as markdown tables.

use super::bench_clusters::{ClusterBench, cluster_markdown};
use super::bench_fidelity::{fidelity_table, spread_table};
use serde::Serialize;

use super::memory::StepMemory;
use super::progress::EpochTiming;
use super::study::{DISTANCE_KINDS, evaluation_markdown};
use super::tables::{DISTANCES, MISSING, acceptance_table, distance_table, table};
use crate::eval::SummaryStats;
use crate::eval::fidelity::Fidelity;
use crate::eval::metrics::DistanceSummary;
use crate::models::cohort::CohortReport;
use crate::models::{Evaluation, StageTiming};

/// Everything one bench run measured.
#[derive(Debug, Serialize)]
pub struct BenchReport {
    /// Phantom family.
    pub family: String,
    /// Training phantoms.
    pub train: usize,
    /// Test phantoms.
    pub test: usize,
    /// Seed of phantoms, fits and samples.
    pub seed: u64,
    /// Fewest and most vertices of the training and test meshes.
    pub vertex_counts: [usize; 2],
    /// The generator's volume distribution and how close the training phantoms are to it.
    pub fidelity_reference: ReferenceFidelity,
    /// One entry per model of `--models`.
    pub models: Vec<ModelBench>,
    /// Peak resident memory of the process (VmHWM), MiB.
    pub process_peak_mib: Option<f64>,
    /// Wall-clock seconds of the whole run.
    pub total_seconds: f64,
}

/// The generator's own volume distribution, from fresh phantoms.
#[derive(Debug, Serialize)]
pub struct ReferenceFidelity {
    /// Fresh phantoms.
    pub phantoms: usize,
    /// Their seed.
    pub seed: u64,
    /// Their exact volumes, ml.
    pub volumes: SummaryStats,
    /// Exact volumes of the training phantoms, ml.
    pub training_exact_volumes: SummaryStats,
    /// Mesh-measured volumes of the training phantoms, ml.
    pub training_measured_volumes: SummaryStats,
    /// Exact volumes of the training phantoms against the fresh ones (sampling noise).
    pub training_exact: Fidelity,
    /// Mesh-measured volumes of the training phantoms against the fresh exact ones
    /// (sampling noise plus discretisation).
    pub training_measured: Fidelity,
}

/// Figures of one model of `--models`.
#[derive(Debug, Serialize)]
pub struct ModelBench {
    /// The model's name: its label, else its type.
    pub model: String,
    /// Model type.
    pub model_type: String,
    /// Parameters, defaults included.
    pub params: serde_json::Value,
    /// Modes kept (PCA models).
    pub n_modes: Option<usize>,
    /// Time and memory of the fit.
    pub fit: FitBench,
    /// Matching and generalisation on the test phantoms, specificity of as many samples as
    /// training meshes.
    pub evaluation: Evaluation,
    /// The timed cohort and its acceptance report.
    pub cohort: CohortBench,
    /// The cohort's volumes against the generator's.
    pub fidelity: VolumeFidelity,
    /// Held-out meshes through the model against the near-copy threshold.
    pub held_out_privacy: super::bench_privacy::HeldOutPrivacy,
    /// Timed specificity of many samples.
    pub specificity: SpecificityBench,
    /// Clusters of multi-atlas models.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clusters: Option<ClusterBench>,
}

/// Time and memory of a fit.
#[derive(Debug, Serialize)]
pub struct FitBench {
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Seconds per stage, as the model reports them.
    pub stages: Vec<StageTiming>,
    /// Seconds per epoch of the stages that report a loss per epoch (empty for rsmp).
    pub epochs: Vec<EpochTiming>,
    /// Resident memory during the fit.
    pub memory: Option<StepMemory>,
}

/// A timed cohort: sampling, biomarkers, acceptance and the nearest training shape of
/// every member (indexing the training shapes included).
#[derive(Debug, Serialize)]
pub struct CohortBench {
    /// Members.
    pub size: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Members per second.
    pub members_per_second: f64,
    /// Resident memory during the sampling.
    pub memory: Option<StepMemory>,
    /// Acceptance (criterion `mean` for the flags) and privacy report.
    pub report: CohortReport,
    /// Time to draw the first member's picture.
    pub render: Option<RenderBench>,
    /// A cohort of the same size conditioned on a volume interval.
    pub conditional: ConditionalBench,
}

/// Time of a picture.
#[derive(Debug, Serialize)]
pub struct RenderBench {
    /// Vertices of the mesh drawn.
    pub vertices: usize,
    /// Milliseconds per view (one 240 px panel with its labels, PNG encoded).
    pub ms_per_view: f64,
}

/// A conditional cohort (volume in [`bench_volume_target`](super::bench_conditional::bench_volume_target)).
#[derive(Debug, Serialize)]
pub struct ConditionalBench {
    /// The volume interval asked for, ml.
    pub target_ml: (f64, f64),
    /// Wall-clock seconds, pilot draws included.
    pub seconds: f64,
    /// Share of members inside the interval.
    pub inside: f64,
    /// Draws per member kept.
    pub draws_per_member: f64,
    /// Mean area (cm²) of the plain cohort and of the conditional one.
    pub area_cm2: Option<(f64, f64)>,
    /// Why it failed (e.g. the target is out of reach).
    pub error: Option<String>,
}

/// Synthetic volumes (ml) against the generator's.
#[derive(Debug, Serialize)]
pub struct VolumeFidelity {
    /// The cohort's volumes, ml.
    pub synthetic: SummaryStats,
    /// W1 (ml) and KS against the fresh phantoms' exact volumes.
    pub fidelity: Fidelity,
    /// Joint acceptance of the fresh phantoms (real subjects of the same population) against
    /// this model's training intervals: what a faithful cohort scores.
    pub fresh_acceptance: crate::eval::acceptance::Rates,
    /// Joint acceptance of the training meshes against their own intervals.
    pub training_acceptance: crate::eval::acceptance::Rates,
    /// Joint acceptance of draws from the Gaussian with the training biomarkers' mean and
    /// covariance: what a generator with a Gaussian latent space can be expected to score.
    pub gaussian_acceptance: crate::eval::acceptance::Rates,
    /// How far the biomarkers lie from the training mean jointly.
    pub distance: BiomarkerDistance,
}

/// 95th percentiles of the Mahalanobis distance of six biomarkers from the training mean,
/// under the training covariance (in training sds along each principal direction): a member
/// whose biomarkers combine as no patient's do lies far out even when each is inside its
/// interval.
#[derive(Debug, Serialize)]
pub struct BiomarkerDistance {
    /// The cohort's members.
    pub cohort: f64,
    /// Fresh phantoms of the population: what a faithful cohort gives.
    pub fresh: f64,
    /// The training meshes themselves.
    pub training: f64,
}

/// Timed specificity against the training meshes.
#[derive(Debug, Serialize)]
pub struct SpecificityBench {
    /// Samples drawn.
    pub samples: usize,
    /// Training meshes compared with.
    pub training_meshes: usize,
    /// Wall-clock seconds: sampling, vertex-to-vertex search of the closest training mesh,
    /// point-to-surface distances to it.
    pub seconds: f64,
    /// Resident memory during the evaluation.
    pub memory: Option<StepMemory>,
    /// Vertex-to-vertex distances, mm.
    pub vertex_to_vertex: DistanceSummary,
    /// Point-to-surface distances, mm.
    pub point_to_surface: Option<DistanceSummary>,
}

pub(super) fn row(label: &str, cells: impl Iterator<Item = String>) -> Vec<String> {
    std::iter::once(label.to_owned()).chain(cells).collect()
}

pub(super) fn header(first: &str, report: &BenchReport) -> Vec<String> {
    row(first, report.models.iter().map(|m| m.model.clone()))
}

fn memory_cell(m: Option<StepMemory>) -> String {
    m.map_or(MISSING.to_owned(), |m| {
        format!("{:.0} (peak {:.0})", m.growth_mib, m.peak_mib)
    })
}

fn fit_table(report: &BenchReport) -> String {
    let mut stages: Vec<String> = Vec::new();
    for m in &report.models {
        for s in &m.fit.stages {
            if !stages.contains(&s.stage) {
                stages.push(s.stage.clone());
            }
        }
    }
    let mut rows: Vec<Vec<String>> = stages
        .iter()
        .map(|stage| {
            row(
                stage,
                report.models.iter().map(|m| {
                    m.fit
                        .stages
                        .iter()
                        .find(|s| &s.stage == stage)
                        .map_or(MISSING.to_owned(), |s| format!("{:.1}", s.seconds))
                }),
            )
        })
        .collect();
    let models = &report.models;
    rows.push(row(
        "total",
        models.iter().map(|m| format!("{:.1}", m.fit.seconds)),
    ));
    rows.push(row(
        "seconds per epoch",
        models.iter().map(|m| {
            let e: Vec<String> = m
                .fit
                .epochs
                .iter()
                .map(|e| format!("{}: {:.3}", e.stage, e.seconds_per_epoch))
                .collect();
            if e.is_empty() {
                MISSING.to_owned()
            } else {
                e.join(", ")
            }
        }),
    ));
    rows.push(row(
        "memory growth during fit, MiB",
        models.iter().map(|m| memory_cell(m.fit.memory)),
    ));
    table(&header("stage (s)", report), &rows)
}

fn cohort_table(report: &BenchReport) -> String {
    let models = &report.models;
    let rows = vec![
        row("members", models.iter().map(|m| m.cohort.size.to_string())),
        row(
            "seconds",
            models.iter().map(|m| format!("{:.2}", m.cohort.seconds)),
        ),
        row(
            "members/s",
            models
                .iter()
                .map(|m| format!("{:.1}", m.cohort.members_per_second)),
        ),
        row(
            "memory growth, MiB",
            models.iter().map(|m| memory_cell(m.cohort.memory)),
        ),
        row(
            "picture, ms per view (vertices)",
            models.iter().map(|m| {
                m.cohort.render.as_ref().map_or(MISSING.to_owned(), |r| {
                    format!("{:.1} ({})", r.ms_per_view, r.vertices)
                })
            }),
        ),
        row(
            &models.first().map_or_else(
                || "conditioned on volume: inside / draws per member".to_owned(),
                |m| {
                    let (min, max) = m.cohort.conditional.target_ml;
                    format!("volume in [{min:.0}, {max:.0}] ml: inside / draws per member")
                },
            ),
            models.iter().map(|m| {
                let c = &m.cohort.conditional;
                match &c.error {
                    Some(e) => format!("unreachable: {}", e.split("; ").nth(1).unwrap_or(e)),
                    None => format!(
                        "{:.1}% / {:.2} ({:.1} s)",
                        100.0 * c.inside,
                        c.draws_per_member,
                        c.seconds
                    ),
                }
            }),
        ),
        row(
            "mean area, plain → conditioned, cm²",
            models.iter().map(|m| {
                m.cohort
                    .conditional
                    .area_cm2
                    .map_or(MISSING.to_owned(), |(a, b)| format!("{a:.1} → {b:.1}"))
            }),
        ),
        row(
            "near copies (privacy guard)",
            models
                .iter()
                .map(|m| m.cohort.report.privacy.near_copies.to_string()),
        ),
    ];
    table(&header("cohort", report), &rows)
}

fn specificity_table(report: &BenchReport) -> String {
    let models = &report.models;
    let rows = vec![
        row(
            "samples × training meshes",
            models.iter().map(|m| {
                format!(
                    "{} × {}",
                    m.specificity.samples, m.specificity.training_meshes
                )
            }),
        ),
        row(
            "seconds",
            models
                .iter()
                .map(|m| format!("{:.1}", m.specificity.seconds)),
        ),
        row(
            "memory growth, MiB",
            models.iter().map(|m| memory_cell(m.specificity.memory)),
        ),
    ];
    let columns: Vec<(String, Vec<Option<DistanceSummary>>)> = models
        .iter()
        .map(|m| {
            let s = &m.specificity;
            (
                m.model.clone(),
                vec![Some(s.vertex_to_vertex), s.point_to_surface],
            )
        })
        .collect();
    format!(
        "{}\n{}",
        table(&header("specificity", report), &rows),
        distance_table(&DISTANCES, &DISTANCE_KINDS, &columns)
    )
}

/// Prints the report as markdown on stdout.
pub fn print_markdown(report: &BenchReport) {
    println!(
        "## Benchmark: {} phantoms, {} training / {} test meshes ({}–{} vertices), seed {}\n",
        report.family,
        report.train,
        report.test,
        report.vertex_counts[0],
        report.vertex_counts[1],
        report.seed
    );
    println!(
        "Distances in mm, mean ± sd over the test meshes (matching, generalisation) or over as \
         many samples as training meshes (specificity). Vertex-to-vertex rows use the closest \
         vertex of the other shape, point-to-surface rows the closest point on its triangles.\n"
    );
    let evaluations: Vec<(String, &Evaluation)> = report
        .models
        .iter()
        .map(|m| (m.model.clone(), &m.evaluation))
        .collect();
    println!("{}", evaluation_markdown(&evaluations));
    println!(
        "### Fit time by stage (s) and memory\n\n{}",
        fit_table(report)
    );
    println!(
        "### Cohort sampling: members with biomarkers, acceptance and nearest training shape\n\n{}",
        cohort_table(report)
    );
    for m in &report.models {
        println!(
            "### Clinical acceptance, {} cohort of {} (%)\n\n{}",
            m.model,
            m.cohort.size,
            acceptance_table(&m.cohort.report)
        );
    }
    let clustered: Vec<String> = report
        .models
        .iter()
        .filter_map(|m| m.clusters.as_ref().map(|c| cluster_markdown(&m.model, c)))
        .collect();
    if !clustered.is_empty() {
        println!("### Clusters\n\n{}", clustered.concat());
    }
    println!(
        "### Spread against the training meshes: cohort mean ratio / sd ratio / KS D\n\n{}",
        spread_table(report)
    );
    println!(
        "### Volume fidelity against the generator ({} fresh phantoms, seed {})\n\n{}",
        report.fidelity_reference.phantoms,
        report.fidelity_reference.seed,
        fidelity_table(report)
    );
    println!(
        "### Specificity against the training meshes, timed\n\n{}",
        specificity_table(report)
    );
    let peak = report
        .process_peak_mib
        .map_or(MISSING.to_owned(), |p| format!("{p:.0} MiB"));
    println!(
        "Process peak resident memory (VmHWM): {peak}; total {:.1} s.",
        report.total_seconds
    );
}
