//! Bit volumes as MagicaVoxel `.vox` and as voxel indices over HTTP (issue 34): a grid longer
//! than 256 along two axes comes as several models placed by the scene graph, read back by a
//! `.vox` reader written here (Python: the chunks, the scene graph walked, each model's voxels
//! put where its transform says) against numpy's `argwhere` of the same volume's `.npy`; the
//! indices are that `argwhere`. Refusals: a grid beyond MagicaVoxel's world, a volume that is
//! not bits.

use super::*;

/// Reads a `.vox` (argv[1]) of a grid X Y Z (argv[2..5]) independently of voxd: every chunk,
/// the scene graph from node 0, each model's voxels at its transform's `_t` less half its
/// size, shifted back by (⌊X/2⌋, ⌊Y/2⌋, 0); compares them and the indices `.npy` (argv[6])
/// with `np.argwhere` of the dense `.npy` (argv[5]). Prints the models, the voxels and the
/// first palette entry.
const READER: &str = r#"
import sys, struct, numpy as np
b = open(sys.argv[1], 'rb').read()
assert b[:4] == b'VOX ' and struct.unpack('<i', b[4:8])[0] == 150
def chunks(at, end):
    while at < end:
        cid = b[at:at + 4]; n, m = struct.unpack('<ii', b[at + 4:at + 12])
        yield cid, b[at + 12:at + 12 + n], (at + 12 + n, at + 12 + n + m)
        at += 12 + n + m
    assert at == end
(cid, _, (s, e)), = list(chunks(8, len(b)))
assert cid == b'MAIN' and e == len(b)
def string(c, at):
    n = struct.unpack('<i', c[at:at + 4])[0]
    return c[at + 4:at + 4 + n].decode(), at + 4 + n
def dct(c, at):
    n = struct.unpack('<i', c[at:at + 4])[0]; at += 4; d = {}
    for _ in range(n):
        k, at = string(c, at); v, at = string(c, at); d[k] = v
    return d, at
sizes, voxels, nodes, rgba = [], [], {}, None
for cid, c, _ in chunks(s, e):
    if cid == b'SIZE':
        sizes.append(struct.unpack('<iii', c))
    elif cid == b'XYZI':
        n = struct.unpack('<i', c[:4])[0]
        voxels.append(np.frombuffer(c[4:4 + 4 * n], np.uint8).reshape(n, 4))
    elif cid in (b'nTRN', b'nGRP', b'nSHP'):
        nid = struct.unpack('<i', c[:4])[0]; _, at = dct(c, 4)
        if cid == b'nTRN':
            child, _, _, frames = struct.unpack('<iiii', c[at:at + 16])
            assert frames == 1
            f, _ = dct(c, at + 16)
            nodes[nid] = ('T', child, np.array([int(x) for x in f.get('_t', '0 0 0').split()]))
        elif cid == b'nGRP':
            n = struct.unpack('<i', c[at:at + 4])[0]
            nodes[nid] = ('G', struct.unpack(f'<{n}i', c[at + 4:at + 4 + 4 * n]))
        else:
            assert struct.unpack('<i', c[at:at + 4])[0] == 1
            nodes[nid] = ('S', struct.unpack('<i', c[at + 4:at + 8])[0])
    elif cid == b'RGBA':
        rgba = np.frombuffer(c, np.uint8).reshape(256, 4)
