//! `.vdb` files read back by OpenVDB itself (Debian's `python3-openvdb`, OpenVDB 10): the same
//! active voxels, the same values bit for bit, tiles, background and world positions as the
//! volume they were written from. Skips with a notice where `pyopenvdb` cannot be imported,
//! unless `VOXD_REQUIRE_OPENVDB=1` (scripts/test.sh sets it once provision.sh has installed it)
//! or `CI` is set, where that is a failure.

use std::collections::BTreeMap;
use std::process::Command;

use crate::common::{Rng, Scratch};
use voxd::codec::VolumeFormat;
use voxd::grid::Grid;
use voxd::volume::sparse::{BRICK_VOXELS, Sparse};
use voxd::volume::{BitVolume, Volume};

/// Reads the file named by argv[1] with OpenVDB and prints, as JSON: the grids, the first one's
/// name, class, value type, background, active voxel count, voxel size; every active value
/// (its first voxel, voxel count, value); and for each (i, j, k) of the file argv[2] (one a
/// line) its value, whether it is on, and its world position. Floats as the hex of their
/// little-endian f32 bytes, so that they compare bit for bit.
const READER: &str = r#"
import json, struct, sys
import pyopenvdb as vdb
grids, meta = vdb.readAll(sys.argv[1])
g = grids[0]
def enc(v):
    return struct.pack('<f', v).hex() if isinstance(v, float) else v
acc = g.getConstAccessor()
out = {
    'grids': len(grids),
    'name': g.name,
    'class': str(g.gridClass),
    'type': g.valueTypeName,
    'background': enc(g.background),
    'active': g.activeVoxelCount(),
    'voxel_size': list(g.transform.voxelSize()),
    'on': [[list(v.min), v.count, enc(v.value)] for v in g.iterOnValues()],
    'queries': [],
}
for line in open(sys.argv[2]):
    ijk = tuple(int(c) for c in line.split())
    out['queries'].append([enc(acc.getValue(ijk)), acc.isValueOn(ijk), list(g.transform.indexToWorld(ijk))])
print(json.dumps(out))
"#;

/// The system Python when it imports pyopenvdb; `None` (with a notice) where it does not and
/// nothing requires it.
fn openvdb_python() -> Option<&'static str> {
    let ok = Command::new("/usr/bin/python3")
        .args(["-c", "import pyopenvdb"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        let required = std::env::var("VOXD_REQUIRE_OPENVDB").as_deref() == Ok("1")
            || std::env::var_os("CI").is_some();
        assert!(
            !required,
            "OpenVDB read-back is required here but /usr/bin/python3 cannot import pyopenvdb (apt-get install python3-openvdb)"
        );
        eprintln!("NOTICE: no pyopenvdb (python3-openvdb); skipping the OpenVDB read-back");
        return None;
    }
    Some("/usr/bin/python3")
}

/// Writes `v` as `.vdb` (through the format table) and has OpenVDB read it, asking for the
/// voxels `queries`.
fn read_back(python: &str, v: &Volume, queries: &[[i64; 3]], name: &str) -> serde_json::Value {
    let bytes = VolumeFormat::Vdb.encode(v).unwrap();
    assert_eq!(VolumeFormat::sniff(&bytes), Some(VolumeFormat::Vdb));
    openvdb_read(python, &bytes, queries, name)
}

