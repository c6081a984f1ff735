//! Round trips and byte layouts of every codec, and their errors on damaged files.
// The index expressions spell out the documented layouts, (x·Y + y)·Z + z, even where x is 1.
#![allow(clippy::identity_op)]

use crate::common::{Rng, random_fill};
use voxd::codec::{VolumeFormat, binvox, npy, vxl};
use voxd::grid::Grid;
use voxd::volume::{BitVolume, DensityVolume, Volume, VolumeKind};

fn random_bits(rng: &mut Rng, dims: [u32; 3]) -> BitVolume {
    let g = Grid {
        origin: [rng.range(-5.0, 5.0), 0.1, -0.3],
        voxel_size: rng.range(0.01, 2.0),
        dims,
    };
    random_fill(rng, g)
}

#[test]
fn bits_round_trip_through_every_format() {
    for seed in 0..40 {
        let mut rng = Rng::new(seed);
        let cubic = seed % 2 == 0;
        let n = 1 + rng.below(70) as u32;
        let dims = if cubic {
            [n; 3]
        } else {
            [n, 1 + rng.below(9) as u32, 1 + rng.below(130) as u32]
        };
        let v = random_bits(&mut rng, dims);
        let vol = Volume::Bits(v.clone());
        let back = vxl::decode(&vxl::encode(&vol, &Default::default()).unwrap())
            .unwrap()
            .0;
        assert_eq!(back, vol, "vxl seed {seed}");
        // npy keeps the bits, not the grid.
        let Volume::Bits(b) = npy::decode(&npy::encode(&vol)).unwrap() else {
            panic!("npy kind")
        };
        assert_eq!(b.words(), v.words(), "npy seed {seed}");
        assert_eq!(b.dims(), dims);
        // binvox keeps the grid when cubic, pads when not.
        let bv = binvox::decode(&binvox::encode(&vol).unwrap()).unwrap();
        // binvox stores the cube's edge length, so the voxel size comes back as scale / n (rounded).
        assert!(
            (bv.grid().voxel_size - v.grid().voxel_size).abs()
                <= 4.0 * f64::EPSILON * v.grid().voxel_size
        );
        assert_eq!(bv.grid().origin, v.grid().origin);
        if cubic {
            assert_eq!(bv.words(), v.words(), "binvox seed {seed}");
        } else {
            let m = *dims.iter().max().unwrap();
            assert_eq!(bv.dims(), [m; 3]);
            assert_eq!(bv.count_ones(), v.count_ones());
            assert!(v.iter_ones().all(|p| bv.get(p[0], p[1], p[2])));
        }
    }
}

#[test]
fn density_round_trips_through_vxl_and_npy() {
    let g = Grid {
        origin: [1.0, 2.0, 3.0],
        voxel_size: 0.5,
        dims: [3, 4, 5],
    };
    let mut d = DensityVolume::new(g, 8);
    d.set(2, 3, 4, 8);
    d.set(0, 1, 2, 3);
    let vol = Volume::Density(d.clone());
    let (back, _) = vxl::decode(&vxl::encode(&vol, &Default::default()).unwrap()).unwrap();
    assert_eq!(back, vol);
    let Volume::Density(n) = npy::decode(&npy::encode(&vol)).unwrap() else {
        panic!("npy kind")
    };
    assert_eq!(n.data(), d.data());
    assert!(matches!(
        binvox::encode(&vol),
        Err(voxd::codec::CodecError::Unsupported { .. })
    ));
}

