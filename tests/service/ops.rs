//! The volume operations over HTTP against the library's own results: density, fills, CSG and
//! intersection, morphology and the preview pictures.
//!
//! Not here: the job lifecycle (`jobs`), the error documents (`contract`).

use super::*;

#[test]
fn density_over_http() {
    let srv = Server::start(&tmpdir("density"), &[]);
    let spot = std::fs::read(data("spot.obj")).unwrap();
    let meta = srv.created(
        "/v1/voxelize?resolution=30&method=density&wait=60",
        &[("Content-Type", "model/obj")],
        &spot,
    );
    assert_eq!(meta["kind"], "density");
    let id = meta["id"].as_str().unwrap();
    let (mesh, g) = mesh_and_grid(
        &data("spot.obj"),
        GridSpec::Resolution {
            n: 30,
            cubic: false,
        },
        0,
    );
    let d = mesh.diagnostics();
    let parity = voxd::engine::fill::Fill::Parity;
    let (want, _) =
        voxd::engine::density::density(&CpuEngine, &mesh, &g, 2, Default::default(), parity, &d)
            .unwrap();
    assert!(
        (meta["volume"].as_f64().unwrap() - want.occupied_voxels() * g.voxel_size.powi(3)).abs()
            < 1e-12
    );
    let npy = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/data?format=npy"),
        &[],
        &[],
    );
    let Volume::Density(got) = VolumeFormat::Npy.decode(&npy.body).unwrap() else {
        panic!("npy should hold density")
    };
    assert_eq!(got.data(), want.data());
    let raw = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/data?format=raw"),
        &[],
        &[],
    );
    assert_eq!(raw.body, want.data());
    let Volume::Density(v) = VolumeFormat::Vxl
        .decode(
            &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
                .body,
        )
        .unwrap()
    else {
        panic!("vxl should hold density")
    };
    assert_eq!(v, want);
    assert_problem(
        &srv.req(
            "GET",
            &format!("/v1/volumes/{id}/data?format=binvox"),
            &[],
            &[],
        ),
        400,
        "invalid-parameter",
    );
    let r = srv.req(
        "POST",
        "/v1/voxelize?method=density&density_factor=3",
        &[("Content-Type", "model/obj")],
        &spot,
    );
    assert_problem(&r, 400, "invalid-parameter");
    let r = srv.req(
        "POST",
        "/v1/voxelize?method=density&density_factor=4&resolution=700",
        &[("Content-Type", "model/obj")],
        &spot,
    );
    assert_problem(&r, 422, "grid-too-large");
}

/// Every fill over HTTP gives the library's bits, and the volume says which fill was used.
#[test]
fn fills_over_http() {
    use voxd::engine::fill::{Fill, voxelize};
    let srv = Server::start(&tmpdir("fills"), &[]);
    let mesh = open_bowl();
    let bowl = to_obj(&mesh);
    let d = mesh.diagnostics();
    let (lo, hi) = mesh.bounds();
    let spec = GridSpec::Resolution {
        n: 24,
        cubic: false,
    };
    let g = Grid::fit(lo, hi, spec, 0, Default::default()).unwrap();
    for (fill, method, used) in [
        ("auto", "solid", "winding"),
        ("winding", "conservative", "winding"),
        ("vote", "interior", "vote"),
        ("flood", "solid", "flood"),
        ("parity", "solid", "parity"),
    ] {
        let meta = srv.created(
            &format!("/v1/voxelize?resolution=24&wait=60&fill={fill}&method={method}"),
            &[("Content-Type", "model/obj")],
            &bowl,
        );
        assert_eq!(meta["fill"]["requested"], fill);
        assert_eq!(meta["fill"]["used"], used);
        assert!(meta["fill"]["odd_parity_columns"].as_u64().unwrap() > 0);
        assert_eq!(meta["fill"]["warning"].is_string(), used == "parity");
        assert_eq!(meta["fill"]["winding"].is_object(), used == "winding");
        let id = meta["id"].as_str().unwrap();
        let got = decode_bits(
            &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
                .body,
        );
        let m: Method = method.parse().unwrap();
        let (want, report) = voxelize(&CpuEngine, &mesh, &g, m, fill.parse().unwrap(), &d).unwrap();
        assert_eq!(got, want, "{fill} {method}");
        assert_eq!(meta["fill"], serde_json::to_value(&report).unwrap());
    }
    // Density under the winding fill.
    let meta = srv.created(
        "/v1/voxelize?resolution=12&wait=60&fill=winding&method=density",
        &[("Content-Type", "model/obj")],
        &bowl,
    );
    assert_eq!(meta["fill"]["used"], "winding");
    let id = meta["id"].as_str().unwrap();
    let Volume::Density(got) = VolumeFormat::Vxl
        .decode(
            &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
                .body,
        )
        .unwrap()
    else {
        panic!("density expected")
    };
    let g12 = Grid::fit(
        lo,
        hi,
        GridSpec::Resolution {
            n: 12,
            cubic: false,
        },
        0,
        Default::default(),
    )
    .unwrap();
    let (want, _) = voxd::engine::density::density(
        &CpuEngine,
        &mesh,
        &g12,
        2,
        Default::default(),
        Fill::Winding,
        &d,
    )
    .unwrap();
    assert_eq!(got, want);
}