/// Has OpenVDB read the `.vdb` `bytes`, asking for the voxels `queries`.
fn openvdb_read(python: &str, bytes: &[u8], queries: &[[i64; 3]], name: &str) -> serde_json::Value {
    let dir = Scratch::new(name);
    let path = dir.join("v.vdb");
    let q = dir.join("queries.txt");
    std::fs::write(&path, bytes).unwrap();
    let lines: Vec<String> = queries
        .iter()
        .map(|p| format!("{} {} {}", p[0], p[1], p[2]))
        .collect();
    std::fs::write(&q, lines.join("\n")).unwrap();
    let o = Command::new(python)
        .args(["-c", READER])
        .arg(&path)
        .arg(&q)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn f32_of(hex: &serde_json::Value) -> f32 {
    let h = hex.as_str().expect("a float as hex");
    let b: Vec<u8> = (0..4)
        .map(|i| u8::from_str_radix(&h[2 * i..2 * i + 2], 16).unwrap())
        .collect();
    f32::from_le_bytes(b.try_into().unwrap())
}

/// Voxel (i, j, k)'s centre, as docs/methods.md puts it.
fn centre(g: &Grid, p: [i64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|a| g.origin[a] + (p[a] as f64 + 0.5) * g.voxel_size)
}

fn check_world(g: &Grid, queries: &[[i64; 3]], got: &serde_json::Value) {
    for (p, a) in queries.iter().zip(got["queries"].as_array().unwrap()) {
        let w = centre(g, *p);
        for (axis, want) in w.iter().enumerate() {
            let have = a[2][axis].as_f64().unwrap();
            assert!(
                (have - want).abs() <= 1e-9 * (1.0 + want.abs()),
                "{p:?}: world {have} != {want}"
            );
        }
    }
}

/// A random sparse distance volume: bricks of in-band values, ±background, ±0 (voxels past the
/// grid the background), tiles inside the grid and at its high faces, across OpenVDB's node
/// boundaries (voxel 128 on y, 4096 on x).
/// With `odd`, some voxels hold an out-of-band value that is not ±background (no level set:
/// OpenVDB's nodes holding one are written with every value).
fn random_sparse(rng: &mut Rng, background: f32, odd: bool) -> Sparse<f32> {
    let grid = Grid {
        origin: [-2.5, 1.25, 0.3],
        voxel_size: 0.1,
        dims: [4110, 140, 21],
    };
    let mut s = Sparse::with_tile_value(grid, background, -background);
    let bd = s.brick_dims();
    let mut picks = vec![
        [0, 0, 0],
        [511, 15, 1],
        [512, 16, 2],
        [513, 17, 2],
        [513, 0, 0],
    ];
    for _ in 0..40 {
        picks.push([0, 1, 2].map(|a| rng.below(bd[a] as u64) as u32));
    }
    let finite_bg = if background.is_finite() {
        background
    } else {
        1.0
    };
    for at in picks {
        let mut b = [background; BRICK_VOXELS];
        for (i, v) in b.iter_mut().enumerate() {
            let p = [i / 64, i / 8 % 8, i % 8].map(|c| c as u32);
            if (0..3).any(|a| at[a] * 8 + p[a] >= grid.dims[a]) {
                continue;
            }
            *v = match rng.below(6) {
                0 if odd && rng.below(8) == 0 => background * 1.5,
                0 => background,
                1 => -background,
                2 => [0.0, -0.0][rng.below(2) as usize],
                _ => (rng.range(-1.0, 1.0) * finite_bg as f64 * 0.999) as f32,
            };
        }
        s.insert_brick(at, b).unwrap();
    }
    let mut tiles = vec![[513, 17, 2], [1, 1, 1], [512, 15, 0]];
    for _ in 0..12 {
        tiles.push([0, 1, 2].map(|a| rng.below(bd[a] as u64) as u32));
    }
    for t in tiles {
        if s.bricks().all(|(b, _)| b != t) {
            s.set_tile(t, true).unwrap();
        }
    }
    s
}

#[test]
fn openvdb_reads_a_sparse_distance_volume_as_our_level_set() {
    let Some(python) = openvdb_python() else {
        return;
    };
    for (seed, background, odd) in [
        (1, 0.3f32, false),
        (2, f32::INFINITY, false),
        (3, 0.3, true),
    ] {
        let mut rng = Rng::new(seed);
        let s = random_sparse(&mut rng, background, odd);
        assert!(s.tile_count() >= 3, "seed {seed}");
        let g = *s.grid();
        let d = g.dims;
        // Every voxel of every brick and tile (those past the grid too), and a few elsewhere.
        let mut queries = vec![];
        let positions: Vec<[u32; 3]> = s.bricks().map(|(b, _)| b).chain(s.tiles()).collect();
        for b in &positions {
            for i in 0..BRICK_VOXELS {
                let p = [i / 64, i / 8 % 8, i % 8];
                queries.push([0, 1, 2].map(|a| (b[a] * 8) as i64 + p[a] as i64));
            }
        }
        for _ in 0..200 {
            queries.push([0, 1, 2].map(|a| rng.below(d[a] as u64) as i64));
        }
        let got = read_back(
            python,
            &Volume::SparseDistance(s.clone()),
            &queries,
            "vdb-sparse",
        );
        assert_eq!(got["grids"], 1);
        assert_eq!(got["name"], "sdf");
        let class = if odd { "unknown" } else { "level set" };
        assert_eq!(got["class"], class, "seed {seed}");
        assert_eq!(got["type"], "float");
        assert_eq!(f32_of(&got["background"]).to_bits(), background.to_bits());
        let vs = got["voxel_size"].as_array().unwrap();
        assert!(vs.iter().all(|v| v.as_f64() == Some(g.voxel_size)));
        // What each voxel holds, from `get` (past the grid: the background); active: in band.
        let want = |p: [i64; 3]| -> f32 {
            if (0..3).all(|a| p[a] < d[a] as i64) {
                s.get(p[0] as u32, p[1] as u32, p[2] as u32)
            } else {
                background
            }
        };
        let mut active: BTreeMap<[i64; 3], u32> = BTreeMap::new();
        for (p, a) in queries.iter().zip(got["queries"].as_array().unwrap()) {
            let w = want(*p);
            assert_eq!(f32_of(&a[0]).to_bits(), w.to_bits(), "seed {seed} {p:?}");
            assert_eq!(
                a[1].as_bool(),
                Some(w.abs() < background),
                "seed {seed} {p:?}"
            );
            if w.abs() < background {
                active.insert(*p, w.to_bits());
            }
        }
        check_world(&g, &queries, &got);
        // Every active value is one of the voxels above, with its value: no other is on.
        let on: BTreeMap<[i64; 3], u32> = got["on"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| {
                assert_eq!(e[1], 1, "an active tile");
                let p = e[0].as_array().unwrap();
                (
                    [0, 1, 2].map(|a| p[a].as_i64().unwrap()),
                    f32_of(&e[2]).to_bits(),
                )
            })
            .collect();
        assert_eq!(on, active, "seed {seed}");
        assert_eq!(got["active"].as_u64(), Some(active.len() as u64));
        assert!(active.len() > 1000, "seed {seed}: {}", active.len());
    }
}

#[test]
fn openvdb_reads_a_bit_volume_as_a_bool_grid() {
    let Some(python) = openvdb_python() else {
        return;
    };
    let mut rng = Rng::new(7);
    let g = Grid {
        origin: [10.0, -3.0, 0.0],
        voxel_size: 0.25,
        dims: [4100, 20, 70],
    };
    let mut b = BitVolume::new(g);
    for _ in 0..600 {
        let p = [0, 1, 2].map(|a| rng.below(g.dims[a] as u64) as u32);
        b.set(p[0], p[1], p[2], true);
    }
    for x in 4088..4096 {
        for y in 8..16 {
            for z in 64..70 {
                b.set(x, y, z, true);
            }
        }
    }
    let set: Vec<[i64; 3]> = b.iter_ones().map(|p| p.map(i64::from)).collect();
    let mut queries = set.clone();
    for _ in 0..300 {
        queries.push([0, 1, 2].map(|a| rng.below(g.dims[a] as u64) as i64));
    }
    let got = read_back(python, &Volume::Bits(b.clone()), &queries, "vdb-bits");
    assert_eq!(got["name"], "mask");
    assert_eq!(got["type"], "bool");
    assert_eq!(got["background"], false);
    assert_eq!(got["active"].as_u64(), Some(b.count_ones()));
    for (p, a) in queries.iter().zip(got["queries"].as_array().unwrap()) {
        let want = b.get(p[0] as u32, p[1] as u32, p[2] as u32);
        assert_eq!(
            (a[0].as_bool(), a[1].as_bool()),
            (Some(want), Some(want)),
            "{p:?}"
        );
    }
    check_world(&g, &queries, &got);
    let mut on: Vec<[i64; 3]> = got["on"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            assert_eq!((e[1].as_u64(), e[2].as_bool()), (Some(1), Some(true)));
            let p = e[0].as_array().unwrap();
            [0, 1, 2].map(|a| p[a].as_i64().unwrap())
        })
        .collect();
    on.sort();
    let mut want = set;
    want.sort();
    assert_eq!(on, want);
}

