//! Times the rigid pre-alignment of LV phantoms to a template, per stage of the search.
//! `cargo run --release --example registration_timing -- [count]`

use std::time::Instant;

use cohortforge::mesh::phantom::{self, Family};
use cohortforge::models::alignment::{AlignmentParams, register};

fn main() {
    let count: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(10);
    let phantoms = phantom::generate(Family::Lv, count + 1, 1);
    let template = &phantoms[0].mesh.vertices;
    let started = Instant::now();
    for p in &phantoms[1..] {
        let t = Instant::now();
        let r = register(template, &p.mesh.vertices, &AlignmentParams::default())
            .expect("registration");
        println!(
            "{} vertices: {:.2} s, {} final iterations, sigma2 {:.3} mm2",
            p.mesh.vertex_count(),
            t.elapsed().as_secs_f64(),
            r.iterations,
            r.sigma2
        );
    }
    println!(
        "mean {:.2} s per mesh",
        started.elapsed().as_secs_f64() / count as f64
    );
}
