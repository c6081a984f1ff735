use super::*;
use crate::mesh::Material;
use crate::mesh::texture::{Filter, TextureRef, Wrap};

fn grid(dims: [u32; 3]) -> Grid {
    Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims,
    }
}

fn white(name: &str) -> Material {
    Material {
        name: name.into(),
        base_color: [1.0; 4],
        texture: None,
    }
}

/// One big triangle in the plane z = 2.5 with a colour per corner: a voxel whose square lies
/// wholly inside it has the colour interpolated at the square's centre (the mean of a linear
/// function over a square), whatever the clipping did.
#[test]
fn vertex_colours_interpolate_to_the_voxels_centre() {
    let p = vec![[0.0, 0.0, 2.5], [20.0, 0.0, 2.5], [0.0, 20.0, 2.5]];
    let c = [
        [1.0, 0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0, 0.5],
        [0.0, 0.0, 1.0, 1.0],
    ];
    let mesh = Mesh::new(p.clone(), vec![[0, 1, 2]])
        .unwrap()
        .with_attributes(Attributes {
            colors: Some(c.to_vec()),
            ..Default::default()
        })
        .unwrap();
    let g = grid([20, 20, 5]);
    let want = Want {
        colour: true,
        material: false,
    };
    let s = surface(&mesh, &g, want, &Control::none()).unwrap();
    for v in [[3u32, 4, 2], [10, 2, 2], [0, 0, 2], [7, 11, 2]] {
        let i = s.keys.binary_search(&key(v, g.dims)).unwrap();
        // Barycentric weights of the square's centre.
        let (x, y) = (f64::from(v[0]) + 0.5, f64::from(v[1]) + 0.5);
        let w = [1.0 - x / 20.0 - y / 20.0, x / 20.0, y / 20.0];
        for (k, got) in s.rgba[i].iter().enumerate() {
            let got = *got;
            let want: f64 = (0..3).map(|j| w[j] * c[j][k] as f64).sum();
            assert!(
                (f64::from(got) - want).abs() < 1e-6,
                "voxel {v:?} channel {k}: {got} vs {want}"
            );
        }
    }
    // A voxel the diagonal edge cuts: the mean over the part inside, not the centre's value.
    let v = [10u32, 9, 2];
    let i = s.keys.binary_search(&key(v, g.dims)).unwrap();
    // The part x + y <= 20 of [10, 11] x [9, 10]: the triangle (10, 9), (11, 9), (10, 10)
    // plus nothing else; its centroid (10 1/3, 9 1/3).
    let x = 10.0 + 1.0 / 3.0;
    let want = x / 20.0; // green weight
    assert!((f64::from(s.rgba[i][1]) - want).abs() < 1e-6);
    // Exactly the voxels the triangle crosses with positive area: x + y < 20 inside the grid.
    assert_eq!(
        s.keys.len(),
        (0..20u32).map(|x| 20 - x).sum::<u32>() as usize
    );
}

/// The material of a voxel is the one with the most area in it; ties go to the lower id.
#[test]
fn material_is_the_largest_area_with_ties_to_the_lowest_id() {
    // Two triangles in z = 0.5 splitting the voxel [0, 1]² along x = 0.3 / 0.5.
    let p = vec![
        [0.0, 0.0, 0.5],
        [0.3, 0.0, 0.5],
        [0.3, 1.0, 0.5],
        [0.0, 1.0, 0.5],
        [1.0, 0.0, 0.5],
        [1.0, 1.0, 0.5],
    ];
    let t = vec![[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]];
    let make = |ids: Vec<u16>| {
        let mut a = Attributes {
            materials: vec![white("a"), white("b"), white("c")],
            material: Some(ids),
            ..Default::default()
        };
        a.materials[1].base_color = [0.0, 0.0, 0.0, 1.0];
        Mesh::new(p.clone(), t.clone())
            .unwrap()
            .with_attributes(a)
            .unwrap()
    };
    let want = Want {
        colour: true,
        material: true,
    };
    let g = grid([1, 1, 1]);
    // 0.3 of the area is material 2, 0.7 material 1 (black).
    let s = surface(&make(vec![2, 2, 1, 1]), &g, want, &Control::none()).unwrap();
    assert_eq!(s.material, vec![1]);
    assert!((f64::from(s.rgba[0][0]) - 0.3).abs() < 1e-6);
    assert!((f64::from(s.rgba[0][3]) - 1.0).abs() < 1e-6);
    // Half and half (x = 0.5): the lower id wins.
    let mut p2 = p.clone();
    p2[1][0] = 0.5;
    p2[2][0] = 0.5;
    let m = Mesh::new(p2, t.clone())
        .unwrap()
        .with_attributes(make(vec![2, 2, 1, 1]).attributes().clone())
        .unwrap();
    let s = surface(&m, &g, want, &Control::none()).unwrap();
    assert_eq!(s.material, vec![1]);
    let m = m.with_attributes(Attributes {
        material: Some(vec![1, 1, 2, 2]),
        ..make(vec![0; 4]).attributes().clone()
    });
    assert_eq!(
        surface(&m.unwrap(), &g, want, &Control::none())
            .unwrap()
            .material,
        vec![1]
    );
}

