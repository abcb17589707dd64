//! The refinement on a few small phantoms: one optimiser step lowers `L_Ref`.

use super::*;
use crate::mesh::phantom::{self, Family};
use crate::models::alignment::simplified;
use crate::models::asmg::AsmgParams;
use crate::models::asmg::Smoother;
use crate::models::asmg::fit::align_training;
use crate::models::progress::Silent;
use crate::nn::{GraphVaeConfig, GraphVaeTraining, Unmonitored, train_graph_vae};

fn small() -> AsmgParams {
    AsmgParams {
        max_vertices: 300,
        atlas_vertices: 200,
        cpd_max_iterations: 30,
        multistart: false,
        ..AsmgParams::default()
    }
}

#[test]
fn one_refinement_step_lowers_the_refinement_loss() {
    let meshes: Vec<Mesh> = phantom::generate(Family::Lv, 4, 21)
        .iter()
        .map(|p| p.canonical_mesh())
        .collect();
    let params = AtlasRAsmgParams {
        asmg: small(),
        ..AtlasRAsmgParams::default()
    };
    let mut stages = Stages::new(&[("alignment", 1.0)]);
    stages.enter("alignment");
    let aligned = align_training(&meshes, &[], &params.asmg, 0, &stages, &mut Silent).unwrap();
    let samples = aligned.samples(&params.asmg);
    let config = GraphVaeConfig::new().with_d_x(6);
    let training = GraphVaeTraining {
        epochs: 1,
        batch_size: 4,
        seed: 3,
        ..GraphVaeTraining::default()
    };
    let graph = train_graph_vae(&samples, &config, &training, &mut Unmonitored).unwrap();
    let atlas = simplified(&aligned.meshes[0], 200).unwrap();
    let smoother = Smoother::new(&atlas, params.asmg.smoothing()).unwrap();
    let targets: Vec<Target> = aligned
        .meshes
        .iter()
        .map(|m| Target::new(m.vertices.clone()).unwrap())
        .collect();
    let mut objective = Refinement {
        atlases: vec![RefineAtlas {
            smoother: &smoother,
            positions: &atlas.vertices,
        }],
        targets: &targets,
        temperature: params.asmg.temperature(),
        w_cd: 1.0,
        w_lap: 1.0,
    };
    // One batch of all four shapes: each epoch's terms are measured before its one step.
    let refine_training = RefineTraining {
        batch_size: 4,
        lr: 1e-3,
        w_kl: 1e-3,
        w_norm: 1e-2,
        seed: 3,
    };
    let mut refiner = GraphRefiner::new(&graph, refine_training).unwrap();
    let atlases = [GraphSample::from_mesh(
        &atlas,
        params.asmg.features.features(),
    )];
    let weights = vec![vec![1.0]; samples.len()];
    let before = refiner
        .epoch(
            &samples,
            &atlases,
            &weights,
            &mut objective,
            &mut Unmonitored,
        )
        .unwrap()
        .unwrap();
    let after = refiner
        .epoch(
            &samples,
            &atlases,
            &weights,
            &mut objective,
            &mut Unmonitored,
        )
        .unwrap()
        .unwrap();
    let l_ref = |e: &RefineEpoch| e.chamfer + e.laplacian;
    eprintln!(
        "L_Ref {:.4} → {:.4} (Chamfer {:.4} → {:.4}, Laplacian {:.4} → {:.4})",
        l_ref(&before),
        l_ref(&after),
        before.chamfer,
        after.chamfer,
        before.laplacian,
        after.laplacian
    );
    assert!(l_ref(&before) > 0.0);
    assert!(l_ref(&after) < l_ref(&before), "{before:?} then {after:?}");
    // The refined network embeds like a trained one: the same sizes, finite values.
    let refined = refiner.trained();
    let z = refined.embed(&samples[0]).unwrap();
    assert_eq!(z.len(), samples[0].vertex_count() * config.d_z);
    assert!(z.iter().all(|v| v.is_finite()));
}
