//! Axis ticks at round values (1, 2, 2.5 or 5 times a power of ten), so that a reader can
//! read values off a plot: 50, 75, 100, 125 ml rather than 45.83, 72.04, 98.26.

/// Tick positions within `[lo, hi]`, about `target` of them, at multiples of a round step,
/// each with its label (as many decimals as the step needs).
pub(super) fn round_ticks(lo: f64, hi: f64, target: usize) -> Vec<(f64, String)> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return vec![(lo, label(lo, 2))];
    }
    let step = round_step((hi - lo) / target.max(1) as f64);
    let decimals = decimals_of(step);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last)
        .map(|k| {
            let v = k as f64 * step;
            (v, label(v, decimals))
        })
        .collect()
}

/// The round number (1, 2, 2.5 or 5 × 10ᵏ) nearest to `raw` (> 0) on a log scale.
fn round_step(raw: f64) -> f64 {
    let magnitude = 10f64.powf(raw.log10().floor());
    let fraction = raw / magnitude;
    let nearest = [1.0, 2.0, 2.5, 5.0, 10.0]
        .into_iter()
        .min_by(|a: &f64, b: &f64| {
            (a / fraction)
                .ln()
                .abs()
                .total_cmp(&(b / fraction).ln().abs())
        })
        .unwrap_or(1.0);
    nearest * magnitude
}

/// Decimals needed to write multiples of `step` exactly (2.5 → 1, 0.25 → 2, 50 → 0).
fn decimals_of(step: f64) -> usize {
    (0..=6)
        .find(|&d| {
            let scaled = step * 10f64.powi(d as i32);
            (scaled - scaled.round()).abs() < 1e-6 * scaled.max(1.0)
        })
        .unwrap_or(6)
}

/// `v` with `decimals` decimals, in scientific notation when very large or small.
fn label(v: f64, decimals: usize) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-4..1e6).contains(&a) {
        format!("{v:.2e}")
    } else if v == 0.0 {
        "0".to_owned()
    } else {
        format!("{v:.decimals$}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(lo: f64, hi: f64) -> Vec<String> {
        round_ticks(lo, hi, 4).into_iter().map(|(_, l)| l).collect()
    }

    #[test]
    fn ticks_fall_on_round_values_inside_the_range() {
        assert_eq!(labels(45.83, 151.0), ["50", "75", "100", "125", "150"]);
        assert_eq!(labels(0.0, 1.0), ["0", "0.25", "0.50", "0.75", "1.00"]);
        assert_eq!(labels(-3.2, 7.9), ["-2.5", "0", "2.5", "5.0", "7.5"]);
        assert_eq!(
            labels(1180.0, 1620.0),
            ["1200", "1300", "1400", "1500", "1600"]
        );
        for (v, _) in round_ticks(45.83, 151.0, 4) {
            assert!((45.83..=151.0).contains(&v));
        }
    }

    #[test]
    fn a_degenerate_range_gives_one_tick() {
        assert_eq!(round_ticks(3.0, 3.0, 4).len(), 1);
        assert_eq!(round_ticks(f64::NAN, 1.0, 4).len(), 1);
    }
}
