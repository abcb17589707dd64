//! Mesh upload in every format, listing, download and re-parse, duplicates, deletion.

use cohortforge::mesh::phantom::{self, Family};
use cohortforge::mesh::validate::{IngestOptions, ingest};
use cohortforge::mesh::{Format, io, measures};
use reqwest::StatusCode;
use reqwest::multipart::{Form, Part};

use crate::support::{TestServer, expect_json, expect_problem};

#[tokio::test]
async fn phantoms_upload_in_every_format_and_download_in_every_format() {
    let s = TestServer::start().await;
    let dataset = s.dataset("lv", "lv").await;
    let phantoms = phantom::generate(Family::Lv, 4, 11);
    let mut ids = Vec::new();
    for (p, format) in phantoms.iter().zip(Format::ALL) {
        let response = s
            .client
            .post(s.url(&format!("/v1/datasets/{dataset}/meshes?name={}", p.name)))
            .header("content-type", format.content_type())
            .body(io::write(&p.mesh, format))
            .send()
            .await
            .unwrap();
        assert!(response.headers().contains_key("location"));
        let record = expect_json(response, StatusCode::CREATED).await;
        assert_eq!(record["name"], p.name.as_str());
        assert_eq!(record["source_format"], format.extension());
        assert_eq!(record["vertex_count"], p.mesh.vertex_count());
        assert_eq!(record["face_count"], p.mesh.face_count());
        assert_eq!(record["watertight"], true);
        assert_eq!(record["components"], 1);
        assert_eq!(record["euler_characteristic"], 2);
        let volume = record["volume_ml"].as_f64().unwrap();
        assert!(
            (volume - measures::volume_ml(&p.mesh)).abs() < 1e-3 * volume,
            "{record}"
        );
        assert_eq!(record["sha256"].as_str().unwrap().len(), 64);
        ids.push((record["id"].as_str().unwrap().to_owned(), p, format));
    }
    assert_eq!(s.mesh_count(&dataset).await, 4);

    for (id, p, uploaded_as) in &ids {
        for format in Format::ALL {
            let url = s.url(&format!(
                "/v1/meshes/{id}/file?format={}",
                format.extension()
            ));
            let response = s.client.get(url).send().await.unwrap();
            assert_eq!(response.status(), StatusCode::OK);
            assert_eq!(response.headers()["content-type"], format.content_type());
            let disposition = response.headers()["content-disposition"]
                .to_str()
                .unwrap()
                .to_owned();
            assert!(disposition.contains(&format!("{}.{}", p.name, format.extension())));
            let bytes = response.bytes().await.unwrap();
            let parsed = ingest(&bytes, format, &IngestOptions::default()).unwrap();
            assert_eq!(parsed.mesh.vertex_count(), p.mesh.vertex_count());
            assert_eq!(parsed.mesh.face_count(), p.mesh.face_count());
            if *uploaded_as != Format::Stl && format != Format::Stl {
                // STL shares no vertices: welding renumbers them in order of appearance.
                assert_eq!(parsed.mesh.faces, p.mesh.faces, "{format:?}");
            }
            let expected = measures::volume_ml(&p.mesh);
            assert!((parsed.summary.volume_ml - expected).abs() < 1e-4 * expected);
        }
    }
}

#[tokio::test]
async fn listing_is_paginated_in_upload_order() {
    let s = TestServer::start().await;
    let dataset = s.dataset("liver", "liver").await;
    let phantoms = phantom::generate(Family::Liver, 5, 3);
    for p in &phantoms {
        let response = s
            .upload(&dataset, "ply", io::write(&p.mesh, Format::Ply))
            .await;
        expect_json(response, StatusCode::CREATED).await;
    }
    let page = expect_json(
        s.client
            .get(s.url(&format!("/v1/datasets/{dataset}/meshes?limit=2&offset=2")))
            .send()
            .await
            .unwrap(),
        StatusCode::OK,
    )
    .await;
    assert_eq!(page["total"], 5);
    assert_eq!(page["limit"], 2);
    let items = page["items"].as_array().unwrap();
    assert_eq!(items.len(), 2);
    assert_eq!(items[0]["vertex_count"], phantoms[2].mesh.vertex_count());
    assert_eq!(items[1]["vertex_count"], phantoms[3].mesh.vertex_count());
}

