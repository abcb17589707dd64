//! Checks of whole mAtlas-R-ASMG fits on a few small phantoms of two sub-populations.

use super::*;
use crate::eval::clustering::adjusted_rand_index;
use crate::geometry::pca::Sampling;
use crate::mesh::phantom::{self, Family, ShapeParams};
use crate::mesh::topology::euler_characteristic;
use crate::models::clusters::winning_cluster;
use crate::models::cohort::draw_rng;
use crate::models::progress::Silent;
use crate::models::{Draw, FitOutcome, ModelType, ShapeModel, StoredModel};

/// Small and quick: meshes of about 300 vertices, atlases of about 200, few epochs.
fn quick(atlases: serde_json::Value) -> serde_json::Value {
    serde_json::json!({
        "atlases": atlases,
        "max_vertices": 300,
        "atlas_vertices": 200,
        "epochs_graph": 2,
        "epochs_vae": 30,
        "epochs_refine": 1,
        "cpd_max_iterations": 40,
    })
}

fn fit(
    model_type: &str,
    params: &serde_json::Value,
    training: &[Mesh],
    holdout: &[Mesh],
) -> FitOutcome {
    let params = ModelType::parse_name(model_type)
        .unwrap()
        .parse_params(params)
        .unwrap();
    let input = FitInput {
        training,
        holdout,
        training_laterality: &[],
        holdout_laterality: &[],
        template_indices: &[],
        seed: 3,
    };
    params.fit(&input, &mut Silent).unwrap()
}

/// Mixed phantoms and their labels (0 bean, 1 ring).
fn mixed(count: usize) -> (Vec<Mesh>, Vec<usize>) {
    phantom::generate(Family::Mixed, count, 5)
        .into_iter()
        .map(|p| {
            let label = match &p.params.shape {
                ShapeParams::Mixed(m) => m.sub_population().genus() as usize,
                _ => unreachable!("a mixed phantom"),
            };
            (p.mesh, label)
        })
        .unzip()
}

#[test]
fn two_atlases_find_the_two_topologies_and_draw_from_each() {
    let (meshes, labels) = mixed(12);
    let (training, holdout) = meshes.split_at(10);
    let outcome = fit(
        "matlas-r-asmg",
        &quick(serde_json::json!(2)),
        training,
        holdout,
    );
    let model: &MatlasModel = outcome.model.downcast().expect("a matlas model");
    let atlases = model.atlases();
    assert_eq!(atlases.len(), 2);
    let mut chi: Vec<i64> = atlases.iter().map(euler_characteristic).collect();
    chi.sort();
    assert_eq!(chi, [0, 2], "one genus-1 and one genus-0 atlas");

    let clusters = outcome
        .summary
        .clusters
        .as_ref()
        .expect("clusters recorded");
    assert_eq!(clusters.training.len(), 10);
    assert_eq!(clusters.holdout.len(), 2);
    for row in clusters.training.iter().chain(&clusters.holdout) {
        assert_eq!(row.len(), 2);
        assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{row:?}");
    }
    assert!((clusters.priors.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    let won: Vec<usize> = clusters
        .training
        .iter()
        .map(|w| winning_cluster(w))
        .collect();
    let ari = adjusted_rand_index(&won, &labels[..10]).unwrap();
    eprintln!(
        "matlas 10+2 mixed: clusters {won:?}, labels {:?}, ARI {ari:.3}",
        &labels[..10]
    );
    assert!(ari > 0.5, "ARI {ari}");

    // Every draw has its cluster's connectivity; the same seed gives the same draws.
    let draws: Vec<Draw> = (0..40)
        .map(|i| {
            model
                .sample(&mut draw_rng(7, i), Sampling::Gaussian)
                .unwrap()
        })
        .collect();
    for d in &draws {
        assert_eq!(d.mesh.faces, atlases[d.cluster].faces);
    }
    assert!(draws.iter().any(|d| d.cluster == 0) && draws.iter().any(|d| d.cluster == 1));
    let again = model
        .sample(&mut draw_rng(7, 3), Sampling::Gaussian)
        .unwrap();
    assert_eq!(again, draws[3]);

    // Priors (1, 0): only cluster 0 is drawn.
    let only_first = MatlasModel::new(model.parts.clone(), vec![1.0, 0.0], model.alpha).unwrap();
    for i in 0..40 {
        let d = only_first
            .sample(&mut draw_rng(8, i), Sampling::Gaussian)
            .unwrap();
        assert_eq!(d.cluster, 0);
        assert_eq!(d.mesh.vertex_count(), atlases[0].vertex_count());
    }

    // Stored and read back, it draws and reconstructs the same.
    let back = StoredModel::from_bytes(&outcome.model.to_bytes().unwrap()).unwrap();
    let back: &MatlasModel = back.downcast().expect("the stored model is matlas");
    let redrawn = back
        .sample(&mut draw_rng(7, 3), Sampling::Gaussian)
        .unwrap();
    assert_eq!(redrawn.cluster, draws[3].cluster);
    for (a, b) in redrawn.mesh.vertices.iter().zip(&draws[3].mesh.vertices) {
        assert!((0..3).all(|d| (a[d] - b[d]).abs() < 1e-4), "{a:?} vs {b:?}");
    }
    let r = back.reconstruct(&holdout[0], None).unwrap();
    assert_eq!(r.mesh.faces, atlases[r.atlas].faces);
    assert_eq!(r.atlas, winning_cluster(&clusters.holdout[0]));
}

#[test]
fn one_atlas_is_atlas_r_asmg() {
    let meshes: Vec<Mesh> = phantom::meshes(Family::Lv, 6, 11);
    let (training, holdout) = meshes.split_at(5);
    // "auto" gives five training meshes one atlas: too few for a generator per cluster.
    // Both deform their normalised shapes onto the meshes (`nonrigid`), and do it alike.
    let mut params = quick(serde_json::json!("auto"));
    params["nonrigid"] = serde_json::json!(true);
    let one = fit("matlas-r-asmg", &params, training, holdout);
    params.as_object_mut().unwrap().remove("atlases");
    let refined = fit("atlas-r-asmg", &params, training, holdout);
    let matlas: &MatlasModel = one.model.downcast().expect("a matlas model");
    let atlas_r: &asmg::AsmgModel = refined.model.downcast().expect("an asmg model");
    assert!(matlas.parts[0].nonrigid.is_some() && atlas_r.nonrigid.is_some());
    let a = one
        .model
        .model
        .sample(&mut draw_rng(2, 0), Sampling::Gaussian)
        .unwrap();
    let b = refined
        .model
        .model
        .sample(&mut draw_rng(2, 0), Sampling::Gaussian)
        .unwrap();
    assert_eq!(a.mesh.faces, b.mesh.faces);
    let largest = a
        .mesh
        .vertices
        .iter()
        .zip(&b.mesh.vertices)
        .flat_map(|(p, q)| (0..3).map(move |d| (p[d] - q[d]).abs()))
        .fold(0.0, f64::max);
    assert!(largest < 1e-3, "draws differ by up to {largest} mm");
    assert_eq!(
        one.summary.clusters.as_ref().map(|c| c.priors.clone()),
        Some(vec![1.0])
    );
}
