//! What the service promises on the wire: every error is a problem document, the probes and
//! metrics answer, and the router and real responses agree with `openapi.yaml` (checked with a
//! small JSON-schema validator of its own).
//!
//! Not here: what the jobs compute (`jobs`, `ops`).

use super::*;

#[test]
fn every_error_is_a_problem_document() {
    let dir = tmpdir("errors");
    let srv = Server::start(
        &dir,
        &[
            "--max-triangles",
            "1000",
            "--max-body-bytes",
            "400000",
            "--max-voxels",
            "1000000",
        ],
    );
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let obj = [("Content-Type", "model/obj")];
    let post =
        |q: &str, h: &[(&str, &str)], b: &[u8]| srv.req("POST", &format!("/v1/voxelize{q}"), h, b);
    assert_problem(
        &post("", &obj, b"v 0 0 0\nv 1 0 0\nf 1 2 9\n"),
        422,
        "invalid-mesh",
    );
    assert_problem(&post("", &obj, b""), 422, "invalid-mesh");
    assert_problem(
        &post("", &[("Content-Type", "text/html")], b"<html>"),
        415,
        "unsupported-media-type",
    );
    assert_problem(
        &post("?format=dwg", &[], b"x"),
        415,
        "unsupported-media-type",
    );
    assert_problem(
        &post("", &[], b"hello there"),
        415,
        "unsupported-media-type",
    );
    let ext = r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"/etc/passwd","byteLength":12}],"meshes":[],"scenes":[]}"#;
    assert_problem(
        &post("", &[("Content-Type", "model/gltf+json")], ext.as_bytes()),
        422,
        "external-resource",
    );
    assert_problem(&post("", &obj, &spot), 422, "too-many-triangles");
    let big = vec![b' '; 500_000];
    assert_problem(&post("", &obj, &big), 413, "body-too-large");
    let small = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n";
    assert_problem(&post("?resolution=200", &obj, small), 422, "grid-too-large");
    assert_problem(
        &post("?method=sculpt", &obj, small),
        400,
        "invalid-parameter",
    );
    assert_problem(&post("?fill=blob", &obj, small), 400, "invalid-parameter");
    assert_problem(
        &post("?resolution=-3", &obj, small),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &post("?origin=0,0&dims=2,2,2&voxel_size=1", &obj, small),
        400,
        "invalid-parameter",
    );
    assert_problem(&post("?colour=red", &obj, small), 400, "invalid-parameter");
    assert_problem(&post("?wait=1000", &obj, small), 400, "invalid-parameter");
    assert_problem(&srv.req("GET", "/v1/jobs/nope", &[], &[]), 404, "not-found");
    assert_problem(
        &srv.req("GET", "/v1/volumes/nope/data", &[], &[]),
        404,
        "not-found",
    );
    assert_problem(
        &srv.req("GET", "/v1/nothing-here", &[], &[]),
        404,
        "not-found",
    );
    assert_problem(
        &srv.req("GET", "/v1/volumes?limit=0", &[], &[]),
        400,
        "invalid-parameter",
    );
    // The request id a caller sends comes back in the problem.
    let r = srv.req("GET", "/v1/jobs/nope", &[("x-request-id", "abc-123")], &[]);
    assert_eq!(
        assert_problem(&r, 404, "not-found")["request_id"],
        "abc-123"
    );
    drop(srv);
    // A store that is full.
    let srv = Server::start(&tmpdir("full"), &["--max-store-bytes", "100"]);
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=16&wait=30",
        &[("Content-Type", "model/obj")],
        small,
    );
    assert_problem(&r, 507, "storage-full");
}

#[test]
fn health_metrics_and_the_openapi_document() {
    let srv = Server::start(&tmpdir("health"), &[]);
    assert_eq!(srv.req("GET", "/healthz", &[], &[]).json()["status"], "ok");
    let ready = srv.req("GET", "/readyz", &[], &[]).json();
    assert_eq!(ready["status"], "ready");
    assert_eq!(ready["engine"], "cpu");
    srv.req(
        "POST",
        "/v1/voxelize?resolution=16&wait=30",
        &[("Content-Type", "model/obj")],
        &std::fs::read(data("spot.obj")).unwrap(),
    );
    let m = String::from_utf8(srv.req("GET", "/metrics", &[], &[]).body).unwrap();
    for want in [
        "voxd_jobs{state=\"succeeded\",method=\"solid\"} 1",
        "voxd_queue_depth 0",
        "voxd_job_duration_seconds_count 1",
        "voxd_engine_info{engine=\"cpu\"} 1",
    ] {
        assert!(m.contains(want), "{want} missing from\n{m}");
    }
    // The GPU's counters only where it runs.
    assert!(!m.contains("voxd_gpu_"), "{m}");
    let doc = srv.req("GET", "/openapi.yaml", &[], &[]);
    assert_eq!(doc.header("content-type"), Some("application/yaml"));
    assert_eq!(doc.body, std::fs::read(repo_file("openapi.yaml")).unwrap());
}

