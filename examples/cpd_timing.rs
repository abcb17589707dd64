use cohortforge::mesh::phantom::{self, Family};
use cohortforge::models::alignment::{AlignmentParams, register};
use std::time::Instant;

fn main() {
    let p = phantom::generate(Family::Lv, 6, 3);
    for k in 1..6 {
        let (t, d) = (&p[0].mesh.vertices, &p[k].mesh.vertices);
        let s = Instant::now();
        let r = register(t, d, &AlignmentParams::default()).unwrap();
        println!(
            "{:.2}s iterations {} sigma2 {:.3}",
            s.elapsed().as_secs_f64(),
            r.iterations,
            r.sigma2
        );
    }
}
