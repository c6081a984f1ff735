//! Property tests (proptest) of the codecs' round trips: random volumes of random dims (1..40
//! per axis) on random grids through every format that reads back, compared exactly where the
//! format keeps a thing and as documented where it does not (npy keeps no grid, binvox is cubic
//! and stores the cube's edge rather than the voxel size); and the sparse brick layout against
//! the dense one, for every voxel type. proptest draws the cases (dims, grid, seed, fill
//! probability); the voxels come from the tests' one generator, `common::Rng`.

use proptest::prelude::*;

use crate::common::Rng;
use voxd::codec::{binvox, npy, vxl};
use voxd::grid::Grid;
use voxd::volume::{
    Attributed, BitVolume, ChannelValues, Dense, DensityVolume, Sparse, Volume, Voxel,
};

/// Cases per property: enough to vary dims, grids and fill, few enough to stay fast.
fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 64,
        ..ProptestConfig::default()
    }
}

fn dims() -> impl Strategy<Value = [u32; 3]> {
    [1u32..=40, 1u32..=40, 1u32..=40]
}

/// Any grid a voxelization could give: origins of either sign over many magnitudes, voxel
/// sizes from 1e-6 to 1e3, each an arbitrary f64 in its range (not a round number).
fn grid(dims: impl Strategy<Value = [u32; 3]>) -> impl Strategy<Value = Grid> {
    (
        [-1e6f64..1e6, -1e3f64..1e3, -1.0f64..1.0],
        -6.0f64..3.0,
        dims,
    )
        .prop_map(|(origin, log_size, dims)| Grid {
            origin,
            voxel_size: 10f64.powf(log_size),
            dims,
        })
}

/// `n` draws from `seed`: with probability `p` a value in 0..256, else `u64::MAX` (background).
fn fill(seed: u64, p: f64, n: usize) -> impl Iterator<Item = u64> {
    let mut rng = Rng::new(seed);
    (0..n).map(move |_| {
        if rng.range(0.0, 1.0) < p {
            rng.next() & 0xff
        } else {
            u64::MAX
        }
    })
}

/// A bit volume on `grid` with each voxel set with probability `p`, drawn from `seed`.
fn bits(grid: Grid, seed: u64, p: f64) -> BitVolume {
    let [x, y, z] = grid.dims;
    let mut v = BitVolume::new(grid);
    let mut rng = Rng::new(seed);
    for i in 0..x {
        for j in 0..y {
            for k in 0..z {
                if rng.range(0.0, 1.0) < p {
                    v.set(i, j, k, true);
                }
            }
        }
    }
    v
}

/// A density volume on `grid` with maximum `max`: each voxel, with probability `p`, a value in
/// 1..=max drawn from `seed`, else 0.
fn density(grid: Grid, max: u8, seed: u64, p: f64) -> DensityVolume {
    let [x, y, z] = grid.dims;
    let mut v = DensityVolume::new(grid, max);
    let mut rng = Rng::new(seed);
    for i in 0..x {
        for j in 0..y {
            for k in 0..z {
                if rng.range(0.0, 1.0) < p {
                    v.set(i, j, k, (rng.below(max as u64) + 1) as u8);
                }
            }
        }
    }
    v
}

fn bits_volume() -> impl Strategy<Value = BitVolume> {
    (grid(dims()), any::<u64>(), 0.0f64..=1.0).prop_map(|(g, s, p)| bits(g, s, p))
}

