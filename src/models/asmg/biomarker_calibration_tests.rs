use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::super::marginal_map::shape_index;
use super::*;

/// Closed box `[a, b, c]` mm with a corner at `origin`: 8 vertices, 12 outward triangles.
fn box_shape(sides: [f64; 3], origin: [f64; 3]) -> Vec<f32> {
    (0..8)
        .flat_map(|i| (0..3).map(move |k| (origin[k] + sides[k] * f64::from((i >> k) & 1)) as f32))
        .collect()
}

fn box_faces() -> Vec<[u32; 3]> {
    let corner = |i: u32| [i & 1, (i >> 1) & 1, (i >> 2) & 1].map(f64::from);
    let mut faces = Vec::new();
    for axis in 0..3 {
        for side in 0..2_u32 {
            let quad: Vec<u32> = (0..8).filter(|i| (i >> axis) & 1 == side).collect();
            // `quad` is ordered by the bits of the other two axes: 0, 1, 3, 2 goes round.
            for tri in [[quad[0], quad[1], quad[3]], [quad[0], quad[3], quad[2]]] {
                let [p, q, r] = tri.map(corner);
                let (u, v) = (
                    [0, 1, 2].map(|k| q[k] - p[k]),
                    [0, 1, 2].map(|k| r[k] - p[k]),
                );
                let normal_along_axis = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ][axis];
                let outward = if side == 1 { 1.0 } else { -1.0 };
                faces.push(if normal_along_axis * outward > 0.0 {
                    tri
                } else {
                    [tri[0], tri[2], tri[1]]
                });
            }
        }
    }
    faces
}

/// Boxes whose sides vary by `sd` mm around 10 mm, at random small offsets.
fn boxes(count: usize, sd: f64, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut normal = move || rng.sample::<f64, _>(StandardNormal);
    (0..count)
        .map(|_| {
            let sides = [0; 3].map(|_| 10.0 + sd * normal());
            let origin = [0; 3].map(|_| 0.5 * normal());
            box_shape(sides, origin)
        })
        .collect()
}

