//! The route table and the request side: typed query strings, bodies and their errors, and one
//! voxelization through the router.
//!
//! Not here: the response contract's edges and downloads (`contract`), API keys (`keys`).

use super::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_router_answers_exactly_the_route_table() {
    let h = harness("table").await;
    for (path, methods) in ROUTES {
        let p = path.replace("{id}", "x");
        for m in ["GET", "POST", "DELETE", "PUT", "PATCH"] {
            let r = call(&h.app, m, &p, None, b"").await;
            let fallback = r.status == StatusCode::NOT_FOUND
                && String::from_utf8_lossy(&r.body).contains("no such route");
            assert!(!fallback, "{m} {p} reached the fallback");
            if methods.contains(&m) {
                assert_ne!(
                    r.status,
                    StatusCode::METHOD_NOT_ALLOWED,
                    "{m} {p} is in the table"
                );
            } else {
                assert_eq!(
                    r.status,
                    StatusCode::METHOD_NOT_ALLOWED,
                    "{m} {p} is not in the table"
                );
            }
        }
    }
    let r = call(&h.app, "GET", "/v1/nothing", None, b"").await;
    r.problem(404, "not-found");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn query_strings_are_typed() {
    let h = harness("query").await;
    let post = |q: &'static str| call(&h.app, "POST", q, Some("model/obj"), TETRA);
    let d = post("/v1/voxelize?colour=red")
        .await
        .problem(400, "invalid-parameter");
    assert!(d.contains("colour") && d.contains("resolution"), "{d}");
    let d = post("/v1/voxelize?method=sculpt")
        .await
        .problem(400, "invalid-parameter");
    assert!(d.contains("sculpt") && d.contains("density"), "{d}");
    let d = post("/v1/voxelize?fill=blob")
        .await
        .problem(400, "invalid-parameter");
    assert!(d.contains("winding"), "{d}");
    post("/v1/voxelize?resolution=-3")
        .await
        .problem(400, "invalid-parameter");
    post("/v1/voxelize?resolution=8&voxel_size=0.1")
        .await
        .problem(400, "invalid-parameter");
    let d = post("/v1/voxelize?origin=0,0&dims=2,2,2&voxel_size=1")
        .await
        .problem(400, "invalid-parameter");
    assert!(d.contains("X,Y,Z"), "{d}");
    post("/v1/voxelize?dims=2,2,2&voxel_size=1")
        .await
        .problem(400, "invalid-parameter");
    post("/v1/voxelize?method=density&density_factor=3")
        .await
        .problem(400, "invalid-parameter");
    post("/v1/voxelize?wait=301")
        .await
        .problem(400, "invalid-parameter");
    post("/v1/voxelize?cubic=maybe")
        .await
        .problem(400, "invalid-parameter");
    post("/v1/voxelize?format=dwg")
        .await
        .problem(415, "unsupported-media-type");
    call(&h.app, "GET", "/v1/volumes?limit=0", None, b"")
        .await
        .problem(400, "invalid-parameter");
    call(&h.app, "GET", "/v1/volumes?page=2", None, b"")
        .await
        .problem(400, "invalid-parameter");
    call(&h.app, "GET", "/v1/volumes/x/preview.png?axis=w", None, b"")
        .await
        .problem(400, "invalid-parameter");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bodies_and_their_errors() {
    let h = harness("bodies").await;
    call(&h.app, "POST", "/v1/voxelize", Some("model/obj"), b"")
        .await
        .problem(422, "invalid-mesh");
    call(&h.app, "POST", "/v1/voxelize", Some("text/html"), b"<html>")
        .await
        .problem(415, "unsupported-media-type");
    let big = vec![b' '; 70_000];
    call(&h.app, "POST", "/v1/voxelize", Some("model/obj"), &big)
        .await
        .problem(413, "body-too-large");
    call(
        &h.app,
        "POST",
        "/v1/voxelize?resolution=200",
        Some("model/obj"),
        TETRA,
    )
    .await
    .problem(422, "grid-too-large");
    // JSON bodies: not JSON, the wrong shape, unknown fields, limits.
    call(&h.app, "POST", "/v1/volumes/csg", None, b"{not json")
        .await
        .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/csg",
        None,
        br#"{"op":"melt","operands":["a"]}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/csg",
        None,
        br#"{"op":"union","operands":[]}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/csg",
        None,
        br#"{"op":"union","operands":["a"],"x":1}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/csg",
        None,
        br#"{"op":"union","operands":["nope"]}"#,
    )
    .await
    .problem(404, "not-found");
    let deep = (0..40).fold(r#""a""#.to_string(), |e, _| {
        format!(r#"{{"op":"union","operands":[{e}]}}"#)
    });
    let d = call(&h.app, "POST", "/v1/volumes/csg", None, deep.as_bytes())
        .await
        .problem(400, "invalid-parameter");
    assert!(d.contains("deeper than 32"), "{d}");
    call(
        &h.app,
        "POST",
        "/v1/volumes/intersect",
        None,
        br#"{"a":"x"}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/x/morphology",
        None,
        br#"{"op":"dilate","radius":65}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/x/morphology",
        None,
        br#"{"op":"dilate"}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(
        &h.app,
        "POST",
        "/v1/volumes/x/morphology",
        None,
        br#"{"op":"dilate","radius":1}"#,
    )
    .await
    .problem(404, "not-found");
    call(
        &h.app,
        "POST",
        "/v1/volumes/x/query",
        None,
        br#"{"points":[[0,0]]}"#,
    )
    .await
    .problem(400, "invalid-parameter");
    call(&h.app, "GET", "/v1/volumes/x/normals?points=1,2", None, b"")
        .await
        .problem(400, "invalid-parameter");
    call(&h.app, "GET", "/v1/jobs/nope", None, b"")
        .await
        .problem(404, "not-found");
    call(&h.app, "DELETE", "/v1/volumes/nope", None, b"")
        .await
        .problem(404, "not-found");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_voxelization_through_the_router() {
    let h = harness("voxelize").await;
    let r = call(
        &h.app,
        "POST",
        "/v1/voxelize?resolution=8&wait=30&name=t",
        Some("model/obj"),
        TETRA,
    )
    .await;
    r.ok(StatusCode::CREATED);
    let meta = r.json();
    let id = meta["id"].as_str().unwrap().to_string();
    assert_eq!(meta["name"], "t");
    assert_eq!(meta["source"]["triangles"], 4);
    // The stored .vxl carries the same metadata keys the command line writes.
    let data = call(&h.app, "GET", &format!("/v1/volumes/{id}/data"), None, b"").await;
    assert_eq!(data.status, StatusCode::OK);
    let (v, header) = crate::codec::vxl::decode(&data.body).unwrap();
    assert_eq!(v.grid().dims, [8, 8, 8]);
    for k in [
        "method",
        "fill",
        "source",
        "source_format",
        "source_sha256",
        "triangles",
        "job",
    ] {
        assert!(header.contains_key(k), "{k} missing from {header:?}");
    }
    // Derived volumes, then density where only bits are accepted.
    let body = format!(r#"{{"op":"intersection","operands":["{id}","{id}"]}}"#);
    let r = call(&h.app, "POST", "/v1/volumes/csg", None, body.as_bytes()).await;
    assert_eq!(r.status, StatusCode::CREATED);
    assert_eq!(r.json()["solid_voxels"], meta["solid_voxels"]);
    let r = call(
        &h.app,
        "POST",
        "/v1/voxelize?resolution=8&wait=30&method=density",
        Some("model/obj"),
        TETRA,
    )
    .await;
    assert_eq!(r.status, StatusCode::CREATED);
    let did = r.json()["id"].as_str().unwrap().to_string();
    call(
        &h.app,
        "GET",
        &format!("/v1/volumes/{did}/stats"),
        None,
        b"",
    )
    .await
    .problem(422, "wrong-volume-kind");
    call(
        &h.app,
        "GET",
        &format!("/v1/volumes/{did}/data?format=binvox"),
        None,
        b"",
    )
    .await
    .problem(400, "invalid-parameter");
    let r = call(&h.app, "GET", "/readyz", None, b"").await;
    assert_eq!(r.status, StatusCode::OK);
    assert_eq!(r.json()["queue_depth"], 0);
    let listed = call(&h.app, "GET", "/v1/volumes?limit=2", None, b"")
        .await
        .json();
    assert_eq!(listed["volumes"].as_array().unwrap().len(), 2);
    assert!(listed["next"].is_string());
}
