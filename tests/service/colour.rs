//! Colour and material voxels over HTTP (issue 34), against expectations computed here: a cube
//! built in the test whose faces read six regions of a texture atlas gives each face's voxels
//! exactly that colour (edge voxels the area-weighted mix in linear light), a solid's inner
//! voxels the colour of a nearest surface voxel, material ids by largest area (ties to the
//! lowest id), vertex colours their barycentric value, a checkerboard the exact mean of its
//! bilinear interpolant, and `Fox.glb` the texture's area-weighted mean colour as trimesh reads
//! it. Downloads: `npy&attributes=rgba|material`, the `.vox` palette, coloured points.

use super::*;

/// A GLB with one mesh: shared positions and texture coordinates, one primitive per entry of
/// `prims` (its triangles' indices and its material), `materials` as glTF JSON, and the PNG
/// `image` (read by texture 0, sampler `sampler`) when given.
fn glb(
    positions: &[[f32; 3]],
    uvs: &[[f32; 2]],
    prims: &[(Vec<u32>, usize)],
    materials: Value,
    image: Option<(&[u8], Value)>,
) -> Vec<u8> {
    let mut bin: Vec<u8> = vec![];
    let mut views = vec![];
    let mut accessors = vec![];
    let mut push = |bin: &mut Vec<u8>, bytes: &[u8]| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let at = bin.len();
        bin.extend_from_slice(bytes);
        views.push(serde_json::json!({"buffer": 0, "byteOffset": at, "byteLength": bytes.len()}));
        views.len() - 1
    };
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let pos = push(&mut bin, &f32s(&positions.concat()));
    let lo: Vec<f32> = (0..3)
        .map(|k| positions.iter().map(|p| p[k]).fold(f32::MAX, f32::min))
        .collect();
    let hi: Vec<f32> = (0..3)
        .map(|k| positions.iter().map(|p| p[k]).fold(f32::MIN, f32::max))
        .collect();
    accessors.push(serde_json::json!({"bufferView": pos, "componentType": 5126, "count": positions.len(), "type": "VEC3", "min": lo, "max": hi}));
    let uv = push(&mut bin, &f32s(&uvs.concat()));
    accessors.push(serde_json::json!({"bufferView": uv, "componentType": 5126, "count": uvs.len(), "type": "VEC2"}));
    let mut primitives = vec![];
    for (idx, material) in prims {
        let bytes: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = push(&mut bin, &bytes);
        accessors.push(serde_json::json!({"bufferView": view, "componentType": 5125, "count": idx.len(), "type": "SCALAR"}));
        primitives.push(serde_json::json!({"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": accessors.len() - 1, "material": material}));
    }
    let mut doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": primitives}],
        "materials": materials,
    });
    if let Some((png, sampler)) = image {
        let view = push(&mut bin, png);
        doc["images"] = serde_json::json!([{"bufferView": view, "mimeType": "image/png"}]);
        doc["samplers"] = serde_json::json!([sampler]);
        doc["textures"] = serde_json::json!([{"source": 0, "sampler": 0}]);
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    doc["accessors"] = accessors.into();
    doc["bufferViews"] = views.into();
    doc["buffers"] = serde_json::json!([{"byteLength": bin.len()}]);
    let mut json = serde_json::to_vec(&doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + json.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

fn png(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> Vec<u8> {
    let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(f(x, y)));
    let mut out = vec![];
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

fn lin(b: u8) -> f64 {
    let c = f64::from(b) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn srgb(l: f64) -> u8 {
    let c = if l <= 0.0031308 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// The data of a `.npy` (its header skipped) and its shape.
fn npy(b: &[u8]) -> (Vec<usize>, &[u8]) {
    let data = npy_payload(b);
    let header = std::str::from_utf8(&b[10..b.len() - data.len()]).unwrap();
    let shape = header.split("'shape': (").nth(1).unwrap();
    let shape = shape.split(')').next().unwrap();
    let dims = shape
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| s.trim().parse().unwrap())
        .collect();
    (dims, data)
}

/// The faces of the cube [LO, HI]³: (axis, side) in the order −x, +x, −y, +y, −z, +z.
const LO: f32 = 1.25;
const HI: f32 = 8.75;
const FACE_COLOURS: [[u8; 4]; 6] = [
    [230, 25, 75, 255],
    [60, 180, 75, 255],
    [255, 225, 25, 255],
    [0, 130, 200, 255],
    [245, 130, 48, 255],
    [145, 30, 180, 255],
];

/// Positions, texture coordinates and each face's indices.
type Cube = (Vec<[f32; 3]>, Vec<[f32; 2]>, Vec<Vec<u32>>);

/// The cube's 24 corners (4 a face) and each face's two triangles (outward), with texture
/// coordinates inside face i's 16 × 16 region of a 48 × 32 atlas, 2 texels from its edges.
pub(super) fn cube() -> Cube {
    let (mut p, mut uv, mut tris) = (vec![], vec![], vec![]);
    for face in 0..6 {
        let axis = face / 2;
        let c = if face % 2 == 0 { LO } else { HI };
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        let base = p.len() as u32;
        let (col, row) = ((face % 3) as f32, (face / 3) as f32);
        for (s, t) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            let mut q = [0.0f32; 3];
            q[axis] = c;
            q[a] = LO + (HI - LO) * s;
            q[b] = LO + (HI - LO) * t;
            p.push(q);
            uv.push([
                (col * 16.0 + 2.0 + 12.0 * s) / 48.0,
                (row * 16.0 + 2.0 + 12.0 * t) / 32.0,
            ]);
        }
        let (t1, t2) = if face % 2 == 1 {
            ([0, 1, 2], [0, 2, 3])
        } else {
            ([0, 2, 1], [0, 3, 2])
        };
        tris.push(
            t1.iter()
                .chain(&t2)
                .map(|&i| base + i)
                .collect::<Vec<u32>>(),
        );
    }
    (p, uv, tris)
}

pub(super) fn atlas() -> Vec<u8> {
    png(48, 32, |x, y| FACE_COLOURS[(y / 16 * 3 + x / 16) as usize])
}

/// Each face's area inside voxel v (the face is the square [LO, HI]² in its plane).
fn face_areas(v: [usize; 3]) -> [f64; 6] {
    let overlap = |i: usize| {
        let (lo, hi) = (i as f64, i as f64 + 1.0);
        (hi.min(HI as f64) - lo.max(LO as f64)).max(0.0)
    };
    std::array::from_fn(|face| {
        let axis = face / 2;
        let c = if face % 2 == 0 { LO } else { HI } as f64;
        if !(v[axis] as f64 <= c && c < v[axis] as f64 + 1.0) {
            return 0.0;
        }
        overlap(v[(axis + 1) % 3]) * overlap(v[(axis + 2) % 3])
    })
}

/// The surface voxels of [`cube`] on the grid `origin=0,0,0&voxel_size=1&dims=10,10,10`, coloured
/// from [`atlas`] (volume `id`): a voxel one face crosses has that face's colour exactly, one
/// two or three cross the area-weighted mix of theirs in linear light (within one step of
/// rounding), and the others none.
pub(super) fn assert_atlas_colours(srv: &Server, id: &str) {
    let get = |q: &str| {
        srv.req("GET", &format!("/v1/volumes/{id}/data?{q}"), &[], &[])
            .ok(200)
            .body
    };
    let rgba = get("format=npy&attributes=rgba");
    let (shape, data) = npy(&rgba);
    assert_eq!(shape, vec![10, 10, 10, 4]);
    let bits = get("format=npy");
    let (_, occ) = npy(&bits);
    let mut single = 0;
    for x in 0..10 {
        for y in 0..10 {
            for z in 0..10 {
                let i = (x * 10 + y) * 10 + z;
                let areas = face_areas([x, y, z]);
                let total: f64 = areas.iter().sum();
                let got = &data[4 * i..4 * i + 4];
                assert_eq!(occ[i] == 1, total > 0.0, "voxel {x} {y} {z}");
                if total == 0.0 {
                    assert_eq!(got, [0, 0, 0, 0]);
                    continue;
                }
                let faces = areas.iter().filter(|&&a| a > 0.0).count();
                let want: Vec<u8> = (0..3)
                    .map(|k| {
                        srgb(
                            (0..6)
                                .map(|f| areas[f] * lin(FACE_COLOURS[f][k]))
                                .sum::<f64>()
                                / total,
                        )
                    })
                    .collect();
                if faces == 1 {
                    single += 1;
                    assert_eq!(got[..3], want[..], "voxel {x} {y} {z}");
                } else {
                    // The mix of two or three faces: its rounding may differ by one.
                    for k in 0..3 {
                        assert!(
                            got[k].abs_diff(want[k]) <= 1,
                            "voxel {x} {y} {z}: {got:?} vs {want:?}"
                        );
                    }
                }
                assert_eq!(got[3], 255);
            }
        }
    }
    assert_eq!(single, 6 * 36);
}

#[test]
fn a_textured_cube_gives_each_face_its_atlas_colour() {
    let dir = tmpdir("colour-atlas");
    let srv = Server::start(&dir, &[]);
    let (p, uv, tris) = cube();
    let prims = vec![(tris.concat(), 0)];
    let body = glb(
        &p,
        &uv,
        &prims,
        serde_json::json!([{"name": "atlas", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]),
        Some((&atlas(), serde_json::json!({}))),
    );
    let grid = "origin=0,0,0&voxel_size=1&dims=10,10,10";
    let v = srv.created(
        &format!("/v1/voxelize?{grid}&method=surface&color=true&wait=60"),
        &[("Content-Type", "model/gltf-binary")],
        &body,
    );
    assert_eq!(v["kind"], "channels", "{v}");
    assert_eq!(
        v["attributes"]["channels"],
        serde_json::json!(["rgba"]),
        "{v}"
    );
    let id = v["id"].as_str().unwrap().to_string();
    assert_atlas_colours(&srv, &id);
    let get = |q: &str| {
        srv.req("GET", &format!("/v1/volumes/{id}/data?{q}"), &[], &[])
            .ok(200)
            .body
    };
    let rgba = get("format=npy&attributes=rgba");
    let (_, data) = npy(&rgba);
    let bits = get("format=npy");
    let (_, occ) = npy(&bits);
    // The .vox palette holds the six colours exactly (fewer than 256 colours: no loss).
    let vox = get("format=vox");
    let pal = &vox[vox.len() - 1024..];
    for c in FACE_COLOURS {
        assert!(pal.chunks(4).any(|e| e == c), "{c:?} not in the palette");
    }
    // The set voxels' indices with their colours, as an .npz: each row's colour is the dense
    // array's at its index.
    let z = srv
        .req(
            "GET",
            &format!("/v1/volumes/{id}/data?format=indices&attributes=rgba"),
            &[],
            &[],
        )
        .ok(200);
    assert_eq!(z.header("content-type"), Some("application/zip"));
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(z.body)).unwrap();
    let mut read = |name: &str| {
        let mut b = vec![];
        std::io::Read::read_to_end(&mut zip.by_name(name).unwrap(), &mut b).unwrap();
        b
    };
    let (idx, rows) = (read("indices.npy"), read("rgba.npy"));
    let ((ishape, idx), (cshape, rows)) = (npy(&idx), npy(&rows));
    assert_eq!(ishape[1], 3);
    assert_eq!(cshape, vec![ishape[0], 4]);
    assert_eq!(ishape[0], occ.iter().filter(|&&b| b == 1).count());
    for (r, xyz) in idx.chunks(12).enumerate() {
        let p: Vec<usize> = xyz
            .chunks(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()) as usize)
            .collect();
        let i = (p[0] * 10 + p[1]) * 10 + p[2];
        assert_eq!(rows[4 * r..4 * r + 4], data[4 * i..4 * i + 4]);
    }
    // Coloured points: 16 bytes a point (x, y, z, r, g, b, a).
    let pts = get("format=points");
    let text = String::from_utf8_lossy(&pts[..300]);
    assert!(text.contains("property uchar red"), "{text}");
    // Refusals: a channel on a format that takes none, a channel the volume lacks.
    let r = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/data?format=binvox&attributes=rgba"),
        &[],
        &[],
    );
    assert_problem(&r, 400, "invalid-parameter");
    let r = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/data?format=npy&attributes=material"),
        &[],
        &[],
    );
    assert_problem(&r, 400, "invalid-parameter");
    // A preview in colour (an RGB PNG).
    let pic = srv
        .req("GET", &format!("/v1/volumes/{id}/preview.png"), &[], &[])
        .ok(200)
        .body;
    assert_eq!(pic[25], 2, "colour type RGB");
}

