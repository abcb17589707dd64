//! How often surfaces fold over: edges whose two triangles face opposite ways
//! ([`folded_edges`]). A member that folds over cannot be meshed into a volume for a
//! simulation without repair, and its biomarkers are measured on a self-overlapping
//! surface. Counted per 1,000 edges, so that surfaces of different resolutions (a cohort's
//! atlas connectivity, the uploaded meshes) compare.

use serde::{Deserialize, Serialize};

use crate::mesh::Mesh;
use crate::mesh::measures::folded_edges;

/// Folded edges per 1,000 above which a model's summary warns that its members fold over.
pub const FOLDING_WARNING_PER_MILLE: f64 = 10.0;

/// Folded edges of a set of surfaces.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Folding {
    /// Folded edges per 1,000 edges, mean over the surfaces.
    pub per_mille: f64,
    /// Surfaces with at least one folded edge.
    pub surfaces_folded: usize,
    /// Surfaces measured.
    pub surfaces: usize,
}

impl Folding {
    /// The folding of `meshes` (`None` when there are none). A surface's edges are counted
    /// as three halves of its triangles, exact for the closed surfaces of members and
    /// validated uploads (an open surface's rate comes out slightly high).
    pub fn of<'a>(meshes: impl IntoIterator<Item = &'a Mesh>) -> Option<Self> {
        let (mut sum, mut folded, mut count) = (0.0, 0, 0);
        for mesh in meshes {
            let edges = 3 * mesh.faces.len() / 2;
            let k = folded_edges(mesh);
            sum += 1000.0 * k as f64 / edges.max(1) as f64;
            folded += usize::from(k > 0);
            count += 1;
        }
        (count > 0).then(|| Self {
            per_mille: sum / count as f64,
            surfaces_folded: folded,
            surfaces: count,
        })
    }

    /// In words, e.g. "3.1 of every 1,000 edges folded over (12 of 20 surfaces have a
    /// fold)".
    pub fn describe(&self) -> String {
        format!(
            "{:.1} of every 1,000 edges folded over ({} of {} surfaces have a fold)",
            self.per_mille, self.surfaces_folded, self.surfaces
        )
    }
}

/// A warning when members fold over far more than the training meshes: above
/// [`FOLDING_WARNING_PER_MILLE`] and three times the training meshes' rate.
pub fn folding_warning(members: &Folding, training: &Folding) -> Option<String> {
    (members.per_mille > FOLDING_WARNING_PER_MILLE && members.per_mille > 3.0 * training.per_mille)
        .then(|| {
            format!(
                "The members fold over at {:.1} of every 1,000 edges, the training meshes at \
                 {:.1}: triangles turned back onto their neighbours, which a volume mesher \
                 for a simulation refuses. Repair the members before meshing them; for a \
                 solid organ such as a kidney, an ASMG-family fit started from an icosphere \
                 (\"atlas\": \"icosphere\") folds about ten times less often (not for hollow \
                 organs such as a ventricle, whose walls it cannot follow)",
                members.per_mille, training.per_mille
            )
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::{cube, folded_square};

    #[test]
    fn folding_counts_per_thousand_edges_and_folded_surfaces() {
        let (c, s) = (cube(), folded_square());
        let f = Folding::of([&c, &s, &c]).unwrap();
        assert_eq!((f.surfaces_folded, f.surfaces), (1, 3));
        // The square: 1 folded edge of 3 (two triangles have 6 edge uses, counted as 3
        // edges); the cubes none.
        assert!((f.per_mille - 1000.0 / 3.0 / 3.0).abs() < 1e-9, "{f:?}");
        assert!(f.describe().starts_with("111.1 of every 1,000 edges"));
        assert!(Folding::of([]).is_none());
    }

    #[test]
    fn a_warning_only_when_members_fold_far_more_than_the_patients() {
        let at = |per_mille| Folding {
            per_mille,
            surfaces_folded: 1,
            surfaces: 1,
        };
        let warning = folding_warning(&at(78.0), &at(0.2)).expect("a warning");
        assert!(
            warning.starts_with("The members fold over at 78.0"),
            "{warning}"
        );
        // Few folds, or no more than the training meshes' own creases: no warning.
        assert!(folding_warning(&at(5.0), &at(0.2)).is_none());
        assert!(folding_warning(&at(12.0), &at(6.0)).is_none());
    }
}
