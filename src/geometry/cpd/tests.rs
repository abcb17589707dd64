use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;
use crate::geometry::points::{IDENTITY3, axis_angle, dist2, rotation_angle, transpose};
use crate::geometry::transform::axis_permutation_rotations;

/// Half-size of the test shape (largest semi-axis), mm.
const SIZE_MM: f64 = 30.0;

/// An ellipsoid-like surface cloud (semi-axes 30, 20, 12 mm) with two asymmetric bumps,
/// centred near (50, −20, 10) mm.
pub(crate) fn bumpy_ellipsoid(n: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let bumps = [
        ([0.6, 0.7, 0.38], 0.35, 0.15),
        ([-0.5, -0.2, 0.84], 0.2, 0.1),
    ];
    (0..n)
        .map(|_| {
            let u = loop {
                let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                let r2 = points::norm2(v);
                if r2 > 1e-6 && r2 <= 1.0 {
                    break points::scale(v, 1.0 / r2.sqrt());
                }
            };
            let r = 1.0
                + bumps
                    .iter()
                    .map(|(c, h, wd)| h * (-dist2(u, *c) / wd).exp())
                    .sum::<f64>();
            [
                50.0 + SIZE_MM * r * u[0],
                -20.0 + 20.0 * r * u[1],
                10.0 + 12.0 * r * u[2],
            ]
        })
        .collect()
}

fn rotation_error(a: &Mat3, b: &Mat3) -> f64 {
    let mut e: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            e = e.max((a[i][j] - b[i][j]).abs());
        }
    }
    e
}

fn shuffled(mut p: Vec<[f64; 3]>, seed: u64) -> Vec<[f64; 3]> {
    p.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    p
}

fn assert_recovered(est: &RigidTransform, truth: &RigidTransform) {
    let rot = rotation_error(&est.rotation, &truth.rotation);
    let trans = dist2(est.translation, truth.translation).sqrt() / SIZE_MM;
    assert!(rot < 1e-3, "rotation error {rot}");
    assert!(trans < 1e-3, "relative translation error {trans}");
    assert!(
        (est.scale - truth.scale).abs() < 1e-3,
        "scale {} vs {}",
        est.scale,
        truth.scale
    );
}

#[test]
fn recovers_rotation_and_translation() {
    let template = bumpy_ellipsoid(300, 1);
    let truth = RigidTransform {
        rotation: axis_angle([1.0, 2.0, 3.0], 0.6),
        translation: [5.0, -10.0, 20.0],
        scale: 1.0,
    };
    let data = shuffled(truth.apply_all(&template), 2);
    let result = rigid_cpd(&template, &data, &RigidCpdParams::default()).unwrap();
    assert_recovered(&result.transform, &truth);
    assert!(result.sigma2 < 1e-3, "sigma2 {}", result.sigma2);
    assert!((points::det(&result.transform.rotation) - 1.0).abs() < 1e-12);
}

#[test]
fn recovers_scale_when_enabled() {
    let template = bumpy_ellipsoid(300, 3);
    let truth = RigidTransform {
        rotation: axis_angle([-1.0, 0.5, 0.2], 0.5),
        translation: [-8.0, 4.0, 2.0],
        scale: 1.2,
    };
    let data = shuffled(truth.apply_all(&template), 4);
    let params = RigidCpdParams {
        scale: true,
        ..RigidCpdParams::default()
    };
    let result = rigid_cpd(&template, &data, &params).unwrap();
    assert_recovered(&result.transform, &truth);
}

#[test]
fn recovers_with_fewer_data_points_than_template_points() {
    let template = bumpy_ellipsoid(400, 5);
    let truth = RigidTransform {
        rotation: axis_angle([0.0, 1.0, 1.0], -0.7),
        translation: [3.0, 3.0, -6.0],
        scale: 1.0,
    };
    let data: Vec<_> = shuffled(truth.apply_all(&template), 6)
        .into_iter()
        .take(230)
        .collect();
    let result = rigid_cpd(&template, &data, &RigidCpdParams::default()).unwrap();
    assert_recovered(&result.transform, &truth);
}