#[test]
fn csg_and_intersect_over_http() {
    let srv = Server::start(&tmpdir("csg"), &[]);
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
    let a = up([1.2, 1.1, 1.3], [9.3, 8.7, 9.1]);
    let b = up([5.4, 0.3, 0.2], [14.1, 13.2, 12.4]);
    let expr = serde_json::json!({"op": "difference", "operands": [a, {"op": "union", "operands": [b, b]}]});
    let meta = srv.created(
        "/v1/volumes/csg?name=a-minus-b",
        &[("Content-Type", "application/json")],
        expr.to_string().as_bytes(),
    );
    assert_eq!(meta["provenance"], expr);
    assert_eq!(meta["grid"]["dims"], serde_json::json!([30, 28, 26]));
    let id = meta["id"].as_str().unwrap();
    let got = decode_bits(
        &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
            .body,
    );
    // Exactly the voxelization of the known boolean (A − B is the box of A left of x = 5.4).
    let g = Grid {
        origin: [0.0; 3],
        voxel_size: 0.5,
        dims: [30, 28, 26],
    };
    let mut p = vec![];
    let mut t = vec![];
    push_box(&mut p, &mut t, [1.2, 1.1, 1.3], [5.4, 8.7, 9.1]);
    let want = CpuEngine
        .voxelize(
            &GridMesh::new(&voxd::mesh::Mesh::new(p, t).unwrap(), &g).unwrap(),
            Method::Solid,
        )
        .unwrap();
    assert_eq!(got, want);
    let i = srv
        .req(
            "POST",
            "/v1/volumes/intersect",
            &[],
            serde_json::json!({"a": a, "b": b}).to_string().as_bytes(),
        )
        .json();
    let inter = srv
        .req(
            "POST",
            "/v1/volumes/csg",
            &[],
            serde_json::json!({"op": "intersection", "operands": [a, b]})
                .to_string()
                .as_bytes(),
        )
        .json();
    assert_eq!(i["voxels"], inter["solid_voxels"]);
    assert!(i["voxels"].as_u64().unwrap() > 0);
    // Errors: misaligned grids, a density operand, unknown ids, bad expressions.
    let r = srv.req(
        "POST",
        "/v1/voxelize?origin=0.25,0,0&voxel_size=0.5&dims=4,4,4&wait=60",
        &obj,
        &box_obj([0.5; 3], [1.5; 3]),
    );
    let shifted = r.json()["id"].as_str().unwrap().to_string();
    let bad =
        |e: serde_json::Value| srv.req("POST", "/v1/volumes/csg", &[], e.to_string().as_bytes());
    assert_problem(
        &bad(serde_json::json!({"op": "union", "operands": [a, shifted]})),
        422,
        "misaligned-grids",
    );
    let d = srv
        .req(
            "POST",
            &format!("/v1/voxelize?{grid}&method=density&wait=60"),
            &obj,
            &box_obj([1.0; 3], [2.0; 3]),
        )
        .json();
    assert_problem(
        &bad(serde_json::json!({"op": "union", "operands": [a, d["id"]]})),
        422,
        "wrong-volume-kind",
    );
    assert_problem(
        &bad(serde_json::json!({"op": "union", "operands": [a, "nope"]})),
        404,
        "not-found",
    );
    assert_problem(
        &bad(serde_json::json!({"op": "sum", "operands": [a]})),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &bad(serde_json::json!({"op": "union", "operands": []})),
        400,
        "invalid-parameter",
    );
    assert_problem(&bad(serde_json::json!(42)), 400, "invalid-parameter");
    let far = srv
        .req(
            "POST",
            "/v1/voxelize?origin=100,100,100&voxel_size=0.5&dims=4,4,4&wait=60",
            &obj,
            &box_obj([100.5; 3], [101.5; 3]),
        )
        .json();
    assert_problem(
        &bad(serde_json::json!({"op": "intersection", "operands": [a, far["id"]]})),
        422,
        "empty-intersection",
    );
    assert_eq!(
        srv.req(
            "POST",
            "/v1/volumes/intersect",
            &[],
            serde_json::json!({"a": a, "b": far["id"]})
                .to_string()
                .as_bytes()
        )
        .json()["voxels"],
        0
    );
    assert_problem(
        &srv.req("POST", "/v1/volumes/intersect", &[], b"{}"),
        400,
        "invalid-parameter",
    );
}