/// The route table (voxd::service::ROUTES) and openapi.yaml list the same paths and methods, and every
/// documented operation answers on the live server (not the fallback).
#[test]
fn router_and_openapi_agree() {
    let yaml = std::fs::read_to_string(repo_file("openapi.yaml")).unwrap();
    let mut documented = std::collections::BTreeSet::new();
    let mut path = None;
    for line in yaml.lines() {
        if line == "components:" {
            break;
        }
        if let Some(p) = line.strip_prefix("  /").and_then(|l| l.strip_suffix(':')) {
            path = Some(format!("/{p}"));
        } else if let (Some(p), Some(m)) = (
            &path,
            line.strip_prefix("    ").and_then(|l| l.strip_suffix(':')),
        ) && ["get", "post", "delete", "put", "patch"].contains(&m)
        {
            documented.insert((p.clone(), m.to_uppercase()));
        }
    }
    let routed: std::collections::BTreeSet<(String, String)> = voxd::service::ROUTES
        .iter()
        .flat_map(|(p, ms)| ms.iter().map(|m| (p.to_string(), m.to_string())))
        .collect();
    assert_eq!(documented, routed, "openapi.yaml and the router disagree");
    let srv = Server::start(&tmpdir("openapi"), &[]);
    for (p, m) in &documented {
        let r = srv.req(m, &p.replace("{id}", "x"), &[], &[]);
        let fallback =
            r.status == 404 && String::from_utf8_lossy(&r.body).contains("no such route");
        assert!(
            !fallback && r.status != 405,
            "{m} {p} is documented but not routed ({})",
            r.status
        );
    }
}

/// Checks `v` against the subset of JSON Schema openapi.yaml uses: $ref, type, nullable,
/// required, properties, items, enum.
fn validate(doc: &Value, schema: &Value, v: &Value, at: &str) -> Result<(), String> {
    if let Some(r) = schema.get("$ref").and_then(Value::as_str) {
        let name = r
            .strip_prefix("#/components/schemas/")
            .ok_or(format!("unsupported $ref {r}"))?;
        return validate(doc, &doc["components"]["schemas"][name], v, at);
    }
    if v.is_null() && schema.get("nullable") == Some(&Value::Bool(true)) {
        return Ok(());
    }
    let ok = match schema.get("type").and_then(Value::as_str) {
        None => true,
        Some("object") => v.is_object(),
        Some("array") => v.is_array(),
        Some("string") => v.is_string(),
        Some("integer") => v.is_i64() || v.is_u64(),
        Some("number") => v.is_number(),
        Some("boolean") => v.is_boolean(),
        Some(t) => return Err(format!("{at}: unsupported type {t}")),
    };
    if !ok {
        return Err(format!("{at}: {v} is not of type {}", schema["type"]));
    }
    if let Some(e) = schema.get("enum").and_then(Value::as_array)
        && !e.contains(v)
    {
        return Err(format!("{at}: {v} is not one of {e:?}"));
    }
    for r in schema
        .get("required")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
    {
        let k = r.as_str().unwrap();
        if v.get(k).is_none() {
            return Err(format!("{at}: required field {k} is missing"));
        }
    }
    if let Some(props) = schema.get("properties").and_then(Value::as_object) {
        for (k, s) in props {
            if let Some(x) = v.get(k) {
                validate(doc, s, x, &format!("{at}.{k}"))?;
            }
        }
    }
    if let (Some(items), Some(arr)) = (schema.get("items"), v.as_array()) {
        for (i, x) in arr.iter().enumerate() {
            validate(doc, items, x, &format!("{at}[{i}]"))?;
        }
    }
    Ok(())
}

