//! The three fixed views of the model frame and the orthographic projection onto a panel.

use serde::Deserialize;

/// A fixed view direction in the model frame (x, y, z in mm).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum View {
    /// From −y towards +y; screen right is +x, up is +z.
    #[default]
    Anterior,
    /// From +x towards −x; screen right is +y, up is +z.
    Lateral,
    /// From +z towards −z; screen right is +x, up is +y.
    Superior,
}

impl View {
    /// All views, in the order a sheet shows them.
    pub const ALL: [View; 3] = [View::Anterior, View::Lateral, View::Superior];

    /// Name as in the API (`?view=`).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Anterior => "anterior",
            Self::Lateral => "lateral",
            Self::Superior => "superior",
        }
    }

    /// The view of that name.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|v| v.as_str() == name)
    }

    /// `(right, up, forward)`: unit vectors of the screen axes and the viewing direction;
    /// `right = forward × up`.
    pub fn axes(self) -> ([f64; 3], [f64; 3], [f64; 3]) {
        match self {
            Self::Anterior => ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]),
            Self::Lateral => ([0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]),
            Self::Superior => ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]),
        }
    }

    /// `[right, up, depth]` of a point (mm); larger depth is farther from the viewer.
    pub fn project(self, p: [f64; 3]) -> [f64; 3] {
        let (r, u, f) = self.axes();
        [dot(p, r), dot(p, u), dot(p, f)]
    }
}

pub(super) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The projected extent of a point set: `(centre [right, up], width, height)` in mm.
pub fn extent(view: View, vertices: &[[f64; 3]]) -> ([f64; 2], f64, f64) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in vertices {
        let q = view.project(*p);
        for a in 0..2 {
            lo[a] = lo[a].min(q[a]);
            hi[a] = hi[a].max(q[a]);
        }
    }
    if vertices.is_empty() {
        return ([0.0; 2], 0.0, 0.0);
    }
    (
        [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0],
        hi[0] - lo[0],
        hi[1] - lo[1],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }

    #[test]
    fn screen_axes_are_right_handed_and_names_round_trip() {
        for view in View::ALL {
            let (r, u, f) = view.axes();
            assert_eq!(cross(f, u), r, "{view:?}");
            assert_eq!(View::parse(view.as_str()), Some(view));
        }
        assert_eq!(View::parse("posterior"), None);
    }

    #[test]
    fn a_box_projects_to_its_sides() {
        let corners: Vec<[f64; 3]> = (0..8)
            .map(|i| {
                [
                    f64::from(i & 1),
                    2.0 * f64::from((i >> 1) & 1),
                    3.0 * f64::from((i >> 2) & 1),
                ]
            })
            .collect();
        let (_, w, h) = extent(View::Anterior, &corners);
        assert_eq!((w, h), (1.0, 3.0));
        let (_, w, h) = extent(View::Lateral, &corners);
        assert_eq!((w, h), (2.0, 3.0));
        let (c, w, h) = extent(View::Superior, &corners);
        assert_eq!((c, w, h), ([0.5, 1.0], 1.0, 2.0));
    }
}
