//! One shape drawn in one view: orthographic projection, triangles filled far to near
//! (painter's order) by tiny-skia with Lambert shading from a light beside the viewer,
//! rendered at twice the size and box-filtered down so that edges are smooth without seams
//! between neighbouring triangles.

use resvg::tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, Transform};

use super::camera::{View, dot};
use super::colour::{SURFACE, ramp, to_rgb8};
use crate::mesh::Mesh;

/// Supersampling factor per side.
const SUPERSAMPLE: u32 = 2;
/// Light that reaches faces turned away from it.
const AMBIENT: f64 = 0.25;

/// Per-vertex values shown as colour, with the range mapped onto the colour ramp.
#[derive(Debug, Clone, Copy)]
pub struct Colouring<'a> {
    /// One value per vertex (e.g. mm).
    pub values: &'a [f64],
    /// Values mapped to the two ends of the ramp.
    pub range: (f64, f64),
}

/// Where a shape sits in its panel: the projected point at the panel centre and the scale.
#[derive(Debug, Clone, Copy)]
pub struct Framing {
    /// `[right, up]` (mm) drawn at the centre of the panel.
    pub centre: [f64; 2],
    /// Pixels per mm.
    pub px_per_mm: f64,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let n = dot(v, v).sqrt();
    (n > 0.0 && n.is_finite()).then(|| v.map(|c| c / n))
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The light direction: towards the viewer, from the upper left.
fn light(view: View) -> [f64; 3] {
    let (r, u, f) = view.axes();
    let v = [0, 1, 2].map(|c| -f[c] + 0.35 * u[c] - 0.25 * r[c]);
    unit(v).unwrap_or([0.0, 0.0, 1.0])
}

/// Base colour of face `f`: the surface colour, or the ramp at its vertices' mean value.
fn base_colour(face: [u32; 3], colouring: Option<&Colouring<'_>>) -> [f64; 3] {
    let Some(c) = colouring else {
        return SURFACE;
    };
    let value = |i: u32| c.values.get(i as usize).copied().unwrap_or(f64::NAN);
    let mean = face.iter().map(|&i| value(i)).sum::<f64>() / 3.0;
    let (lo, hi) = c.range;
    let span = if hi > lo { hi - lo } else { 1.0 };
    ramp((mean - lo) / span)
}

/// `mesh` drawn in `view` on a white `width × height` px panel.
pub fn draw(
    mesh: &Mesh,
    colouring: Option<&Colouring<'_>>,
    view: View,
    framing: Framing,
    (width, height): (u32, u32),
) -> Option<Pixmap> {
    let (w, h) = (width * SUPERSAMPLE, height * SUPERSAMPLE);
    let mut fine = Pixmap::new(w, h)?;
    fine.fill(Color::WHITE);
    let s = framing.px_per_mm * f64::from(SUPERSAMPLE);
    let projected: Vec<[f64; 3]> = mesh.vertices.iter().map(|p| view.project(*p)).collect();
    let screen = |q: [f64; 3]| {
        (
            (f64::from(w) / 2.0 + (q[0] - framing.centre[0]) * s) as f32,
            (f64::from(h) / 2.0 - (q[1] - framing.centre[1]) * s) as f32,
        )
    };
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .copied()
        .filter(|f| f.iter().all(|&i| (i as usize) < projected.len()))
        .collect();
    let depth = |f: &[u32; 3]| f.iter().map(|&i| projected[i as usize][2]).sum::<f64>();
    let mut order: Vec<usize> = (0..faces.len()).collect();
    order.sort_by(|&a, &b| {
        depth(&faces[b])
            .total_cmp(&depth(&faces[a]))
            .then(a.cmp(&b))
    });
    let l = light(view);
    let mut paint = Paint {
        anti_alias: false,
        ..Paint::default()
    };
    for k in order {
        let [a, b, c] = faces[k].map(|i| mesh.vertices[i as usize]);
        let shade = unit(cross(sub(b, a), sub(c, a)))
            .map_or(AMBIENT, |n| AMBIENT + (1.0 - AMBIENT) * dot(n, l).abs());
        let [r, g, bl] = to_rgb8(base_colour(faces[k], colouring).map(|x| x * shade));
        paint.set_color_rgba8(r, g, bl, 255);
        let mut path = PathBuilder::new();
        let [p, q, t] = faces[k].map(|i| screen(projected[i as usize]));
        path.move_to(p.0, p.1);
        path.line_to(q.0, q.1);
        path.line_to(t.0, t.1);
        path.close();
        if let Some(path) = path.finish() {
            fine.fill_path(
                &path,
                &paint,
                FillRule::Winding,
                Transform::identity(),
                None,
            );
        }
    }
    downsample(&fine, width, height)
}

/// Box filter of the supersampled panel (opaque pixels, so premultiplied is plain RGB).
fn downsample(fine: &Pixmap, width: u32, height: u32) -> Option<Pixmap> {
    let mut out = Pixmap::new(width, height)?;
    let (src, stride) = (fine.data(), fine.width() as usize * 4);
    let n = SUPERSAMPLE as usize;
    let area = (n * n) as u32;
    let dst = out.data_mut();
    for y in 0..height as usize {
        for x in 0..width as usize {
            for c in 0..4 {
                let mut sum = 0u32;
                for dy in 0..n {
                    for dx in 0..n {
                        sum += u32::from(src[(y * n + dy) * stride + (x * n + dx) * 4 + c]);
                    }
                }
                dst[(y * width as usize + x) * 4 + c] = ((sum + area / 2) / area) as u8;
            }
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::render::camera::extent;

    /// A closed box `[0, a] × [0, b] × [0, c]` (mm), 12 triangles.
    pub(crate) fn cuboid(a: f64, b: f64, c: f64) -> Mesh {
        let vertices = (0..8)
            .map(|i| {
                [
                    a * f64::from(i & 1),
                    b * f64::from((i >> 1) & 1),
                    c * f64::from((i >> 2) & 1),
                ]
            })
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let faces = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        Mesh::new(vertices, faces)
    }

    fn covered(p: &Pixmap) -> usize {
        p.pixels()
            .iter()
            .filter(|c| (c.red(), c.green(), c.blue()) != (255, 255, 255))
            .count()
    }

    #[test]
    fn a_box_covers_its_projected_area_in_every_view() {
        let mesh = cuboid(10.0, 20.0, 30.0);
        let px_per_mm = 4.0;
        for (view, (sw, sh)) in
            View::ALL
                .into_iter()
                .zip([(10.0, 30.0), (20.0, 30.0), (10.0, 20.0)])
        {
            let (centre, w, h) = extent(view, &mesh.vertices);
            assert_eq!((w, h), (sw, sh));
            let framing = Framing { centre, px_per_mm };
            let pixmap = draw(&mesh, None, view, framing, (200, 200)).unwrap();
            let expected = sw * sh * px_per_mm * px_per_mm;
            let perimeter = 2.0 * (sw + sh) * px_per_mm;
            let got = covered(&pixmap) as f64;
            assert!(
                (got - expected).abs() <= perimeter / 2.0 + 4.0,
                "{view:?}: {got} px against {expected}"
            );
        }
    }

    #[test]
    fn the_same_shape_draws_the_same_pixels_and_values_change_the_colour() {
        let mesh = cuboid(10.0, 10.0, 10.0);
        let framing = Framing {
            centre: [5.0, 5.0],
            px_per_mm: 5.0,
        };
        let first = draw(&mesh, None, View::Lateral, framing, (80, 80)).unwrap();
        let again = draw(&mesh, None, View::Lateral, framing, (80, 80)).unwrap();
        assert_eq!(first.data(), again.data());
        let values = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
        let colouring = Colouring {
            values: &values,
            range: (0.0, 7.0),
        };
        let coloured = draw(&mesh, Some(&colouring), View::Lateral, framing, (80, 80)).unwrap();
        assert_ne!(first.data(), coloured.data());
        assert_eq!(covered(&first), covered(&coloured));
    }
}