proptest! {
    #![proptest_config(config())]

    /// vxl keeps everything: bits, dims, origin and voxel size, bit for bit.
    #[test]
    fn bits_through_vxl(v in bits_volume()) {
        let vol = Volume::Bits(v);
        let (back, _) = vxl::decode(&vxl::encode(&vol, &Default::default()).unwrap()).unwrap();
        prop_assert_eq!(back.grid(), vol.grid());
        prop_assert_eq!(back, vol);
    }

    /// npy keeps the bits and dims; the grid comes back as origin 0, voxel size 1.
    #[test]
    fn bits_through_npy(v in bits_volume()) {
        let Volume::Bits(b) = npy::decode(&npy::encode(&Volume::Bits(v.clone()))).unwrap() else {
            panic!("0/1 data reads back as bits");
        };
        prop_assert_eq!(b.grid(), &Grid { origin: [0.0; 3], voxel_size: 1.0, dims: v.dims() });
        prop_assert_eq!(b.words(), v.words());
    }

    /// binvox on a cube keeps the bits and the origin exactly; the voxel size comes back as
    /// the stored edge length over n, within a few ulps.
    #[test]
    fn cubic_bits_through_binvox(
        g in grid((1u32..=40).prop_map(|n| [n; 3])),
        seed in any::<u64>(),
        p in 0.0f64..=1.0,
    ) {
        let v = bits(g, seed, p);
        let back = binvox::decode(&binvox::encode(&Volume::Bits(v.clone())).unwrap()).unwrap();
        prop_assert_eq!(back.dims(), v.dims());
        prop_assert_eq!(back.grid().origin, v.grid().origin);
        let (a, b) = (back.grid().voxel_size, v.grid().voxel_size);
        prop_assert!((a - b).abs() <= 4.0 * f64::EPSILON * b, "{} vs {}", a, b);
        prop_assert_eq!(back.words(), v.words());
    }

    /// binvox pads any other grid on its high sides to a cube of the longest axis: the bits
    /// are where they were and nothing is set in the padding.
    #[test]
    fn other_bits_through_binvox_are_padded(v in bits_volume()) {
        let back = binvox::decode(&binvox::encode(&Volume::Bits(v.clone())).unwrap()).unwrap();
        let n = *v.dims().iter().max().unwrap();
        prop_assert_eq!(back.dims(), [n; 3]);
        prop_assert_eq!(back.grid().origin, v.grid().origin);
        prop_assert_eq!(back.count_ones(), v.count_ones());
        prop_assert!(v.iter_ones().all(|p| back.get(p[0], p[1], p[2])));
    }

    /// Density volumes (maximum 8 or 64) through vxl: values, maximum and grid exactly.
    #[test]
    fn density_through_vxl(
        g in grid(dims()),
        max in prop_oneof![Just(8u8), Just(64u8)],
        seed in any::<u64>(),
        p in 0.0f64..=1.0,
    ) {
        let vol = Volume::Density(density(g, max, seed, p));
        let (back, _) = vxl::decode(&vxl::encode(&vol, &Default::default()).unwrap()).unwrap();
        prop_assert_eq!(back, vol);
    }

    /// Density volumes through npy: the values come back (as a density volume with maximum 8,
    /// or 64 once a value is over 8; as bits when every value is 0 or 1), on origin 0, size 1.
    #[test]
    fn density_through_npy(
        g in grid(dims()),
        max in prop_oneof![Just(8u8), Just(64u8)],
        seed in any::<u64>(),
        p in 0.0f64..=1.0,
    ) {
        let d = density(g, max, seed, p);
        let back = npy::decode(&npy::encode(&Volume::Density(d.clone()))).unwrap();
        prop_assert_eq!(back.grid(), &Grid { origin: [0.0; 3], voxel_size: 1.0, dims: d.grid().dims });
        let top = d.data().iter().copied().max().unwrap();
        match back {
            Volume::Density(b) => {
                prop_assert!(top > 1);
                prop_assert_eq!(b.max(), if top <= 8 { 8 } else { 64 });
                prop_assert_eq!(b.data(), d.data());
            }
            other => {
                let Volume::Bits(b) = other else { panic!("npy decodes to bits or density") };
                prop_assert!(top <= 1);
                let [x, y, z] = d.grid().dims;
                for i in 0..x {
                    for j in 0..y {
                        for k in 0..z {
                            prop_assert_eq!(b.get(i, j, k), d.get(i, j, k) == 1);
                        }
                    }
                }
            }
        }
    }
}

