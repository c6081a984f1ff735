//! The response side's edges: the contract's corner cases, downloads streamed in bounded chunks
//! (and a damaged stored volume found while streaming), list pages bounded in bytes.
//!
//! Not here: request parsing (`requests`), API keys (`keys`).

use super::*;

/// The contract in both directions: bounded conversions, one ETag per content coding with weak
/// `If-None-Match`, `If-Match` on delete, content codings refused, names bounded, grids that
/// cannot be represented refused before anything is stored, 405 as a problem.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn contract_edges() {
    let h = harness("contract").await;
    let obj = [("content-type", "model/obj")];
    // A 4096×1×1 volume is tiny stored, but 4096³ as binvox: refused before any work.
    let (r, _) = call_with(
        &h.app,
        "POST",
        "/v1/voxelize?origin=0,0,0&voxel_size=0.001&dims=4096,1,1&wait=30",
        &obj,
        TETRA,
    )
    .await;
    r.ok(StatusCode::CREATED);
    let id = r.json()["id"].as_str().unwrap().to_string();
    let d = call(
        &h.app,
        "GET",
        &format!("/v1/volumes/{id}/data?format=binvox"),
        None,
        b"",
    )
    .await
    .problem(422, "grid-too-large");
    assert!(d.contains("binvox"), "{d}");
    // ETags: identity and gzip differ; a weak If-None-Match of a representation is fresh for a
    // request of that representation (the same Accept-Encoding), and only for it.
    let uri = format!("/v1/volumes/{id}/data?format=npy");
    let (plain, ph) = call_with(&h.app, "GET", &uri, &[], b"").await;
    let (gz, gh) = call_with(&h.app, "GET", &uri, &[("accept-encoding", "gzip")], b"").await;
    assert_eq!((plain.status, gz.status), (StatusCode::OK, StatusCode::OK));
    assert_eq!(gh.get("content-encoding").unwrap(), "gzip");
    let (pt, gt) = (ph["etag"].to_str().unwrap(), gh["etag"].to_str().unwrap());
    assert_ne!(pt, gt);
    for (ae, t, status) in [
        ("identity", pt.to_string(), StatusCode::NOT_MODIFIED),
        ("gzip", gt.to_string(), StatusCode::NOT_MODIFIED),
        ("gzip", format!("W/{gt}"), StatusCode::NOT_MODIFIED),
        ("identity", gt.to_string(), StatusCode::OK),
        ("gzip", pt.to_string(), StatusCode::OK),
    ] {
        let hd = [("accept-encoding", ae), ("if-none-match", &t)];
        let (r, _) = call_with(&h.app, "GET", &uri, &hd, b"").await;
        assert_eq!(r.status, status, "{ae} {t}");
    }
    // If-Match on delete.
    let (r, _) = call_with(
        &h.app,
        "DELETE",
        &format!("/v1/volumes/{id}"),
        &[("if-match", "\"0000000000000000-vxl\"")],
        b"",
    )
    .await;
    r.problem(412, "precondition-failed");
    let (r, _) = call_with(
        &h.app,
        "DELETE",
        &format!("/v1/volumes/{id}"),
        &[("if-match", pt)],
        b"",
    )
    .await;
    assert_eq!(r.status, StatusCode::NO_CONTENT);
    // Content codings.
    let (r, _) = call_with(
        &h.app,
        "POST",
        "/v1/voxelize",
        &[("content-type", "model/obj"), ("content-encoding", "br")],
        TETRA,
    )
    .await;
    r.problem(415, "unsupported-media-type");
    let (r, _) = call_with(
        &h.app,
        "POST",
        "/v1/voxelize",
        &[("content-type", "model/obj"), ("content-encoding", "gzip")],
        TETRA,
    )
    .await;
    // Said to be gzip, but not: the body's content is at fault (as for a broken gzip stream).
    r.problem(422, "invalid-mesh");
    let (r, _) = call_with(
        &h.app,
        "POST",
        "/v1/volumes/intersect",
        &[("content-encoding", "gzip")],
        b"{}",
    )
    .await;
    r.problem(415, "unsupported-media-type");
    // Names, empty queries, grids that cannot be represented, methods.
    let long = format!("/v1/voxelize?name={}", "n".repeat(300));
    call(&h.app, "POST", &long, Some("model/obj"), TETRA)
        .await
        .problem(400, "invalid-parameter");
    // A name's limit is in characters (what openapi.yaml's maxLength counts), not bytes: 256
    // three-byte characters are a name, 257 are not.
    let euro = "%E2%82%AC";
    let name = |n: usize| format!("/v1/voxelize?resolution=8&wait=30&name={}", euro.repeat(n));
    let (r, _) = call_with(&h.app, "POST", &name(256), &obj, TETRA).await;
    r.ok(StatusCode::CREATED);
    assert_eq!(r.json()["name"], "€".repeat(256));
    h.app
        .store
        .delete(r.json()["id"].as_str().unwrap())
        .await
        .unwrap();
    call(&h.app, "POST", &name(257), Some("model/obj"), TETRA)
        .await
        .problem(400, "invalid-parameter");
    call(&h.app, "POST", "/v1/volumes/x/query", None, b"{}")
        .await
        .problem(400, "invalid-parameter");
    call(&h.app, "POST", "/v1/volumes/x/query", None, b"null")
        .await
        .problem(400, "invalid-parameter");
    let subnormal =
        b"v 0 0 0\nv 5e-324 0 0\nv 0 5e-324 0\nv 0 0 5e-324\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    call(
        &h.app,
        "POST",
        "/v1/voxelize?wait=30",
        Some("model/obj"),
        subnormal,
    )
    .await
    .problem(400, "invalid-parameter");
    assert_eq!(
        h.app.store.usage().await.unwrap().volumes,
        0,
        "nothing was stored"
    );
    call(&h.app, "PUT", "/v1/volumes", None, b"")
        .await
        .problem(405, "method-not-allowed");
    // A union of two small volumes far apart lives on a huge grid: refused before any is read.
    let mut ids = vec![];
    for o in ["0,0,0", "100,100,100"] {
        let uri = format!("/v1/voxelize?origin={o}&voxel_size=0.25&dims=4,4,4&wait=30");
        let (r, _) = call_with(&h.app, "POST", &uri, &obj, TETRA).await;
        r.ok(StatusCode::CREATED);
        ids.push(r.json()["id"].as_str().unwrap().to_string());
    }
    let body = format!(r#"{{"op":"union","operands":["{}","{}"]}}"#, ids[0], ids[1]);
    let d = call(&h.app, "POST", "/v1/volumes/csg", None, body.as_bytes())
        .await
        .problem(422, "grid-too-large");
    assert!(d.contains("union"), "{d}");
}

