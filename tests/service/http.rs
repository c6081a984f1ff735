//! HTTP semantics of the volume routes, as curl-like clients meet them (RFC 9110/9111): one ETag
//! per content coding, the same on the 200 and the 304; `Vary` and `Cache-Control` on both;
//! `If-Match` compared strongly and `If-None-Match` weakly on GET and DELETE; byte ranges of
//! identity downloads, so that an interrupted download resumes (by hand, and with real `curl -C -`
//! and `wget -c` where they are installed).

use super::*;

/// A server with one stored box volume: the server and the volume's id.
fn with_volume(name: &str) -> (Server, String) {
    let srv = Server::start(&tmpdir(name), &[]);
    let meta = srv.created(
        "/v1/voxelize?origin=0,0,0&voxel_size=0.5&dims=30,28,26&wait=60",
        &[("Content-Type", "model/obj")],
        &box_obj([1.2, 1.1, 1.3], [9.3, 8.7, 9.1]),
    );
    let id = meta["id"].as_str().unwrap().to_string();
    (srv, id)
}

/// `Vary` and `Cache-Control` as a 200 and a 304 of the volume routes carry them.
fn cache_headers(r: &Resp) {
    let vary = r.header("vary").unwrap_or_default().to_ascii_lowercase();
    assert!(
        vary.contains("accept-encoding"),
        "{} Vary: {vary:?}",
        r.status
    );
    assert_eq!(
        r.header("cache-control"),
        Some("private, no-cache"),
        "{}",
        r.status
    );
}

fn decoded(r: &Resp) -> Vec<u8> {
    use std::io::Read;
    match r.header("content-encoding") {
        None => r.body.clone(),
        Some("gzip") => {
            let mut out = vec![];
            flate2::read::GzDecoder::new(&r.body[..])
                .read_to_end(&mut out)
                .unwrap();
            out
        }
        Some("zstd") => zstd::decode_all(&r.body[..]).unwrap(),
        Some(c) => panic!("coding {c}"),
    }
}