/// Stores `v` in a data directory (as the service stores volumes), for a server started on it.
fn store_in(dir: &std::path::Path, v: &Volume) -> String {
    use voxd::app::metadata::{Origin, build};
    use voxd::app::store::VolumeStore;
    let provenance = serde_json::json!({"test": "vdb"});
    let built = build(
        v,
        &Origin::Derived {
            method: "test",
            provenance: &provenance,
            materials: &[],
        },
        Some("sparse".into()),
        "test",
    )
    .unwrap();
    let id = built.meta.id.clone();
    let store = voxd::store::fs::FsStore::open(dir, 1 << 30).unwrap();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
        .block_on(store.put(built.meta, built.vxl))
        .unwrap();
    id
}

/// Over HTTP: a stored sparse distance volume downloads as `.vdb` (OpenVDB reads the voxels
/// back) and as `.npy` (numpy loads float32 (X, Y, Z), every voxel what `get` says); a grid
/// over the server's voxel limit is refused as `.npy` with its bytes, and still downloads as
/// `.vdb`.
#[test]
fn sparse_distance_volumes_download_as_vdb_and_npy() {
    let Some(python) = openvdb_python() else {
        return;
    };
    let dir = crate::common::tmpdir("vdb-http");
    let g = Grid {
        origin: [1.0, 2.0, -3.0],
        voxel_size: 0.5,
        dims: [40, 33, 21],
    };
    let mut s = Sparse::with_tile_value(g, 1.5f32, -1.5);
    let mut rng = Rng::new(11);
    for _ in 0..300 {
        let p = [0, 1, 2].map(|a| rng.below(g.dims[a] as u64) as u32);
        s.set(p[0], p[1], p[2], (rng.range(-1.0, 1.0) * 1.4) as f32);
    }
    s.set_tile([4, 4, 2], true).unwrap();
    s.set_tile([0, 0, 0], true).unwrap();
    // 1.2 million voxels: over the limit of 1 million below, as a dense array.
    let big_grid = Grid {
        dims: [120, 100, 100],
        ..g
    };
    let mut big = Sparse::with_tile_value(big_grid, 1.5f32, -1.5);
    big.set(119, 99, 99, -0.25);
    let id = store_in(&dir, &Volume::SparseDistance(s.clone()));
    let big_id = store_in(&dir, &Volume::SparseDistance(big));
    let server = crate::service::Server::start(&dir, &["--max-voxels", "1000000"]);
    let get = |path: &str| crate::common::request(&server.addr, "GET", path, &[], b"");

    let r = get(&format!("/v1/volumes/{id}/data?format=vdb"));
    assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(r.header("content-type"), Some("application/x-vdb"));
    assert!(
        r.header("content-disposition")
            .is_some_and(|d| d.contains(".vdb"))
    );
    let mut queries = vec![];
    for x in 0..g.dims[0] as i64 {
        for y in 0..g.dims[1] as i64 {
            for z in (0..g.dims[2] as i64).step_by(4) {
                queries.push([x, y, z]);
            }
        }
    }
    let got = openvdb_read(python, &r.body, &queries, "vdb-http-read");
    assert_eq!(got["class"], "level set");
    for (p, a) in queries.iter().zip(got["queries"].as_array().unwrap()) {
        let want = s.get(p[0] as u32, p[1] as u32, p[2] as u32);
        assert_eq!(f32_of(&a[0]).to_bits(), want.to_bits(), "{p:?}");
        assert_eq!(a[1].as_bool(), Some(want.abs() < 1.5), "{p:?}");
    }
    check_world(&g, &queries, &got);

    let r = get(&format!("/v1/volumes/{id}/data?format=npy"));
    assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
    let npy = dir.join("d.npy");
    let raw = dir.join("d.raw");
    std::fs::write(&npy, &r.body).unwrap();
    let script = "import numpy as np, sys; a = np.load(sys.argv[1]); assert a.dtype == np.float32, a.dtype; print(*a.shape); open(sys.argv[2], 'wb').write(a.astype('<f4').tobytes(order='C'))";
    let o = Command::new(python)
        .args(["-c", script])
        .arg(&npy)
        .arg(&raw)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(String::from_utf8(o.stdout).unwrap().trim(), "40 33 21");
    let data = std::fs::read(&raw).unwrap();
    let [nx, ny, nz] = g.dims;
    assert_eq!(data.len() as u32, nx * ny * nz * 4);
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                let at = (((x * ny + y) * nz + z) * 4) as usize;
                let v = f32::from_le_bytes(data[at..at + 4].try_into().unwrap());
                assert_eq!(v.to_bits(), s.get(x, y, z).to_bits(), "({x}, {y}, {z})");
            }
        }
    }
    let r = get(&format!("/v1/volumes/{id}/data?format=raw"));
    assert_eq!((r.status, r.body), (200, data));

    // Over the limit as a dense array: refused with the numbers; as .vdb it is sparse.
    let r = get(&format!("/v1/volumes/{big_id}/data?format=npy"));
    assert_eq!(r.status, 422, "{}", String::from_utf8_lossy(&r.body));
    let detail = r.json()["detail"].as_str().unwrap().to_string();
    for want in ["1200000 voxels", "4800000 bytes", "4000000 bytes", "vdb"] {
        assert!(detail.contains(want), "{want:?} not in {detail:?}");
    }
    let r = get(&format!("/v1/volumes/{big_id}/data?format=vdb"));
    assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
    let got = openvdb_read(python, &r.body, &[[119, 99, 99], [0, 0, 0]], "vdb-http-big");
    assert_eq!(got["active"], 1);
    let q = got["queries"].as_array().unwrap();
    assert_eq!((f32_of(&q[0][0]), f32_of(&q[1][0])), (-0.25, 1.5));
    // bits that are no distance: refused by the table.
    let r = get(&format!("/v1/volumes/{id}/data?format=binvox"));
    assert_eq!(r.status, 400);
    drop(server);
}