/// Downloads stream: a conversion arrives in bounded chunks with its exact length announced
/// (the whole response is never built in memory), and a damaged stored volume ends its stream
/// with an error instead of arriving whole.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn downloads_stream_in_bounded_chunks() {
    use futures_util::StreamExt;
    let h = harness("stream").await;
    // 1024×32×32 = 2^20 voxels (the harness's limit): 1 MiB as .npy.
    let (r, _) = call_with(
        &h.app,
        "POST",
        "/v1/voxelize?origin=0,0,0&voxel_size=0.001&dims=1024,32,32&wait=30",
        &[("content-type", "model/obj")],
        TETRA,
    )
    .await;
    r.ok(StatusCode::CREATED);
    let id = r.json()["id"].as_str().unwrap().to_string();
    let get = |uri: String| {
        let app = h.app.clone();
        async move {
            router(app)
                .oneshot(Request::get(uri).body(Body::empty()).unwrap())
                .await
                .unwrap()
        }
    };
    let res = get(format!("/v1/volumes/{id}/data?format=npy")).await;
    assert_eq!(res.status(), StatusCode::OK);
    let len: usize = res.headers()["content-length"]
        .to_str()
        .unwrap()
        .parse()
        .unwrap();
    let mut body = res.into_body().into_data_stream();
    let (mut frames, mut got) = (0, vec![]);
    while let Some(c) = body.next().await {
        let c = c.unwrap();
        assert!(c.len() <= 256 << 10, "a chunk of {} bytes", c.len());
        frames += 1;
        got.extend_from_slice(&c);
    }
    assert_eq!(got.len(), len);
    assert!(frames >= 4, "{frames} chunks");
    let stored = h.app.store.read(&id).await.unwrap().unwrap();
    let (v, _) = crate::codec::vxl::decode(&stored).unwrap();
    assert_eq!(got, crate::codec::npy::encode(&v));
    // Stored bytes damaged on disk: a volume within the first chunk is a problem document; a
    // longer one fails before its last chunk (never arrives whole).
    assert!(stored.len() < 256 << 10);
    let last = stored.len() - 1;
    damage(&h.dir, &stored, last);
    call(&h.app, "GET", &format!("/v1/volumes/{id}/data"), None, b"")
        .await
        .problem(500, "internal");
    // Random bits do not compress: a .vxl of several chunks.
    let mut noisy = crate::volume::BitVolume::new(crate::Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims: [4096, 32, 32],
    });
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    for x in 0..4096 {
        for y in 0..32 {
            for z in 0..32 {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                noisy.set(x, y, z, seed & 1 == 1);
            }
        }
    }
    let vxl = crate::codec::vxl::encode(&crate::volume::Volume::Bits(noisy), &Default::default())
        .unwrap();
    assert!(vxl.len() > 256 << 10, "{} bytes", vxl.len());
    let mut meta = h.app.store.get(&id).await.unwrap().unwrap();
    meta.id = "big".into();
    meta.bytes = vxl.len() as u64;
    meta.sha256 = crate::app::sha256_hex(&vxl);
    h.app.store.put(meta, vxl.clone().into()).await.unwrap();
    damage(&h.dir, &vxl, last);
    let res = get("/v1/volumes/big/data".into()).await;
    assert_eq!(res.status(), StatusCode::OK);
    let mut body = res.into_body().into_data_stream();
    let mut got = 0;
    let err = loop {
        match body.next().await {
            Some(Ok(c)) => got += c.len(),
            Some(Err(e)) => break e,
            None => panic!("a damaged volume streamed whole ({got} bytes)"),
        }
    };
    assert!(
        got < vxl.len() && err.to_string().contains("sha256"),
        "{got}: {err}"
    );
}

