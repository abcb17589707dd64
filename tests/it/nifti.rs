//! NIfTI label volume uploads (raw and multipart), their errors, and simplification on upload.

use cohortforge::mesh::phantom::{self, Family};
use cohortforge::mesh::{Format, io};
use cohortforge::segmentation::affine::{Affine, AffineSource};
use cohortforge::segmentation::write::encode_labels;
use reqwest::StatusCode;
use reqwest::multipart::{Form, Part};
use serde_json::{Value, json};

use crate::support::{TestServer, expect_json, expect_problem};

/// A 40×36×16 volume (0.9 × 0.9 × 2.5 mm, axes permuted and flipped like KiTS19) with an
/// ellipsoid labelled 1 and a box labelled 2.
fn volume(gzip: bool) -> Vec<u8> {
    let dims = [16, 36, 40];
    let affine = Affine {
        linear: [[0.0, 0.0, -0.9], [0.0, -0.9, 0.0], [-2.5, 0.0, 0.0]],
        offset: [10.0, 20.0, 30.0],
        source: AffineSource::Sform,
    };
    let mut labels = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = affine.apply([i as f64, j as f64, k as f64]);
                let e = ((p[0] + 8.0) / 10.0).powi(2)
                    + ((p[1] - 4.0) / 8.0).powi(2)
                    + ((p[2] - 10.0) / 12.0).powi(2);
                let in_box = p[0] < -20.0 && p[1] < 0.0 && p[2] > 0.0 && p[2] < 10.0;
                labels.push(if e <= 1.0 {
                    1
                } else if in_box {
                    2
                } else {
                    0
                });
            }
        }
    }
    encode_labels(dims, &labels, &affine, gzip)
}

async fn post(
    s: &TestServer,
    dataset: &str,
    query: &str,
    content_type: &str,
    body: Vec<u8>,
) -> reqwest::Response {
    s.client
        .post(s.url(&format!("/v1/datasets/{dataset}/meshes{query}")))
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .unwrap()
}

fn assert_closed(record: &Value) {
    assert_eq!(record["watertight"], true, "{record}");
    assert_eq!(record["components"], 1, "{record}");
    assert_eq!(record["euler_characteristic"], 2, "{record}");
    assert_eq!(record["warnings"], json!([]), "{record}");
}

#[tokio::test]
async fn a_gzip_label_volume_becomes_a_closed_mesh_with_its_source() {
    let s = TestServer::start().await;
    let dataset = s.dataset("kidneys", "kidney").await;
    let response = post(
        &s,
        &dataset,
        "?name=left",
        "application/x-nifti",
        volume(true),
    )
    .await;
    let record = expect_json(response, StatusCode::CREATED).await;
    assert_closed(&record);
    assert_eq!(record["name"], "left");
    assert_eq!(record["source_format"], "nifti");
    let source = &record["source"];
    assert_eq!(source["labels"], json!([1]));
    assert_eq!(source["component"], "largest");
    assert_eq!(source["fill_holes"], true);
    assert_eq!(source["voxel_mm"], 1.5);
    assert_eq!(source["smooth_sigma_mm"], 1.0);
    assert_eq!(source["affine"], "sform");
    assert_eq!(source["dims"], json!([16, 36, 40]));
    let spacing: Vec<f64> = serde_json::from_value(source["voxel_spacing_mm"].clone()).unwrap();
    assert!(
        (spacing[0] - 2.5).abs() < 1e-5 && (spacing[2] - 0.9).abs() < 1e-5,
        "{spacing:?}"
    );
    // Ellipsoid 10 × 8 × 12 mm semi-axes: 4.02 ml.
    let (mesh_ml, voxel_ml) = (
        record["volume_ml"].as_f64().unwrap(),
        source["voxel_volume_ml"].as_f64().unwrap(),
    );
    assert!((voxel_ml - 4.021).abs() < 0.15, "{voxel_ml}");
    // Smoothing (sigma 1 mm) shrinks a body this small and curved by a few per cent.
    assert!(
        (mesh_ml - voxel_ml).abs() < 0.08 * voxel_ml,
        "{mesh_ml} vs {voxel_ml}"
    );
    assert_eq!(s.mesh_count(&dataset).await, 1);
}

#[tokio::test]
async fn parameters_and_plain_nii_with_format_query() {
    let s = TestServer::start().await;
    let dataset = s.dataset("boxes", "kidney").await;
    let query =
        "?format=nifti&label=2&smooth_sigma_mm=0.5&voxel_mm=1&fill_holes=false&component=all";
    let response = post(
        &s,
        &dataset,
        query,
        "application/octet-stream",
        volume(false),
    )
    .await;
    let record = expect_json(response, StatusCode::CREATED).await;
    assert_eq!(record["source"]["labels"], json!([2]));
    assert_eq!(record["source"]["voxel_mm"], 1.0);
    assert_eq!(record["source"]["smooth_sigma_mm"], 0.5);
    assert_eq!(record["source"]["fill_holes"], false);
    assert_eq!(record["source"]["component"], "all");
    assert!(record["bbox_max"][0].as_f64().unwrap() < -19.0, "{record}");
    let gz = post(
        &s,
        &dataset,
        "?format=nifti&label=1,2&component=all",
        "application/gzip",
        volume(true),
    )
    .await;
    let both = expect_json(gz, StatusCode::CREATED).await;
    assert_eq!(both["components"], 2);
}

