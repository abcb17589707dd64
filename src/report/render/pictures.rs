//! The pictures the service offers, as sheets: atlases, modes of variation, a held-out mesh
//! beside its reconstruction coloured by error, and cohort members.

use super::camera::View;
use super::sheet::{ColourBar, Panel, RenderError, Sheet};
use crate::mesh::Mesh;
use crate::models::shape_modes::ShapeMode;

/// Default side of a panel, px.
pub const DEFAULT_PANEL_PX: u32 = 240;

/// `views` or, when none is asked for, all three.
fn views(view: Option<View>) -> Vec<View> {
    view.map_or_else(|| View::ALL.to_vec(), |v| vec![v])
}

/// Every atlas in the chosen views (a row per atlas).
pub fn atlases(
    title: &str,
    atlases: &[(usize, &Mesh)],
    view: Option<View>,
    panel_px: u32,
) -> Result<Vec<u8>, RenderError> {
    let views = views(view);
    let panels = atlases
        .iter()
        .flat_map(|(m, mesh)| {
            views.iter().map(move |v| Panel {
                mesh,
                view: *v,
                caption: format!(
                    "atlas {m}, {} ({} vertices)",
                    v.as_str(),
                    mesh.vertex_count()
                ),
                values: None,
            })
        })
        .collect();
    Sheet {
        title: title.to_owned(),
        columns: views.len(),
        panel_px,
        panels,
        colour_bar: None,
    }
    .render()
}

/// Each mode a row: −step, mean, +step, in one view.
pub fn modes(
    title: &str,
    modes: &[ShapeMode],
    view: View,
    panel_px: u32,
) -> Result<Vec<u8>, RenderError> {
    let panels = modes
        .iter()
        .flat_map(|mode| {
            let (dv, da) = mode.effect;
            let step = mode.step_sd;
            [
                (format!("{}: −{step} sd", mode.label)),
                (format!("{}: mean ({})", mode.label, view.as_str())),
                (format!("+{step} sd: {dv:+.1} ml, {da:+.1} cm²")),
            ]
            .into_iter()
            .zip(&mode.shapes)
            .map(move |(caption, mesh)| Panel {
                mesh,
                view,
                caption,
                values: None,
            })
        })
        .collect();
    Sheet {
        title: title.to_owned(),
        columns: 3,
        panel_px,
        panels,
        colour_bar: None,
    }
    .render()
}

/// Rows of the held-out mesh (in the model frame) and of its reconstruction coloured by
/// `errors` (mm per reconstruction vertex), in the chosen views.
pub fn reconstruction(
    title: &str,
    held_out: &Mesh,
    reconstructed: &Mesh,
    errors: &[f64],
    view: Option<View>,
    panel_px: u32,
) -> Result<Vec<u8>, RenderError> {
    let views = views(view);
    let top = errors.iter().copied().fold(0.0, f64::max);
    let mut panels: Vec<Panel<'_>> = views
        .iter()
        .map(|v| Panel {
            mesh: held_out,
            view: *v,
            caption: format!("held-out mesh, {}", v.as_str()),
            values: None,
        })
        .collect();
    panels.extend(views.iter().map(|v| Panel {
        mesh: reconstructed,
        view: *v,
        caption: format!("reconstruction, {}", v.as_str()),
        values: Some(errors),
    }));
    Sheet {
        title: title.to_owned(),
        columns: views.len(),
        panel_px,
        panels,
        colour_bar: Some(ColourBar {
            range: (0.0, if top > 0.0 { top } else { 1.0 }),
            label: "distance of each reconstruction vertex to the held-out surface, mm".into(),
        }),
    }
    .render()
}

/// Members `(index, mesh)` in one view, `columns` a row; or one member in every view.
pub fn members(
    title: &str,
    members: &[(usize, &Mesh)],
    view: Option<View>,
    panel_px: u32,
) -> Result<Vec<u8>, RenderError> {
    let single = members.len() == 1;
    let views = if single {
        views(view)
    } else {
        vec![view.unwrap_or_default()]
    };
    let panels: Vec<Panel<'_>> = members
        .iter()
        .flat_map(|(index, mesh)| {
            views.iter().map(move |v| Panel {
                mesh,
                view: *v,
                caption: format!("member {index}, {}", v.as_str()),
                values: None,
            })
        })
        .collect();
    Sheet {
        title: title.to_owned(),
        columns: if single {
            views.len()
        } else {
            panels.len().min(4)
        },
        panel_px,
        panels,
        colour_bar: None,
    }
    .render()
}