fn mean_sd(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

fn column(shapes: &[Vec<f32>], faces: &[[u32; 3]], k: usize) -> Vec<f64> {
    shapes.iter().map(|s| biomarkers(s, faces)[k]).collect()
}

/// The draws after calibration.
fn calibrated(c: &BiomarkerCalibration, drawn: &[Vec<f32>], faces: &[[u32; 3]]) -> Vec<Vec<f32>> {
    drawn
        .iter()
        .map(|d| {
            let mut d = d.clone();
            c.apply(&mut d, faces);
            d
        })
        .collect()
}

#[test]
fn a_box_measures_its_volume_and_area() {
    let [volume, area] = biomarkers(
        &box_shape([10.0, 20.0, 30.0], [5.0, -3.0, 2.0]),
        &box_faces(),
    );
    assert!(
        (volume - 6.0).abs() < 1e-9,
        "6,000 mm³ = 6 ml, got {volume}"
    );
    assert!((area - 22.0).abs() < 1e-9, "2,200 mm² = 22 cm², got {area}");
}

#[test]
fn narrow_draws_get_the_training_volume_and_area_spread() {
    let faces = box_faces();
    let training = boxes(200, 1.0, 1);
    // Draws vary half as much and sit 0.3 mm small on every side.
    let drawn: Vec<Vec<f32>> = boxes(400, 0.5, 2)
        .into_iter()
        .map(|s| s.iter().map(|x| x * 0.97).collect())
        .collect();
    let c = BiomarkerCalibration::fit(&training, None, &[], &drawn, &faces).expect("a calibration");
    let calibrated = calibrated(&c, &drawn, &faces);
    for (k, name) in ["volume", "area"].iter().enumerate() {
        let (train_mean, train_sd) = mean_sd(&column(&training, &faces, k));
        let (drawn_mean, drawn_sd) = mean_sd(&column(&drawn, &faces, k));
        let (mean, sd) = mean_sd(&column(&calibrated, &faces, k));
        assert!(drawn_sd < 0.6 * train_sd, "{name}: the draws start narrow");
        assert!(drawn_mean < 0.95 * train_mean, "{name}: and small");
        assert!(
            (mean / train_mean - 1.0).abs() < 0.01,
            "{name} mean {mean} vs {train_mean}"
        );
        assert!(
            (sd / train_sd - 1.0).abs() < 0.05,
            "{name} sd {sd} vs {train_sd}"
        );
    }
}

#[test]
fn a_shape_of_another_width_is_left_alone() {
    let faces = box_faces();
    let c = BiomarkerCalibration::fit(&boxes(20, 1.0, 3), None, &[], &boxes(20, 0.5, 4), &faces)
        .unwrap();
    let mut other = vec![1.0_f32; 9];
    c.apply(&mut other, &faces);
    assert_eq!(other, vec![1.0_f32; 9]);
}

#[test]
fn training_shapes_of_one_volume_and_area_give_no_calibration() {
    let faces = box_faces();
    // The same box moved around: no biomarker varies, nothing to regress on.
    let moved: Vec<Vec<f32>> = (0..10)
        .map(|i| box_shape([10.0, 12.0, 14.0], [f64::from(i), 0.0, 0.0]))
        .collect();
    assert!(BiomarkerCalibration::fit(&moved, None, &[], &boxes(20, 0.5, 5), &faces).is_none());
}

#[test]
fn draws_get_the_measured_biomarkers_of_the_training_meshes_when_given() {
    let faces = box_faces();
    let training = boxes(200, 1.0, 6);
    // The meshes are 2% larger than their shapes on every side (6% in volume, 4% in area).
    let measured: Vec<[f64; 2]> = training
        .iter()
        .map(|s| biomarkers(&s.iter().map(|x| 1.02 * x).collect::<Vec<_>>(), &faces))
        .collect();
    let drawn = boxes(400, 0.5, 7);
    let c = BiomarkerCalibration::fit(&training, None, &measured, &drawn, &faces).unwrap();
    let calibrated = calibrated(&c, &drawn, &faces);
    for k in 0..2 {
        let targets: Vec<f64> = measured.iter().map(|r| r[k]).collect();
        let ((target_mean, target_sd), (mean, sd)) =
            (mean_sd(&targets), mean_sd(&column(&calibrated, &faces, k)));
        assert!(
            (mean / target_mean - 1.0).abs() < 0.01,
            "{k}: mean {mean} vs {target_mean}"
        );
        assert!(
            (sd / target_sd - 1.0).abs() < 0.05,
            "{k}: sd {sd} vs {target_sd}"
        );
    }
}

/// Each draw's calibrated biomarkers as the map gives them, `[draws][2]`.
fn targets(c: &BiomarkerCalibration, drawn: &[Vec<f32>], faces: &[[u32; 3]]) -> Vec<[f64; 2]> {
    drawn
        .iter()
        .map(|d| c.target(&biomarkers(d, faces)))
        .collect()
}

/// The share of draws whose calibrated volume and area are both within `tolerance`
/// (relative) of their targets.
fn share_on_target(
    c: &BiomarkerCalibration,
    drawn: &[Vec<f32>],
    faces: &[[u32; 3]],
    tolerance: f64,
) -> f64 {
    let wanted = targets(c, drawn, faces);
    let hits = calibrated(c, drawn, faces)
        .iter()
        .zip(&wanted)
        .filter(|(s, t)| {
            let b = biomarkers(s, faces);
            (0..2).all(|k| ((b[k] - t[k]) / t[k]).abs() <= tolerance)
        })
        .count();
    hits as f64 / drawn.len() as f64
}

#[test]
fn repeated_moves_put_the_draws_on_their_targets() {
    let faces = box_faces();
    // Volume is cubic in the sides: one move along the regression lands beside the target.
    let drawn = boxes(400, 0.5, 9);
    let fitted = BiomarkerCalibration::fit(&boxes(200, 1.0, 8), None, &[], &drawn, &faces);
    // Affine targets: a box's volume and area are tied so closely that the quantile maps'
    // targets leave some of these draws off them after the last move (on 100 LV phantoms
    // every draw meets them).
    let c = BiomarkerCalibration {
        marginals: None,
        shape_maps: None,
        ..fitted.unwrap()
    };
    assert_eq!(c.steps, CALIBRATION_STEPS);
    let one = BiomarkerCalibration {
        steps: 1,
        ..c.clone()
    };
    let single = share_on_target(&one, &drawn, &faces, 1e-4);
    let repeated = share_on_target(&c, &drawn, &faces, 1e-4);
    assert!(single < 0.05, "one move: {single} on target");
    assert!(repeated > 0.9, "repeated moves: {repeated} on target");
}

#[test]
fn a_calibration_stored_without_steps_moves_once() {
    let faces = box_faces();
    let c = BiomarkerCalibration::fit(&boxes(200, 1.5, 10), None, &[], &boxes(50, 0.4, 11), &faces)
        .unwrap();
    let mut stored = serde_json::to_value(&c).unwrap();
    stored.as_object_mut().unwrap().remove("steps");
    let read: BiomarkerCalibration = serde_json::from_value(stored).unwrap();
    assert_eq!(read.steps, 1);
    let one = BiomarkerCalibration { steps: 1, ..c };
    let drawn = boxes(50, 0.4, 11);
    assert_eq!(
        calibrated(&read, &drawn, &faces),
        calibrated(&one, &drawn, &faces)
    );
}

/// Boxes whose sides are `10·exp(0.15·z)` mm: their volumes are skewed to the right.
fn skewed_boxes(count: usize, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|_| {
            let sides = [0; 3].map(|_| 10.0 * (0.15 * rng.sample::<f64, _>(StandardNormal)).exp());
            box_shape(sides, [0.0; 3])
        })
        .collect()
}

