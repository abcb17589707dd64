//! Colours of rendered shapes: the plain surface and a perceptually ordered map for
//! per-vertex values (distances in mm).

/// The surface colour of shapes without values, linear RGB in `[0, 1]`.
pub const SURFACE: [f64; 3] = [0.78, 0.80, 0.86];

/// Anchors of the value map (a viridis-like ramp: dark blue, teal, green, yellow).
const ANCHORS: [[f64; 3]; 5] = [
    [0.267, 0.005, 0.329],
    [0.229, 0.322, 0.546],
    [0.128, 0.567, 0.551],
    [0.369, 0.789, 0.383],
    [0.993, 0.906, 0.144],
];

/// The colour of `t` in `[0, 1]` (clamped; NaN is the low end).
pub fn ramp(t: f64) -> [f64; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (ANCHORS.len() - 1) as f64;
    let i = (x.floor() as usize).min(ANCHORS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (ANCHORS[i], ANCHORS[i + 1]);
    [0, 1, 2].map(|c| a[c] + f * (b[c] - a[c]))
}

/// `rgb` in `[0, 1]` as 8-bit channels.
pub fn to_rgb8(rgb: [f64; 3]) -> [u8; 3] {
    rgb.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
}

/// `#rrggbb` of a colour, for SVG.
pub fn hex(rgb: [f64; 3]) -> String {
    let [r, g, b] = to_rgb8(rgb);
    format!("#{r:02x}{g:02x}{b:02x}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_runs_from_dark_to_light_and_clamps() {
        assert_eq!(ramp(0.0), ANCHORS[0]);
        assert_eq!(ramp(1.0), ANCHORS[4]);
        assert_eq!(ramp(-3.0), ramp(0.0));
        assert_eq!(ramp(f64::NAN), ramp(0.0));
        let brightness = |t: f64| ramp(t).iter().sum::<f64>();
        assert!(
            (0..10).all(|i| brightness(f64::from(i) / 10.0) < brightness(f64::from(i + 1) / 10.0))
        );
        assert_eq!(hex([1.0, 0.0, 0.5]), "#ff0080");
    }
}
