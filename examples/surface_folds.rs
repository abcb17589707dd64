//! How folded a model's surfaces are: edges whose two triangles turn by more than 90°
//! (`mesh::measures::folded_edges`), for the training meshes, the atlas, the training shapes
//! as the model normalises them and 200 draws.
//!
//! `cargo run --release --example surface_folds -- MODEL [MESHES]` fits MODEL (`rsmp`,
//! `asmg`, `atlas-r-asmg`, `matlas-r-asmg`) with seed 1 to the meshes of the directory
//! MESHES, or to 40 LV phantoms, with `PARAMS` (JSON, as a fit request's `params`):
//!
//!     cargo run --release --example surface_folds -- asmg ../shared/data/kits19/kidney-meshes
//!     PARAMS='{"mirror": true, "features": "spatial"}' cargo run --release \
//!         --example surface_folds -- asmg ../shared/data/kits19/kidney-meshes

use cohortforge::cli::mesh_dir::read_mesh_dir;
use cohortforge::mesh::Mesh;
use cohortforge::mesh::measures::folded_edges;
use cohortforge::mesh::phantom::{self, Family};
use cohortforge::models::progress::Silent;
use cohortforge::models::{FitInput, ModelType};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn summary(label: &str, shapes: &[Mesh]) {
    let folds: Vec<usize> = shapes.iter().map(folded_edges).collect();
    let mean = folds.iter().sum::<usize>() as f64 / folds.len() as f64;
    let max = folds.iter().copied().max().unwrap_or(0);
    let edges = shapes.first().map_or(0, |m| m.faces.len() * 3 / 2);
    println!(
        "{label:18} n {:4}: folded edges mean {mean:6.1}, max {max:4} (of about {edges} edges)",
        shapes.len()
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let model = args.get(1).map_or("asmg", String::as_str);
    let meshes: Vec<Mesh> = match args.get(2) {
        Some(dir) => read_mesh_dir(std::path::Path::new(dir))
            .expect("a directory of meshes")
            .into_iter()
            .map(|m| m.mesh)
            .collect(),
        None => phantom::meshes(Family::Lv, 40, 1),
    };
    let input = FitInput::new(&meshes, &[], 1);
    let json = std::env::var("PARAMS").map_or(serde_json::Value::Null, |text| {
        serde_json::from_str(&text).expect("PARAMS is JSON")
    });
    let params = ModelType::parse_name(model)
        .expect("a model type")
        .parse_params(&json)
        .expect("valid params");
    let outcome = params.fit(&input, &mut Silent).expect("a fit");
    let stored = &outcome.model;
    let atlas = &stored.model.atlases()[0];
    summary("training meshes", &meshes);
    summary("atlas", std::slice::from_ref(atlas));
    let normalised: Vec<Mesh> = stored.training.normalised_f64()[0]
        .iter()
        .map(|v| Mesh::new(v.clone(), atlas.faces.clone()))
        .collect();
    summary("normalised shapes", &normalised);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let drawn: Vec<Mesh> = (0..200)
        .map(|_| {
            stored
                .model
                .sample(&mut rng, Default::default())
                .expect("a draw")
                .mesh
        })
        .collect();
    summary("draws", &drawn);
}
