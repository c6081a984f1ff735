//! Operations on distance volumes over HTTP: `sdf` of a stored bit volume, `threshold` back,
//! statistics, point queries and CSG of distance volumes, and their refusals. The oracles are
//! the bit volumes the service voxelized (downloaded) and arithmetic on them here.

use super::*;
use voxd::volume::Sparse;

fn decode_distance(b: &[u8]) -> Sparse<f32> {
    match VolumeFormat::Vxl.decode(b).unwrap() {
        Volume::SparseDistance(s) => s,
        other => panic!("expected a sparse distance volume, got {:?}", other.kind()),
    }
}

#[test]
fn distance_operations_over_http() {
    let srv = Server::start(&tmpdir("distance-ops"), &[]);
    let obj = [("Content-Type", "model/obj")];
    let grid = "origin=0,0,0&voxel_size=0.5&dims=30,28,26";
    let up = |lo, hi| {
        srv.created(
            &format!("/v1/voxelize?{grid}&wait=60"),
            &obj,
            &box_obj(lo, hi),
        )["id"]
            .as_str()
            .unwrap()
            .to_string()
    };
    let data = |id: &str| {
        srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
            .body
    };
    let a = up([1.2, 1.1, 1.3], [9.3, 8.7, 9.1]);
    let b = up([5.4, 0.3, 0.2], [14.1, 13.2, 12.4]);
    let (ba, bb) = (decode_bits(&data(&a)), decode_bits(&data(&b)));
    assert!(ba.count_ones() > 1000 && bb.count_ones() > 1000);

    // sdf of a bit volume: negative exactly at its voxels, ∓s/2 across its faces.
    let meta = srv.created(&format!("/v1/volumes/{a}/sdf?band=2&name=a-sdf"), &[], &[]);
    assert_eq!(meta["kind"], "sparse-distance");
    assert_eq!(meta["provenance"]["sdf"]["band"], 2);
    let sa_id = meta["id"].as_str().unwrap().to_string();
    let sa = decode_distance(&data(&sa_id));
    assert_eq!(sa.background(), 1.0);
    let [nx, ny, nz] = ba.dims();
    let mut faces = 0;
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let (v, set) = (sa.get(x, y, z), ba.get(x, y, z));
                assert_eq!(v.is_sign_negative(), set, "{x} {y} {z}");
                assert!(v.abs() >= 0.25 && v.abs() <= 1.0);
                if set && x + 1 < nx && !ba.get(x + 1, y, z) {
                    assert_eq!(v, -0.25);
                    assert_eq!(sa.get(x + 1, y, z), 0.25);
                    faces += 1;
                }
            }
        }
    }
    assert!(faces > 0);
    let sb_id = srv.created(&format!("/v1/volumes/{b}/sdf"), &[], &[])["id"]
        .as_str()
        .unwrap()
        .to_string();
    assert_eq!(decode_distance(&data(&sb_id)).background(), 1.5); // band 3 by default

    // threshold at 0 gives the bit volume back; at −0.3 the voxels deeper than that.
    let t = srv.created(&format!("/v1/volumes/{sa_id}/threshold?level=0"), &[], &[]);
    assert_eq!(t["kind"], "bits");
    assert_eq!(decode_bits(&data(t["id"].as_str().unwrap())), ba);
    let t = srv.created(
        &format!("/v1/volumes/{sa_id}/threshold?level=-0.3"),
        &[],
        &[],
    );
    let inner = decode_bits(&data(t["id"].as_str().unwrap()));
    let deep = (0..nx)
        .flat_map(|x| (0..ny).flat_map(move |y| (0..nz).map(move |z| [x, y, z])))
        .filter(|&[x, y, z]| sa.get(x, y, z) < -0.3)
        .count() as u64;
    assert_eq!(inner.count_ones(), deep);
    assert!(deep > 0 && deep < ba.count_ones());

    // Statistics.
    let st = srv
        .req("GET", &format!("/v1/volumes/{sa_id}/stats"), &[], &[])
        .json();
    assert_eq!(st["band_voxels"], 2.0);
    assert_eq!(st["inside_voxels"], ba.count_ones());
    assert_eq!(
        st["enclosed_volume"].as_f64().unwrap(),
        ba.count_ones() as f64 * 0.125
    );
    assert_eq!(st["min"], -1.0);
    assert_eq!(st["max"], 1.0);

    // A point at a voxel centre: the interpolation is the voxel's value; between two centres
    // along x, their mean, with the slope between them.
    let c = |i: u32| 0.5 * f64::from(i) + 0.25;
    let (x, y, z) = (4u32, 5u32, 6u32);
    let q = serde_json::json!({"points": [[c(x), c(y), c(z)], [c(x) + 0.25, c(y), c(z)]]});
    let ans = srv
        .req(
            "POST",
            &format!("/v1/volumes/{sa_id}/query"),
            &[("Content-Type", "application/json")],
            q.to_string().as_bytes(),
        )
        .json();
    let (v0, v1) = (f64::from(sa.get(x, y, z)), f64::from(sa.get(x + 1, y, z)));
    let p = &ans["points"];
    assert_eq!(p[0]["value"].as_f64().unwrap(), v0);
    assert_eq!(p[0]["distance"].as_f64().unwrap(), v0);
    assert!((p[1]["distance"].as_f64().unwrap() - (v0 + v1) / 2.0).abs() < 1e-12);
    assert!((p[1]["gradient"][0].as_f64().unwrap() - (v1 - v0) / 0.5).abs() < 1e-12);

    // CSG of distance volumes: the insides combine as the bit volumes do.
    let csg = |op: &str, x: &str, y: &str| {
        let e = serde_json::json!({"op": op, "operands": [x, y]});
        srv.req("POST", "/v1/volumes/csg", &[], e.to_string().as_bytes())
    };
    for op in ["union", "intersection", "difference"] {
        let r = csg(op, &sa_id, &sb_id);
        assert_eq!(r.status, 201, "{op}: {}", String::from_utf8_lossy(&r.body));
        let id = r.json()["id"].as_str().unwrap().to_string();
        let got = decode_distance(&data(&id));
        assert_eq!(got.background(), 1.0, "{op}: the narrower band");
        let mut want = ba.clone();
        match op {
            "union" => want.union_with(&bb),
            "intersection" => want.intersect_with(&bb),
            _ => want.subtract(&bb),
        }
        let st = srv
            .req("GET", &format!("/v1/volumes/{id}/stats"), &[], &[])
            .json();
        assert_eq!(st["inside_voxels"], want.count_ones(), "{op}");
        let t = srv.created(&format!("/v1/volumes/{id}/threshold?level=0"), &[], &[]);
        assert_eq!(decode_bits(&data(t["id"].as_str().unwrap())), want, "{op}");
    }

    // Refusals.
    assert_problem(&csg("union", &sa_id, &b), 422, "wrong-volume-kind");
    assert_problem(&csg("union", &a, &sb_id), 422, "wrong-volume-kind");
    assert_problem(&csg("xor", &sa_id, &sb_id), 400, "invalid-parameter");
    let post = |path: String| srv.req("POST", &path, &[], &[]);
    assert_problem(
        &post(format!("/v1/volumes/{a}/threshold?level=0")),
        422,
        "wrong-volume-kind",
    );
    assert_problem(
        &post(format!("/v1/volumes/{sa_id}/sdf")),
        422,
        "wrong-volume-kind",
    );
    assert_problem(
        &post(format!("/v1/volumes/{sa_id}/threshold")),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &post(format!("/v1/volumes/{a}/sdf?band=0")),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &post(format!("/v1/volumes/{a}/sdf?band=65")),
        400,
        "invalid-parameter",
    );
    assert_problem(&post("/v1/volumes/nope/sdf".into()), 404, "not-found");
    let other = srv.created(
        "/v1/voxelize?origin=0,0,0&voxel_size=0.5&dims=30,28,27&wait=60",
        &obj,
        &box_obj([1.0; 3], [5.0; 3]),
    );
    let o = other["id"].as_str().unwrap();
    let so = srv.created(&format!("/v1/volumes/{o}/sdf"), &[], &[]);
    assert_problem(
        &csg("union", &sa_id, so["id"].as_str().unwrap()),
        422,
        "misaligned-grids",
    );
    srv.stop();
}