#[test]
fn a_mesh_without_colour_is_refused_clearly() {
    let mesh = Mesh::new(
        vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let colour = Want {
        colour: true,
        material: false,
    };
    let material = Want {
        colour: false,
        material: true,
    };
    let g = grid([2, 2, 2]);
    assert_eq!(
        surface(&mesh, &g, colour, &Control::none()),
        Err(ColourError::NoColour)
    );
    assert_eq!(
        surface(&mesh, &g, material, &Control::none()),
        Err(ColourError::NoMaterials)
    );
}

/// Inside a solid, each voxel takes the nearest wall's colour: a 10³ cube of voxels whose
/// sources are its x = 0 wall (red) and x = 9 wall (blue) splits down the middle.
#[test]
fn interior_voxels_take_the_nearest_surface_voxel() {
    let g = grid([10, 10, 10]);
    let mut bits = BitVolume::new(g);
    for x in 0..10 {
        for y in 0..10 {
            for z in 0..10 {
                bits.set(x, y, z, true);
            }
        }
    }
    let mut keys = vec![];
    for y in 0..10 {
        for z in 0..10 {
            keys.push(key([0, y, z], g.dims));
            keys.push(key([9, y, z], g.dims));
        }
    }
    keys.sort();
    let src = propagate::nearest(&bits, &keys, &Control::none()).unwrap();
    for (r, v) in bits.iter_ones().enumerate() {
        let s = propagate::coords(keys[src[r] as usize], g.dims);
        let d = |a: [u32; 3]| {
            (0..3)
                .map(|k| (a[k] as i64 - v[k] as i64).pow(2))
                .sum::<i64>()
        };
        // The nearest source, by brute force.
        let best = keys
            .iter()
            .map(|&k| d(propagate::coords(k, g.dims)))
            .min()
            .unwrap();
        assert_eq!(d(s), best, "voxel {v:?} took {s:?}");
        assert_eq!(s[0], if v[0] < 5 { 0 } else { 9 });
    }
}

/// A textured quad whose texture is one colour gives that colour exactly (sRGB bytes through
/// linear light and back), in every filter and wrap mode.
#[test]
fn a_uniform_texture_gives_its_colour_exactly() {
    let img = Image::from_rgba(4, 4, vec![[200, 30, 90, 255]; 16]);
    for filter in [Filter::Linear, Filter::Nearest] {
        let p = vec![
            [0.0, 0.0, 0.5],
            [3.0, 0.0, 0.5],
            [3.0, 3.0, 0.5],
            [0.0, 3.0, 0.5],
        ];
        let a = Attributes {
            materials: vec![Material {
                name: "t".into(),
                base_color: [1.0; 4],
                texture: Some(TextureRef {
                    image: 0,
                    wrap: [Wrap::Repeat; 2],
                    filter,
                }),
            }],
            material: Some(vec![0, 0]),
            uv: Some(crate::mesh::Uv::Corners(vec![
                [[0.0, 0.0], [5.0, 0.0], [5.0, 5.0]],
                [[0.0, 0.0], [5.0, 5.0], [0.0, 5.0]],
            ])),
            images: vec![img.clone()],
            ..Default::default()
        };
        let mesh = Mesh::new(p, vec![[0, 1, 2], [0, 2, 3]])
            .unwrap()
            .with_attributes(a)
            .unwrap();
        let mut bits = BitVolume::new(grid([3, 3, 1]));
        for x in 0..3 {
            for y in 0..3 {
                bits.set(x, y, 0, true);
            }
        }
        let want = Want {
            colour: true,
            material: true,
        };
        let out = attribute(&mesh, bits, want, &Control::none()).unwrap();
        let ChannelValues::Rgba8(c) = &out.channel(RGBA).unwrap().values else {
            panic!()
        };
        assert_eq!(c, &vec![[200, 30, 90, 255]; 9]);
    }
}

#[test]
fn sub_triangles_tile_the_triangle() {
    for n in [1u32, 2, 4, 8] {
        let mut pts = vec![];
        sub_centroids(n, |s, r| pts.push((s, r)));
        assert_eq!(pts.len() as u32, n * n);
        // The mean of the centroids of equal parts is the whole's centroid.
        let m = pts.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
        let k = f64::from(n * n);
        assert!((m.0 / k - 1.0 / 3.0).abs() < 1e-12 && (m.1 / k - 1.0 / 3.0).abs() < 1e-12);
        assert!(pts.iter().all(|&(s, r)| s > 0.0 && r > 0.0 && s + r < 1.0));
    }
}

/// A random bit volume on `dims` and sorted source keys: each voxel set when `set(rng)`, and a
/// source when `source(rng, set)`.
fn random_sources(
    rng: &mut crate::testkit::Rng,
    dims: [u32; 3],
    set: impl Fn(&mut crate::testkit::Rng) -> bool,
    source: impl Fn(&mut crate::testkit::Rng, bool) -> bool,
) -> (BitVolume, Vec<u64>) {
    let mut bits = BitVolume::new(grid(dims));
    let mut keys = vec![];
    for x in 0..dims[0] {
        for y in 0..dims[1] {
            for z in 0..dims[2] {
                let on = set(rng);
                bits.set(x, y, z, on);
                if source(rng, on) {
                    keys.push(key([x, y, z], dims));
                }
            }
        }
    }
    (bits, keys)
}

/// The nearest source by brute force: least squared distance, ties by the lowest key.
fn brute_nearest(v: [u32; 3], keys: &[u64], dims: [u32; 3]) -> usize {
    let d2 = |k: u64| {
        let s = propagate::coords(k, dims);
        (0..3)
            .map(|a| (i64::from(s[a]) - i64::from(v[a])).pow(2))
            .sum::<i64>()
    };
    (0..keys.len())
        .min_by_key(|&i| (d2(keys[i]), keys[i]))
        .expect("a source")
}

/// The feature transform's tie rule, against brute force: on small grids with few sources many
/// voxels are equally near several, and each must get the lowest key among them.
#[test]
fn the_transform_breaks_ties_by_the_lowest_key() {
    let mut rng = crate::testkit::Rng::new(341);
    let mut ties = 0;
    for i in 0..80 {
        let mut dims = [0; 3].map(|_| 2 + rng.below(10) as u32);
        if i >= 60 {
            // y and z lines over several of the passes' tiles of 16, the last one short.
            dims[1] = 17 + rng.below(30) as u32;
            dims[2] = 17 + rng.below(30) as u32;
        }
        let (bits, keys) =
            random_sources(&mut rng, dims, |r| r.below(3) > 0, |r, _| r.below(12) == 0);
        if keys.is_empty() {
            continue;
        }
        let got = propagate::transform(&bits, &keys, &Control::none()).unwrap();
        for (r, v) in bits.iter_ones().enumerate() {
            let want = brute_nearest(v, &keys, dims);
            assert_eq!(got[r] as usize, want, "voxel {v:?} of {dims:?}");
            // Count the voxels where the rule had to choose.
            let d2 = |k: u64| {
                let s = propagate::coords(k, dims);
                (0..3)
                    .map(|a| (i64::from(s[a]) - i64::from(v[a])).pow(2))
                    .sum::<i64>()
            };
            let best = d2(keys[want]);
            ties += usize::from(keys.iter().filter(|&&k| d2(k) == best).count() > 1);
        }
    }
    assert!(
        ties > 1000,
        "only {ties} tied voxels: the test does not test ties"
    );
}

/// The direct lookup used when nearly every set voxel is a source gives the transform's answer
/// (and brute force's); it declines when a voxel has no source within its radius or too many
/// voxels are not sources, and `nearest` is then the transform's.
#[test]
fn the_local_lookup_equals_the_transform() {
    let mut rng = crate::testkit::Rng::new(342);
    let mut looked_up = 0;
    for round in 0..40 {
        let dims = [0; 3].map(|_| 3 + rng.below(14) as u32);
        // Sources: the set voxels but a few, and a few unset voxels.
        let (bits, keys) = random_sources(
            &mut rng,
            dims,
            |r| r.below(4) == 0,
            |r, set| {
                if set {
                    r.below(40) > 0
                } else {
                    r.below(30) == 0
                }
            },
        );
        if keys.is_empty() {
            continue;
        }
        let radius = 1 + (round % 4) as u32;
        let want = propagate::transform(&bits, &keys, &Control::none()).unwrap();
        if let Some(got) = propagate::local(&bits, &keys, radius, &Control::none()).unwrap() {
            assert_eq!(got, want, "{dims:?}, radius {radius}");
            looked_up += got
                .iter()
                .zip(bits.iter_ones())
                .filter(|&(&s, v)| keys[s as usize] != key(v, dims))
                .count();
        }
        let all = propagate::nearest(&bits, &keys, &Control::none()).unwrap();
        assert_eq!(all, want);
        for (r, v) in bits.iter_ones().enumerate() {
            assert_eq!(want[r] as usize, brute_nearest(v, &keys, dims), "{v:?}");
        }
    }
    assert!(looked_up > 100, "only {looked_up} voxels were looked up");
    // A set voxel with no source within the radius: declined.
    let g = grid([20, 20, 20]);
    let mut bits = BitVolume::new(g);
    bits.set(0, 0, 0, true);
    bits.set(19, 19, 19, true);
    let keys = vec![0];
    assert_eq!(
        propagate::local(&bits, &keys, 6, &Control::none()).unwrap(),
        None
    );
    assert_eq!(
        propagate::nearest(&bits, &keys, &Control::none()).unwrap(),
        vec![0, 0]
    );
    // Most set voxels not sources: declined.
    for x in 0..20 {
        for y in 0..20 {
            for z in 0..20 {
                bits.set(x, y, z, true);
            }
        }
    }
    assert_eq!(
        propagate::local(&bits, &keys, 40, &Control::none()).unwrap(),
        None
    );
}
