//! Tenants apart (issue 30, defect 5), end to end with an API keys file: volumes and jobs are
//! owned by the tenant of the key that made them; another tenant's are `404 not-found` on every
//! route (as if they did not exist, so ids do not leak) and absent from its listings; a
//! `read-only` key reads its tenant's and gets `403 forbidden` for every write; an `admin` key
//! reads and writes every tenant's. The real `voxd serve` on 127.0.0.1.

use crate::auth::keygen;
use crate::common::*;
use crate::service::{Server, box_obj};

/// One tenant's view: a key's Authorization header value.
struct Key(String);

impl Key {
    fn new(name: &str, options: &str, lines: &mut String) -> Key {
        let (key, line) = keygen(name);
        lines.push_str(&line);
        lines.push_str(options);
        lines.push('\n');
        Key(format!("Bearer {key}"))
    }

    fn req(&self, srv: &Server, method: &str, path: &str, body: &[u8]) -> Resp {
        let h = [
            ("authorization", self.0.as_str()),
            ("content-type", "application/json"),
        ];
        request(&srv.addr, method, path, &h, body)
    }

    fn upload(&self, srv: &Server, wait: u32) -> Resp {
        let h = [
            ("authorization", self.0.as_str()),
            ("content-type", "model/obj"),
        ];
        let grid = "origin=0,0,0&voxel_size=0.5&dims=20,20,20";
        request(
            &srv.addr,
            "POST",
            &format!("/v1/voxelize?{grid}&wait={wait}"),
            &h,
            &box_obj([1.2, 1.1, 1.3], [7.3, 8.7, 6.1]),
        )
    }

