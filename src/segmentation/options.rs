//! What to make of a label volume: labels, component, holes, resampling and smoothing.

use serde::Serialize;

/// Default label: 1 (the first structure in most segmentation tools).
pub const DEFAULT_LABEL: i64 = 1;
/// Default Gaussian smoothing, mm.
pub const DEFAULT_SMOOTH_SIGMA_MM: f64 = 1.0;
/// Default isotropic resampling size, mm.
pub const DEFAULT_VOXEL_MM: f64 = 1.5;
/// Most labels one request may select.
pub const MAX_LABELS: usize = 256;
/// Smallest and largest accepted `voxel_mm`.
pub const VOXEL_MM_RANGE: (f64, f64) = (0.1, 20.0);
/// Largest accepted `smooth_sigma_mm`.
pub const MAX_SMOOTH_SIGMA_MM: f64 = 20.0;

/// Which connected parts (6-connectivity) of the selected labels make the surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Component {
    /// The part with the most voxels.
    #[default]
    Largest,
    /// Every part.
    All,
}

impl std::str::FromStr for Component {
    type Err = OptionsError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "largest" => Ok(Component::Largest),
            "all" => Ok(Component::All),
            _ => Err(OptionsError::new(
                "component",
                format!("component must be 'largest' or 'all', not '{s}'"),
            )),
        }
    }
}

/// Parameters of turning a label volume into a surface.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Labels whose voxels form the structure (one or more).
    pub labels: Vec<i64>,
    /// Which connected parts to keep.
    pub component: Component,
    /// Fill cavities (background not connected to the outside).
    pub fill_holes: bool,
    /// Standard deviation of the Gaussian smoothing, mm (0: none).
    pub smooth_sigma_mm: f64,
    /// Size of the isotropic voxels the surface is extracted from, mm.
    pub voxel_mm: f64,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            labels: vec![DEFAULT_LABEL],
            component: Component::Largest,
            fill_holes: true,
            smooth_sigma_mm: DEFAULT_SMOOTH_SIGMA_MM,
            voxel_mm: DEFAULT_VOXEL_MM,
        }
    }
}

/// An invalid parameter, naming the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct OptionsError {
    /// The parameter, e.g. `voxel_mm`.
    pub field: &'static str,
    /// What is wrong with it.
    pub message: String,
}

impl OptionsError {
    fn new(field: &'static str, message: impl Into<String>) -> Self {
        Self {
            field,
            message: message.into(),
        }
    }
}

impl Options {
    /// Rejects values that cannot work, naming the field.
    pub fn check(&self) -> Result<(), OptionsError> {
        if self.labels.is_empty() || self.labels.len() > MAX_LABELS {
            return Err(OptionsError::new(
                "label",
                format!("give between 1 and {MAX_LABELS} labels"),
            ));
        }
        let (lo, hi) = VOXEL_MM_RANGE;
        if !(self.voxel_mm.is_finite() && (lo..=hi).contains(&self.voxel_mm)) {
            return Err(OptionsError::new(
                "voxel_mm",
                format!(
                    "voxel_mm must be between {lo} and {hi} mm, got {}",
                    self.voxel_mm
                ),
            ));
        }
        let sigma = self.smooth_sigma_mm;
        if !(sigma.is_finite() && (0.0..=MAX_SMOOTH_SIGMA_MM).contains(&sigma)) {
            return Err(OptionsError::new(
                "smooth_sigma_mm",
                format!(
                    "smooth_sigma_mm must be between 0 and {MAX_SMOOTH_SIGMA_MM} mm, got {sigma}"
                ),
            ));
        }
        Ok(())
    }

    /// Parses a label list such as `1` or `1,2`.
    pub fn parse_labels(text: &str) -> Result<Vec<i64>, OptionsError> {
        let labels = text
            .split(',')
            .map(|s| {
                s.trim().parse::<i64>().map_err(|_| {
                    OptionsError::new(
                        "label",
                        format!("label must be an integer or a comma-separated list, got '{text}'"),
                    )
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let options = Options {
            labels,
            ..Options::default()
        };
        options.check()?;
        Ok(options.labels)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_bad_values_name_their_field() {
        assert!(Options::default().check().is_ok());
        let bad = |o: Options| o.check().unwrap_err().field;
        assert_eq!(
            bad(Options {
                voxel_mm: 0.0,
                ..Options::default()
            }),
            "voxel_mm"
        );
        assert_eq!(
            bad(Options {
                voxel_mm: f64::NAN,
                ..Options::default()
            }),
            "voxel_mm"
        );
        assert_eq!(
            bad(Options {
                smooth_sigma_mm: -1.0,
                ..Options::default()
            }),
            "smooth_sigma_mm"
        );
        assert_eq!(
            bad(Options {
                labels: vec![],
                ..Options::default()
            }),
            "label"
        );
    }

    #[test]
    fn labels_and_components_parse() {
        assert_eq!(Options::parse_labels("1").unwrap(), vec![1]);
        assert_eq!(Options::parse_labels(" 1, 2 ").unwrap(), vec![1, 2]);
        assert_eq!(Options::parse_labels("kidney").unwrap_err().field, "label");
        assert_eq!("ALL".parse::<Component>().unwrap(), Component::All);
        assert_eq!("most".parse::<Component>().unwrap_err().field, "component");
    }
}