#[test]
fn morphology_over_http() {
    let srv = Server::start(&tmpdir("morph"), &["--max-voxels", "200000"]);
    let r = srv.req(
        "POST",
        "/v1/voxelize?origin=0,0,0&voxel_size=1&dims=20,20,20&wait=60",
        &[("Content-Type", "model/obj")],
        &box_obj([5.0; 3], [12.0; 3]),
    );
    let id = r.json()["id"].as_str().unwrap().to_string();
    let stored = decode_bits(
        &srv.req("GET", &format!("/v1/volumes/{id}/data"), &[], &[])
            .body,
    );
    let body = serde_json::json!({"op": "dilate", "radius": 2, "kernel": "sphere", "grow": true});
    let meta = srv.created(
        &format!("/v1/volumes/{id}/morphology?name=fat"),
        &[],
        body.to_string().as_bytes(),
    );
    assert_eq!(meta["grid"]["dims"], serde_json::json!([24, 24, 24]));
    assert_eq!(meta["provenance"]["morphology"]["of"], id.as_str());
    let got = decode_bits(
        &srv.req(
            "GET",
            &format!("/v1/volumes/{}/data", meta["id"].as_str().unwrap()),
            &[],
            &[],
        )
        .body,
    );
    let want = voxd::volume::morph::apply(
        &stored,
        voxd::volume::morph::MorphOp::Dilate,
        2,
        voxd::volume::morph::Kernel::Sphere,
        true,
    );
    assert_eq!(got, want);
    let post = |b: serde_json::Value| {
        srv.req(
            "POST",
            &format!("/v1/volumes/{id}/morphology"),
            &[],
            b.to_string().as_bytes(),
        )
    };
    assert_eq!(
        post(serde_json::json!({"op": "erode", "radius": 1})).json()["solid_voxels"],
        5 * 5 * 5
    );
    assert_problem(
        &post(serde_json::json!({"op": "melt", "radius": 1})),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &post(serde_json::json!({"op": "erode", "radius": 99})),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &post(serde_json::json!({"op": "erode", "radius": 1, "kernel": "star"})),
        400,
        "invalid-parameter",
    );
    assert_problem(
        &post(serde_json::json!({"op": "dilate", "radius": 30, "grow": true})),
        422,
        "grid-too-large",
    );
    assert_problem(
        &srv.req(
            "POST",
            "/v1/volumes/nope/morphology",
            &[],
            br#"{"op":"erode","radius":1}"#,
        ),
        404,
        "not-found",
    );
}

