//! API keys through the router: which routes they guard, and each key's own rates and job
//! limits.
//!
//! Not here: parsing the keys file (`service::auth`).

use super::*;

/// With keys, every /v1 route needs one: none or a wrong one is 401 with the Bearer challenge
/// (before the route is even looked at: an unknown /v1 path too), a valid one passes;
/// /healthz, /readyz, /metrics and /openapi.yaml stay open unless --protect-metrics, which
/// closes /metrics only.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn api_keys_guard_v1_and_leave_the_probes_open() {
    let (key, line) = crate::service::auth::generate("team-a").unwrap();
    let h = keyed("keys-guard", &line, false).await;
    let auth = format!("Bearer {key}");
    for (method, path) in ROUTES
        .iter()
        .filter(|(p, _)| p.starts_with("/v1"))
        .flat_map(|(p, ms)| ms.iter().map(move |m| (*m, p.replace("{id}", "x"))))
        .chain([("GET", "/v1/nope".to_string())])
    {
        let (r, hd) = call_with(&h.app, method, &path, &[], b"").await;
        r.problem(401, "unauthorized");
        assert_eq!(hd["www-authenticate"], "Bearer realm=\"voxd\"", "{path}");
        let (r, hd) = call_with(
            &h.app,
            method,
            &path,
            &[("authorization", "Bearer voxd_wrong")],
            b"",
        )
        .await;
        r.problem(401, "unauthorized");
        assert_eq!(
            hd["www-authenticate"],
            "Bearer realm=\"voxd\", error=\"invalid_token\""
        );
        let (r, _) = call_with(&h.app, method, &path, &[("authorization", &auth)], b"").await;
        assert_ne!(r.status, StatusCode::UNAUTHORIZED, "{method} {path}");
    }
    let (r, _) = call_with(
        &h.app,
        "GET",
        "/v1/volumes",
        &[("authorization", &auth)],
        b"",
    )
    .await;
    assert_eq!(r.status, StatusCode::OK);
    for open in ["/healthz", "/readyz", "/metrics", "/openapi.yaml"] {
        assert_eq!(
            call(&h.app, "GET", open, None, b"").await.status,
            StatusCode::OK,
            "{open}"
        );
    }
    let metrics = String::from_utf8(call(&h.app, "GET", "/metrics", None, b"").await.body).unwrap();
    assert!(
        metrics.contains("voxd_key_requests_total{key=\"team-a\"}"),
        "{metrics}"
    );
    assert!(!metrics.contains(&key));

    let h = keyed("keys-metrics", &line, true).await;
    call(&h.app, "GET", "/metrics", None, b"")
        .await
        .problem(401, "unauthorized");
    let (r, _) = call_with(&h.app, "GET", "/metrics", &[("authorization", &auth)], b"").await;
    assert_eq!(r.status, StatusCode::OK);
    for open in ["/healthz", "/readyz"] {
        assert_eq!(
            call(&h.app, "GET", open, None, b"").await.status,
            StatusCode::OK,
            "{open}"
        );
    }
}

/// Per key: a request rate (429 rate-limited with Retry-After) and a number of jobs queued or
/// running (429 too-many-jobs), each key on its own; a job's record names its key; a job
/// canceled frees its place.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn api_keys_have_their_own_rates_and_job_limits() {
    let (ka, la) = crate::service::auth::generate("limited").unwrap();
    let (kb, lb) = crate::service::auth::generate("other").unwrap();
    let h = keyed(
        "keys-limits",
        &format!("{la}:rate=1,burst=4,jobs=2\n{lb}:rate=0,jobs=0\n"),
        false,
    )
    .await;
    let (a, b) = (format!("Bearer {ka}"), format!("Bearer {kb}"));
    let submit = async |auth: &str| {
        call_with(
            &h.app,
            "POST",
            "/v1/voxelize?resolution=8",
            &[("authorization", auth), ("content-type", "model/obj")],
            TETRA,
        )
        .await
    };
    let mut ids = Vec::new();
    for _ in 0..2 {
        let (r, _) = submit(&a).await;
        r.ok(StatusCode::ACCEPTED);
        assert_eq!(r.json()["key_name"], "limited");
        ids.push(r.json()["id"].as_str().unwrap().to_string());
    }
    let (r, hd) = submit(&a).await;
    let detail = r.problem(429, "too-many-jobs");
    assert!(
        detail.contains("limited") && detail.contains('2'),
        "{detail}"
    );
    assert!(hd.contains_key("retry-after"));
    // The other key is held back by neither limit of the first.
    for _ in 0..5 {
        let (r, _) = submit(&b).await;
        assert_eq!(r.status, StatusCode::ACCEPTED);
        assert_eq!(r.json()["key_name"], "other");
    }
    // The burst of 4 is spent (3 submits, this cancel); the 5th request within the second
    // waits: 1 s.
    let (r, _) = call_with(
        &h.app,
        "DELETE",
        &format!("/v1/jobs/{}", ids[0]),
        &[("authorization", &a)],
        b"",
    )
    .await;
    r.ok(StatusCode::OK);
    let (r, hd) = call_with(&h.app, "GET", "/v1/volumes", &[("authorization", &a)], b"").await;
    r.problem(429, "rate-limited");
    assert_eq!(hd["retry-after"], "1");
    // After a second, one more request is allowed: a submit, in the place the cancel freed.
    tokio::time::sleep(std::time::Duration::from_millis(1100)).await;
    let (r, _) = submit(&a).await;
    r.ok(StatusCode::ACCEPTED);
    // A full queue (16: 2 of one key and 5 of the other queued so far, 9 more) refuses before
    // the upload is read or parsed: a body that is no mesh at all is 429 queue-full, not 422.
    for _ in 0..9 {
        assert_eq!(submit(&b).await.0.status, StatusCode::ACCEPTED);
    }
    let (r, hd) = call_with(
        &h.app,
        "POST",
        "/v1/voxelize?resolution=8",
        &[("authorization", &b), ("content-type", "model/obj")],
        b"this is not a mesh",
    )
    .await;
    r.problem(429, "queue-full");
    assert_eq!(hd["retry-after"], "5");
}