/// Checks that OpenVDB reads `vdb` as the sparse distance volume `s`: every voxel's value and
/// state (every third z, all x and y), world positions, the active count.
fn check_level_set(python: &str, vdb: &[u8], s: &Sparse<f32>, name: &str) {
    let g = *s.grid();
    let bg = s.background();
    let mut queries = vec![];
    for x in 0..g.dims[0] as i64 {
        for y in 0..g.dims[1] as i64 {
            for z in (x % 3..g.dims[2] as i64).step_by(3) {
                queries.push([x, y, z]);
            }
        }
    }
    let got = openvdb_read(python, vdb, &queries, name);
    assert_eq!(
        (&got["name"], &got["class"]),
        (&"sdf".into(), &"level set".into())
    );
    assert_eq!(f32_of(&got["background"]).to_bits(), bg.to_bits());
    for (p, a) in queries.iter().zip(got["queries"].as_array().unwrap()) {
        let want = s.get(p[0] as u32, p[1] as u32, p[2] as u32);
        assert_eq!(f32_of(&a[0]).to_bits(), want.to_bits(), "{name} {p:?}");
        assert_eq!(a[1].as_bool(), Some(want.abs() < bg), "{name} {p:?}");
    }
    check_world(&g, &queries, &got);
    let [nx, ny, nz] = g.dims;
    let mut active = 0u64;
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                active += u64::from(s.get(x, y, z).abs() < bg);
            }
        }
    }
    assert!(active > 100, "{name}: {active}");
    assert_eq!(got["active"].as_u64(), Some(active), "{name}");
}

