//! Gaussian kernel density estimate of a biomarker sample and its mode.

use super::EvalError;
use super::error::check_values;
use super::stats::{quantile_sorted, sample_sd, sorted};

/// Grid points used to locate the highest peak before refining it.
pub const MODE_GRID_POINTS: usize = 2001;
/// The grid spans `[min − 3h, max + 3h]`.
const GRID_MARGIN_BANDWIDTHS: f64 = 3.0;
/// Mean-shift refinement stops when a step is below this many bandwidths.
const REFINE_TOLERANCE_BANDWIDTHS: f64 = 1e-10;
/// Mean-shift refinement iteration cap.
const REFINE_MAX_ITERATIONS: usize = 10_000;
/// IQR of a normal distribution in standard deviations.
const NORMAL_IQR_SD: f64 = 1.34;

/// Silverman's rule-of-thumb bandwidth `h = 0.9·min(σ, IQR/1.34)·n^{−1/5}` (falls back to σ
/// when the IQR is zero). Zero when all values are equal.
pub fn silverman_bandwidth(values: &[f64]) -> Result<f64, EvalError> {
    check_values(values, 2, "kde")?;
    let sd = sample_sd(values);
    let s = sorted(values);
    let iqr = quantile_sorted(&s, 0.75) - quantile_sorted(&s, 0.25);
    let spread = if iqr > 0.0 {
        sd.min(iqr / NORMAL_IQR_SD)
    } else {
        sd
    };
    Ok(0.9 * spread * (values.len() as f64).powf(-0.2))
}

/// Unnormalised Gaussian KDE `Σᵢ exp(−(x − vᵢ)²/2h²)`.
fn density(values: &[f64], h: f64, x: f64) -> f64 {
    let k = 0.5 / (h * h);
    values.iter().map(|v| (-(x - v) * (x - v) * k).exp()).sum()
}

/// One mean-shift step, which climbs the Gaussian KDE monotonically.
fn mean_shift(values: &[f64], h: f64, x: f64) -> f64 {
    let k = 0.5 / (h * h);
    let (mut num, mut den) = (0.0, 0.0);
    for v in values {
        let w = (-(x - v) * (x - v) * k).exp();
        num += w * v;
        den += w;
    }
    if den > 0.0 { num / den } else { x }
}

/// Mode of the sample: the argmax of its Gaussian KDE with Silverman's bandwidth, found on
/// a fine grid over `[min − 3h, max + 3h]` and refined by mean shift. Needs ≥ 2 values.
pub fn kde_mode(values: &[f64]) -> Result<f64, EvalError> {
    let h = silverman_bandwidth(values)?;
    let s = sorted(values);
    let (lo_v, hi_v) = (s[0], s[s.len() - 1]);
    if h <= 0.0 || hi_v <= lo_v {
        return Ok(lo_v);
    }
    let lo = lo_v - GRID_MARGIN_BANDWIDTHS * h;
    let step = (hi_v + GRID_MARGIN_BANDWIDTHS * h - lo) / (MODE_GRID_POINTS - 1) as f64;
    let mut best = (lo, f64::NEG_INFINITY);
    for i in 0..MODE_GRID_POINTS {
        let x = lo + step * i as f64;
        let f = density(values, h, x);
        if f > best.1 {
            best = (x, f);
        }
    }
    let mut x = best.0;
    for _ in 0..REFINE_MAX_ITERATIONS {
        let next = mean_shift(values, h, x);
        let done = (next - x).abs() <= REFINE_TOLERANCE_BANDWIDTHS * h;
        x = next;
        if done {
            break;
        }
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bandwidth_by_hand() {
        // [1..5]: σ = √2.5 ≈ 1.5811, IQR = 4 − 2 = 2 → 2/1.34 ≈ 1.4925 is smaller;
        // h = 0.9 · 1.4925 · 5^{−0.2}.
        let h = silverman_bandwidth(&[1.0, 2.0, 3.0, 4.0, 5.0]).unwrap();
        assert!((h - 0.9 * (2.0 / 1.34) * 5f64.powf(-0.2)).abs() < 1e-12);
    }

    #[test]
    fn symmetric_sample_has_mode_at_centre() {
        let m = kde_mode(&[1.0, 2.0, 3.0, 4.0, 5.0]).unwrap();
        assert!((m - 3.0).abs() < 1e-8, "{m}");
    }

    #[test]
    fn bimodal_sample_picks_the_taller_mode() {
        // 30 values spread around 0 and 12 around 10 (deterministic, symmetric clusters).
        let mut v: Vec<f64> = (0..30).map(|i| -1.0 + 2.0 * i as f64 / 29.0).collect();
        v.extend((0..12).map(|i| 9.0 + 2.0 * i as f64 / 11.0));
        let m = kde_mode(&v).unwrap();
        assert!(m.abs() < 0.5, "{m}");
        // Mirror the weights: now the cluster at 10 is taller.
        let mut w: Vec<f64> = (0..12).map(|i| -1.0 + 2.0 * i as f64 / 11.0).collect();
        w.extend((0..30).map(|i| 9.0 + 2.0 * i as f64 / 29.0));
        let m = kde_mode(&w).unwrap();
        assert!((m - 10.0).abs() < 0.5, "{m}");
    }

    #[test]
    fn constant_sample_mode_is_the_value() {
        assert_eq!(kde_mode(&[4.0, 4.0, 4.0]).unwrap(), 4.0);
        assert!(kde_mode(&[4.0]).is_err());
    }
}
