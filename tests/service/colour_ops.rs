//! CSG and morphology of colour and material volumes over HTTP (issue 34): the first operand set
//! at a voxel gives its colour and material (a voxel only a plain bit volume covers gets
//! (0, 0, 0, 0) and the "none" material), the operands' material tables merge into one, and
//! what a dilation adds takes its nearest source voxel's values.

use super::*;

/// A zipped OBJ of the box [lo, hi] (a `usemtl name` material with colour `kd`).
fn coloured_box(name: &str, kd: [f32; 3], lo: [f64; 3], hi: [f64; 3]) -> Vec<u8> {
    let obj = material_boxes_obj("m.mtl", &[(name, lo, hi)]);
    let mtl = format!("newmtl {name}\nKd {} {} {}\n", kd[0], kd[1], kd[2]);
    super::zip_upload::zip_of(&[("b/box.obj", obj.as_bytes()), ("b/m.mtl", mtl.as_bytes())])
}

const GRID: &str = "origin=0,0,0&voxel_size=1&dims=12,8,8";

fn voxelize(srv: &Server, body: &[u8], colour: bool) -> String {
    let q = if colour {
        "&color=true&material=true"
    } else {
        ""
    };
    let ct = if colour {
        "application/zip"
    } else {
        "text/plain"
    };
    let v = srv.created(
        &format!("/v1/voxelize?{GRID}&method=solid{q}&wait=60"),
        &[("Content-Type", ct)],
        body,
    );
    v["id"].as_str().unwrap().to_string()
}

/// The dense (X, Y, Z) rgba and material arrays of volume `id` (and its occupancy).
fn arrays(srv: &Server, id: &str) -> (Vec<[u8; 4]>, Vec<u16>, Vec<u8>) {
    let get = |q: &str| {
        let b = srv
            .req("GET", &format!("/v1/volumes/{id}/data?{q}"), &[], &[])
            .ok(200)
            .body;
        npy_payload(&b).to_vec()
    };
    let rgba = rgba_of(srv, id);
    let mat = get("format=npy&attributes=material")
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    (rgba, mat, get("format=npy"))
}

const RED: [u8; 4] = [255, 0, 0, 255];
const BLUE: [u8; 4] = [0, 0, 255, 255];

#[test]
fn csg_and_morphology_carry_colour_and_material() {
    let srv = Server::start(&tmpdir("colour-ops"), &[]);
    // Red: voxels x 1..7; blue: x 4..10 (y, z 1..6 both): they share x 4..7.
    let red = voxelize(
        &srv,
        &coloured_box("red", [1.0, 0.0, 0.0], [1.0; 3], [7.0, 6.0, 6.0]),
        true,
    );
    let blue = voxelize(
        &srv,
        &coloured_box("blue", [0.0, 0.0, 1.0], [4.0, 1.0, 1.0], [10.0, 6.0, 6.0]),
        true,
    );
    let plain = voxelize(&srv, &box_obj([8.0, 1.0, 1.0], [11.0, 6.0, 6.0]), false);
    let csg = |operands: &[&str]| {
        let e = serde_json::json!({"op": "union", "operands": operands});
        srv.created("/v1/volumes/csg", &[], e.to_string().as_bytes())
    };
    let at = |x: usize, y: usize, z: usize| (x * 8 + y) * 8 + z;
    for (first, second, overlap) in [(&red, &blue, RED), (&blue, &red, BLUE)] {
        let m = csg(&[first, second]);
        assert_eq!(m["kind"], "channels", "{m}");
        let names: Vec<&str> = m["attributes"]["materials"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["name"].as_str().unwrap())
            .collect();
        let want_names = if overlap == RED {
            ["red", "blue"]
        } else {
            ["blue", "red"]
        };
        assert_eq!(names, want_names, "{m}");
        let (rgba, mat, occ) = arrays(&srv, m["id"].as_str().unwrap());
        assert_eq!(rgba[at(2, 3, 3)], RED);
        assert_eq!(rgba[at(5, 3, 3)], overlap, "the first operand wins");
        assert_eq!(rgba[at(8, 3, 3)], BLUE);
        let id_of = |n: &str| names.iter().position(|&x| x == n).unwrap() as u16;
        assert_eq!(mat[at(2, 3, 3)], id_of("red"));
        assert_eq!(mat[at(8, 3, 3)], id_of("blue"));
        assert_eq!(occ[at(0, 3, 3)], 0);
        assert_eq!(rgba[at(0, 3, 3)], [0; 4]);
    }
    // With a plain volume: its own voxels are transparent and of material "none".
    let m = csg(&[&red, &plain]);
    let table = m["attributes"]["materials"].as_array().unwrap().clone();
    assert_eq!(table.len(), 2, "{m}");
    assert_eq!(table[1]["name"], "none");
    let (rgba, mat, occ) = arrays(&srv, m["id"].as_str().unwrap());
    assert_eq!(
        (occ[at(9, 3, 3)], rgba[at(9, 3, 3)], mat[at(9, 3, 3)]),
        (1, [0; 4], 1)
    );
    assert_eq!((rgba[at(3, 3, 3)], mat[at(3, 3, 3)]), (RED, 0));
    // Difference keeps the first operand's colours on its remaining voxels.
    let e = serde_json::json!({"op": "difference", "operands": [&blue, &red]});
    let m = srv.created("/v1/volumes/csg", &[], e.to_string().as_bytes());
    let (rgba, _, occ) = arrays(&srv, m["id"].as_str().unwrap());
    for (i, &o) in occ.iter().enumerate() {
        assert_eq!(rgba[i], if o == 1 { BLUE } else { [0; 4] });
    }
    // Dilation: the added voxels take the nearest source voxel's colour (here all red), and the
    // grown grid keeps the table.
    let body = serde_json::json!({"op": "dilate", "radius": 1, "kernel": "cross", "grow": true});
    let m = srv.created(
        &format!("/v1/volumes/{red}/morphology"),
        &[],
        body.to_string().as_bytes(),
    );
    assert_eq!(m["kind"], "channels", "{m}");
    assert_eq!(m["attributes"]["materials"][0]["name"], "red");
    assert_eq!(m["grid"]["dims"], serde_json::json!([14, 10, 10]));
    let colours: std::collections::BTreeSet<[u8; 4]> = rgba_of(&srv, m["id"].as_str().unwrap())
        .into_iter()
        .collect();
    assert_eq!(colours.into_iter().collect::<Vec<_>>(), [[0u8; 4], RED]);
}
