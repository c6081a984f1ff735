//! Kept meshes over HTTP (issue 33): a volume made from an upload keeps the mesh under the
//! upload's sha256 — one copy for every volume made from the same bytes, counted in the store's
//! usage, removed with the last of them — and from it `GET /v1/volumes/{id}/hermite` (the same
//! arrays as `voxd hermite` on the same file and grid) and `GET …/mesh?algorithm=
//! dual-contouring` (watertight and consistent for trimesh, its volume close to the source's).
//! Refusals: a derived volume keeps no mesh (`source-not-kept`, 409), too many edges.

use std::collections::BTreeMap;

use super::*;

/// The arrays of an `.npz` (entry name → its `.npy` bytes, header and data).
fn npz_entries(bytes: &[u8]) -> BTreeMap<String, Vec<u8>> {
    let mut z = zip::ZipArchive::new(std::io::Cursor::new(bytes)).unwrap();
    let mut out = BTreeMap::new();
    for i in 0..z.len() {
        let mut f = z.by_index(i).unwrap();
        let mut b = vec![];
        f.read_to_end(&mut b).unwrap();
        out.insert(f.name().unwrap().to_string(), b);
    }
    out
}

fn stored_bytes(srv: &Server) -> u64 {
    srv.req("GET", "/readyz", &[], &[]).ok(200).json()["stored_bytes"]
        .as_u64()
        .unwrap()
}

/// Files in the store's `sources/` directory.
fn sources(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir.join("sources"))
        .map(|d| d.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default()
}