#[tokio::test]
async fn multipart_upload_is_all_or_nothing() {
    let s = TestServer::start().await;
    let dataset = s.dataset("lv", "lv").await;
    let phantoms = phantom::generate(Family::Lv, 3, 5);
    let form = |bad: bool| {
        let mut form = Form::new();
        for (i, p) in phantoms.iter().enumerate() {
            let bytes = if bad && i == 1 {
                b"solid broken\nfacet normal".to_vec()
            } else {
                io::write(&p.mesh, Format::Stl)
            };
            form = form.part(
                "file",
                Part::bytes(bytes).file_name(format!("{}.stl", p.name)),
            );
        }
        form
    };
    let url = s.url(&format!("/v1/datasets/{dataset}/meshes"));
    let refused = s
        .client
        .post(&url)
        .multipart(form(true))
        .send()
        .await
        .unwrap();
    let body = expect_problem(
        refused,
        StatusCode::UNPROCESSABLE_ENTITY,
        "mesh.parse_error",
    )
    .await;
    assert_eq!(body["part"], 1, "{body}");
    assert_eq!(
        s.mesh_count(&dataset).await,
        0,
        "a refused batch stored meshes"
    );

    let stored = s
        .client
        .post(&url)
        .multipart(form(false))
        .send()
        .await
        .unwrap();
    let body = expect_json(stored, StatusCode::CREATED).await;
    let meshes = body["meshes"].as_array().unwrap();
    assert_eq!(meshes.len(), 3);
    assert_eq!(meshes[2]["name"], phantoms[2].name.as_str());
    assert_eq!(s.mesh_count(&dataset).await, 3);

    let empty = s
        .client
        .post(&url)
        .multipart(Form::new().text("note", "x"))
        .send()
        .await
        .unwrap();
    expect_problem(
        empty,
        StatusCode::UNPROCESSABLE_ENTITY,
        "request.unexpected_part",
    )
    .await;
}

#[tokio::test]
async fn same_geometry_twice_is_a_conflict_naming_the_mesh() {
    let s = TestServer::start().await;
    let dataset = s.dataset("lv", "lv").await;
    let p = &phantom::generate(Family::Lv, 1, 9)[0];
    let first = expect_json(
        s.upload(&dataset, "obj", io::write(&p.mesh, Format::Obj))
            .await,
        StatusCode::CREATED,
    )
    .await;
    let second = s
        .upload(&dataset, "obj", io::write(&p.mesh, Format::Obj))
        .await;
    let body = expect_problem(second, StatusCode::CONFLICT, "mesh.duplicate").await;
    assert_eq!(body["existing_mesh_id"], first["id"]);
    assert!(
        body["detail"]
            .as_str()
            .unwrap()
            .contains(first["id"].as_str().unwrap())
    );
    assert_eq!(s.mesh_count(&dataset).await, 1);
    // Another dataset may hold the same geometry.
    let other = s.dataset("other", "lv").await;
    expect_json(
        s.upload(&other, "obj", io::write(&p.mesh, Format::Obj))
            .await,
        StatusCode::CREATED,
    )
    .await;
}

#[tokio::test]
async fn deleting_meshes_and_datasets() {
    let s = TestServer::start().await;
    let dataset = s.dataset("lv", "lv").await;
    let phantoms = phantom::generate(Family::Lv, 2, 1);
    let mut ids = Vec::new();
    for p in &phantoms {
        let r = expect_json(
            s.upload(&dataset, "stl", io::write(&p.mesh, Format::Stl))
                .await,
            StatusCode::CREATED,
        )
        .await;
        ids.push(r["id"].as_str().unwrap().to_owned());
    }
    let deleted = s
        .client
        .delete(s.url(&format!("/v1/meshes/{}", ids[0])))
        .send()
        .await
        .unwrap();
    assert_eq!(deleted.status(), StatusCode::NO_CONTENT);
    let gone = s
        .client
        .get(s.url(&format!("/v1/meshes/{}", ids[0])))
        .send()
        .await
        .unwrap();
    expect_problem(gone, StatusCode::NOT_FOUND, "mesh.not_found").await;
    assert_eq!(s.mesh_count(&dataset).await, 1);

    s.client
        .delete(s.url(&format!("/v1/datasets/{dataset}")))
        .send()
        .await
        .unwrap();
    let file = s
        .client
        .get(s.url(&format!("/v1/meshes/{}/file", ids[1])))
        .send()
        .await
        .unwrap();
    expect_problem(file, StatusCode::NOT_FOUND, "mesh.not_found").await;
    let upload = s
        .upload(&dataset, "stl", io::write(&phantoms[0].mesh, Format::Stl))
        .await;
    expect_problem(upload, StatusCode::NOT_FOUND, "dataset.not_found").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_uploads_of_one_geometry_store_it_once() {
    let s = TestServer::start().await;
    let dataset = s.dataset("lv", "lv").await;
    let bytes = io::write(&phantom::generate(Family::Lv, 1, 12)[0].mesh, Format::Stl);
    let url = s.url(&format!("/v1/datasets/{dataset}/meshes?format=stl"));
    let mut uploads = tokio::task::JoinSet::new();
    for _ in 0..8 {
        let request = s.client.post(&url).body(bytes.clone());
        uploads.spawn(async move { request.send().await.unwrap() });
    }
    let responses = uploads.join_all().await;
    let statuses: Vec<StatusCode> = responses.iter().map(|r| r.status()).collect();
    assert_eq!(
        statuses
            .iter()
            .filter(|s| **s == StatusCode::CREATED)
            .count(),
        1,
        "{statuses:?}"
    );
    for response in responses {
        if response.status() != StatusCode::CREATED {
            expect_problem(response, StatusCode::CONFLICT, "mesh.duplicate").await;
        }
    }
    assert_eq!(s.mesh_count(&dataset).await, 1);
}

#[tokio::test]
async fn octet_stream_uploads_and_downloads_for_generated_clients() {
    let s = TestServer::start().await;
    let dataset = s.dataset("lv", "lv").await;
    let p = &phantom::generate(Family::Lv, 1, 13)[0];
    let response = s
        .client
        .post(s.url(&format!("/v1/datasets/{dataset}/meshes?format=ply&name=lv")))
        .header("content-type", "application/octet-stream")
        .body(io::write(&p.mesh, Format::Ply))
        .send()
        .await
        .unwrap();
    let record = expect_json(response, StatusCode::CREATED).await;
    assert_eq!(record["source_format"], "ply");
    let url = s.url(&format!(
        "/v1/meshes/{}/file?format=stl",
        record["id"].as_str().unwrap()
    ));
    let download = |accept: &'static str| {
        let request = s.client.get(&url).header("accept", accept);
        async move { request.send().await.unwrap() }
    };
    let generic = download("application/octet-stream").await;
    assert_eq!(generic.status(), StatusCode::OK);
    assert_eq!(
        generic.headers()["content-type"],
        "application/octet-stream"
    );
    let native = download("model/stl, application/octet-stream;q=0.5").await;
    assert_eq!(native.headers()["content-type"], "model/stl");
    assert_eq!(
        generic.bytes().await.unwrap(),
        native.bytes().await.unwrap(),
        "the same file whatever its declared type"
    );
    // Errors stay problem+json.
    let missing = s
        .client
        .get(s.url("/v1/meshes/none/file"))
        .header("accept", "application/octet-stream")
        .send()
        .await
        .unwrap();
    expect_problem(missing, StatusCode::NOT_FOUND, "mesh.not_found").await;
    // The document declares the generic type beside the mesh types.
    let spec = expect_json(
        s.client.get(s.url("/openapi.json")).send().await.unwrap(),
        StatusCode::OK,
    )
    .await;
    let content = &spec["paths"]["/v1/meshes/{id}/file"]["get"]["responses"]["200"]["content"];
    assert!(content["application/octet-stream"].is_object(), "{content}");
    let upload = &spec["paths"]["/v1/datasets/{id}/meshes"]["post"]["requestBody"]["content"];
    assert!(upload["application/octet-stream"].is_object(), "{upload}");
}

