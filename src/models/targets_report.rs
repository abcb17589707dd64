//! What a conditional cohort's report says about its targets.

use serde::{Deserialize, Serialize};

use super::cohort::Member;
use super::conditional::{Conditional, Target};
use crate::eval::Biomarkers;
use crate::eval::stats::{mean, sample_sd};

/// How the members meet one target.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
pub struct TargetReport {
    /// The biomarker's JSON name.
    pub biomarker: String,
    /// Its unit.
    pub unit: String,
    /// The target as asked: `{min, max}` or `{mean, sd}`.
    pub target: Target,
    /// `[min, max]` the model's own pilot draws reach.
    pub reachable: [f64; 2],
    /// Share of members inside the target (1 for interval targets, which are enforced;
    /// share within mean ± 2 sd for distribution targets).
    pub inside: f64,
    /// The members' mean.
    pub mean: f64,
    /// The members' sample standard deviation.
    pub sd: f64,
}

/// The targets of a cohort.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
pub struct TargetsReport {
    /// How members were drawn.
    pub method: String,
    /// One entry per target.
    pub targets: Vec<TargetReport>,
    /// Draws per member kept (1 when no draw was rejected).
    pub draws_per_member: f64,
}

impl TargetsReport {
    /// From the sampler, the members and the number of draws made.
    pub fn new(conditional: &Conditional, members: &[Member], draws: usize) -> Self {
        let targets = conditional
            .targets()
            .map(|(name, target, (low, high))| {
                let b = Biomarkers::NAMES
                    .iter()
                    .position(|n| *n == name)
                    .unwrap_or(0);
                let values: Vec<f64> = members.iter().map(|m| m.biomarkers.values()[b]).collect();
                let inside = match target {
                    Target::Distribution { mean, sd } => Target::Interval {
                        min: Some(mean - 2.0 * sd),
                        max: Some(mean + 2.0 * sd),
                    },
                    t => t,
                };
                let share = values.iter().filter(|v| inside.admits(**v)).count() as f64
                    / values.len().max(1) as f64;
                TargetReport {
                    biomarker: name.to_owned(),
                    unit: Biomarkers::UNITS[b].to_owned(),
                    target,
                    reachable: [low, high],
                    inside: share,
                    mean: mean(&values),
                    sd: if values.len() > 1 {
                        sample_sd(&values)
                    } else {
                        0.0
                    },
                }
            })
            .collect();
        Self {
            method: "conditional Gaussian of (code, biomarkers) from the model's own draws"
                .to_owned(),
            targets,
            draws_per_member: draws as f64 / members.len().max(1) as f64,
        }
    }
}
