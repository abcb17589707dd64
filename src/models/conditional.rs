//! Conditional cohorts: members whose biomarkers meet targets (an interval, or a normal
//! distribution), drawn by conditioning the model's Gaussian rather than by rejection.
//!
//! Per cluster, the pilot draws of [`latent_effects`] give the joint Gaussian of the
//! standard-normal code `ε ~ N(0, I)` and the targeted biomarkers `b_T ≈ a + G·ε + r`
//! (`r ~ N(0, R)`, what the linear fit leaves). A draw picks a cluster by its prior times the
//! chance that its pilot draws meet the targets, draws target values `t` (from the targeted
//! distribution, or from the model's own marginal of `b_T` truncated to the intervals, one
//! biomarker after the other), then `ε | b_T = t` by Matheron's rule:
//! `ε = ξ + Gᵀ S⁻¹ (t − a − G ξ − r)` with `ξ ~ N(0, I)`, `r ~ N(0, R)`, `S = G Gᵀ + R`.
//! The generator is not linear, so a shape that misses an interval is moved along the gain
//! `Gᵀ S⁻¹` by the difference between the target values and its own biomarkers (at most
//! [`CORRECTIONS`] steps); members still outside are drawn again (the cohort loop counts
//! those draws).

use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::latent_effects::{LatentEffects, STANDARD_CLIP, latent_effects};
use super::{Draw, ModelError, ShapeModel};
use crate::eval::Biomarkers;
use crate::eval::normal::truncated;

/// What a cohort asks of one biomarker.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(untagged, deny_unknown_fields)]
pub enum Target {
    /// Members distributed as `N(mean, sd²)`.
    Distribution {
        /// Mean.
        mean: f64,
        /// Standard deviation (> 0).
        sd: f64,
    },
    /// Every member inside `[min, max]` (either end may be open).
    Interval {
        /// Lower end.
        min: Option<f64>,
        /// Upper end.
        max: Option<f64>,
    },
}

impl Target {
    fn bounds(&self) -> Option<(f64, f64)> {
        match *self {
            Self::Interval { min, max } => Some((
                min.unwrap_or(f64::NEG_INFINITY),
                max.unwrap_or(f64::INFINITY),
            )),
            Self::Distribution { .. } => None,
        }
    }

    /// `value` is inside the interval (always true for a distribution).
    pub fn admits(&self, value: f64) -> bool {
        self.bounds()
            .is_none_or(|(lo, hi)| (lo..=hi).contains(&value))
    }

    fn describe(&self, unit: &str) -> String {
        match *self {
            Self::Interval { min, max } => {
                let end =
                    |v: Option<f64>, open: &str| v.map_or(open.to_owned(), |v| format!("{v}"));
                format!(
                    "the interval [{}, {}] {unit}",
                    end(min, "−∞"),
                    end(max, "∞")
                )
            }
            Self::Distribution { mean, sd } => format!("a mean of {mean} {unit} (sd {sd})"),
        }
    }
}

/// Steps that move a draw's code towards its target values when the generator's
/// non-linearity put the shape outside an interval.
const CORRECTIONS: usize = 3;
/// A draw for a distribution target is near enough within this many of its sd.
const DISTRIBUTION_TOLERANCE: f64 = 0.25;

/// The conditional Gaussian of one cluster.
struct ClusterCondition {
    cluster: usize,
    /// `a` restricted to the targets, `[T]`.
    intercept: DVector<f64>,
    /// `G` restricted to the targets, `[T, L]`.
    gradient: DMatrix<f64>,
    /// `S = G Gᵀ + R`, `[T, T]`.
    marginal: DMatrix<f64>,
    /// `Gᵀ S⁻¹`, `[L, T]`.
    gain: DMatrix<f64>,
    /// Cholesky factor of `R`, `[T, T]`.
    residual_factor: DMatrix<f64>,
}

/// A sampler of members that meet targets.
pub struct Conditional {
    /// `(biomarker index, name, target)`.
    targets: Vec<(usize, String, Target)>,
    clusters: Vec<ClusterCondition>,
    /// Cumulative probability of each entry of `clusters`.
    cumulative: Vec<f64>,
    /// `[min, max]` of each target's biomarker over every pilot draw.
    reachable: Vec<(f64, f64)>,
}