/// Real responses, checked against the operation's documented status codes, media types and
/// schemas in openapi.yaml.
#[test]
fn real_responses_match_the_openapi_schemas() {
    let yaml = std::fs::read_to_string(repo_file("openapi.yaml")).unwrap();
    let doc: Value = serde_norway::from_str(&yaml).unwrap();
    let srv = Server::start(&tmpdir("schemas"), &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let obj: &[(&str, &str)] = &[("Content-Type", "model/obj")];
    let mut checked = 0;
    let mut check = |template: &str, method: &str, r: &Resp| {
        let op = &doc["paths"][template][method];
        assert!(op.is_object(), "{method} {template} is not documented");
        let mut resp = &op["responses"][r.status.to_string()];
        assert!(
            resp.is_object(),
            "{method} {template} answered {} which is not documented",
            r.status
        );
        if let Some(name) = resp.get("$ref").and_then(Value::as_str) {
            resp = &doc["components"]["responses"]
                [name.strip_prefix("#/components/responses/").unwrap()];
        }
        let Some(content) = resp.get("content") else {
            assert!(
                r.body.is_empty(),
                "{method} {template} {}: undocumented body",
                r.status
            );
            return;
        };
        let ct = r
            .header("content-type")
            .unwrap_or("")
            .split(';')
            .next()
            .unwrap()
            .to_string();
        let media = content.get(&ct).unwrap_or_else(|| {
            panic!(
                "{method} {template} {}: media type {ct} not documented",
                r.status
            )
        });
        if ct.ends_with("json")
            && let Err(e) = validate(&doc, &media["schema"], &r.json(), "body")
        {
            panic!("{method} {template} {}: {e}", r.status);
        }
        checked += 1;
    };
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=30&wait=60&name=a",
        obj,
        &spot,
    );
    check("/v1/voxelize", "post", &r);
    let vid = r.json()["id"].as_str().unwrap().to_string();
    let bowl = to_obj(&open_bowl());
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=20&wait=60&fill=auto",
        obj,
        &bowl,
    );
    assert!(r.json()["fill"]["winding"].is_object());
    check("/v1/voxelize", "post", &r);
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=20&wait=60&fill=parity",
        obj,
        &bowl,
    );
    assert!(r.json()["fill"]["warning"].is_string());
    check("/v1/voxelize", "post", &r);
    let r = srv.req("POST", "/v1/voxelize?resolution=31", obj, &spot);
    check("/v1/voxelize", "post", &r);
    let jid = r.json()["id"].as_str().unwrap().to_string();
    check(
        "/v1/voxelize",
        "post",
        &srv.req("POST", "/v1/voxelize?method=x", obj, &spot),
    );
    check(
        "/v1/voxelize",
        "post",
        &srv.req("POST", "/v1/voxelize", obj, b"v 1 2 3\n"),
    );
    check(
        "/v1/voxelize",
        "post",
        &srv.req(
            "POST",
            "/v1/voxelize",
            &[("Content-Type", "image/png")],
            b"x",
        ),
    );
    std::thread::sleep(Duration::from_millis(300));
    check(
        "/v1/jobs/{id}",
        "get",
        &srv.req("GET", &format!("/v1/jobs/{jid}"), &[], &[]),
    );
    check(
        "/v1/jobs/{id}",
        "get",
        &srv.req("GET", "/v1/jobs/none", &[], &[]),
    );
    check(
        "/v1/jobs/{id}",
        "delete",
        &srv.req("DELETE", &format!("/v1/jobs/{jid}"), &[], &[]),
    );
    check(
        "/v1/volumes",
        "get",
        &srv.req("GET", "/v1/volumes?limit=1", &[], &[]),
    );
    check(
        "/v1/volumes",
        "get",
        &srv.req("GET", "/v1/volumes?limit=x", &[], &[]),
    );
    check(
        "/v1/volumes/{id}",
        "get",
        &srv.req("GET", &format!("/v1/volumes/{vid}"), &[], &[]),
    );
    for f in ["vxl", "npy", "binvox"] {
        check(
            "/v1/volumes/{id}/data",
            "get",
            &srv.req(
                "GET",
                &format!("/v1/volumes/{vid}/data?format={f}"),
                &[],
                &[],
            ),
        );
    }
    check(
        "/v1/volumes/{id}/data",
        "get",
        &srv.req(
            "GET",
            &format!("/v1/volumes/{vid}/data?format=obj"),
            &[],
            &[],
        ),
    );
    check("/healthz", "get", &srv.req("GET", "/healthz", &[], &[]));
    check("/readyz", "get", &srv.req("GET", "/readyz", &[], &[]));
    check("/metrics", "get", &srv.req("GET", "/metrics", &[], &[]));
    check(
        "/openapi.yaml",
        "get",
        &srv.req("GET", "/openapi.yaml", &[], &[]),
    );
    check(
        "/v1/volumes/{id}",
        "delete",
        &srv.req("DELETE", &format!("/v1/volumes/{vid}"), &[], &[]),
    );
    check(
        "/v1/volumes/{id}",
        "delete",
        &srv.req("DELETE", &format!("/v1/volumes/{vid}"), &[], &[]),
    );
    assert_eq!(checked, 22);
}
