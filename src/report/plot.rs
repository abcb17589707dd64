//! Single plots of the report pages: their errors, their download formats, and the figure
//! that shows a plot on a page with links to its downloads.
//!
//! Each plot has a stable name (a biomarker key on the cohort page, `generalisation`,
//! `explained_variance`, `loss_<network>`, … on the model page) under which
//! `plots/{name}` serves it alone, relative to the page.

use std::fmt::Write;

use thiserror::Error;

/// Why a single plot cannot be drawn.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum PlotError {
    /// The name is not a plot of this page.
    #[error("there is no plot named '{name}'; the plots here are: {}", available.join(", "))]
    Unknown {
        /// The requested name.
        name: String,
        /// The names this page has, in page order.
        available: Vec<String>,
    },
    /// The name is a kind of plot that this page does not have.
    #[error("the plot '{name}' does not exist here: {reason}; the plots here are: {}", available.join(", "))]
    Unavailable {
        /// The requested name.
        name: String,
        /// Why this page has no such plot.
        reason: String,
        /// The names this page has, in page order.
        available: Vec<String>,
    },
}

impl PlotError {
    /// Stable code: `plot.not_found` or `plot.not_available`.
    pub fn code(&self) -> &'static str {
        match self {
            Self::Unknown { .. } => "plot.not_found",
            Self::Unavailable { .. } => "plot.not_available",
        }
    }

    /// The plot names that exist, in page order.
    pub fn available(&self) -> &[String] {
        match self {
            Self::Unknown { available, .. } | Self::Unavailable { available, .. } => available,
        }
    }
}

/// How a single plot is delivered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlotFormat {
    /// The SVG of the page, as a document of its own.
    #[default]
    Svg,
    /// The SVG rasterised at its own size (see [`super::png`]).
    Png,
}

impl PlotFormat {
    /// Every format, for messages.
    pub const NAMES: [&'static str; 2] = ["svg", "png"];

    /// The format called `name` (`svg` or `png`, any case).
    pub fn from_name(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().as_str() {
            "svg" => Some(Self::Svg),
            "png" => Some(Self::Png),
            _ => None,
        }
    }

    /// Media type of the body.
    pub fn content_type(self) -> &'static str {
        match self {
            Self::Svg => "image/svg+xml",
            Self::Png => "image/png",
        }
    }

    /// File extension.
    pub fn extension(self) -> &'static str {
        match self {
            Self::Svg => "svg",
            Self::Png => "png",
        }
    }
}

/// `name` as one URL path segment: unreserved characters kept, others percent-encoded.
fn path_segment(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    for b in name.bytes() {
        if b.is_ascii_alphanumeric() || b"-_.~".contains(&b) {
            out.push(char::from(b));
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    out
}

/// A plot on a page, with links to it alone as SVG and PNG (relative to the page).
pub(super) fn figure(name: &str, svg: &str) -> String {
    let href = format!("plots/{}", path_segment(name));
    format!(
        "<figure>{svg}<figcaption><a href=\"{href}\">SVG</a> · <a href=\"{href}?format=png\">PNG</a></figcaption></figure>"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_parse_by_name() {
        assert_eq!(PlotFormat::from_name("PNG"), Some(PlotFormat::Png));
        assert_eq!(PlotFormat::from_name("svg"), Some(PlotFormat::Svg));
        assert_eq!(PlotFormat::from_name("gif"), None);
        assert_eq!(PlotFormat::default().content_type(), "image/svg+xml");
    }

    #[test]
    fn figure_links_escape_the_name() {
        let html = figure("a b/c", "<svg/>");
        assert!(
            html.contains("href=\"plots/a%20b%2Fc?format=png\""),
            "{html}"
        );
        assert!(html.starts_with("<figure><svg/>"));
    }

    #[test]
    fn errors_list_the_available_names() {
        let e = PlotError::Unknown {
            name: "x".into(),
            available: vec!["a".into(), "b".into()],
        };
        assert_eq!(e.code(), "plot.not_found");
        assert!(e.to_string().ends_with("a, b"), "{e}");
    }
}
