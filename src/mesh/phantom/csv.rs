//! The phantoms' ground truth as CSV: one row per phantom.

use super::{LOBE_NAMES, MixedParams, Phantom, ShapeParams};
use crate::mesh::measures::volume_ml;

/// Columns before the shape parameters.
const HEAD: [&str; 2] = ["name", "family"];
/// Columns after the shape parameters.
const TAIL: [&str; 11] = [
    "vertex_count",
    "face_count",
    "volume_ml",
    "mesh_volume_ml",
    "pose_qw",
    "pose_qx",
    "pose_qy",
    "pose_qz",
    "pose_tx_mm",
    "pose_ty_mm",
    "pose_tz_mm",
];

/// CSV (comma-separated, `\n` line ends) with a header and one row per phantom: name,
/// family, every generating parameter of the family (mm, ml; liver axes unitless), vertex
/// and face counts, the exact `volume_ml`, the mesh's `mesh_volume_ml` (divergence
/// theorem) and the pose (`x_mesh = R x_canonical + t`, R as a unit quaternion `w, x, y, z`).
///
/// Numbers are written in full (shortest round-trip form). With several families the
/// header holds every family's columns and other families' cells are empty.
pub fn params_csv(phantoms: &[Phantom]) -> String {
    let rows: Vec<Vec<(String, String)>> = phantoms.iter().map(row).collect();
    let mut shape_names: Vec<String> = Vec::new();
    for r in &rows {
        for (name, _) in &r[HEAD.len()..r.len() - TAIL.len()] {
            if !shape_names.contains(name) {
                shape_names.push(name.clone());
            }
        }
    }
    let header: Vec<String> = HEAD
        .iter()
        .map(|s| s.to_string())
        .chain(shape_names)
        .chain(TAIL.iter().map(|s| s.to_string()))
        .collect();
    let mut out = header.join(",");
    out.push('\n');
    for r in &rows {
        let cells: Vec<&str> = header
            .iter()
            .map(|h| {
                r.iter()
                    .find(|(n, _)| n == h)
                    .map_or("", |(_, v)| v.as_str())
            })
            .collect();
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

/// `(column, value)` pairs of one phantom: head, shape parameters, tail.
fn row(p: &Phantom) -> Vec<(String, String)> {
    let mut cells = vec![
        ("name".to_string(), p.name.clone()),
        ("family".to_string(), p.family().to_string()),
    ];
    if let ShapeParams::Mixed(m) = &p.params.shape {
        let label = m.sub_population().as_str();
        cells.push(("subpopulation".to_string(), label.to_string()));
    }
    let mut num = |name: String, value: f64| cells.push((name, value.to_string()));
    match &p.params.shape {
        ShapeParams::Lv(lv) => {
            num("outer_radius_x_mm".into(), lv.outer_radius_x_mm);
            num("outer_radius_y_mm".into(), lv.outer_radius_y_mm);
            num("outer_half_length_mm".into(), lv.outer_half_length_mm);
            num("inner_radius_x_mm".into(), lv.inner_radius_x_mm);
            num("inner_radius_y_mm".into(), lv.inner_radius_y_mm);
            num("inner_half_length_mm".into(), lv.inner_half_length_mm);
            num("base_height_mm".into(), lv.base_height_mm);
            num("long_axis_mm".into(), lv.long_axis_mm());
            num("wall_thickness_mm".into(), lv.wall_thickness_mm());
            num("apex_thickness_mm".into(), lv.apex_thickness_mm());
            num("cavity_volume_ml".into(), lv.cavity_volume_ml());
            num("edge_length_mm".into(), lv.edge_length_mm);
        }
        ShapeParams::Liver(liver) => {
            for (axis, value) in ["a", "b", "c"].iter().zip(liver.axes) {
                num(format!("axis_{axis}"), value);
            }
            num("scale_mm".into(), liver.scale_mm);
            for (name, lobe) in LOBE_NAMES.iter().zip(&liver.lobes) {
                for (axis, d) in ["x", "y", "z"].iter().zip(lobe.direction) {
                    num(format!("{name}_dir_{axis}"), d);
                }
                num(format!("{name}_amplitude"), lobe.amplitude);
                num(format!("{name}_concentration"), lobe.concentration);
            }
            num("sphere_points".into(), liver.sphere_points as f64);
            num("jitter".into(), liver.jitter);
        }
        ShapeParams::Mixed(MixedParams::Bean {
            radius_mm,
            points,
            jitter,
        }) => {
            for (axis, r) in ["x", "y", "z"].iter().zip(radius_mm) {
                num(format!("radius_{axis}_mm"), *r);
            }
            num("sphere_points".into(), *points as f64);
            num("jitter".into(), *jitter);
        }
        ShapeParams::Mixed(MixedParams::Ring {
            major_radius_mm,
            tube_radius_mm,
            tube_half_height_mm,
            n_around,
            n_tube,
        }) => {
            num("major_radius_mm".into(), *major_radius_mm);
            num("tube_radius_mm".into(), *tube_radius_mm);
            num("tube_half_height_mm".into(), *tube_half_height_mm);
            num("n_around".into(), *n_around as f64);
            num("n_tube".into(), *n_tube as f64);
        }
    }
    let q = p.params.pose.quaternion();
    let t = p.params.pose.translation_mm;
    let tail = [
        p.mesh.vertex_count() as f64,
        p.mesh.face_count() as f64,
        p.params.volume_ml,
        volume_ml(&p.mesh),
        q[0],
        q[1],
        q[2],
        q[3],
        t[0],
        t[1],
        t[2],
    ];
    for (name, value) in TAIL.iter().zip(tail) {
        num(name.to_string(), value);
    }
    cells
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::phantom::{Family, generate};

    fn column<'a>(csv: &'a str, name: &str) -> Vec<&'a str> {
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let k = header.iter().position(|h| *h == name).unwrap();
        lines.map(|l| l.split(',').nth(k).unwrap()).collect()
    }

    #[test]
    fn lv_csv_has_a_row_per_phantom_and_parsable_numbers() {
        let phantoms = generate(Family::Lv, 3, 1);
        let csv = params_csv(&phantoms);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 4);
        let width = lines[0].split(',').count();
        assert_eq!(width, HEAD.len() + 12 + TAIL.len());
        assert!(lines.iter().all(|l| l.split(',').count() == width));
        assert_eq!(column(&csv, "name"), ["lv_000", "lv_001", "lv_002"]);
        let counts = column(&csv, "vertex_count");
        assert_eq!(counts[1], phantoms[1].mesh.vertex_count().to_string());
        let v: f64 = column(&csv, "volume_ml")[2].parse().unwrap();
        assert_eq!(v, phantoms[2].params.volume_ml);
    }

    #[test]
    fn mixed_families_share_a_header_with_empty_cells() {
        let mut phantoms = generate(Family::Lv, 1, 2);
        phantoms.extend(generate(Family::Liver, 1, 2));
        let csv = params_csv(&phantoms);
        assert_eq!(column(&csv, "family"), ["lv", "liver"]);
        assert_eq!(column(&csv, "scale_mm")[0], "");
        assert_eq!(column(&csv, "wall_thickness_mm")[1], "");
        assert!(!column(&csv, "right_lobe_amplitude")[1].is_empty());
        let header = csv.lines().next().unwrap();
        assert!(header.starts_with("name,family,outer_radius_x_mm"));
        assert!(header.ends_with("pose_tz_mm"));
    }
}