#[test]
fn tolerates_noise_and_outliers() {
    // 0.1 mm jitter on every point and 30 uniform outliers in a 100 mm box.
    let template = bumpy_ellipsoid(300, 14);
    let truth = RigidTransform {
        rotation: axis_angle([0.5, -1.0, 0.3], 0.4),
        translation: [2.0, -3.0, 4.0],
        scale: 1.0,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(15);
    let mut data: Vec<[f64; 3]> = truth
        .apply_all(&template)
        .into_iter()
        .map(|p| std::array::from_fn(|k| p[k] + rng.random_range(-0.1..0.1)))
        .collect();
    data.extend(
        (0..30).map(|_| {
            std::array::from_fn(|k| [50.0, -20.0, 10.0][k] + rng.random_range(-50.0..50.0))
        }),
    );
    let result = rigid_cpd(&template, &data, &RigidCpdParams::default()).unwrap();
    let rot = rotation_error(&result.transform.rotation, &truth.rotation);
    let trans = dist2(result.transform.translation, truth.translation).sqrt();
    assert!(rot < 5e-3, "rotation error {rot}");
    assert!(trans < 0.2, "translation error {trans} mm");
}

#[test]
fn multistart_recovers_a_large_rotation_that_one_start_misses() {
    let template = bumpy_ellipsoid(150, 7);
    let centre = points::centroid(&template, None);
    let turn =
        RigidTransform::rotation_about(axis_angle([0.2, 0.3, 1.0], 150f64.to_radians()), centre);
    let truth = RigidTransform {
        translation: points::add(turn.translation, [10.0, 0.0, -5.0]),
        ..turn
    };
    let data = shuffled(truth.apply_all(&template), 8);
    let params = RigidCpdParams::default();
    let single = rigid_cpd_multistart(&template, &data, &params, &[IDENTITY3]).unwrap();
    let miss = rotation_angle(&points::mat_mul(
        &transpose(&single.transform.rotation),
        &truth.rotation,
    ));
    assert!(
        miss > 0.2,
        "single start unexpectedly found the rotation (residual angle {miss})"
    );
    let multi =
        rigid_cpd_multistart(&template, &data, &params, &axis_permutation_rotations()).unwrap();
    assert_recovered(&multi.transform, &truth);
    assert!(multi.negative_log_likelihood < single.negative_log_likelihood);
}

#[test]
fn rejects_bad_params_and_inputs() {
    let t = bumpy_ellipsoid(10, 9);
    let bad = RigidCpdParams {
        w: 1.0,
        ..RigidCpdParams::default()
    };
    assert_eq!(
        rigid_cpd(&t, &t, &bad).unwrap_err().code(),
        "geometry.invalid_params"
    );
    assert_eq!(
        rigid_cpd(&t, &[], &RigidCpdParams::default())
            .unwrap_err()
            .code(),
        "geometry.empty_point_set"
    );
    let same = vec![[1.0, 2.0, 3.0]; 5];
    assert_eq!(
        rigid_cpd(&same, &same, &RigidCpdParams::default())
            .unwrap_err()
            .code(),
        "geometry.degenerate_input"
    );
    assert_eq!(
        rigid_cpd_multistart(&t, &t, &RigidCpdParams::default(), &[])
            .unwrap_err()
            .code(),
        "geometry.invalid_params"
    );
}

#[test]
fn same_seed_same_result() {
    let template = bumpy_ellipsoid(200, 10);
    let data = axis_angle([1.0, 0.0, 0.0], 0.3);
    let data = RigidTransform {
        rotation: data,
        translation: [1.0, 2.0, 3.0],
        scale: 1.0,
    }
    .apply_all(&bumpy_ellipsoid(250, 11));
    let a = rigid_cpd(&template, &data, &RigidCpdParams::default()).unwrap();
    let b = rigid_cpd(&template, &data, &RigidCpdParams::default()).unwrap();
    assert_eq!(a, b);
}

/// Timing of rigid CPD on 2,000 × 2,000 points (printed, not asserted).
/// Run with `cargo test --lib geometry::cpd::tests::timing -- --ignored --nocapture`.
#[test]
#[ignore]
fn timing_2000_by_2000() {
    let template = bumpy_ellipsoid(2000, 12);
    let truth = RigidTransform {
        rotation: axis_angle([1.0, 1.0, 0.0], 0.5),
        translation: [4.0, 0.0, 0.0],
        scale: 1.0,
    };
    let data = truth.apply_all(&bumpy_ellipsoid(2000, 13));
    let (start, cpu_start) = (std::time::Instant::now(), process_cpu_seconds());
    let r = rigid_cpd(&template, &data, &RigidCpdParams::default()).unwrap();
    let (elapsed, cpu) = (
        start.elapsed().as_secs_f64(),
        process_cpu_seconds() - cpu_start,
    );
    println!(
        "rigid CPD 2000x2000: wall {elapsed:.3} s, cpu {cpu:.2} s, {} iterations \
         ({:.1} ms wall per E+M step), converged {}, sigma2 {:.4}",
        r.iterations,
        elapsed * 1e3 / (r.iterations + 1) as f64,
        r.converged,
        r.sigma2
    );
}

/// User + system CPU time of this process in seconds (Linux; 0 elsewhere).
fn process_cpu_seconds() -> f64 {
    const TICKS_PER_SECOND: f64 = 100.0;
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after_name = stat.rsplit(')').next().unwrap_or_default();
    let fields: Vec<&str> = after_name.split_whitespace().collect();
    // Fields 14 and 15 of stat (utime, stime) sit at indices 11 and 12 after the name.
    let ticks: f64 = [11, 12]
        .iter()
        .filter_map(|i| fields.get(*i)?.parse::<f64>().ok())
        .sum();
    ticks / TICKS_PER_SECOND
}
