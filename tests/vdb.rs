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
    let dir = Scratch::new(name);
    let path = dir.join("v.vdb");
    let q = dir.join("queries.txt");
    let bytes = VolumeFormat::Vdb.encode(v).unwrap();
    assert_eq!(VolumeFormat::sniff(&bytes), Some(VolumeFormat::Vdb));
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
fn random_sparse(rng: &mut Rng, background: f32) -> Sparse<f32> {
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
    for (seed, background) in [(1, 0.3f32), (2, f32::INFINITY)] {
        let mut rng = Rng::new(seed);
        let s = random_sparse(&mut rng, background);
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
        assert_eq!(got["class"], "level set");
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