#[test]
fn byte_layouts_are_the_documented_ones() {
    let g = Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims: [2, 3, 70],
    };
    let mut v = BitVolume::new(g);
    v.set(1, 2, 65, true);
    let vol = Volume::Bits(v);
    // npy: C order (x, y, z), header padded to 64 bytes.
    let n = npy::encode(&vol);
    let hlen = u16::from_le_bytes([n[8], n[9]]) as usize;
    assert_eq!((10 + hlen) % 64, 0);
    assert!(
        std::str::from_utf8(&n[10..10 + hlen])
            .unwrap()
            .contains("'shape': (2, 3, 70)")
    );
    let data = &n[10 + hlen..];
    assert_eq!(
        data.iter().position(|&b| b == 1),
        Some((1 * 3 + 2) * 70 + 65)
    );
    // vxl: header JSON, then words where column (1, 2) is word (1·3 + 2)·2 and bit 65 is word 1, bit 1.
    let e = vxl::encode(&vol, &Default::default()).unwrap();
    let hl = u32::from_le_bytes(e[12..16].try_into().unwrap()) as usize;
    let h: serde_json::Value = serde_json::from_slice(&e[16..16 + hl]).unwrap();
    assert_eq!(h["layout"], "x-y-zcolumns-u64le");
    assert_eq!(h["dims"], serde_json::json!([2, 3, 70]));
    let raw = zstd::decode_all(&e[16 + hl..]).unwrap();
    let words: Vec<u64> = raw
        .chunks(8)
        .map(|c| u64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(
        words.iter().position(|&w| w != 0),
        Some((1 * 3 + 2) * 2 + 1)
    );
    assert_eq!(words[(1 * 3 + 2) * 2 + 1], 1 << 1);
    // binvox: y fastest, then z, then x; voxel (1, 0, 0) of a 2³ cube is index 4.
    let mut c = BitVolume::new(Grid {
        origin: [0.5, 0.0, -1.0],
        voxel_size: 0.25,
        dims: [2, 2, 2],
    });
    c.set(1, 0, 0, true);
    let b = binvox::encode(&Volume::Bits(c)).unwrap();
    let text = "#binvox 1\ndim 2 2 2\ntranslate 0.5 0 -1\nscale 0.5\ndata\n";
    assert_eq!(&b[..text.len()], text.as_bytes());
    assert_eq!(&b[text.len()..], &[0, 4, 1, 1, 0, 3]);
}

#[test]
fn damaged_files_are_refused() {
    let mut rng = Rng::new(3);
    let vol = Volume::Bits(random_bits(&mut rng, [9, 9, 9]));
    let good = vxl::encode(&vol, &Default::default()).unwrap();
    let bad = |b: &[u8]| vxl::decode(b).unwrap_err().to_string();
    assert!(bad(&good[..good.len() - 5]).contains("vxl"));
    assert!(bad(b"hello").contains("bad magic"));
    let mut v2 = good.clone();
    v2[8] = 9;
    assert!(bad(&v2).contains("version 9"));
    let mut flipped = good.clone();
    let last = flipped.len() - 6;
    flipped[last] ^= 0x55;
    assert!(
        vxl::decode(&flipped).is_err(),
        "a damaged payload must not decode"
    );
    let n = npy::encode(&vol);
    assert!(
        npy::decode(&n[..n.len() - 1])
            .unwrap_err()
            .to_string()
            .contains("data bytes")
    );
    // A shape whose voxel count does not fit in u64 (the fuzzer's find: the count overflowed
    // before it was compared with the bytes present) is refused, not multiplied out.
    for shape in [
        "4294967295, 4294967295, 4294967295",
        "29999999, 9999999, 900000000",
    ] {
        let mut h = format!("{{'descr': '|u1', 'fortran_order': False, 'shape': ({shape}), }}");
        while (10 + h.len() + 1) % 64 != 0 {
            h.push(' ');
        }
        h.push('\n');
        let mut f = b"\x93NUMPY\x01\x00".to_vec();
        f.extend_from_slice(&(h.len() as u16).to_le_bytes());
        f.extend_from_slice(h.as_bytes());
        f.extend_from_slice(&[1; 8]);
        let e = npy::decode(&f).unwrap_err().to_string();
        assert!(
            e.contains("data bytes") && e.contains("got 8"),
            "{shape}: {e}"
        );
    }
    // The same for binvox: dims whose count wraps u64 to a small one are out of range.
    for dim in [
        "4294967295 4294967295 4294967295",
        "2097152 2097152 4194304",
    ] {
        let f = format!("#binvox 1\ndim {dim}\ntranslate 0 0 0\nscale 1\ndata\n\x01\x08");
        let e = binvox::decode(f.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("dims out of range"), "{dim}: {e}");
    }
    let b = binvox::encode(&vol).unwrap();
    assert!(
        binvox::decode(&b[..b.len() - 2])
            .unwrap_err()
            .to_string()
            .contains("truncated")
    );
    let mut over = b.clone();
    over.extend_from_slice(&[1, 255]);
    assert!(
        binvox::decode(&over)
            .unwrap_err()
            .to_string()
            .contains("past the end")
    );
    assert_eq!(VolumeFormat::sniff(&good), Some(VolumeFormat::Vxl));
    assert_eq!(VolumeFormat::sniff(&n), Some(VolumeFormat::Npy));
    assert_eq!(VolumeFormat::sniff(&b), Some(VolumeFormat::Binvox));
}

