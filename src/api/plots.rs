//! Single plots of the report pages, as SVG (default) or PNG:
//! `GET /v1/cohorts/{id}/plots/{name}` and `GET /v1/models/{id}/plots/{name}`.

use axum::extract::State;
use axum::response::Response;
use serde::Deserialize;
use utoipa::{IntoParams, ToSchema};
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::AppState;
use super::error::{ApiError, Problem};
use super::extract::{Path, Query};
use super::meshes::file_response;
use super::reports::{CohortData, ModelData};
use crate::report::png::svg_to_png;
use crate::report::{PlotFormat, cohort_plot, model_plot};

pub(super) fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(cohort_plot_file))
        .routes(routes!(model_plot_file))
}

/// Query of a plot download.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
#[serde(deny_unknown_fields)]
pub struct PlotQuery {
    /// `svg` (default: the plot as on the page) or `png` (the same plot rasterised at its
    /// own size, 560 × 320 px, on white).
    #[param(value_type = Option<super::vocabulary::PlotFormatName>, inline)]
    pub format: Option<String>,
}

impl PlotQuery {
    /// The requested format; an unknown one is a 400.
    fn format(&self) -> Result<PlotFormat, ApiError> {
        match &self.format {
            None => Ok(PlotFormat::default()),
            Some(name) => {
                PlotFormat::from_name(name).ok_or_else(|| ApiError::unsupported_plot_format(name))
            }
        }
    }
}

/// A PNG plot in the body (documentation type).
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct PlotImage(#[allow(dead_code)] Vec<u8>);

/// One plot of the cohort's report page alone, as SVG or PNG.
///
/// The violin of one biomarker: the training population against the cohort, with its
/// acceptance intervals. `name` is the biomarker's key in the cohort's report (e.g.
/// `volume_ml`); an unknown name is a 404 whose `available` lists the names.
#[utoipa::path(
    get, path = "/v1/cohorts/{id}/plots/{name}", tag = "cohorts",
    params(
        ("id" = String, Path, description = "Cohort id"),
        ("name" = String, Path, description = "Biomarker key, e.g. `volume_ml`"),
        PlotQuery,
    ),
    responses(
        (status = 200, description = "The plot", content(
            (String = "image/svg+xml"), (PlotImage = "image/png"))),
        (status = 400, description = "Unknown format (`plot.unsupported_format`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such cohort (`cohort.not_found`) or plot (`plot.not_found`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn cohort_plot_file(
    State(state): State<AppState>,
    Path((id, name)): Path<(String, String)>,
    Query(query): Query<PlotQuery>,
) -> Result<Response, ApiError> {
    let format = query.format()?;
    let cohort = CohortData::load(&state, &id).await?;
    let svg = cohort_plot(&cohort.page(), &name)?;
    plot_response(&format!("cohort-{id}-{name}"), svg, format).await
}

/// One plot of the model's report page alone, as SVG or PNG.
///
/// Names: `generalisation`, `specificity`, `matching` (HD, ED and ED* distributions),
/// `explained_variance` (PCA models) and `loss_<network>` for each trained network (e.g.
/// `loss_graph_vae`, `loss_beta_vae`). An unknown name is a 404 `plot.not_found`; a plot
/// this model lacks (explained variance of a model without PCA, a loss curve of a
/// closed-form fit, generalisation without held-out meshes) is a 404 `plot.not_available`
/// saying why. Both list the `available` names.
#[utoipa::path(
    get, path = "/v1/models/{id}/plots/{name}", tag = "models",
    params(
        ("id" = String, Path, description = "Model id"),
        ("name" = String, Path, description = "Plot name, e.g. `specificity`"),
        PlotQuery,
    ),
    responses(
        (status = 200, description = "The plot", content(
            (String = "image/svg+xml"), (PlotImage = "image/png"))),
        (status = 400, description = "Unknown format (`plot.unsupported_format`)", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such model (`model.not_found`), no such plot (`plot.not_found`), or not for this model (`plot.not_available`)", body = Problem, content_type = "application/problem+json"),
    )
)]
async fn model_plot_file(
    State(state): State<AppState>,
    Path((id, name)): Path<(String, String)>,
    Query(query): Query<PlotQuery>,
) -> Result<Response, ApiError> {
    let format = query.format()?;
    let model = ModelData::load(&state, &id).await?;
    let svg = model_plot(&model.page(), &name)?;
    plot_response(&format!("model-{id}-{name}"), svg, format).await
}

/// The plot in `format`, shown inline, saved as `<stem>.<extension>`.
async fn plot_response(stem: &str, svg: String, format: PlotFormat) -> Result<Response, ApiError> {
    let body = match format {
        PlotFormat::Svg => svg.into_bytes(),
        PlotFormat::Png => tokio::task::spawn_blocking(move || svg_to_png(&svg))
            .await
            .map_err(|e| ApiError::internal(e.to_string()))?
            .map_err(|e| ApiError::internal(e.to_string()))?,
    };
    Ok(file_response(
        body,
        format.content_type(),
        "inline",
        &format!("{stem}.{}", format.extension()),
    ))
}