fn restrict(effects: &LatentEffects, idx: &[usize]) -> Result<ClusterCondition, ModelError> {
    let t = idx.len();
    let l = effects.gradient.ncols();
    let intercept = DVector::from_iterator(t, idx.iter().map(|&b| effects.intercept[b]));
    let gradient = DMatrix::from_fn(t, l, |i, j| effects.gradient[(idx[i], j)]);
    let residual = DMatrix::from_fn(t, t, |i, j| effects.residual[(idx[i], idx[j])]);
    let ridge = 1e-9 * (1.0 + residual.trace().abs());
    let residual_factor = (residual.clone() + DMatrix::identity(t, t) * ridge)
        .cholesky()
        .map(|c| c.l())
        .ok_or_else(|| ModelError::Numerical("residual covariance of the targets".into()))?;
    let marginal = &gradient * gradient.transpose() + residual + DMatrix::identity(t, t) * ridge;
    let inverse = marginal
        .clone()
        .try_inverse()
        .ok_or_else(|| ModelError::Numerical("the targets' covariance is singular".into()))?;
    Ok(ClusterCondition {
        cluster: effects.cluster,
        gain: gradient.transpose() * inverse,
        intercept,
        gradient,
        marginal,
        residual_factor,
    })
}

/// How likely the pilot draws of a cluster make the targets (share inside the intervals,
/// times the density of each targeted mean under the cluster's spread).
fn cluster_likelihood(effects: &LatentEffects, targets: &[(usize, String, Target)]) -> f64 {
    let inside = effects
        .pilot
        .iter()
        .filter(|p| targets.iter().all(|(b, _, t)| t.admits(p[*b])))
        .count() as f64
        / effects.pilot.len().max(1) as f64;
    targets.iter().fold(inside, |acc, (b, _, t)| match *t {
        Target::Distribution { mean, sd } => {
            let s2 = effects.residual[(*b, *b)]
                + effects.gradient.row(*b).iter().map(|g| g * g).sum::<f64>()
                + sd * sd;
            let z = (mean - effects.intercept[*b]) / s2.sqrt();
            acc * crate::eval::normal::pdf(z) / s2.sqrt()
        }
        Target::Interval { .. } => acc,
    })
}