/// The volumes of tests/data/v1-{bits,density}.vxl, which the version-1 writer made (commit
/// 117d9fa, before the other kinds existed): rebuilt here by the same rule.
fn v1_volumes() -> (Volume, Volume) {
    let g = Grid {
        origin: [-1.5, 0.25, 2.0],
        voxel_size: 0.125,
        dims: [5, 3, 70],
    };
    let mut b = BitVolume::new(g);
    for x in 0..5u32 {
        for y in 0..3u32 {
            for z in 0..70u32 {
                if (x * 7 + y * 13 + z * 3) % 5 < 2 || z == 69 {
                    b.set(x, y, z, true);
                }
            }
        }
    }
    let g = Grid {
        origin: [0.0, -2.0, 1.0],
        voxel_size: 0.5,
        dims: [4, 6, 5],
    };
    let mut d = DensityVolume::new(g, 8);
    for x in 0..4u32 {
        for y in 0..6u32 {
            for z in 0..5u32 {
                d.set(x, y, z, ((x + 2 * y + 3 * z) % 9) as u8);
            }
        }
    }
    (Volume::Bits(b), Volume::Density(d))
}

#[test]
fn version_1_files_read_back_identically_and_are_still_written_byte_for_byte() {
    let (bits, density) = v1_volumes();
    for (file, want, method) in [
        ("v1-bits.vxl", bits, "solid"),
        ("v1-density.vxl", density, "density"),
    ] {
        let bytes = std::fs::read(crate::common::data(file)).unwrap();
        assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 1);
        let (got, meta) = vxl::decode(&bytes).unwrap();
        assert_eq!(got, want, "{file}");
        assert_eq!(meta["method"], method, "{file}");
        // The writer still writes version 1 for these kinds, the same bytes: a stored volume's
        // sha256 does not change.
        assert_eq!(vxl::encode(&got, &meta).unwrap(), bytes, "{file}");
    }
}

/// The kinds added after version 1, one small volume each.
fn new_kinds() -> Vec<Volume> {
    use voxd::volume::{Attributed, ChannelValues, Dense, Sparse};
    let g = Grid {
        origin: [0.5, -1.0, 2.0],
        voxel_size: 0.25,
        dims: [3, 9, 17],
    };
    let mut distance = Dense::new(g, 2.5f32);
    distance.set(1, 8, 16, -0.75);
    let mut material = Dense::new(g, 0u16);
    material.set(2, 0, 3, 513);
    let mut colour = Dense::new(g, [0u8; 4]);
    colour.set(0, 4, 9, [255, 128, 1, 200]);
    let mut bits = BitVolume::new(g);
    for p in [[0, 0, 0], [2, 8, 16], [1, 3, 9]] {
        bits.set(p[0], p[1], p[2], true);
    }
    let mut channels = Attributed::new(bits);
    channels
        .add(
            "colour",
            ChannelValues::Rgba8(vec![[1, 2, 3, 4], [5, 6, 7, 8], [9, 9, 9, 9]]),
        )
        .unwrap();
    channels
        .add(
            "distance",
            ChannelValues::F32(vec![0.5, -1.0, f32::INFINITY]),
        )
        .unwrap();
    let sparse_distance = Sparse::from_dense(&distance, 2.5);
    let sparse_material = Sparse::from_dense(&material, 0);
    let sparse_colour = Sparse::from_dense(&colour, [0; 4]);
    vec![
        Volume::Distance(distance),
        Volume::Material(material),
        Volume::Colour(colour),
        Volume::Channels(channels),
        Volume::SparseDistance(sparse_distance),
        Volume::SparseMaterial(sparse_material),
        Volume::SparseColour(sparse_colour),
    ]
}