/// A dense volume of `T` from a seed: each voxel `background` with probability 1 − p, else a
/// value `pick` makes from the random word.
fn dense_of<T: Voxel>(
    grid: Grid,
    seed: u64,
    p: f64,
    background: T,
    pick: impl Fn(u64) -> T,
) -> Dense<T> {
    let n = grid.voxel_count() as usize;
    let data = fill(seed, p, n)
        .map(|r| if r == u64::MAX { background } else { pick(r) })
        .collect();
    Dense::from_data(grid, data).unwrap()
}

/// Dense → sparse → dense is the identity, the sparse volume has a brick exactly where the
/// dense one differs from the background, and it survives `.vxl` (as `wrap` makes it a volume).
fn sparse_round_trip<T: Voxel>(
    d: &Dense<T>,
    background: T,
    wrap: impl Fn(Sparse<T>) -> Volume,
) -> Result<(), TestCaseError> {
    let s = Sparse::from_dense(d, background);
    prop_assert_eq!(&s.to_dense(), d);
    let [nx, ny, nz] = d.dims();
    let mut differing = std::collections::BTreeSet::new();
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                prop_assert_eq!(s.get(x, y, z), d.get(x, y, z));
                if d.get(x, y, z) != background {
                    differing.insert([x / 8, y / 8, z / 8]);
                }
            }
        }
    }
    let bricks: std::collections::BTreeSet<[u32; 3]> = s.bricks().map(|(at, _)| at).collect();
    prop_assert_eq!(bricks, differing);
    prop_assert_eq!(s.count_occupied(), d.count_occupied());
    let vol = wrap(s);
    let (back, _) = vxl::decode(&vxl::encode(&vol, &Default::default()).unwrap()).unwrap();
    prop_assert_eq!(back, vol);
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    /// Narrow-band distances (`Sparse<f32>`, background +∞ or a band width): through bricks and
    /// `.vxl` and back.
    #[test]
    fn sparse_distances_round_trip(
        g in grid(dims()),
        seed in any::<u64>(),
        p in 0.0f64..=0.3,
        band in prop_oneof![Just(f32::INFINITY), Just(3.0f32)],
    ) {
        let d = dense_of(g, seed, p, band, |r| (r as f32 - 128.0) / 16.0);
        sparse_round_trip(&d, band, Volume::SparseDistance)?;
        let vol = Volume::Distance(d);
        let (back, _) = vxl::decode(&vxl::encode(&vol, &Default::default()).unwrap()).unwrap();
        prop_assert_eq!(back, vol);
    }

    /// Material ids and colours, sparse and dense, through `.vxl`.
    #[test]
    fn sparse_materials_and_colours_round_trip(
        g in grid(dims()),
        seed in any::<u64>(),
        p in 0.0f64..=1.0,
    ) {
        let m = dense_of(g, seed, p, 0u16, |r| r as u16 * 257);
        sparse_round_trip(&m, 0, Volume::SparseMaterial)?;
        let c = dense_of(g, seed ^ 1, p, [0u8; 4], |r| [r as u8, 1, 2, 255 - r as u8]);
        sparse_round_trip(&c, [0; 4], Volume::SparseColour)?;
        for vol in [Volume::Material(m), Volume::Colour(c)] {
            let (back, _) =
                vxl::decode(&vxl::encode(&vol, &Default::default()).unwrap()).unwrap();
            prop_assert_eq!(back, vol);
        }
    }

    /// Bit volumes with attribute channels: the bits and every channel come back.
    #[test]
    fn channels_round_trip(v in bits_volume(), seed in any::<u64>()) {
        let n = v.count_ones() as usize;
        let mut a = Attributed::new(v);
        let ids: Vec<u16> = fill(seed, 1.0, n).map(|r| r as u16).collect();
        let d: Vec<f32> = fill(seed ^ 7, 1.0, n).map(|r| r as f32 / 8.0).collect();
        a.add("material", ChannelValues::U16(ids)).unwrap();
        a.add("distance", ChannelValues::F32(d)).unwrap();
        let vol = Volume::Channels(a);
        let (back, _) = vxl::decode(&vxl::encode(&vol, &Default::default()).unwrap()).unwrap();
        prop_assert_eq!(back, vol);
    }
}
