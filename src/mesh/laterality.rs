//! Which of a paired organ a mesh is: the patient's left or right kidney, lung, ... Left and
//! right forms are mirror images of one another; a model that learns both on one side
//! mirrors the meshes of the other (see the `mirror` option of the ASMG family).

use std::fmt;
use std::str::FromStr;

use super::Mesh;

/// The patient's side of a paired organ.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize, utoipa::ToSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum Laterality {
    /// The patient's left.
    Left,
    /// The patient's right.
    Right,
}

impl Laterality {
    /// Every side, in the order of their names.
    pub const ALL: [Laterality; 2] = [Laterality::Left, Laterality::Right];

    /// The name used in requests and records: `left` or `right`.
    pub fn as_str(self) -> &'static str {
        match self {
            Laterality::Left => "left",
            Laterality::Right => "right",
        }
    }

    /// The other side: what a mirror image of an organ of this side is.
    pub fn opposite(self) -> Self {
        match self {
            Laterality::Left => Laterality::Right,
            Laterality::Right => Laterality::Left,
        }
    }
}

impl fmt::Display for Laterality {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A name that is neither `left` nor `right`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownLaterality(pub String);

impl fmt::Display for UnknownLaterality {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "'{}' is not a side: use left or right", self.0)
    }
}

impl std::error::Error for UnknownLaterality {}

impl FromStr for Laterality {
    type Err = UnknownLaterality;

    /// `left` or `right`, in any case.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Laterality::ALL
            .into_iter()
            .find(|side| side.as_str().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| UnknownLaterality(s.to_owned()))
    }
}

/// The mirror image of a point (mm) in the plane `x = 0`.
pub fn mirror_point(p: [f64; 3]) -> [f64; 3] {
    [-p[0], p[1], p[2]]
}

/// `mesh` reflected through the plane `x = 0` (mm), its triangles rewound so that they still
/// face outwards: the organ of the other side. Volume, area and extents are unchanged.
pub fn mirror_image(mesh: &Mesh) -> Mesh {
    Mesh::new(
        mesh.vertices.iter().copied().map(mirror_point).collect(),
        mesh.faces.iter().map(|&[a, b, c]| [a, c, b]).collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::measures::volume_ml;

    #[test]
    fn a_mirror_image_keeps_its_volume_and_mirrored_twice_is_the_mesh() {
        // A tetrahedron with one corner off the plane x = 0.
        let mesh = Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [10.0, 0.0, 0.0],
                [0.0, 10.0, 0.0],
                [3.0, 2.0, 10.0],
            ],
            vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        );
        let mirrored = mirror_image(&mesh);
        assert_eq!(mirrored.vertices[1], [-10.0, 0.0, 0.0]);
        assert!(volume_ml(&mesh) > 0.0);
        assert!((volume_ml(&mirrored) - volume_ml(&mesh)).abs() < 1e-12);
        assert_eq!(mirror_image(&mirrored), mesh);
    }

    #[test]
    fn names_parse_back_and_others_are_refused() {
        for side in Laterality::ALL {
            assert_eq!(side.as_str().parse::<Laterality>(), Ok(side));
            assert_eq!(side.opposite().opposite(), side);
            assert_ne!(side.opposite(), side);
        }
        assert_eq!(" Right".parse::<Laterality>(), Ok(Laterality::Right));
        let err = "both".parse::<Laterality>().unwrap_err();
        assert_eq!(err.to_string(), "'both' is not a side: use left or right");
        assert_eq!(
            serde_json::to_string(&Laterality::Left).unwrap(),
            "\"left\""
        );
    }
}