fn skewness(values: &[f64]) -> f64 {
    let (mean, sd) = mean_sd(values);
    let n = values.len() as f64;
    values
        .iter()
        .map(|v| ((v - mean) / sd).powi(3))
        .sum::<f64>()
        / n
}

#[test]
fn draws_take_the_skew_of_the_training_volumes() {
    let faces = box_faces();
    let training = skewed_boxes(300, 12);
    let drawn = boxes(3000, 0.5, 13);
    let c = BiomarkerCalibration::fit(&training, None, &[], &drawn, &faces).unwrap();
    assert!(c.shape_maps.is_some());
    let affine_only = BiomarkerCalibration {
        shape_maps: None,
        ..c.clone()
    };
    let fresh = boxes(1000, 0.5, 14);
    let trained = skewness(&column(&training, &faces, 0));
    let matched = skewness(&column(&calibrated(&c, &fresh, &faces), &faces, 0));
    let affine = skewness(&column(
        &calibrated(&affine_only, &fresh, &faces),
        &faces,
        0,
    ));
    assert!(trained > 0.5, "training volume skew {trained}");
    assert!(
        (matched - trained).abs() < 0.25 && (matched - trained).abs() < (affine - trained).abs(),
        "skew: training {trained}, quantile-matched {matched}, affine {affine}"
    );
    let (t_mean, t_sd) = mean_sd(&column(&training, &faces, 0));
    let (m_mean, m_sd) = mean_sd(&column(&calibrated(&c, &fresh, &faces), &faces, 0));
    assert!((m_mean / t_mean - 1.0).abs() < 0.02, "{m_mean} vs {t_mean}");
    assert!((m_sd / t_sd - 1.0).abs() < 0.08, "{m_sd} vs {t_sd}");
}

/// The affine target of a draw whose biomarkers are `b`.
fn affine_target(c: &BiomarkerCalibration, b: [f64; 2]) -> [f64; 2] {
    let d = [b[0] - c.drawn_mean[0], b[1] - c.drawn_mean[1]];
    [0, 1].map(|k| c.target_mean[k] + c.map[k][0] * d[0] + c.map[k][1] * d[1])
}

