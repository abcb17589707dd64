//! Model quality in mm (SPEC §3): generalisation, specificity and matching quality, each as
//! per-item surface distances plus mean ± sd.
//!
//! Distances follow [`SurfaceDistances`]: for a pair `(g, g')`, `ED` averages over `g`'s
//! vertices and `ED*` over `g'`'s. The first argument of each function plays `g`.

use serde::{Deserialize, Serialize};

use super::{EvalError, MeanStd};
use crate::geometry::distance::{SurfaceDistances, directed, surface_distances_indexed};
use crate::geometry::kdtree::PointCloudIndex;

/// Mean ± sd of each distance over a set of pairs (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct DistanceSummary {
    /// Hausdorff distance.
    pub hd: MeanStd,
    /// Mean closest-point distance from `g` to `g'`.
    pub ed: MeanStd,
    /// Mean closest-point distance from `g'` to `g`.
    pub ed_star: MeanStd,
    /// Chamfer distance `ED + ED*`.
    pub cd: MeanStd,
}

impl DistanceSummary {
    /// Of a non-empty list of per-pair distances.
    pub fn from_pairs(pairs: &[SurfaceDistances]) -> Result<Self, EvalError> {
        let of = |f: fn(&SurfaceDistances) -> f64| {
            MeanStd::from_values(&pairs.iter().map(f).collect::<Vec<_>>())
        };
        Ok(Self {
            hd: of(|d| d.hd)?,
            ed: of(|d| d.ed)?,
            ed_star: of(|d| d.ed_star)?,
            cd: of(|d| d.cd)?,
        })
    }
}

/// Distances of paired shapes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairedDistances {
    /// One entry per pair, in input order.
    pub per_pair: Vec<SurfaceDistances>,
    /// Mean ± sd over the pairs.
    pub summary: DistanceSummary,
}

/// Specificity: each sample against its closest training shape.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Specificity {
    /// Distances of each sample to its closest training shape, in sample order.
    pub per_sample: Vec<SurfaceDistances>,
    /// Index of the closest training shape (by ED) of each sample.
    pub closest_training: Vec<usize>,
    /// Mean ± sd over the samples.
    pub summary: DistanceSummary,
}

/// Vertex sets with their k-d trees, built once and compared many times.
#[derive(Debug)]
pub struct IndexedShapes<'a> {
    shapes: Vec<&'a [[f64; 3]]>,
    indices: Vec<PointCloudIndex>,
}

impl<'a> IndexedShapes<'a> {
    /// Indexes every shape; fails on an empty or non-finite one.
    pub fn new<S: AsRef<[[f64; 3]]>>(shapes: &'a [S]) -> Result<Self, EvalError> {
        let shapes: Vec<&[[f64; 3]]> = shapes.iter().map(AsRef::as_ref).collect();
        let indices = parallel_map(&shapes, |s| PointCloudIndex::new(s))
            .into_iter()
            .collect::<Result<_, _>>()?;
        Ok(Self { shapes, indices })
    }

    /// Number of shapes.
    pub fn len(&self) -> usize {
        self.shapes.len()
    }

    /// Whether there are no shapes.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }
}

