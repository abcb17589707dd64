//! Which end of the long axis makes drawn shapes longer: the distance from the centroid to
//! the farthest point on each side of the long axis, and how far that point stands out of
//! the 20 next-farthest (a spike or a wavy rim rather than a longer shape).

use cohortforge::eval::stats;
use cohortforge::mesh::Mesh;
use nalgebra::Vector3;

/// Prints mean (top, bottom, top spike, bottom spike) in mm over `shapes`; "top" is the end
/// towards `reference` (the mean reproduced shape's long axis), or either end without one.
pub fn print_ends(stage: &str, shapes: &[Mesh], reference: Option<&Vector3<f64>>) {
    let rows: Vec<[f64; 4]> = shapes.iter().map(|m| ends(m, reference)).collect();
    let column = |j: usize| stats::mean(&rows.iter().map(|r| r[j]).collect::<Vec<_>>());
    println!(
        "{stage:15} top {:.2}  bottom {:.2} mm  spike top {:.2}  bottom {:.2} mm",
        column(0),
        column(1),
        column(2),
        column(3)
    );
}

fn ends(mesh: &Mesh, reference: Option<&Vector3<f64>>) -> [f64; 4] {
    let (centroid, mut axis) = super::major_axis(mesh);
    if reference.is_some_and(|r| axis.dot(r) < 0.0) {
        axis = -axis;
    }
    let mut heights: Vec<f64> = mesh
        .vertices
        .iter()
        .map(|p| (Vector3::from(*p) - centroid).dot(&axis))
        .collect();
    heights.sort_by(f64::total_cmp);
    let n = heights.len();
    let top = heights[n - 1];
    let bottom = -heights[0];
    let k = 20.min(n - 1);
    let spike_top = top - stats::mean(&heights[n - 1 - k..n - 1]);
    let spike_bottom = bottom + stats::mean(&heights[1..=k]);
    [top, bottom, spike_top, spike_bottom]
}