/// Decodes an 8-bit grayscale PNG (checking every chunk's CRC): (width, height, pixels).
fn decode_png(b: &[u8]) -> (u32, u32, Vec<u8>) {
    assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n");
    let (mut pos, mut w, mut h, mut idat) = (8, 0, 0, Vec::new());
    loop {
        let len = u32::from_be_bytes(b[pos..pos + 4].try_into().unwrap()) as usize;
        let kind = &b[pos + 4..pos + 8];
        let data = &b[pos + 8..pos + 8 + len];
        let mut crc = flate2::Crc::new();
        crc.update(kind);
        crc.update(data);
        assert_eq!(
            crc.sum().to_be_bytes(),
            b[pos + 8 + len..pos + 12 + len],
            "CRC of {:?}",
            String::from_utf8_lossy(kind)
        );
        match kind {
            b"IHDR" => {
                w = u32::from_be_bytes(data[..4].try_into().unwrap());
                h = u32::from_be_bytes(data[4..8].try_into().unwrap());
                assert_eq!(&data[8..], &[8, 0, 0, 0, 0]);
            }
            b"IDAT" => idat.extend_from_slice(data),
            b"IEND" => break,
            _ => {}
        }
        pos += 12 + len;
    }
    let mut raw = Vec::new();
    flate2::read::ZlibDecoder::new(&idat[..])
        .read_to_end(&mut raw)
        .unwrap();
    assert_eq!(raw.len(), (h * (w + 1)) as usize);
    let pixels = raw
        .chunks(w as usize + 1)
        .flat_map(|r| {
            assert_eq!(r[0], 0);
            r[1..].to_vec()
        })
        .collect();
    (w, h, pixels)
}

#[test]
fn preview_pictures() {
    let srv = Server::start(&tmpdir("preview"), &[]);
    let r = srv.req(
        "POST",
        "/v1/voxelize?origin=0,0,0&voxel_size=1&dims=12,10,8&wait=60",
        &[("Content-Type", "model/obj")],
        &box_obj([2.0, 3.0, 1.0], [6.0, 9.0, 4.0]),
    );
    let id = r.json()["id"].as_str().unwrap().to_string();
    let png = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/preview.png?axis=z&slice=2"),
        &[],
        &[],
    );
    assert_eq!(png.header("content-type"), Some("image/png"));
    // A slice wins over a projection given with it (two plain parameters in the contract).
    let both = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/preview.png?axis=z&slice=2&projection=sum"),
        &[],
        &[],
    );
    assert_eq!(both.body, png.body);
    let (w, h, px) = decode_png(&png.body);
    assert_eq!((w, h), (12, 10));
    // Row 0 is the top (y = 9): the box covers x 2..6, y 3..9 on slice z = 2.
    for (i, &p) in px.iter().enumerate() {
        let (x, y) = (i as u32 % w, h - 1 - i as u32 / w);
        assert_eq!(
            p,
            if (2..6).contains(&x) && (3..9).contains(&y) {
                255
            } else {
                0
            },
            "pixel ({x},{y})"
        );
    }
    let (w, h, px) = decode_png(
        &srv.req(
            "GET",
            &format!("/v1/volumes/{id}/preview.png?axis=x&projection=sum"),
            &[],
            &[],
        )
        .body,
    );
    assert_eq!((w, h), (10, 8));
    assert_eq!(px.iter().filter(|&&p| p == 255).count(), 6 * 3);
    assert_problem(
        &srv.req(
            "GET",
            &format!("/v1/volumes/{id}/preview.png?slice=99"),
            &[],
            &[],
        ),
        404,
        "not-found",
    );
    assert_problem(
        &srv.req(
            "GET",
            &format!("/v1/volumes/{id}/preview.png?axis=w"),
            &[],
            &[],
        ),
        400,
        "invalid-parameter",
    );
}