/// End to end, both fronts: `method=sdf` of a real mesh over HTTP downloaded as `.vdb`, and
/// `voxd voxelize --method sdf -o x.vdb`, each read by OpenVDB as the volume its `.vxl` holds.
#[test]
fn sdf_downloads_and_cli_output_read_back_in_openvdb() {
    let Some(python) = openvdb_python() else {
        return;
    };
    let dir = crate::common::tmpdir("vdb-sdf");
    let mesh = crate::common::data("spot.obj");
    let server = crate::service::Server::start(&dir, &[]);
    let body = std::fs::read(&mesh).unwrap();
    let r = crate::common::request(
        &server.addr,
        "POST",
        "/v1/voxelize?method=sdf&band=3&fill=winding&resolution=40&padding=2&wait=120",
        &[("Content-Type", "model/obj")],
        &body,
    );
    assert_eq!(r.status, 201, "{}", String::from_utf8_lossy(&r.body));
    let id = r.json()["id"].as_str().unwrap().to_string();
    let get = |f: &str| {
        let r = crate::common::request(
            &server.addr,
            "GET",
            &format!("/v1/volumes/{id}/data?format={f}"),
            &[],
            b"",
        );
        assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
        r.body
    };
    let Volume::SparseDistance(s) = VolumeFormat::Vxl.decode(&get("vxl")).unwrap() else {
        panic!("not a sparse distance volume")
    };
    check_level_set(python, &get("vdb"), &s, "http");
    drop(server);

    let (vxl, vdb) = (dir.join("spot.vxl"), dir.join("spot.vdb"));
    for out in [&vxl, &vdb] {
        let o = crate::common::run_voxd(&[
            "voxelize",
            mesh.to_str().unwrap(),
            "--method",
            "sdf",
            "--band",
            "2",
            "--fill",
            "winding",
            "--resolution",
            "36",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let Volume::SparseDistance(s) = VolumeFormat::Vxl
        .decode(&std::fs::read(&vxl).unwrap())
        .unwrap()
    else {
        panic!("not a sparse distance volume")
    };
    check_level_set(python, &std::fs::read(&vdb).unwrap(), &s, "cli");
}