impl Conditional {
    /// Fits the conditional Gaussians of `model` for `targets` (biomarker name → target),
    /// from pilot draws seeded by `seed`; a target outside the reach of every cluster is
    /// [`ModelError::TargetUnreachable`].
    pub fn new<M: ShapeModel + Sync + ?Sized>(
        model: &M,
        targets: &[(String, Target)],
        seed: u64,
    ) -> Result<Self, ModelError> {
        let latent = model.standard_latent().ok_or_else(|| {
            ModelError::InvalidInput("this model cannot condition its draws on targets".into())
        })?;
        let targets: Vec<(usize, String, Target)> = targets
            .iter()
            .map(|(name, t)| {
                let b = Biomarkers::NAMES
                    .iter()
                    .position(|n| n == name)
                    .ok_or_else(|| {
                        ModelError::InvalidInput(format!("no biomarker is called {name}"))
                    })?;
                Ok((b, name.clone(), *t))
            })
            .collect::<Result<_, ModelError>>()?;
        let idx: Vec<usize> = targets.iter().map(|(b, _, _)| *b).collect();
        let effects = latent
            .dimensions
            .iter()
            .enumerate()
            .map(|(m, &l)| latent_effects(model, m, l, seed))
            .collect::<Result<Vec<_>, _>>()?;
        let reachable: Vec<(f64, f64)> = idx
            .iter()
            .map(|&b| {
                effects
                    .iter()
                    .map(|e| e.pilot_range(b))
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (a, c)| {
                        (lo.min(a), hi.max(c))
                    })
            })
            .collect();
        let sampler = Self {
            clusters: effects
                .iter()
                .map(|e| restrict(e, &idx))
                .collect::<Result<_, _>>()?,
            cumulative: Vec::new(),
            targets,
            reachable,
        };
        sampler.check_reach()?;
        let weights: Vec<f64> = effects
            .iter()
            .map(|e| {
                latent.priors.get(e.cluster).copied().unwrap_or(0.0)
                    * cluster_likelihood(e, &sampler.targets)
            })
            .collect();
        let total: f64 = weights.iter().sum();
        if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(sampler.unreachable(0, "no draw of any cluster meets every target at once"));
        }
        let cumulative = weights
            .iter()
            .scan(0.0, |acc, w| {
                *acc += w / total;
                Some(*acc)
            })
            .collect();
        Ok(Self {
            cumulative,
            ..sampler
        })
    }

    /// The error naming target `k` and its reachable range.
    pub fn unreachable(&self, k: usize, detail: &str) -> ModelError {
        let (b, name, _) = &self.targets[k];
        let (low, high) = self.reachable[k];
        ModelError::TargetUnreachable {
            biomarker: name.clone(),
            detail: detail.to_owned(),
            low,
            high,
            unit: Biomarkers::UNITS[*b],
        }
    }

    fn check_reach(&self) -> Result<(), ModelError> {
        for (k, (b, _, t)) in self.targets.iter().enumerate() {
            let (low, high) = self.reachable[k];
            let outside = match t.bounds() {
                Some((lo, hi)) => hi < low || lo > high,
                None => {
                    matches!(t, Target::Distribution { mean, .. } if *mean < low || *mean > high)
                }
            };
            if outside {
                let what = t.describe(Biomarkers::UNITS[*b]);
                return Err(
                    self.unreachable(k, &format!("{what} lies outside what the model reaches"))
                );
            }
        }
        Ok(())
    }

    /// Every interval target admits `biomarkers`.
    pub fn meets(&self, biomarkers: &Biomarkers) -> bool {
        let values = biomarkers.values();
        self.targets.iter().all(|(b, _, t)| t.admits(values[*b]))
    }

    /// The targets, `(name, target, reachable range)`.
    pub fn targets(&self) -> impl Iterator<Item = (&str, Target, (f64, f64))> + '_ {
        self.targets
            .iter()
            .zip(&self.reachable)
            .map(|((_, n, t), r)| (n.as_str(), *t, *r))
    }

    /// One draw conditioned on the targets.
    pub fn draw<M: ShapeModel + ?Sized>(
        &self,
        model: &M,
        rng: &mut ChaCha8Rng,
    ) -> Result<Draw, ModelError> {
        let u: f64 = rng.random();
        let c = self
            .cumulative
            .iter()
            .position(|p| u < *p)
            .map_or(&self.clusters[self.clusters.len() - 1], |i| {
                &self.clusters[i]
            });
        let t = self.target_values(c, rng);
        let (l, n) = (c.gradient.ncols(), self.targets.len());
        let normal =
            |rng: &mut ChaCha8Rng, k: usize| DVector::from_fn(k, |_, _| StandardNormal.sample(rng));
        let xi: DVector<f64> = normal(rng, l);
        let r = &c.residual_factor * normal(rng, n);
        let mut eps = &xi + &c.gain * (&t - &c.intercept - &c.gradient * &xi - r);
        let mut mesh = self.decode(model, c.cluster, &mut eps)?;
        // The generator is not linear: move the code along the fitted gain until the shape's
        // own biomarkers meet the interval targets and lie near the values drawn for the
        // distribution targets (or the steps run out).
        for _ in 0..CORRECTIONS {
            let values = Biomarkers::from_mesh(&mesh)?.values();
            let near = self
                .targets
                .iter()
                .zip(t.iter())
                .all(|((b, _, target), t)| match *target {
                    Target::Distribution { sd, .. } => {
                        (values[*b] - t).abs() <= DISTRIBUTION_TOLERANCE * sd
                    }
                    Target::Interval { .. } => target.admits(values[*b]),
                });
            if near {
                break;
            }
            let got =
                DVector::from_iterator(t.len(), self.targets.iter().map(|(b, _, _)| values[*b]));
            eps += &c.gain * (&t - got);
            mesh = self.decode(model, c.cluster, &mut eps)?;
        }
        Ok(Draw {
            mesh,
            cluster: c.cluster,
        })
    }

    /// The shape of `eps`, clipped to the model's support first.
    fn decode<M: ShapeModel + ?Sized>(
        &self,
        model: &M,
        cluster: usize,
        eps: &mut DVector<f64>,
    ) -> Result<crate::mesh::Mesh, ModelError> {
        eps.apply(|e| *e = e.clamp(-STANDARD_CLIP, STANDARD_CLIP));
        model
            .decode_standard(cluster, &[eps.iter().copied().collect()])?
            .pop()
            .ok_or_else(|| ModelError::Numerical("the generator returned nothing".into()))
    }

    /// Target values `[T]`: from each distribution target, then each interval target from the
    /// cluster's marginal given the values already drawn, truncated to its interval.
    fn target_values(&self, c: &ClusterCondition, rng: &mut ChaCha8Rng) -> DVector<f64> {
        let n = self.targets.len();
        let mut t = DVector::zeros(n);
        let mut set: Vec<usize> = Vec::with_capacity(n);
        let order = (0..n)
            .filter(|&k| self.targets[k].2.bounds().is_none())
            .chain((0..n).filter(|&k| self.targets[k].2.bounds().is_some()));
        for k in order.collect::<Vec<_>>() {
            let z: f64 = StandardNormal.sample(rng);
            let u: f64 = rng.random();
            t[k] = match self.targets[k].2 {
                Target::Distribution { mean, sd } => mean + sd * z,
                Target::Interval { .. } => {
                    let (mean, var) = conditional_moments(&c.intercept, &c.marginal, &t, &set, k);
                    let (lo, hi) = self.targets[k]
                        .2
                        .bounds()
                        .unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
                    truncated(mean, var.max(0.0).sqrt(), lo, hi, u).unwrap_or(if mean < lo {
                        lo
                    } else {
                        hi
                    })
                }
            };
            set.push(k);
        }
        t
    }
}