#[test]
fn solids_colour_their_inside_and_materials_go_by_area() {
    let dir = tmpdir("colour-solid");
    let srv = Server::start(&dir, &[]);
    let (p, uv, tris) = cube();
    // Faces −x, −y, −z are material 0 (red), +x, +y, +z material 1 (blue).
    let prims: Vec<(Vec<u32>, usize)> = tris
        .iter()
        .enumerate()
        .map(|(f, t)| (t.clone(), f % 2))
        .collect();
    let body = glb(
        &p,
        &uv,
        &prims,
        serde_json::json!([
            {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1]}},
            {"name": "blue", "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 1, 1]}}
        ]),
        None,
    );
    let v = srv.created(
        "/v1/voxelize?origin=0,0,0&voxel_size=1&dims=10,10,10&color=true&material=true&wait=60",
        &[("Content-Type", "model/gltf-binary")],
        &body,
    );
    assert_eq!(
        v["attributes"]["materials"],
        serde_json::json!([
            {"id": 0, "name": "red", "base_color": [1.0, 0.0, 0.0, 1.0]},
            {"id": 1, "name": "blue", "base_color": [0.0, 0.0, 1.0, 1.0]}
        ]),
        "{v}"
    );
    let id = v["id"].as_str().unwrap().to_string();
    let get = |q: &str| {
        srv.req("GET", &format!("/v1/volumes/{id}/data?{q}"), &[], &[])
            .ok(200)
            .body
    };
    let m = get("format=npy&attributes=material");
    let (shape, m) = npy(&m);
    assert_eq!(shape, vec![10, 10, 10]);
    let c = get("format=npy&attributes=rgba");
    let (_, c) = npy(&c);
    let material = |v: [usize; 3]| {
        let i = (v[0] * 10 + v[1]) * 10 + v[2];
        u16::from_le_bytes([m[2 * i], m[2 * i + 1]])
    };
    let colour = |v: [usize; 3]| {
        let i = 4 * ((v[0] * 10 + v[1]) * 10 + v[2]);
        [c[i], c[i + 1], c[i + 2], c[i + 3]]
    };
    // The solid is the 8³ block 1..=8; its outer layer is the surface's.
    let surface: Vec<[usize; 3]> = (1..=8)
        .flat_map(|x| (1..=8).flat_map(move |y| (1..=8).map(move |z| [x, y, z])))
        .filter(|v| face_areas(*v).iter().any(|&a| a > 0.0))
        .collect();
    for v in &surface {
        let a = face_areas(*v);
        let (m0, m1) = (a[0] + a[2] + a[4], a[1] + a[3] + a[5]);
        let want = if m1 > m0 { 1 } else { 0 };
        assert_eq!(material(*v), want, "voxel {v:?}: areas {m0} {m1}");
        let red = srgb(m0 / (m0 + m1));
        let blue = srgb(m1 / (m0 + m1));
        let got = colour(*v);
        assert!(
            got[0].abs_diff(red) <= 1 && got[2].abs_diff(blue) <= 1,
            "{v:?} {got:?}"
        );
    }
    // A tie (an edge between a red and a blue face, equal areas) goes to the lower id.
    assert_eq!(material([8, 1, 4]), 0);
    assert_eq!(material([8, 8, 8]), 1);
    // Inside: the values of a nearest surface voxel.
    for x in 2..=7 {
        for y in 2..=7 {
            for z in 2..=7 {
                let v = [x, y, z];
                let d = |s: &[usize; 3]| {
                    (0..3)
                        .map(|k| (s[k] as i64 - v[k] as i64).pow(2))
                        .sum::<i64>()
                };
                let best = surface.iter().map(d).min().unwrap();
                assert!(
                    surface.iter().any(|s| d(s) == best
                        && colour(*s) == colour(v)
                        && material(*s) == material(v)),
                    "voxel {v:?} took {:?}",
                    colour(v)
                );
            }
        }
    }
}