out = []
def walk(nid, t):
    node = nodes[nid]
    if node[0] == 'T':
        walk(node[1], t + node[2])
    elif node[0] == 'G':
        for ch in node[1]:
            walk(ch, t)
    else:
        v, size = voxels[node[1]], np.array(sizes[node[1]])
        assert (v[:, 3] == 1).all() and (size <= 256).all()
        out.append(v[:, :3].astype(np.int64) + t - size // 2)
walk(0, np.zeros(3, np.int64))
X, Y, Z = map(int, sys.argv[2:5])
got = np.concatenate(out) + np.array([X // 2, Y // 2, 0])
got = got[np.lexsort(got.T[::-1])]
want = np.argwhere(np.load(sys.argv[5]))
idx = np.load(sys.argv[6])
assert idx.dtype == np.uint32 and idx.shape == want.shape, (idx.dtype, idx.shape, want.shape)
assert (idx == want).all()
assert got.shape == want.shape and (got == want).all()
print(len(sizes), len(want), *rgba[0])
"#;

#[test]
fn a_long_grid_comes_as_vox_models_in_place_and_as_indices() {
    let dir = tmpdir("vox-route");
    let srv = Server::start(&dir, &[]);
    // A box's surface on a 600 × 40 × 300 grid: 3 × 1 × 2 models.
    let obj = box_obj([10.2, 3.3, 5.5], [590.7, 36.1, 290.2]);
    let v = srv.created(
        "/v1/voxelize?origin=0,0,0&voxel_size=1&dims=600,40,300&method=surface&wait=120",
        &[("Content-Type", "model/obj")],
        &obj,
    );
    let id = v["id"].as_str().unwrap().to_string();
    let get = |format: &str| {
        srv.req(
            "GET",
            &format!("/v1/volumes/{id}/data?format={format}"),
            &[],
            &[],
        )
        .ok(200)
    };
    let vox = get("vox");
    assert_eq!(vox.header("content-type"), Some("application/x-vox"));
    assert_eq!(
        vox.header("content-length")
            .map(|n| n.parse::<usize>().unwrap()),
        Some(vox.body.len())
    );
    assert!(
        vox.header("content-disposition")
            .is_some_and(|d| d.contains(".vox")),
        "{:?}",
        vox.headers
    );
    assert!(vox.body.starts_with(b"VOX "));
    let idx = get("indices");
    assert!(
        idx.header("content-disposition")
            .is_some_and(|d| d.contains(".indices.npy")),
        "{:?}",
        idx.headers
    );
    assert_eq!(
        idx.header("content-length")
            .map(|n| n.parse::<usize>().unwrap()),
        Some(idx.body.len())
    );
    let npy = get("npy");
    let points = get("points");
    assert_eq!(points.header("content-type"), Some("application/x-ply"));
    assert!(
        points
            .header("content-disposition")
            .is_some_and(|d| d.contains(".points.ply")),
        "{:?}",
        points.headers
    );
    // A range of the .vox (its length is known before it is written).
    let part = srv.req(
        "GET",
        &format!("/v1/volumes/{id}/data?format=vox"),
        &[("Range", "bytes=100-199")],
        &[],
    );
    assert_eq!(part.status, 206);
    assert_eq!(part.body, vox.body[100..200]);
    let Some(py) = crate::cli::python_with("numpy") else {
        return;
    };
    let paths = [
        ("a.vox", &vox.body),
        ("a.npy", &npy.body),
        ("a.indices.npy", &idx.body),
    ]
    .map(|(name, body)| {
        let p = dir.join(name);
        std::fs::write(&p, body).unwrap();
        p
    });
    let o = Command::new(py)
        .args(["-c", READER])
        .arg(&paths[0])
        .args(["600", "40", "300"])
        .args([&paths[1], &paths[2]])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let line = String::from_utf8(o.stdout).unwrap();
    let f: Vec<u64> = line
        .split_whitespace()
        .map(|s| s.parse().unwrap())
        .collect();
    assert_eq!(f[0], 6, "{line}");
    assert!(f[1] > 300_000, "{line}");
    assert_eq!(f[2..], [200, 200, 200, 255], "{line}");
    // The volume's count of set voxels is the indices' rows.
    assert_eq!(Some(f[1]), v["solid_voxels"].as_u64(), "{v}");
    // trimesh reads the point cloud: one point a set voxel, at its centre (origin 0, size 1).
    if let Some(tpy) = crate::mesh_cli::trimesh_python() {
        let p = dir.join("a.points.ply");
        std::fs::write(&p, &points.body).unwrap();
        let script = "import sys, numpy as np, trimesh\n\
            pc = trimesh.load(sys.argv[1])\n\
            assert isinstance(pc, trimesh.PointCloud), type(pc)\n\
            idx = np.load(sys.argv[2]).astype(np.float64)\n\
            assert np.array_equal(np.asarray(pc.vertices), idx + 0.5)\n\
            print(len(pc.vertices))";
        let o = Command::new(tpy)
            .args(["-c", script])
            .args([&p, &paths[2]])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(
            String::from_utf8(o.stdout).unwrap().trim(),
            f[1].to_string()
        );
    }
}

#[test]
fn vox_refuses_a_grid_beyond_magicavoxels_world_and_volumes_not_bits() {
    let dir = tmpdir("vox-refusals");
    let srv = Server::start(&dir, &[]);
    let obj = box_obj([0.2, 0.2, 0.2], [0.8, 0.8, 0.8]);
    let wide = srv.created(
        "/v1/voxelize?origin=0,0,0&voxel_size=0.5&dims=2001,2,2&wait=60",
        &[("Content-Type", "model/obj")],
        &obj,
    );
    let r = srv.req(
        "GET",
        &format!(
            "/v1/volumes/{}/data?format=vox",
            wide["id"].as_str().unwrap()
        ),
        &[],
        &[],
    );
    let p = assert_problem(&r, 422, "grid-too-large");
    let detail = p["detail"].as_str().unwrap();
    assert!(
        detail.contains("2000x2000x1000") && detail.contains("2001x2x2"),
        "{detail}"
    );
    let sdf = srv.created(
        "/v1/voxelize?origin=-0.5,-0.5,-0.5&voxel_size=0.25&dims=8,8,8&method=sdf&wait=60",
        &[("Content-Type", "model/obj")],
        &obj,
    );
    for format in ["vox", "indices"] {
        let r = srv.req(
            "GET",
            &format!(
                "/v1/volumes/{}/data?format={format}",
                sdf["id"].as_str().unwrap()
            ),
            &[],
            &[],
        );
        assert_problem(&r, 400, "invalid-parameter");
    }
}

/// `-o x.vox` and `-o x.indices.npy` pick the formats by extension; dot_vox reads the `.vox`
/// (one model, every voxel of the `.vxl` once), and the indices are the set voxels in C order.
#[test]
fn voxelize_writes_vox_and_indices_by_extension() {
    let run = |out: &Path| {
        let o = run_voxd(&[
            "voxelize",
            data("spot.obj").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--resolution",
            "33",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let dir = tmpdir("vox-cli");
    let vxl = dir.join("spot-vox.vxl");
    run(&vxl);
    let Volume::Bits(v) = VolumeFormat::Vxl
        .decode(&std::fs::read(&vxl).unwrap())
        .unwrap()
    else {
        panic!()
    };
    let vox = dir.join("spot.vox");
    let warned = run(&vox);
    assert!(warned.contains("vox keeps only the voxels"), "{warned}");
    let data = dot_vox::load(vox.to_str().unwrap()).unwrap();
    assert_eq!(data.models.len(), 1);
    let m = &data.models[0];
    assert_eq!(m.voxels.len() as u64, v.count_ones());
    for p in &m.voxels {
        assert!(v.get(u32::from(p.x), u32::from(p.y), u32::from(p.z)));
    }
    let idx = dir.join("spot.indices.npy");
    run(&idx);
    let bytes = std::fs::read(&idx).unwrap();
    let header = voxd::codec::indices::header(v.count_ones());
    assert_eq!(&bytes[..header.len()], &header[..]);
    let rows: Vec<[u32; 3]> = bytes[header.len()..]
        .chunks(12)
        .map(|r| {
            std::array::from_fn(|k| u32::from_le_bytes(r[4 * k..4 * k + 4].try_into().unwrap()))
        })
        .collect();
    let mut want = vec![];
    let d = v.dims();
    for x in 0..d[0] {
        for y in 0..d[1] {
            for z in 0..d[2] {
                if v.get(x, y, z) {
                    want.push([x, y, z]);
                }
            }
        }
    }
    assert_eq!(rows, want);
}