    fn listed(&self, srv: &Server) -> Vec<String> {
        let v = self
            .req(srv, "GET", "/v1/volumes?limit=100", b"")
            .ok(200)
            .json();
        v["volumes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["id"].as_str().unwrap().to_string())
            .collect()
    }
}

/// Every route that names volume `v` or job `j` (method, path, body), reads then writes.
fn routes(v: &str, other: &str, j: &str) -> Vec<(&'static str, String, String)> {
    let csg = format!(r#"{{"op":"union","operands":["{v}","{other}"]}}"#);
    vec![
        ("GET", format!("/v1/volumes/{v}"), String::new()),
        ("GET", format!("/v1/volumes/{v}/data"), String::new()),
        (
            "GET",
            format!("/v1/volumes/{v}/data?format=npy"),
            String::new(),
        ),
        ("GET", format!("/v1/volumes/{v}/stats"), String::new()),
        (
            "POST",
            format!("/v1/volumes/{v}/query"),
            r#"{"points":[[1,1,1]]}"#.into(),
        ),
        (
            "GET",
            format!("/v1/volumes/{v}/normals?points=1,1,1"),
            String::new(),
        ),
        ("GET", format!("/v1/volumes/{v}/preview.png"), String::new()),
        (
            "POST",
            "/v1/volumes/intersect".into(),
            format!(r#"{{"a":"{v}","b":"{other}"}}"#),
        ),
        (
            "POST",
            "/v1/volumes/intersect".into(),
            format!(r#"{{"a":"{other}","b":"{v}"}}"#),
        ),
        ("GET", format!("/v1/jobs/{j}"), String::new()),
        // Writes.
        (
            "POST",
            format!("/v1/volumes/{v}/morphology"),
            r#"{"op":"dilate","radius":1}"#.into(),
        ),
        ("POST", "/v1/volumes/csg".into(), csg),
        ("DELETE", format!("/v1/jobs/{j}"), String::new()),
        ("DELETE", format!("/v1/volumes/{v}"), String::new()),
    ]
}

#[test]
fn tenants_see_only_their_own_volumes_and_jobs() {
    let dir = Scratch::new("tenants");
    let mut lines = String::from("# tenants\n");
    let a = Key::new("team-a", "", &mut lines);
    let b = Key::new("team-b", ":jobs=4", &mut lines);
    let reader = Key::new("a-dashboard", ":role=read-only,tenant=team-a", &mut lines);
    let admin = Key::new("ops", ":role=admin", &mut lines);
    let keys = dir.join("keys");
    std::fs::write(&keys, lines).unwrap();
    let srv = Server::start(&dir, &["--api-keys-file", keys.to_str().unwrap()]);
    let id = |r: Resp| r.ok(201).json()["id"].as_str().unwrap().to_string();
    let va = id(a.upload(&srv, 60));
    let va2 = id(a.upload(&srv, 60));
    let vb = id(b.upload(&srv, 60));
    let ja = a.upload(&srv, 0).ok(202).json()["id"]
        .as_str()
        .unwrap()
        .to_string();
    let jb = b.upload(&srv, 0).ok(202).json()["id"]
        .as_str()
        .unwrap()
        .to_string();
    assert_eq!(
        a.req(&srv, "GET", &format!("/v1/volumes/{va}"), b"")
            .ok(200)
            .json()["owner"],
        "team-a"
    );

    // Another tenant: 404 on every route that names A's volume or job, whatever the method;
    // and the same for A on B's. Nothing changed for the owner.
    for (who, theirs, mine, job) in [(&b, &va, &vb, &ja), (&a, &vb, &va2, &jb)] {
        for (method, path, body) in routes(theirs, mine, job) {
            let r = who.req(&srv, method, &path, body.as_bytes());
            r.problem(404, "not-found");
        }
    }
    // A CSG with one of another tenant's operands is not found either, whichever comes first.
    let csg = format!(r#"{{"op":"union","operands":["{vb}","{va}"]}}"#);
    b.req(&srv, "POST", "/v1/volumes/csg", csg.as_bytes())
        .problem(404, "not-found");
    assert!(!b.listed(&srv).contains(&va) && b.listed(&srv).contains(&vb));
    let listed = a.listed(&srv);
    assert!(listed.contains(&va) && listed.contains(&va2) && !listed.contains(&vb));
    a.req(&srv, "GET", &format!("/v1/volumes/{va}"), b"")
        .ok(200);
    let job = a
        .req(&srv, "GET", &format!("/v1/jobs/{ja}"), b"")
        .ok(200)
        .json();
    assert_eq!(job["owner"], "team-a");

    // Read-only, of tenant A: reads A's (not B's); every write is 403.
    for (method, path, body) in routes(&va, &va2, &ja) {
        let r = reader.req(&srv, method, &path, body.as_bytes());
        let write = method == "DELETE" || path.ends_with("/morphology") || path.ends_with("/csg");
        if write {
            r.problem(403, "forbidden");
        } else {
            assert!(r.status < 300, "{method} {path}: {}", r.status);
        }
    }
    reader.upload(&srv, 60).problem(403, "forbidden");
    reader
        .req(&srv, "GET", &format!("/v1/volumes/{vb}"), b"")
        .problem(404, "not-found");
    assert!(reader.listed(&srv).contains(&va));

    // Admin: every tenant's, reads and writes.
    let all = admin.listed(&srv);
    assert!(all.contains(&va) && all.contains(&vb));
    admin
        .req(&srv, "GET", &format!("/v1/jobs/{jb}"), b"")
        .ok(200);
    let csg = format!(r#"{{"op":"union","operands":["{va}","{vb}"]}}"#);
    let mixed = admin
        .req(&srv, "POST", "/v1/volumes/csg", csg.as_bytes())
        .ok(201)
        .json();
    assert_eq!(mixed["owner"], "ops");
    admin
        .req(&srv, "DELETE", &format!("/v1/volumes/{vb}"), b"")
        .ok(204);
    // The owners still do what they may with their own.
    a.req(
        &srv,
        "POST",
        &format!("/v1/volumes/{va}/morphology"),
        br#"{"op":"dilate","radius":1}"#,
    )
    .ok(201);
    a.req(&srv, "DELETE", &format!("/v1/volumes/{va}"), b"")
        .ok(204);
    b.req(&srv, "GET", &format!("/v1/volumes/{vb}"), b"")
        .problem(404, "not-found");
}