#[test]
fn etags_per_coding_and_conditionals() {
    let (srv, id) = with_volume("http-etags");
    let uri = format!("/v1/volumes/{id}/data?format=npy");
    let get = |h: &[(&str, &str)]| srv.req("GET", &uri, h, &[]);
    let plain = get(&[]).ok(200);
    let mut seen = vec![];
    for (ae, coding) in [
        (None, None),
        (Some("gzip"), Some("gzip")),
        (Some("zstd"), Some("zstd")),
        (Some("gzip, deflate, br, zstd"), Some("zstd")),
        (Some("zstd;q=0.5, gzip"), Some("gzip")),
        (Some("gzip;q=0"), None),
    ] {
        let ae: Vec<(&str, &str)> = ae.map(|a| ("Accept-Encoding", a)).into_iter().collect();
        let r = get(&ae).ok(200);
        assert_eq!(r.header("content-encoding"), coding, "{ae:?}");
        assert_eq!(decoded(&r), plain.body, "{ae:?}");
        cache_headers(&r);
        let etag = r.header("etag").unwrap().to_string();
        // The 304 carries exactly the 200's ETag, whether asked strongly, weakly, in a list.
        for inm in [
            etag.clone(),
            format!("W/{etag}"),
            format!("\"x\", {etag}"),
            "*".into(),
        ] {
            let mut h = ae.clone();
            h.push(("If-None-Match", &inm));
            let n = get(&h);
            assert_eq!(n.status, 304, "{ae:?} {inm}");
            assert!(n.body.is_empty());
            assert_eq!(n.header("etag"), Some(etag.as_str()), "{ae:?} {inm}");
            cache_headers(&n);
        }
        // If-Match: strong comparison.
        let mut h = ae.clone();
        h.push(("If-Match", &etag));
        assert_eq!(get(&h).status, 200);
        let weak = format!("W/{etag}");
        let mut h = ae.clone();
        h.push(("If-Match", &weak));
        get(&h).problem(412, "precondition-failed");
        seen.push((ae, etag));
    }
    // One ETag per coding, and a coding's ETag matches no other coding's request.
    let tags: std::collections::BTreeSet<&String> = seen.iter().map(|(_, t)| t).collect();
    assert_eq!(tags.len(), 3, "{seen:?}");
    let (gz, zs) = (&seen[1].1, &seen[2].1);
    let r = get(&[("Accept-Encoding", "zstd"), ("If-None-Match", gz)]).ok(200);
    assert_eq!(r.header("content-encoding"), Some("zstd"));
    assert_eq!(r.header("etag"), Some(zs.as_str()));
    let r = get(&[("If-None-Match", gz)]).ok(200);
    assert_eq!(r.header("content-encoding"), None);
    get(&[("Accept-Encoding", "gzip"), ("If-Match", zs)]).problem(412, "precondition-failed");
    // .vxl is compressed already: one representation whatever is accepted.
    let vxl = format!("/v1/volumes/{id}/data");
    let a = srv.req("GET", &vxl, &[], &[]).ok(200);
    let b = srv
        .req("GET", &vxl, &[("Accept-Encoding", "zstd, gzip")], &[])
        .ok(200);
    assert_eq!(b.header("content-encoding"), None);
    assert_eq!(a.header("etag"), b.header("etag"));

    // The metadata: the same rules.
    let meta = format!("/v1/volumes/{id}");
    for ae in ["identity", "gzip", "zstd"] {
        let r = srv
            .req("GET", &meta, &[("Accept-Encoding", ae)], &[])
            .ok(200);
        cache_headers(&r);
        assert_eq!(
            serde_json::from_slice::<Value>(&decoded(&r)).unwrap()["id"],
            id.as_str()
        );
        let etag = r.header("etag").unwrap().to_string();
        let n = srv.req(
            "GET",
            &meta,
            &[("Accept-Encoding", ae), ("If-None-Match", &etag)],
            &[],
        );
        assert_eq!((n.status, n.header("etag")), (304, Some(etag.as_str())));
        cache_headers(&n);
        let weak = format!("W/{etag}");
        srv.req(
            "GET",
            &meta,
            &[("Accept-Encoding", ae), ("If-Match", &weak)],
            &[],
        )
        .problem(412, "precondition-failed");
    }
    let meta_tag = srv
        .req("GET", &meta, &[], &[])
        .header("etag")
        .unwrap()
        .to_string();

    // DELETE: a failed precondition keeps the volume.
    let weak = format!("W/{meta_tag}");
    for h in [
        ("If-Match", "\"0000000000000000-npy\""),
        ("If-Match", weak.as_str()),
        ("If-None-Match", "*"),
        ("If-None-Match", meta_tag.as_str()),
    ] {
        srv.req("DELETE", &meta, &[h], &[])
            .problem(412, "precondition-failed");
        srv.req("GET", &meta, &[], &[]).ok(200);
    }
    // Any representation's ETag, compared strongly, is the volume's: here the gzip download's.
    srv.req("DELETE", &meta, &[("If-Match", gz)], &[]).ok(204);
    srv.req("GET", &meta, &[], &[]).problem(404, "not-found");
    srv.stop();
}