/// Applies `f` to each item on scoped threads; output order equals input order.
pub(crate) fn parallel_map<T: Sync, U: Send>(items: &[T], f: impl Fn(&T) -> U + Sync) -> Vec<U> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(items.len())
        .max(1);
    if threads == 1 {
        return items.iter().map(&f).collect();
    }
    let chunk = items.len().div_ceil(threads);
    std::thread::scope(|scope| {
        let handles: Vec<_> = items
            .chunks(chunk)
            .map(|c| scope.spawn(|| c.iter().map(&f).collect::<Vec<_>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    })
}

/// `distance` of each pair `(a[i], b[i])` (in parallel) and their summary; the lists must
/// be equally long and non-empty.
pub(crate) fn paired_with<A: Sync, B: Sync>(
    a: &[A],
    b: &[B],
    distance: impl Fn(&A, &B) -> Result<SurfaceDistances, EvalError> + Sync,
) -> Result<PairedDistances, EvalError> {
    if a.len() != b.len() {
        return Err(EvalError::DimensionMismatch {
            what: "paired shapes",
            expected: a.len(),
            found: b.len(),
        });
    }
    let pairs: Vec<(&A, &B)> = a.iter().zip(b).collect();
    let per_pair = parallel_map(&pairs, |(g, h)| distance(g, h))
        .into_iter()
        .collect::<Result<Vec<_>, _>>()?;
    let summary = DistanceSummary::from_pairs(&per_pair)?;
    Ok(PairedDistances { per_pair, summary })
}

/// Vertex-to-vertex distances of pairs `(a[i], b[i])`.
fn paired<A: AsRef<[[f64; 3]]> + Sync, B: AsRef<[[f64; 3]]> + Sync>(
    a: &[A],
    b: &[B],
) -> Result<PairedDistances, EvalError> {
    paired_with(a, b, |g, h| {
        let (g, h) = (g.as_ref(), h.as_ref());
        Ok(surface_distances_indexed(
            g,
            &PointCloudIndex::new(g)?,
            h,
            &PointCloudIndex::new(h)?,
        ))
    })
}

/// Generalisation: distances between each reconstruction (`g`) of a held-out shape and the
/// original (`g'`).
pub fn generalisation<A, B>(
    reconstructions: &[A],
    originals: &[B],
) -> Result<PairedDistances, EvalError>
where
    A: AsRef<[[f64; 3]]> + Sync,
    B: AsRef<[[f64; 3]]> + Sync,
{
    paired(reconstructions, originals)
}

/// Matching quality: distances between each input mesh's vertices (`g`) and its normalised
/// shape (`g'`).
pub fn matching<A, B>(inputs: &[A], normalised: &[B]) -> Result<PairedDistances, EvalError>
where
    A: AsRef<[[f64; 3]]> + Sync,
    B: AsRef<[[f64; 3]]> + Sync,
{
    paired(inputs, normalised)
}

/// Specificity: each sample (`g`) against the training shape (`g'`) with the smallest
/// `ED(sample, training)`, ties to the lower index.
pub fn specificity_indexed<S: AsRef<[[f64; 3]]> + Sync>(
    samples: &[S],
    training: &IndexedShapes<'_>,
) -> Result<Specificity, EvalError> {
    if training.is_empty() {
        return Err(EvalError::TooFewValues {
            what: "training shapes",
            required: 1,
            found: 0,
        });
    }
    let results = parallel_map(
        samples,
        |s| -> Result<(usize, SurfaceDistances), EvalError> {
            let s = s.as_ref();
            let own = PointCloudIndex::new(s)?;
            let mut best = (0, f64::INFINITY);
            for (k, index) in training.indices.iter().enumerate() {
                let ed = directed(s, index).mean;
                if ed < best.1 {
                    best = (k, ed);
                }
            }
            let k = best.0;
            Ok((
                k,
                surface_distances_indexed(s, &own, training.shapes[k], &training.indices[k]),
            ))
        },
    )
    .into_iter()
    .collect::<Result<Vec<_>, _>>()?;
    let (closest_training, per_sample): (Vec<usize>, Vec<SurfaceDistances>) =
        results.into_iter().unzip();
    let summary = DistanceSummary::from_pairs(&per_sample)?;
    Ok(Specificity {
        per_sample,
        closest_training,
        summary,
    })
}

/// [`specificity_indexed`] building the training indices first.
pub fn specificity<S, T>(samples: &[S], training: &[T]) -> Result<Specificity, EvalError>
where
    S: AsRef<[[f64; 3]]> + Sync,
    T: AsRef<[[f64; 3]]>,
{
    specificity_indexed(samples, &IndexedShapes::new(training)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shifted(p: &[[f64; 3]], dz: f64) -> Vec<[f64; 3]> {
        p.iter().map(|v| [v[0], v[1], v[2] + dz]).collect()
    }

    fn square() -> Vec<[f64; 3]> {
        vec![
            [0.0, 0.0, 0.0],
            [10.0, 0.0, 0.0],
            [0.0, 10.0, 0.0],
            [10.0, 10.0, 0.0],
        ]
    }

    #[test]
    fn generalisation_by_hand() {
        // Pair 1 offset by 1 mm, pair 2 by 3 mm: every distance equals the offset.
        let recon = vec![shifted(&square(), 1.0), shifted(&square(), 3.0)];
        let orig = vec![square(), square()];
        let g = generalisation(&recon, &orig).unwrap();
        assert_eq!(g.per_pair[1].hd, 3.0);
        assert_eq!(g.summary.hd.mean, 2.0);
        assert!((g.summary.hd.std - 2f64.sqrt()).abs() < 1e-12);
        assert_eq!(g.summary.cd.mean, 4.0);
        assert!(generalisation(&recon, &orig[..1]).is_err());
    }

    #[test]
    fn specificity_picks_the_closest_training_shape() {
        let training = vec![
            shifted(&square(), 0.0),
            shifted(&square(), 5.0),
            shifted(&square(), 20.0),
        ];
        let samples = vec![
            shifted(&square(), 4.0),
            shifted(&square(), 19.0),
            shifted(&square(), -1.0),
        ];
        let s = specificity(&samples, &training).unwrap();
        assert_eq!(s.closest_training, vec![1, 2, 0]);
        assert_eq!(
            s.per_sample.iter().map(|d| d.ed).collect::<Vec<_>>(),
            vec![1.0, 1.0, 1.0]
        );
        assert_eq!(
            s.summary.hd,
            MeanStd {
                mean: 1.0,
                std: 0.0
            }
        );
        let empty: Vec<Vec<[f64; 3]>> = Vec::new();
        assert!(specificity(&samples, &empty).is_err());
    }

    #[test]
    fn matching_is_asymmetric_for_subsets() {
        // The normalised shape holds only two of the input's four corners.
        let input = vec![square()];
        let normalised = vec![vec![[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]]];
        let m = matching(&input, &normalised).unwrap();
        let d = m.per_pair[0];
        assert_eq!(d.ed_star, 0.0);
        assert_eq!(d.ed, 5.0);
        assert_eq!(d.hd, 10.0);
    }
}
