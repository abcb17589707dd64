//! The tables trial tools read: cohort members, PCA modes, and the training and held-out
//! meshes of a model, as CSV built from what is stored.

use super::csv::{Cell, Csv};
use crate::eval::Biomarkers;
use crate::geometry::distance::SurfaceDistances;

/// File name of member `index` in a cohort archive of meshes with `extension`.
pub fn member_file_name(index: usize, extension: &str) -> String {
    format!("member_{index:05}.{extension}")
}

fn number(v: &serde_json::Value, key: &str) -> Cell {
    v.get(key).and_then(serde_json::Value::as_f64).into()
}

fn flag(v: Option<&serde_json::Value>) -> Cell {
    v.and_then(serde_json::Value::as_bool).into()
}

/// One row per member (stored member summaries, in member order): index, draw, cluster,
/// every biomarker by its JSON name, the acceptance flags, the near-copy fields and the
/// member's file name in an archive of `extension` files.
pub fn members_csv(members: &[serde_json::Value], extension: &str) -> String {
    let mut header = vec!["index", "draw", "cluster"];
    header.extend(Biomarkers::NAMES);
    header.extend([
        "accepted_range",
        "accepted_mode",
        "accepted_mean",
        "near_copy",
        "nearest_training_mm",
        "nearest_training_mesh_id",
        "file",
    ]);
    let mut csv = Csv::new(&header);
    for (position, m) in members.iter().enumerate() {
        let index = m
            .get("index")
            .and_then(serde_json::Value::as_u64)
            .map_or(position, |i| i as usize);
        let mut row = vec![Cell::from(index), number(m, "draw"), number(m, "cluster")];
        let biomarkers = m.get("biomarkers");
        row.extend(Biomarkers::NAMES.iter().map(|name| {
            biomarkers
                .and_then(|b| b.get(*name))
                .and_then(serde_json::Value::as_f64)
                .into()
        }));
        let accepted = m.get("accepted");
        row.extend(["range", "mode", "mean"].map(|c| flag(accepted.and_then(|a| a.get(c)))));
        row.push(flag(m.get("near_copy")));
        row.push(number(m, "nearest_training_mm"));
        row.push(
            m.get("nearest_training_mesh_id")
                .and_then(serde_json::Value::as_str)
                .into(),
        );
        row.push(Cell::Text(member_file_name(index, extension)));
        csv.row(row);
    }
    csv.finish()
}

/// One row per kept PCA mode: its variance (mm²), sd (mm), share of the total variance and
/// the cumulative share (from `cumulative`, over every mode found at fit time).
pub fn modes_csv(variances_mm2: &[f64], cumulative: &[f64]) -> String {
    let mut csv = Csv::new(&[
        "mode",
        "eigenvalue_mm2",
        "sd_mm",
        "explained_variance",
        "cumulative_explained_variance",
    ]);
    for (i, l) in variances_mm2.iter().enumerate() {
        let c = cumulative.get(i).copied();
        let previous = if i == 0 {
            Some(0.0)
        } else {
            cumulative.get(i - 1).copied()
        };
        let share = c.zip(previous).map(|(c, p)| c - p);
        csv.row(vec![
            (i + 1).into(),
            (*l).into(),
            l.sqrt().into(),
            share.into(),
            c.into(),
        ]);
    }
    csv.finish()
}

/// A mesh of a model's training or held-out set.
#[derive(Debug, Clone)]
pub struct MeshRow<'a> {
    /// The mesh id.
    pub mesh_id: &'a str,
    /// `training` or `holdout`.
    pub role: &'static str,
    /// Its biomarkers in [`Biomarkers::NAMES`] order.
    pub biomarkers: [f64; 6],
    /// Its reconstruction against it (held-out meshes).
    pub generalisation: Option<SurfaceDistances>,
    /// It against its normalised shape (held-out meshes).
    pub matching: Option<SurfaceDistances>,
    /// Soft cluster weights `w_km` (multi-atlas models).
    pub weights: Option<&'a [f64]>,
}

/// One row per mesh: id, role, biomarkers, reconstruction and matching distances (mm) and,
/// for models with `clusters` atlases (more than one), the weights and the winning cluster.
pub fn training_csv(rows: &[MeshRow<'_>], clusters: usize) -> String {
    let mut header: Vec<String> = ["mesh_id", "role"].map(String::from).to_vec();
    header.extend(Biomarkers::NAMES.map(String::from));
    for what in ["generalisation", "matching"] {
        header.extend(["hd_mm", "ed_mm", "ed_star_mm", "cd_mm"].map(|m| format!("{what}_{m}")));
    }
    if clusters > 1 {
        header.extend((0..clusters).map(|m| format!("weight_{m}")));
        header.push("cluster".into());
    }
    let mut csv = Csv::new(&header);
    for r in rows {
        let mut row = vec![Cell::from(r.mesh_id), Cell::from(r.role)];
        row.extend(r.biomarkers.map(Cell::from));
        for d in [r.generalisation, r.matching] {
            row.extend(match d {
                Some(d) => [d.hd, d.ed, d.ed_star, d.cd].map(Cell::from),
                None => std::array::from_fn(|_| Cell::Empty),
            });
        }
        if clusters > 1 {
            let w = r.weights.unwrap_or(&[]);
            row.extend((0..clusters).map(|m| Cell::from(w.get(m).copied())));
            row.push(
                (!w.is_empty())
                    .then(|| crate::models::clusters::winning_cluster(w))
                    .into(),
            );
        }
        csv.row(row);
    }
    csv.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn members_rows_follow_the_stored_summaries() {
        let member = serde_json::json!({
            "index": 2, "draw": 5, "cluster": 1,
            "biomarkers": {"volume_ml": 101.5, "area_cm2": 80.25},
            "accepted": {"range": true, "mode": false, "mean": true},
            "near_copy": false, "nearest_training_mm": 1.5, "nearest_training_mesh_id": "m-1"
        });
        let csv = members_csv(&[member], "stl");
        let lines: Vec<&str> = csv.lines().collect();
        assert!(lines[0].starts_with("index,draw,cluster,volume_ml,area_cm2,sphericity"));
        assert!(lines[0].ends_with("nearest_training_mesh_id,file"));
        assert_eq!(
            lines[1],
            "2,5,1,101.5,80.25,,,,,true,false,true,false,1.5,m-1,member_00002.stl"
        );
    }

    #[test]
    fn modes_have_their_share_of_the_variance() {
        let csv = modes_csv(&[4.0, 1.0], &[0.6, 0.9, 1.0]);
        assert_eq!(
            csv,
            "mode,eigenvalue_mm2,sd_mm,explained_variance,cumulative_explained_variance\r\n\
             1,4,2,0.6,0.6\r\n2,1,1,0.30000000000000004,0.9\r\n"
        );
    }
}