#[test]
fn ranges_resume_downloads() {
    let (srv, id) = with_volume("http-ranges");
    for format in ["npy", "vxl", "raw"] {
        let uri = format!("/v1/volumes/{id}/data?format={format}");
        let get = |h: &[(&str, &str)]| srv.req("GET", &uri, h, &[]);
        let full = get(&[]).ok(200);
        let n = full.body.len();
        assert!(n > 300, "{format}: {n}");
        assert_eq!(full.header("accept-ranges"), Some("bytes"), "{format}");
        assert_eq!(full.header("content-length"), Some(n.to_string().as_str()));
        let etag = full.header("etag").unwrap().to_string();
        let part = |spec: &str, h: &[(&str, &str)]| {
            let mut h = h.to_vec();
            let range = format!("bytes={spec}");
            h.push(("Range", &range));
            get(&h)
        };
        for (spec, lo, hi) in [
            ("10-99".to_string(), 10, 99),
            ("0-0".into(), 0, 0),
            (format!("{}-", n - 5), n - 5, n - 1),
            ("-100".into(), n - 100, n - 1),
            (format!("200-{}", n * 2), 200, n - 1),
        ] {
            // A Range wins over Accept-Encoding: its bytes are the identity body's.
            let r = part(
                &spec,
                &[("Accept-Encoding", "gzip, zstd"), ("If-Range", &etag)],
            );
            assert_eq!(r.status, 206, "{format} {spec}");
            assert_eq!(r.header("content-encoding"), None);
            assert_eq!(
                r.header("content-range"),
                Some(format!("bytes {lo}-{hi}/{n}").as_str()),
            );
            assert_eq!(r.header("etag"), Some(etag.as_str()));
            assert_eq!(r.body, &full.body[lo..=hi], "{format} {spec}");
            cache_headers(&r);
        }
        // Past the end: 416 with the length.
        let r = part(&format!("{n}-"), &[]);
        r.problem(416, "range-not-satisfiable");
        assert_eq!(
            r.header("content-range"),
            Some(format!("bytes */{n}").as_str())
        );
        part("-0", &[]).problem(416, "range-not-satisfiable");
        // Several ranges, another unit, or an If-Range that is not the current strong ETag:
        // the whole body.
        for (spec, h) in [
            ("0-1,5-6", vec![]),
            (
                "0-9",
                vec![("If-Range", "\"0000000000000000-npy\"".to_string())],
            ),
            ("0-9", vec![("If-Range", format!("W/{etag}"))]),
        ] {
            let h: Vec<(&str, &str)> = h.iter().map(|(k, v)| (*k, v.as_str())).collect();
            let r = part(spec, &h).ok(200);
            assert_eq!(r.body, full.body, "{format} {spec} {h:?}");
        }
        // An interrupted download, resumed as `curl -C -` or `wget -c` does.
        let mut got = full.body[..n / 3].to_vec();
        let rest = part(&format!("{}-", got.len()), &[("If-Range", &etag)]).ok(206);
        got.extend_from_slice(&rest.body);
        assert_eq!(got, full.body, "{format}");
    }
    // .binvox's length is only known once it is encoded: no ranges, the whole body.
    let uri = format!("/v1/volumes/{id}/data?format=binvox");
    let full = srv.req("GET", &uri, &[], &[]).ok(200);
    assert_eq!(full.header("accept-ranges"), None);
    let r = srv.req("GET", &uri, &[("Range", "bytes=0-9")], &[]).ok(200);
    assert_eq!(r.body, full.body);
    srv.stop();
}

/// Real clients resume a download cut short: `curl -C -` and `wget -c` (each where installed).
#[test]
fn curl_and_wget_resume_downloads() {
    let (srv, id) = with_volume("http-curl");
    let dir = tmpdir("http-curl-files");
    let url = format!("http://{}/v1/volumes/{id}/data?format=npy", srv.addr);
    let full = srv
        .req(
            "GET",
            &format!("/v1/volumes/{id}/data?format=npy"),
            &[],
            &[],
        )
        .ok(200);
    let tools: [(&str, &[&str]); 2] = [
        ("curl", &["-sS", "-f", "-C", "-", "-o"]),
        ("wget", &["-q", "-c", "-O"]),
    ];
    for (tool, args) in tools {
        let file = dir.join(format!("{tool}.npy"));
        std::fs::write(&file, &full.body[..full.body.len() / 2]).unwrap();
        let out = Command::new(tool).args(args).arg(&file).arg(&url).output();
        let Ok(out) = out else {
            eprintln!("{tool} is not installed: not tried");
            continue;
        };
        assert!(
            out.status.success(),
            "{tool}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(std::fs::read(&file).unwrap(), full.body, "{tool}");
    }
    srv.stop();
}