#[test]
fn kept_meshes_give_hermite_data_and_dual_contouring_and_go_with_their_last_volume() {
    let dir = tmpdir("hermite-route");
    let srv = Server::start(&dir, &[]);
    let spot_path = data("spot.obj");
    let spot = std::fs::read(&spot_path).unwrap();
    let grid = "origin=-0.75,-0.9,-0.75&voxel_size=0.0625&dims=24,30,30";
    let make = |q: &str| {
        srv.created(
            &format!("/v1/voxelize?{grid}&wait=60&{q}"),
            &[("Content-Type", "model/obj")],
            &spot,
        )
    };
    let a = make("name=spot");
    assert_eq!(a["source"]["kept"], true, "{a}");
    let key = a["source"]["sha256"].as_str().unwrap().to_string();
    let kept = sources(&dir);
    assert_eq!(kept.len(), 1, "{kept:?}");
    assert!(kept[0].ends_with(&key));
    let source_len = std::fs::metadata(&kept[0]).unwrap().len();
    let with_one = stored_bytes(&srv);
    // A second volume of the same upload shares the kept mesh: usage grows by its own files.
    let b = make("method=surface");
    assert_eq!(b["source"]["sha256"], key.as_str());
    assert_eq!(sources(&dir).len(), 1);
    let with_two = stored_bytes(&srv);
    let b_files = b["bytes"].as_u64().unwrap();
    assert!(
        with_two - with_one >= b_files && with_two - with_one < b_files + source_len,
        "usage {with_one} → {with_two}, the second volume's data {b_files}, the mesh {source_len}"
    );

    // The Hermite data over HTTP: the arrays `voxd hermite` writes for the same file and grid.
    let (ida, idb) = (a["id"].as_str().unwrap(), b["id"].as_str().unwrap());
    let r = srv
        .req("GET", &format!("/v1/volumes/{ida}/hermite"), &[], &[])
        .ok(200);
    assert!(
        r.header("content-disposition")
            .unwrap()
            .contains("spot.npz")
    );
    let http = npz_entries(&r.body);
    let npz = dir.join("cli.npz");
    let o = run_voxd(&[
        "hermite",
        spot_path.to_str().unwrap(),
        "-o",
        npz.to_str().unwrap(),
        "--origin",
        "-0.75,-0.9,-0.75",
        "--voxel-size",
        "0.0625",
        "--dims",
        "24,30,30",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cli = npz_entries(&std::fs::read(&npz).unwrap());
    assert_eq!(
        http.keys().collect::<Vec<_>>(),
        cli.keys().collect::<Vec<_>>()
    );
    for (name, bytes) in &cli {
        assert!(&http[name] == bytes, "{name} differs from voxd hermite's");
    }
    assert!(http["edges.npy"].len() > 4000);
    // The surface volume's Hermite data is its mesh's solid's: the same.
    let r = srv
        .req("GET", &format!("/v1/volumes/{idb}/hermite"), &[], &[])
        .ok(200);
    assert!(npz_entries(&r.body) == http);
    // A revalidation computes nothing.
    let etag = r.header("etag").unwrap().to_string();
    let again = srv.req(
        "GET",
        &format!("/v1/volumes/{idb}/hermite"),
        &[("If-None-Match", &etag)],
        &[],
    );
    assert_eq!(again.status, 304);

    // Dual contouring over HTTP, read by trimesh where its venv is.
    let r = srv
        .req(
            "GET",
            &format!("/v1/volumes/{ida}/mesh?algorithm=dual-contouring&format=ply"),
            &[],
            &[],
        )
        .ok(200);
    assert_eq!(r.header("content-type"), Some("model/ply"));
    if let Some(py) = crate::mesh_cli::trimesh_python() {
        let f = dir.join("dc.ply");
        std::fs::write(&f, &r.body).unwrap();
        let (watertight, consistent, volume, faces) = crate::mesh_cli::trimesh_check(&py, &f);
        assert!(watertight && consistent, "dual contouring over HTTP");
        assert!(faces > 1000);
        let voxels = a["volume"].as_f64().unwrap();
        assert!(
            (volume / voxels - 1.0).abs() < 0.05,
            "{volume} vs the voxels' {voxels}"
        );
    }

    // A derived volume keeps no mesh: said before any work.
    let derived = srv.created(
        &format!("/v1/volumes/{ida}/morphology"),
        &[],
        br#"{"op": "dilate", "radius": 1}"#,
    );
    let did = derived["id"].as_str().unwrap();
    assert!(derived["source"].get("kept").is_none(), "{derived}");
    for path in [
        format!("/v1/volumes/{did}/hermite"),
        format!("/v1/volumes/{did}/mesh?algorithm=dual-contouring"),
    ] {
        let r = srv.req("GET", &path, &[], &[]);
        let p = assert_problem(&r, 409, "source-not-kept");
        assert!(
            p["detail"]
                .as_str()
                .unwrap()
                .contains("voxelize the mesh again")
        );
    }
    let r = srv.req("GET", "/v1/volumes/0123456789abcdef/hermite", &[], &[]);
    assert_problem(&r, 404, "not-found");

    // Deleting one volume keeps the mesh for the other; deleting the last removes it, and the
    // usage is what the derived volume alone takes.
    srv.req("DELETE", &format!("/v1/volumes/{ida}"), &[], &[])
        .ok(204);
    assert_eq!(sources(&dir).len(), 1);
    srv.req("GET", &format!("/v1/volumes/{idb}/hermite"), &[], &[])
        .ok(200);
    srv.req("DELETE", &format!("/v1/volumes/{idb}"), &[], &[])
        .ok(204);
    assert_eq!(sources(&dir), Vec::<PathBuf>::new());
    let derived_files = derived["bytes"].as_u64().unwrap();
    let left = stored_bytes(&srv);
    assert!(
        left >= derived_files && left < derived_files + 4096,
        "{left} bytes stored for a volume of {derived_files}"
    );
    srv.stop();

    // Over the limit: the differing edges against --max-triangles, refused with the numbers.
    let srv = Server::start(&tmpdir("hermite-route-limit"), &["--max-triangles", "6000"]);
    let v = srv.created(
        "/v1/voxelize?resolution=96&wait=60",
        &[("Content-Type", "model/obj")],
        &spot,
    );
    let id = v["id"].as_str().unwrap();
    let r = srv.req("GET", &format!("/v1/volumes/{id}/hermite"), &[], &[]);
    let p = assert_problem(&r, 422, "too-many-triangles");
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("over the limit of 6000"),
        "{p}"
    );
    srv.stop();
}