/// A PLY triangle with sRGB vertex colours: a voxel wholly inside it has the barycentric mix
/// (in linear light) at its square's centre.
#[test]
fn vertex_colours_interpolate_and_refusals_are_clear() {
    let dir = tmpdir("colour-vertex");
    let srv = Server::start(&dir, &[]);
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 4.5 255 0 0\n16 0 4.5 0 255 0\n0 16 4.5 0 0 255\n3 0 1 2\n";
    let v = srv.created(
        "/v1/voxelize?origin=0,0,0&voxel_size=1&dims=16,16,9&method=surface&color=true&wait=60",
        &[("Content-Type", "model/ply")],
        ply.as_bytes(),
    );
    let id = v["id"].as_str().unwrap().to_string();
    let c = rgba_of(&srv, &id);
    for (x, y) in [(2usize, 3usize), (5, 5), (0, 0), (9, 4)] {
        let i = (x * 16 + y) * 9 + 4;
        let (u, w) = ((x as f64 + 0.5) / 16.0, (y as f64 + 0.5) / 16.0);
        let want = [1.0 - u - w, u, w].map(srgb);
        assert_eq!(c[i][..3], want, "voxel ({x}, {y})");
    }
    // A mesh with no colour asked for colour, a material on a mesh without materials, colour
    // with a method that is not bits.
    let obj = box_obj([0.0; 3], [1.0; 3]);
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=8&color=true&wait=10",
        &[("Content-Type", "model/obj")],
        &obj,
    );
    let p = assert_problem(&r, 422, "missing-attributes");
    assert!(p["detail"].as_str().unwrap().contains("no colour"), "{p}");
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=8&material=true&wait=10",
        &[("Content-Type", "model/ply")],
        ply.as_bytes(),
    );
    assert_problem(&r, 422, "missing-attributes");
    let r = srv.req(
        "POST",
        "/v1/voxelize?resolution=8&method=sdf&color=true",
        &[("Content-Type", "model/ply")],
        ply.as_bytes(),
    );
    assert_problem(&r, 400, "invalid-parameter");
}

