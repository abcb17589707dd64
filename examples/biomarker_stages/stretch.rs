//! Draws moved in biomarker space along the training shapes' regression on chosen
//! biomarkers: a linear stretch to a share of the training meshes' covariance, and a
//! rank-for-rank match of each biomarker's marginal (experiments beside the calibration).

use cohortforge::mesh::Mesh;
use cohortforge::models::asmg::marginal_map::MarginalMap;
use nalgebra::{DMatrix, DVector};

use super::{row, vertex_count};

/// `shapes` moved along the training shapes' regression on the biomarkers `columns` (of
/// [`row`]) so that those biomarkers' covariance becomes `share`² times the training meshes'.
pub fn biomarker_stretched(
    training: &[Mesh],
    shapes: &[Mesh],
    meshes: &[Mesh],
    share: f64,
    columns: &[usize],
) -> Vec<Mesh> {
    let k = columns.len();
    let pick = |m: &Mesh| {
        let r = row(m);
        DVector::from_iterator(k, columns.iter().map(|&c| r[c]))
    };
    let centred = |rows: &[DVector<f64>]| {
        let mean = rows.iter().fold(DVector::zeros(k), |s, r| s + r) / rows.len() as f64;
        let cov = rows.iter().fold(DMatrix::zeros(k, k), |s, r| {
            s + (r - &mean) * (r - &mean).transpose()
        }) / (rows.len() as f64 - 1.0);
        (mean, cov)
    };
    let b_train: Vec<DVector<f64>> = training.iter().map(pick).collect();
    let (b_mean, b_cov) = centred(&b_train);
    let n = vertex_count(training) * 3;
    let x = |m: &Mesh| DVector::from_iterator(n, m.vertices.iter().flat_map(|p| *p));
    let x_mean = training.iter().fold(DVector::zeros(n), |s, m| s + x(m)) / training.len() as f64;
    let cross = training
        .iter()
        .zip(&b_train)
        .fold(DMatrix::zeros(n, k), |s, (m, b)| {
            s + (x(m) - &x_mean) * (b - &b_mean).transpose()
        })
        / (training.len() as f64 - 1.0);
    let direction = cross * b_cov.try_inverse().unwrap();
    let (_, target) = centred(&meshes.iter().map(pick).collect::<Vec<_>>());
    let b_drawn: Vec<DVector<f64>> = shapes.iter().map(pick).collect();
    let (d_mean, d_cov) = centred(&b_drawn);
    let sqrt = |m: &DMatrix<f64>, power: f64| {
        let e = m.clone().symmetric_eigen();
        let d = DMatrix::from_diagonal(&e.eigenvalues.map(|v| v.powf(power)));
        &e.eigenvectors * d * e.eigenvectors.transpose()
    };
    let map = sqrt(&(target * share * share), 0.5) * sqrt(&d_cov, -0.5);
    shapes
        .iter()
        .zip(&b_drawn)
        .map(|(m, b)| {
            let deviation = b - &d_mean;
            let step = &direction * (&map * &deviation - &deviation);
            let moved = x(m) + step;
            let vertices = moved
                .as_slice()
                .chunks_exact(3)
                .map(|p| [p[0], p[1], p[2]])
                .collect();
            Mesh::new(vertices, m.faces.clone())
        })
        .collect()
}

/// `shapes` moved along the training shapes' regression on the biomarkers `columns` so that
/// each biomarker's marginal becomes that of a smoothed density of the training meshes'
/// (a Gaussian kernel density shrunk to their sd), rank for rank.
pub fn quantile_matched(
    training: &[Mesh],
    shapes: &[Mesh],
    meshes: &[Mesh],
    columns: &[usize],
) -> Vec<Mesh> {
    let k = columns.len();
    let pick = |m: &Mesh| {
        let r = row(m);
        DVector::from_iterator(k, columns.iter().map(|&c| r[c]))
    };
    let b_train: Vec<DVector<f64>> = training.iter().map(pick).collect();
    let nt = b_train.len() as f64;
    let b_mean = b_train.iter().fold(DVector::zeros(k), |s, r| s + r) / nt;
    let b_cov = b_train.iter().fold(DMatrix::zeros(k, k), |s, r| {
        s + (r - &b_mean) * (r - &b_mean).transpose()
    }) / (nt - 1.0);
    let n = vertex_count(training) * 3;
    let x = |m: &Mesh| DVector::from_iterator(n, m.vertices.iter().flat_map(|p| *p));
    let x_mean = training.iter().fold(DVector::zeros(n), |s, m| s + x(m)) / nt;
    let cross = training
        .iter()
        .zip(&b_train)
        .fold(DMatrix::zeros(n, k), |s, (m, b)| {
            s + (x(m) - &x_mean) * (b - &b_mean).transpose()
        })
        / (nt - 1.0);
    let direction = cross * b_cov.try_inverse().unwrap();
    let b_drawn: Vec<DVector<f64>> = shapes.iter().map(pick).collect();
    let targets: Vec<Vec<f64>> = (0..k)
        .map(|c| {
            let values: Vec<f64> = meshes.iter().map(|m| row(m)[columns[c]]).collect();
            let drawn: Vec<f64> = b_drawn.iter().map(|b| b[c]).collect();
            rank_matched(&drawn, &values)
        })
        .collect();
    shapes
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let delta = DVector::from_fn(k, |c, _| targets[c][i] - b_drawn[i][c]);
            let moved = x(m) + &direction * delta;
            let vertices = moved
                .as_slice()
                .chunks_exact(3)
                .map(|p| [p[0], p[1], p[2]])
                .collect();
            Mesh::new(vertices, m.faces.clone())
        })
        .collect()
}

/// Each value of `drawn` through the model's quantile map from the draws' distribution to a
/// smoothed density of `reference` (the values themselves where no map can be fitted).
fn rank_matched(drawn: &[f64], reference: &[f64]) -> Vec<f64> {
    match MarginalMap::fit(drawn, reference, &vec![1.0; reference.len()]) {
        Some(map) => drawn.iter().map(|x| map.apply(*x)).collect(),
        None => drawn.to_vec(),
    }
}