#[tokio::test]
async fn the_side_of_a_mesh_is_given_at_upload_and_changed_later() {
    let s = TestServer::start().await;
    let dataset = s.dataset("kidneys", "kidney").await;
    let phantoms = phantom::generate(Family::Liver, 2, 4);
    let upload = async |k: usize, query: &str| {
        s.client
            .post(s.url(&format!("/v1/datasets/{dataset}/meshes?format=obj{query}")))
            .body(io::write(&phantoms[k].mesh, Format::Obj))
            .send()
            .await
            .expect("request")
    };
    let left = expect_json(upload(0, "&laterality=left").await, StatusCode::CREATED).await;
    assert_eq!(left["laterality"], "left");
    let wrong = upload(1, "&laterality=both").await;
    let problem = expect_problem(
        wrong,
        StatusCode::UNPROCESSABLE_ENTITY,
        "request.invalid_field",
    )
    .await;
    assert_eq!(problem["field"], "laterality");
    assert!(
        problem["detail"]
            .as_str()
            .unwrap()
            .contains("use left or right")
    );
    assert_eq!(s.mesh_count(&dataset).await, 1);
    let unknown = expect_json(upload(1, "").await, StatusCode::CREATED).await;
    assert!(unknown.get("laterality").is_none(), "{unknown}");

    let patch = async |id: &str, body: serde_json::Value| {
        s.client
            .patch(s.url(&format!("/v1/meshes/{id}")))
            .json(&body)
            .send()
            .await
            .expect("request")
    };
    let id = unknown["id"].as_str().unwrap();
    let right = expect_json(
        patch(id, serde_json::json!({"laterality": "right"})).await,
        StatusCode::OK,
    )
    .await;
    assert_eq!(right["laterality"], "right");
    let fetched = s
        .client
        .get(s.url(&format!("/v1/meshes/{id}")))
        .send()
        .await
        .unwrap();
    assert_eq!(
        expect_json(fetched, StatusCode::OK).await["laterality"],
        "right"
    );
    // An empty body changes nothing; null clears the side.
    let same = expect_json(patch(id, serde_json::json!({})).await, StatusCode::OK).await;
    assert_eq!(same["laterality"], "right");
    let cleared = expect_json(
        patch(id, serde_json::json!({"laterality": null})).await,
        StatusCode::OK,
    )
    .await;
    assert!(cleared.get("laterality").is_none(), "{cleared}");
    let bad = patch(id, serde_json::json!({"laterality": "up"})).await;
    expect_problem(
        bad,
        StatusCode::UNPROCESSABLE_ENTITY,
        "request.invalid_field",
    )
    .await;
    let missing = patch("no-such-mesh", serde_json::json!({"laterality": "left"})).await;
    expect_problem(missing, StatusCode::NOT_FOUND, "mesh.not_found").await;
}