/// The textured cube as a GLB (its triangles `indices`) whose image is not an image.
fn cube_with_a_bad_image(indices: Vec<u32>) -> Vec<u8> {
    let (p, uv, _) = cube();
    glb(
        &p,
        &uv,
        &[(indices, 0)],
        serde_json::json!([{"name": "atlas", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]),
        Some((b"not an image at all", serde_json::json!({}))),
    )
}

const GRID_10: &str = "origin=0,0,0&voxel_size=1&dims=10,10,10";
const GLB: [(&str, &str); 1] = [("Content-Type", "model/gltf-binary")];

/// The detail of the `invalid-mesh` problem a solid of GLB `body` on a 10³ grid gets, with
/// the query's `extra` parameters.
fn invalid_mesh_detail(srv: &Server, extra: &str, body: &[u8]) -> String {
    let r = srv.req(
        "POST",
        &format!("/v1/voxelize?{GRID_10}&method=solid{extra}&wait=60"),
        &GLB,
        body,
    );
    let p = assert_problem(&r, 422, "invalid-mesh");
    p["detail"].as_str().unwrap().to_string()
}

/// Textures are read only for colour: a cube whose image is not a PNG or JPEG voxelizes
/// without colour (its materials kept; the image is never decoded) and is refused with colour,
/// the image named.
#[test]
fn textures_are_read_only_for_colour() {
    let dir = tmpdir("colour-textures-on-demand");
    let srv = Server::start(&dir, &[]);
    let body = cube_with_a_bad_image(cube().2.concat());
    let v = srv.created(
        &format!("/v1/voxelize?{GRID_10}&method=solid&material=true&wait=60"),
        &GLB,
        &body,
    );
    assert_eq!(v["attributes"]["materials"][0]["name"], "atlas", "{v}");
    let detail = invalid_mesh_detail(&srv, "&color=true", &body);
    assert!(
        detail.contains("glTF image 0") && detail.contains("not a PNG or JPEG"),
        "{detail}"
    );
}

/// The loader decodes a glTF's images while it reads its geometry: with both broken, the
/// image's error is the one reported (as when the images were decoded first), every time; the
/// geometry's without colour.
#[test]
fn an_image_error_comes_before_a_geometry_error() {
    let dir = tmpdir("colour-error-order");
    let srv = Server::start(&dir, &[]);
    let mut broken = cube().2.concat();
    broken[4] = 99;
    let body = cube_with_a_bad_image(broken);
    for _ in 0..3 {
        let detail = invalid_mesh_detail(&srv, "&color=true", &body);
        assert!(detail.contains("glTF image 0"), "{detail}");
    }
    let detail = invalid_mesh_detail(&srv, "", &body);
    assert!(
        !detail.contains("glTF image") && detail.contains("99"),
        "{detail}"
    );
}

/// A checkerboard of 4 × 4-texel squares on a plane, sampled bilinearly: each voxel's colour is
/// the mean of the texture's bilinear interpolant over the voxel's part of the plane, computed
/// here exactly (a bilinear function's mean over a rectangle is its value at the rectangle's
/// centre, summed cell by cell between texel centres).
#[test]
fn a_checkerboard_averages_over_the_voxel() {
    let dir = tmpdir("colour-checker");
    let srv = Server::start(&dir, &[]);
    let (w, h) = (32u32, 32u32);
    let texel = |x: i64, y: i64| -> f64 {
        let (x, y) = (x.rem_euclid(i64::from(w)), y.rem_euclid(i64::from(h)));
        if (x / 4 + y / 4) % 2 == 0 { 1.0 } else { 0.0 }
    };
    let image = png(w, h, |x, y| {
        let v = if texel(x.into(), y.into()) == 1.0 {
            255
        } else {
            0
        };
        [v, v, v, 255]
    });
    // The quad [0, 12]² in z = 0.5; u = x / 12, v = y / 12: a voxel is 32/12 texels wide.
    let p = [
        [0.0, 0.0, 0.5],
        [12.0, 0.0, 0.5],
        [12.0, 12.0, 0.5],
        [0.0, 12.0, 0.5],
    ];
    let uv = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let body = glb(
        &p,
        &uv,
        &[(vec![0, 1, 2, 0, 2, 3], 0)],
        serde_json::json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]),
        Some((&image, serde_json::json!({"magFilter": 9729}))),
    );
    let v = srv.created(
        "/v1/voxelize?origin=0,0,0&voxel_size=1&dims=12,12,1&method=surface&color=true&wait=60",
        &[("Content-Type", "model/gltf-binary")],
        &body,
    );
    let id = v["id"].as_str().unwrap().to_string();
    let c = rgba_of(&srv, &id);
    // The bilinear interpolant at texel coordinates (s, t) (texel centres at half integers).
    let f = |s: f64, t: f64| {
        let (x, y) = (s - 0.5, t - 0.5);
        let (i, j) = (x.floor(), y.floor());
        let (a, b) = (x - i, y - j);
        let (i, j) = (i as i64, j as i64);
        (1.0 - a) * (1.0 - b) * texel(i, j)
            + a * (1.0 - b) * texel(i + 1, j)
            + (1.0 - a) * b * texel(i, j + 1)
            + a * b * texel(i + 1, j + 1)
    };
    let scale = f64::from(w) / 12.0;
    let mut worst = 0.0f64;
    for x in 0..12usize {
        for y in 0..12usize {
            // The voxel's square in texel units, cut at the texel centres.
            let (s0, s1) = (x as f64 * scale, (x + 1) as f64 * scale);
            let (t0, t1) = (y as f64 * scale, (y + 1) as f64 * scale);
            let cuts = |a: f64, b: f64| {
                let mut v = vec![a];
                let mut k = (a - 0.5).floor() + 1.5;
                while k < b {
                    v.push(k);
                    k += 1.0;
                }
                v.push(b);
                v
            };
            let (cs, ct) = (cuts(s0, s1), cuts(t0, t1));
            let mut sum = 0.0;
            for si in cs.windows(2) {
                for ti in ct.windows(2) {
                    let area = (si[1] - si[0]) * (ti[1] - ti[0]);
                    sum += area * f((si[0] + si[1]) / 2.0, (ti[0] + ti[1]) / 2.0);
                }
            }
            let want = sum / ((s1 - s0) * (t1 - t0));
            let got = lin(c[x * 12 + y][0]);
            worst = worst.max((got - want).abs());
        }
    }
    // The sampling's error (the midpoint rule on sub-triangles of at most a texel's area, where
    // the interpolant is bilinear and kinked at texel centres) and the byte's rounding.
    assert!(worst < 0.02, "worst difference {worst}");
}