/// A list page is bounded in bytes as well as in count, and the pages together hold every
/// volume once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn list_pages_are_bounded_in_bytes() {
    let h = harness_with("listbytes", |l| Limits {
        max_list_page_bytes: 1500,
        ..l
    })
    .await;
    let mut ids = std::collections::BTreeSet::new();
    for _ in 0..5 {
        let r = call(
            &h.app,
            "POST",
            "/v1/voxelize?resolution=4&wait=30",
            Some("model/obj"),
            TETRA,
        )
        .await;
        assert_eq!(r.status, StatusCode::CREATED);
        ids.insert(r.json()["id"].as_str().unwrap().to_string());
    }
    let (mut seen, mut uri, mut pages) = (
        std::collections::BTreeSet::new(),
        "/v1/volumes?limit=100".to_string(),
        0,
    );
    loop {
        let r = call(&h.app, "GET", &uri, None, b"").await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(r.content_type, "application/json");
        let page = r.json();
        let vols = page["volumes"].as_array().unwrap();
        assert!(!vols.is_empty());
        // One volume alone may pass the bound; more than one never do.
        assert!(
            vols.len() == 1 || r.body.len() <= 1500 + 100,
            "{} bytes",
            r.body.len()
        );
        for v in vols {
            assert!(seen.insert(v["id"].as_str().unwrap().to_string()));
        }
        pages += 1;
        match page["next"].as_str() {
            Some(n) => uri = n.to_string(),
            None => break,
        }
        assert!(pages < 10);
    }
    assert_eq!(seen, ids);
    assert!(pages >= 3, "{pages} pages");
}