/// Mean and variance of component `k` of `N(mean, cov)` given the components `set` at `t`.
fn conditional_moments(
    mean: &DVector<f64>,
    cov: &DMatrix<f64>,
    t: &DVector<f64>,
    set: &[usize],
    k: usize,
) -> (f64, f64) {
    if set.is_empty() {
        return (mean[k], cov[(k, k)]);
    }
    let p = set.len();
    let spp = DMatrix::from_fn(p, p, |i, j| cov[(set[i], set[j])]);
    let skp = DVector::from_fn(p, |i, _| cov[(k, set[i])]);
    let diff = DVector::from_fn(p, |i, _| t[set[i]] - mean[set[i]]);
    match spp.try_inverse() {
        Some(inv) => {
            let w = inv * &skp;
            (mean[k] + w.dot(&diff), cov[(k, k)] - w.dot(&skp))
        }
        None => (mean[k], cov[(k, k)]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conditioning_a_bivariate_normal() {
        // Unit variances, correlation 0.8: given x₀ = 1, x₁ ~ N(0.8, 0.36).
        let mean = DVector::from_vec(vec![0.0, 0.0]);
        let cov = DMatrix::from_row_slice(2, 2, &[1.0, 0.8, 0.8, 1.0]);
        let t = DVector::from_vec(vec![1.0, 0.0]);
        let (m, v) = conditional_moments(&mean, &cov, &t, &[0], 1);
        assert!((m - 0.8).abs() < 1e-12 && (v - 0.36).abs() < 1e-12);
        assert_eq!(conditional_moments(&mean, &cov, &t, &[], 1), (0.0, 1.0));
    }

    #[test]
    fn targets_parse_as_intervals_or_distributions() {
        let t: Target = serde_json::from_str(r#"{"min": 120, "max": 160}"#).unwrap();
        assert_eq!(
            t,
            Target::Interval {
                min: Some(120.0),
                max: Some(160.0)
            }
        );
        assert!(t.admits(120.0) && !t.admits(160.5));
        let t: Target = serde_json::from_str(r#"{"mean": 140, "sd": 10}"#).unwrap();
        assert_eq!(
            t,
            Target::Distribution {
                mean: 140.0,
                sd: 10.0
            }
        );
        assert!(t.admits(1e9));
        let open: Target = serde_json::from_str(r#"{"min": 120}"#).unwrap();
        assert!(open.admits(1e6) && !open.admits(119.0));
    }
}