/// A calibration of 500 boxes to 100 skew-volumed ones (seeds `seed` and `seed + 1`).
fn skewed_calibration(seed: u64) -> BiomarkerCalibration {
    let (training, drawn) = (skewed_boxes(100, seed), boxes(500, 0.5, seed + 1));
    BiomarkerCalibration::fit(&training, None, &[], &drawn, &box_faces()).unwrap()
}

#[test]
fn a_calibration_stored_without_maps_keeps_affine_targets() {
    let c = skewed_calibration(15);
    let mut stored = serde_json::to_value(&c).unwrap();
    stored.as_object_mut().unwrap().remove("marginals");
    stored.as_object_mut().unwrap().remove("shape_maps");
    let read: BiomarkerCalibration = serde_json::from_value(stored).unwrap();
    assert_eq!((&read.marginals, &read.shape_maps), (&None, &None));
    let b = [1.1 * c.drawn_mean[0], 1.05 * c.drawn_mean[1]];
    assert_eq!(read.target(&b), affine_target(&c, b));
    assert_ne!(c.target(&b), affine_target(&c, b));
}

#[test]
fn a_calibration_stored_with_separate_maps_keeps_them() {
    let fitted = skewed_calibration(17);
    // A volume map and an area map as models fitted with per-biomarker maps stored them.
    let maps = vec![
        MarginalMap::fit(&[1.0, 2.0, 3.0, 4.0], &[2.0, 4.0, 6.0, 9.0], &[1.0; 4]).unwrap(),
        MarginalMap::fit(&[5.0, 6.0, 7.0, 8.0], &[5.0, 5.5, 6.0, 6.5], &[1.0; 4]).unwrap(),
    ];
    let mut stored = serde_json::to_value(BiomarkerCalibration {
        marginals: Some(maps.clone()),
        ..fitted.clone()
    })
    .unwrap();
    stored.as_object_mut().unwrap().remove("shape_maps");
    let read: BiomarkerCalibration = serde_json::from_value(stored).unwrap();
    let b = [1.2, 6.1];
    let affine = affine_target(&fitted, b);
    assert_eq!(
        read.target(&b),
        [maps[0].apply(affine[0]), maps[1].apply(affine[1])]
    );
}

/// Area over volume^(2/3) of each shape.
fn shape_indices(shapes: &[Vec<f32>], faces: &[[u32; 3]]) -> Vec<f64> {
    shapes
        .iter()
        .map(|s| {
            let [volume, area] = biomarkers(s, faces);
            shape_index(volume, area)
        })
        .collect()
}

#[test]
fn draws_keep_the_training_shapes_roundness() {
    // Skewed training boxes whose volumes and areas are mapped each on its own would take
    // shape indices no training box has; mapping the volume and the shape index keeps them.
    let faces = box_faces();
    let training = skewed_boxes(300, 19);
    let drawn = boxes(3000, 0.5, 20);
    let c = BiomarkerCalibration::fit(&training, None, &[], &drawn, &faces).unwrap();
    let affine: Vec<[f64; 2]> = targets(
        &BiomarkerCalibration {
            shape_maps: None,
            ..c.clone()
        },
        &drawn,
        &faces,
    );
    let separate = BiomarkerCalibration {
        shape_maps: None,
        marginals: (0..2)
            .map(|k| {
                let from: Vec<f64> = affine.iter().map(|t| t[k]).collect();
                MarginalMap::fit(&from, &column(&training, &faces, k), &[1.0; 300])
            })
            .collect(),
        ..c.clone()
    };
    let index_sd = |targets: Vec<[f64; 2]>| {
        let indices: Vec<f64> = targets.iter().map(|t| shape_index(t[0], t[1])).collect();
        mean_sd(&indices).1
    };
    let trained = mean_sd(&shape_indices(&training, &faces)).1;
    let joint = index_sd(targets(&c, &drawn, &faces));
    let apart = index_sd(targets(&separate, &drawn, &faces));
    assert!(
        (joint / trained - 1.0).abs() < 0.1 && (joint - trained).abs() < (apart - trained).abs(),
        "shape index sd: training {trained}, volume and index mapped {joint}, volume and area \
         mapped {apart}"
    );
}