/// A channel volume whose payload passes the one-shot limit (4 MiB) is streamed to the
/// encoder from where its values lie: the same layout (the bits' words, then each channel's
/// values), one frame, and the volume back.
#[test]
fn a_large_channel_volume_is_written_in_the_documented_layout() {
    use voxd::volume::{Attributed, ChannelValues};
    let g = Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims: [64, 128, 160],
    };
    let mut bits = BitVolume::new(g);
    for x in 0..64 {
        for y in 0..128 {
            for z in 0..160 {
                bits.set(x, y, z, (x * 7 + y * 13 + z * 3) % 5 != 0);
            }
        }
    }
    let n = bits.count_ones() as usize;
    let rgba: Vec<[u8; 4]> = (0..n)
        .map(|i| {
            [
                (i % 251) as u8,
                (i / 251 % 253) as u8,
                (i * 7 % 255) as u8,
                255,
            ]
        })
        .collect();
    let ids: Vec<u16> = (0..n).map(|i| (i * 31 % 65521) as u16).collect();
    let mut v = Attributed::new(bits.clone());
    v.add("rgba", ChannelValues::Rgba8(rgba.clone())).unwrap();
    v.add("material", ChannelValues::U16(ids.clone())).unwrap();
    let vol = Volume::Channels(v);
    let e = vxl::encode(&vol, &Default::default()).unwrap();
    let hl = u32::from_le_bytes(e[12..16].try_into().unwrap()) as usize;
    let raw = zstd::decode_all(&e[16 + hl..]).unwrap();
    let mut want: Vec<u8> = bits.words().iter().flat_map(|w| w.to_le_bytes()).collect();
    want.extend(rgba.iter().flatten());
    want.extend(ids.iter().flat_map(|i| i.to_le_bytes()));
    assert!(
        want.len() > 4 << 20,
        "{} bytes: not past the one-shot limit",
        want.len()
    );
    assert_eq!(raw.len(), want.len());
    assert!(
        raw == want,
        "the payload differs from the documented layout"
    );
    assert_eq!(vxl::decode(&e).unwrap().0, vol);
}

#[test]
fn new_kinds_round_trip_through_vxl_version_2_and_other_formats_refuse_them() {
    for vol in new_kinds() {
        let kind = vol.kind();
        let e = vxl::encode(&vol, &Default::default()).unwrap();
        assert_eq!(
            u32::from_le_bytes(e[8..12].try_into().unwrap()),
            2,
            "{kind}"
        );
        let hl = u32::from_le_bytes(e[12..16].try_into().unwrap()) as usize;
        let h: serde_json::Value = serde_json::from_slice(&e[16..16 + hl]).unwrap();
        assert_eq!(h["kind"], kind.as_str());
        assert_eq!(vxl::decode(&e).unwrap().0, vol, "{kind}");
        for f in [
            VolumeFormat::Npy,
            VolumeFormat::Binvox,
            VolumeFormat::Raw,
            VolumeFormat::Vdb,
        ] {
            // npy and raw hold distances (as float32), vdb sparse distances; all four hold bit
            // volumes with channels (their bits, or with npy and raw one channel).
            let holds = kind == VolumeKind::Channels
                || match f {
                    VolumeFormat::Npy | VolumeFormat::Raw => {
                        matches!(kind, VolumeKind::Distance | VolumeKind::SparseDistance)
                    }
                    VolumeFormat::Vdb => kind == VolumeKind::SparseDistance,
                    _ => false,
                };
            match f.check(&vol) {
                Ok(()) => assert!(holds, "{f:?} {kind}"),
                Err(e) => {
                    assert!(!holds, "{f:?} {kind}: {e}");
                    assert!(e.to_string().contains(kind.as_str()), "{f:?} {kind}: {e}");
                }
            }
        }
        // A version-1 header may not name a kind version 1 did not have.
        let mut v1 = e.clone();
        v1[8] = 1;
        assert!(
            vxl::decode(&v1)
                .unwrap_err()
                .to_string()
                .contains("unknown kind")
        );
    }
}

