//! Whole fills: blocks decided as wholes against every voxel decided one by one, and the
//! super-blocks' intervals against the exact caps' winding number at their voxels.
//!
//! Not here: the fill against the other fills and real meshes (`tests/fill.rs`).

use super::*;

#[test]
fn blocks_decide_as_voxel_by_voxel_evaluation_does() {
    // The meshes fill the first grid; in the second they lie among `SUPER`³ blocks of
    // blocks, which the caps' interval decides whole.
    let grids = [
        Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [32, 31, 33],
        },
        SUPER_GRID,
    ];
    let mut total = WindingStats::default();
    let cases = grids
        .iter()
        .flat_map(|&g| holey_meshes().into_iter().map(move |m| (g, m)));
    for (i, (grid, mesh)) in cases.enumerate() {
        let (a, sa) = solid_impl(&mesh, &grid, &Control::none(), true, false).unwrap();
        let (b, sb) = solid_impl(&mesh, &grid, &Control::none(), false, false).unwrap();
        assert_eq!(sa.voxels(), grid.voxel_count());
        assert_eq!(sb.voxels(), grid.voxel_count());
        assert_eq!(sb.cap_block_voxels + sb.mesh_block_voxels, 0);
        let tris: Vec<_> = (0..mesh.triangles().len())
            .map(|t| mesh.triangle(t))
            .collect();
        let [nx, ny, nz] = grid.dims;
        let differ: Vec<[u32; 3]> = (0..nx)
            .flat_map(|x| (0..ny).flat_map(move |y| (0..nz).map(move |z| [x, y, z])))
            .filter(|&[x, y, z]| a.get(x, y, z) != b.get(x, y, z))
            .collect();
        for &[x, y, z] in &differ {
            let w = exact_winding_number(tris.iter().copied(), grid.voxel_center(x, y, z));
            assert!(
                (w.abs() - 0.5).abs() <= 0.05,
                "mesh {i}: voxel {:?} differs, w = {w}",
                [x, y, z]
            );
        }
        eprintln!("mesh {i}: {sa:?}; {} differ", differ.len());
        assert_eq!(sb.near_evaluated_voxels, 0);
        total.cap_block_voxels += sa.cap_block_voxels;
        total.mesh_block_voxels += sa.mesh_block_voxels;
        total.cap_evaluated_voxels += sa.cap_evaluated_voxels;
        total.near_evaluated_voxels += sa.near_evaluated_voxels;
    }
    assert!(
        total.cap_block_voxels > 10_000
            && total.mesh_block_voxels > 200
            && total.cap_evaluated_voxels > 100
            && total.near_evaluated_voxels > 1_000,
        "{total:?}"
    );
}

/// Every voxel of a `SUPER`³ block of blocks that the caps' interval decides: the exact sum
/// over the (snapped) caps lies in the interval, and within ½ of the block's k.
#[test]
fn super_block_intervals_hold_every_voxel() {
    let grid = SUPER_GRID;
    let size = SUPER * BLOCK;
    let (mut decided, mut nonzero, mut widest) = (0, 0, 0f64);
    // And a bowl: a hemisphere whose one cap is a disc across the grid's middle.
    let mut meshes = holey_meshes();
    let (p, mut t) = uv_sphere([12.3, 14.1, 8.2], 29.0, 24);
    t.retain(|tri| tri.iter().map(|&v| p[v as usize][2]).sum::<f64>() / 3.0 < 8.2);
    meshes.push(Mesh::new(p, t).unwrap());
    for (i, mesh) in meshes.iter().enumerate() {
        let (closed, caps) = closed_by_caps(mesh);
        let trees = Trees::new(mesh, &closed, &caps, &grid);
        let cert = Certifier::new(&grid, &trees, true);
        let cap_tris: Vec<[[f64; 3]; 3]> = caps
            .iter()
            .map(|t| t.map(|v| snapped_world(&grid, closed.positions()[v as usize])))
            .collect();
        let ns = grid.dims.map(|d| d.div_ceil(size));
        for s in (0..ns[0])
            .flat_map(|x| (0..ns[1]).flat_map(move |y| (0..ns[2]).map(move |z| [x, y, z])))
        {
            let lo = s.map(|v| v * size);
            let interval = cert.super_interval(lo);
            let decision = cert.decide_super(lo);
            let Some(Decision::Ne(k, _)) = decision else {
                assert!(decision.is_none(), "mesh {i} block {s:?}: only Ne is made");
                continue;
            };
            let (v, e, crude) = interval.expect("a decision comes from an interval");
            decided += 1;
            nonzero += u32::from(crude >= CAP_LIMIT * 4.0 * PI);
            let hi = [0, 1, 2].map(|a| (lo[a] + size).min(grid.dims[a]));
            // The block's faces: off the caps w_caps is harmonic, so its extremes over the
            // block lie there (and the interior is checked by the other tests' blocks).
            let on_face = |p: [u32; 3]| (0..3).any(|a| p[a] == lo[a] || p[a] + 1 == hi[a]);
            for x in lo[0]..hi[0] {
                for y in lo[1]..hi[1] {
                    for z in lo[2]..hi[2] {
                        if !on_face([x, y, z]) {
                            continue;
                        }
                        let q = grid.voxel_center(x, y, z);
                        let w = exact_winding_number(cap_tris.iter().copied(), q);
                        widest = widest.max((w - v).abs());
                        assert!(
                            (w - v).abs() <= e && (w - k as f64).abs() < 0.5,
                            "mesh {i} block {s:?} voxel {:?}: w_caps {w}, interval {v} ± {e}, k {k}",
                            [x, y, z]
                        );
                    }
                }
            }
        }
    }
    eprintln!("{decided} blocks decided, {nonzero} past the crude bound, widest {widest}");
    // Blocks were decided whole, some of them near enough to the caps that the crude bound
    // did not do it, and their caps' winding number varies over them.
    assert!(
        decided > 100 && nonzero > 10 && widest > 0.015,
        "{decided} {nonzero} {widest}"
    );
}