/// `Fox.glb`'s surface voxels, coloured, average to the texture's area-weighted mean colour as
/// trimesh reads the mesh and its texture (sampled densely here). The voxel mean weights every
/// surface voxel alike while each holds a different area of surface (between nearly none and
/// about 1.7 voxel faces); the fox's colour regions are far larger than a voxel, so the two
/// means differ little: 0.004–0.008 in linear light measured at 64³–256³. Tolerance 0.02.
#[test]
fn fox_surface_colour_is_its_textures_mean() {
    let Some(py) = crate::mesh_cli::trimesh_python() else {
        return;
    };
    let dir = tmpdir("colour-fox");
    let srv = Server::start(&dir, &[]);
    let fox = std::fs::read(data("Fox.glb")).unwrap();
    let v = srv.created(
        "/v1/voxelize?resolution=128&method=surface&color=true&wait=60",
        &[("Content-Type", "model/gltf-binary")],
        &fox,
    );
    let id = v["id"].as_str().unwrap().to_string();
    let get = |q: &str| {
        let p = dir.join(format!("fox-{}.npy", q.len()));
        let b = srv
            .req("GET", &format!("/v1/volumes/{id}/data?{q}"), &[], &[])
            .ok(200)
            .body;
        std::fs::write(&p, b).unwrap();
        p
    };
    let (rgba, bits) = (get("format=npy&attributes=rgba"), get("format=npy"));
    let script = r#"
import sys, numpy as np, trimesh
m = trimesh.load(sys.argv[1], force='mesh')
uv = np.asarray(m.visual.uv, np.float64)
img = np.asarray(m.visual.material.baseColorTexture.convert('RGBA'), np.float64) / 255.0
H, W = img.shape[:2]
lin = lambda c: np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
tex = lin(img[..., :3])
f, v = m.faces, m.vertices
area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
n = 40
tot = np.zeros(3)
for i in range(n + 1):
    for j in range(n + 1 - i):
        a, b = i / n, j / n
        u = (1 - a - b) * uv[f[:, 0]] + a * uv[f[:, 1]] + b * uv[f[:, 2]]
        # trimesh flips glTF's v (top-down) to bottom-up.
        x = np.clip((u[:, 0] % 1.0) * W, 0, W - 1).astype(int)
        y = np.clip(((1 - u[:, 1]) % 1.0) * H, 0, H - 1).astype(int)
        tot += (tex[y, x] * area[:, None]).sum(0)
want = tot / (area.sum() * (n + 1) * (n + 2) / 2)
vox = np.load(sys.argv[2]).astype(np.float64) / 255.0
occ = np.load(sys.argv[3]).astype(bool)
got = lin(vox[occ][:, :3]).mean(0)
d = np.abs(got - want).max()
assert d < 0.02, (got, want)
print(d)
"#;
    let o = Command::new(py)
        .args(["-c", script])
        .arg(data("Fox.glb"))
        .args([&rgba, &bits])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