#[test]
fn version_2_layouts_are_the_documented_ones() {
    let vols = new_kinds();
    let payload = |v: &Volume| {
        let e = vxl::encode(v, &Default::default()).unwrap();
        let hl = u32::from_le_bytes(e[12..16].try_into().unwrap()) as usize;
        let h: serde_json::Value = serde_json::from_slice(&e[16..16 + hl]).unwrap();
        (h, zstd::decode_all(&e[16 + hl..]).unwrap())
    };
    // distance: xyz-f32le, voxel (1, 8, 16) at (1·9 + 8)·17 + 16.
    let (h, p) = payload(&vols[0]);
    assert_eq!(h["layout"], "xyz-f32le");
    let at = ((1 * 9 + 8) * 17 + 16) * 4;
    assert_eq!(p[at..at + 4], (-0.75f32).to_le_bytes());
    assert_eq!(p[..4], 2.5f32.to_le_bytes());
    // material: xyz-u16le.
    let (h, p) = payload(&vols[1]);
    assert_eq!(h["layout"], "xyz-u16le");
    let at = ((2 * 9 + 0) * 17 + 3) * 2;
    assert_eq!(p[at..at + 2], [1, 2]);
    // colour: xyz-rgba8.
    let (h, p) = payload(&vols[2]);
    assert_eq!(h["layout"], "xyz-rgba8");
    let at = (4 * 17 + 9) * 4; // x = 0
    assert_eq!(p[at..at + 4], [255, 128, 1, 200]);
    // channels: the bit words, then each channel's values in set-voxel (column) order.
    let (h, p) = payload(&vols[3]);
    assert_eq!(h["layout"], "x-y-zcolumns-u64le+channels");
    assert_eq!(h["set_voxels"], 3);
    assert_eq!(
        h["channels"],
        serde_json::json!([
            {"name": "colour", "value_type": "rgba8"},
            {"name": "distance", "value_type": "f32le"}
        ])
    );
    let words = 3 * 9 * 1 * 8;
    assert_eq!(p.len(), words + 3 * 4 + 3 * 4);
    assert_eq!(p[words..words + 12], [1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 9]);
    assert_eq!(p[words + 16..words + 20], (-1.0f32).to_le_bytes());
    // sparse: background, brick coordinates (3 × u32), 512 values per brick in
    // ((x%8)·8 + y%8)·8 + z%8 order. The distance's one differing voxel (1, 8, 16) is in
    // brick (0, 1, 2) at offset (1·8 + 0)·8 + 0.
    let (h, p) = payload(&vols[4]);
    assert_eq!(h["layout"], "bricks8-f32le");
    assert_eq!(h["bricks"], 1);
    assert_eq!(p.len(), 4 + 12 + 512 * 4);
    assert_eq!(p[..4], 2.5f32.to_le_bytes());
    assert_eq!(p[4..16], [0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
    let at = 16 + ((1 * 8 + 0) * 8 + 0) * 4;
    assert_eq!(p[at..at + 4], (-0.75f32).to_le_bytes());
}

/// A `.vxl` of version 2 from a header and a payload, as a damaged or hostile writer might make.
fn vxl_v2(header: serde_json::Value, payload: &[u8]) -> Vec<u8> {
    let h = serde_json::to_vec(&header).unwrap();
    let mut out = b"\x89VXL\r\n\x1a\n".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(h.len() as u32).to_le_bytes());
    out.extend_from_slice(&h);
    out.extend_from_slice(&zstd::encode_all(payload, 3).unwrap());
    out
}

#[test]
fn damaged_version_2_files_are_refused() {
    let header = |bricks: u64| {
        serde_json::json!({"kind": "sparse-material", "dims": [9, 8, 8], "origin": [0.0, 0.0, 0.0],
            "voxel_size": 1.0, "layout": "bricks8-u16le", "bricks": bricks})
    };
    let brick = |at: [u32; 3], v: u16| {
        let mut b: Vec<u8> = at.iter().flat_map(|c| c.to_le_bytes()).collect();
        b.extend(std::iter::repeat_n(v.to_le_bytes(), 512).flatten());
        b
    };
    let file = |bricks: &[([u32; 3], u16)]| {
        let mut coords = vec![0u8, 0];
        let mut values = vec![];
        for &(at, v) in bricks {
            let b = brick(at, v);
            coords.extend_from_slice(&b[..12]);
            values.extend_from_slice(&b[12..]);
        }
        coords.extend_from_slice(&values);
        vxl_v2(header(bricks.len() as u64), &coords)
    };
    let err = |b: &[u8]| vxl::decode(b).unwrap_err().to_string();
    // Brick (0, 0, 0) lies inside the 9×8×8 grid; brick (1, 0, 0) mostly past it.
    let Volume::SparseMaterial(s) = vxl::decode(&file(&[([0, 0, 0], 7)])).unwrap().0 else {
        panic!("kind")
    };
    assert_eq!(s.get(7, 7, 7), 7);
    assert_eq!(s.get(8, 0, 0), 0);
    assert!(err(&file(&[([1, 0, 0], 7)])).contains("outside the grid"));
    assert!(err(&file(&[([0, 0, 0], 7), ([0, 0, 0], 7)])).contains("out of order"));
    assert!(err(&file(&[([0, 1, 0], 7)])).contains("outside the brick grid"));
    // More bricks than the grid has is refused before the payload is read.
    assert!(err(&vxl_v2(header(3), &[0; 8])).contains("the grid has 2"));
    let mut wrong_layout = header(0);
    wrong_layout["layout"] = "bricks8-f32le".into();
    assert!(err(&vxl_v2(wrong_layout, &[0, 0])).contains("unknown sparse-material layout"));
    // Channels: set_voxels must be the bits' count.
    let ch = serde_json::json!({"kind": "channels", "dims": [1, 1, 3], "origin": [0.0, 0.0, 0.0],
        "voxel_size": 1.0, "layout": "x-y-zcolumns-u64le+channels", "set_voxels": 1,
        "channels": [{"name": "id", "value_type": "u8"}]});
    let mut payload = 0b101u64.to_le_bytes().to_vec();
    payload.push(9);
    assert!(err(&vxl_v2(ch, &payload)).contains("set_voxels is 1"));
}

/// A NaN distance equals nothing, so a volume holding one would not equal itself read back:
/// refused wherever a `.vxl` holds distances.
#[test]
fn nan_distances_are_refused() {
    let dense = serde_json::json!({"kind": "distance", "dims": [1, 1, 2], "origin": [0.0, 0.0, 0.0],
        "voxel_size": 1.0, "layout": "xyz-f32le"});
    let mut p = 1.0f32.to_le_bytes().to_vec();
    p.extend_from_slice(&f32::NAN.to_le_bytes());
    let e = vxl::decode(&vxl_v2(dense, &p)).unwrap_err().to_string();
    assert!(e.contains("NaN"), "{e}");
    let sparse = serde_json::json!({"kind": "sparse-distance", "dims": [1, 1, 2],
        "origin": [0.0, 0.0, 0.0], "voxel_size": 1.0, "layout": "bricks8-f32le", "bricks": 0});
    let e = vxl::decode(&vxl_v2(sparse, &f32::NAN.to_le_bytes()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("NaN"), "{e}");
}

/// A distance volume as `.npy` is `<f4`, shape (X, Y, Z), C order: every voxel of a sparse one
/// (bricks, tiles, background) at `((x·Y + y)·Z + z)·4` after the header, read here by that
/// offset against `get`; `.raw` is the same bytes without the header; a dense one reads back.
#[test]
fn distance_volumes_are_float32_arrays_in_npy_and_raw() {
    use voxd::volume::{Dense, Sparse};
    let g = Grid {
        origin: [0.5, -1.0, 2.0],
        voxel_size: 0.25,
        dims: [19, 9, 17],
    };
    let mut s = Sparse::with_tile_value(g, 0.75f32, -0.75);
    s.set(1, 8, 16, -0.5);
    s.set(18, 0, 3, -0.0);
    s.set(9, 2, 10, 0.125);
    s.set_tile([1, 0, 0], true).unwrap();
    s.set_tile([2, 1, 2], true).unwrap();
    let vol = Volume::SparseDistance(s.clone());
    let n = npy::encode(&vol);
    let hl = u16::from_le_bytes([n[8], n[9]]) as usize;
    let header = std::str::from_utf8(&n[10..10 + hl]).unwrap();
    assert!(
        header.contains("'descr': '<f4'") && header.contains("(19, 9, 17)"),
        "{header}"
    );
    let data = &n[10 + hl..];
    assert_eq!(data.len(), 19 * 9 * 17 * 4);
    assert_eq!(VolumeFormat::Npy.encoded_len(&vol), Some(n.len() as u64));
    for x in 0..19u32 {
        for y in 0..9u32 {
            for z in 0..17u32 {
                let at = (((x * 9 + y) * 17 + z) * 4) as usize;
                let v = f32::from_le_bytes(data[at..at + 4].try_into().unwrap());
                assert_eq!(v.to_bits(), s.get(x, y, z).to_bits(), "({x}, {y}, {z})");
            }
        }
    }
    // Spot checks that do not go through `get`: a tile's voxel, the background, a brick's.
    let f = |x: usize, y: usize, z: usize| {
        let at = ((x * 9 + y) * 17 + z) * 4;
        f32::from_le_bytes(data[at..at + 4].try_into().unwrap())
    };
    assert_eq!((f(9, 0, 0), f(0, 0, 0), f(1, 8, 16)), (-0.75, 0.75, -0.5));
    assert_eq!(f(18, 0, 3).to_bits(), (-0.0f32).to_bits());
    let mut raw = vec![];
    VolumeFormat::Raw.write(&vol, &mut raw).unwrap();
    assert_eq!(raw, data);
    // Dense distances read back as themselves.
    let d: Dense<f32> = s.to_dense();
    let dv = Volume::Distance(d.clone());
    let Volume::Distance(back) = npy::decode(&npy::encode(&dv)).unwrap() else {
        panic!("npy kind")
    };
    assert_eq!(back.data(), d.data());
    assert_eq!(&npy::encode(&dv), &n);
}