#[tokio::test]
async fn multipart_takes_nii_gz_parts_beside_meshes() {
    let s = TestServer::start().await;
    let dataset = s.dataset("mixed", "kidney").await;
    let p = phantom::subject(Family::Lv, 5, 0);
    let form = Form::new()
        .part(
            "file",
            Part::bytes(volume(true)).file_name("case_00001.nii.gz"),
        )
        .part(
            "file",
            Part::bytes(io::write(&p.mesh, Format::Obj)).file_name("lv.obj"),
        );
    let response = s
        .client
        .post(s.url(&format!("/v1/datasets/{dataset}/meshes")))
        .multipart(form)
        .send()
        .await
        .unwrap();
    let body = expect_json(response, StatusCode::CREATED).await;
    let meshes = body["meshes"].as_array().unwrap();
    assert_eq!(meshes[0]["name"], "case_00001");
    assert_eq!(meshes[0]["source_format"], "nifti");
    assert_closed(&meshes[0]);
    assert_eq!(meshes[1]["source_format"], "obj");
    assert_eq!(meshes[1]["source"], Value::Null);
}

#[tokio::test]
async fn malformed_volumes_get_their_code_and_store_nothing() {
    let s = TestServer::start().await;
    let dataset = s.dataset("bad", "kidney").await;
    let mut bad_magic = volume(false);
    bad_magic[344..348].copy_from_slice(b"xyz\0");
    let mut datatype = volume(false);
    datatype[70..72].copy_from_slice(&128i16.to_le_bytes());
    let full = volume(false);
    let cases: Vec<(&str, Vec<u8>, StatusCode, &str)> = vec![
        (
            "",
            bad_magic,
            StatusCode::UNPROCESSABLE_ENTITY,
            "nifti.parse_error",
        ),
        (
            "",
            full[..full.len() - 100].to_vec(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "nifti.parse_error",
        ),
        (
            "",
            datatype,
            StatusCode::UNPROCESSABLE_ENTITY,
            "nifti.unsupported_datatype",
        ),
        (
            "?label=7",
            volume(true),
            StatusCode::UNPROCESSABLE_ENTITY,
            "nifti.empty_label",
        ),
        (
            "?voxel_mm=0",
            volume(true),
            StatusCode::UNPROCESSABLE_ENTITY,
            "request.invalid_field",
        ),
        (
            "?component=some",
            volume(true),
            StatusCode::UNPROCESSABLE_ENTITY,
            "request.invalid_field",
        ),
    ];
    for (query, bytes, status, code) in cases {
        let response = post(&s, &dataset, query, "application/x-nifti", bytes).await;
        let problem = expect_problem(response, status, code).await;
        if code == "nifti.empty_label" {
            let detail = problem["detail"].as_str().unwrap();
            assert!(
                detail.contains("labels present: 1 (") && detail.contains("2 ("),
                "{detail}"
            );
        }
    }
    assert_eq!(s.mesh_count(&dataset).await, 0);
}

#[tokio::test]
async fn target_vertices_simplifies_uploads_from_the_query_or_the_dataset() {
    let s = TestServer::start().await;
    let dataset = s.dataset("lv", "lv").await;
    let p = phantom::subject(Family::Lv, 9, 0);
    let n = p.mesh.vertex_count();
    assert!(n > 1000, "{n}");
    let obj = io::write(&p.mesh, Format::Obj);
    let response = post(
        &s,
        &dataset,
        "?format=obj&target_vertices=500",
        "model/obj",
        obj.clone(),
    )
    .await;
    let record = expect_json(response, StatusCode::CREATED).await;
    assert_closed(&record);
    let count = record["vertex_count"].as_u64().unwrap();
    assert!((450..=525).contains(&count), "{count}");
    assert_eq!(record["original_vertex_count"], n);
    let simplification = &record["source"]["simplification"];
    assert_eq!(simplification["target_vertices"], 500);
    assert_eq!(simplification["vertex_count_before"], n);
    let before = simplification["volume_ml_before"].as_f64().unwrap();
    let after = record["volume_ml"].as_f64().unwrap();
    assert!((after - before).abs() < 0.01 * before, "{before} → {after}");
    let too_few = post(&s, &dataset, "?target_vertices=3", "model/obj", obj.clone()).await;
    expect_problem(
        too_few,
        StatusCode::UNPROCESSABLE_ENTITY,
        "request.invalid_field",
    )
    .await;

    let response = s
        .client
        .post(s.url("/v1/datasets"))
        .json(&json!({"name": "small", "organ": "lv", "target_vertices": 400}))
        .send()
        .await
        .unwrap();
    let small = expect_json(response, StatusCode::CREATED).await;
    assert_eq!(small["target_vertices"], 400);
    let id = small["id"].as_str().unwrap();
    let record = expect_json(
        post(&s, id, "", "model/obj", obj).await,
        StatusCode::CREATED,
    )
    .await;
    assert!(record["vertex_count"].as_u64().unwrap() <= 420, "{record}");
    let nifti = post(&s, id, "", "application/x-nifti", volume(true)).await;
    let record = expect_json(nifti, StatusCode::CREATED).await;
    assert_closed(&record);
    assert!(record["vertex_count"].as_u64().unwrap() <= 420, "{record}");
    assert!(record["source"]["simplification"].is_object(), "{record}");
    assert!(record["source"]["labels"].is_array(), "{record}");
}
