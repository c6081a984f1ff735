//! Point and ray queries: exact cases on a box, and random rays against a fine-stepping march.

use crate::common::*;
use voxd::grid::Grid;
use voxd::volume::query::{point_value, ray};
use voxd::volume::{BitVolume, Volume, VoxelValue};

fn box_volume() -> Volume {
    let mut v = BitVolume::new(Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims: [8, 8, 8],
    });
    for x in 2..6 {
        for y in 2..6 {
            for z in 2..6 {
                v.set(x, y, z, true);
            }
        }
    }
    Volume::Bits(v)
}

#[test]
fn axis_rays_through_a_box() {
    let v = box_volume();
    let h = ray(&v, [-1.0, 3.5, 3.5], [2.0, 0.0, 0.0]).unwrap();
    assert_eq!(
        (h.solid_voxels, h.entry, h.exit, h.thickness),
        (4, Some(3.0), Some(7.0), 4.0)
    );
    let h = ray(&v, [3.5, 3.5, 20.0], [0.0, 0.0, -1.0]).unwrap();
    assert_eq!(
        (h.solid_voxels, h.entry, h.exit, h.thickness),
        (4, Some(14.0), Some(18.0), 4.0)
    );
    let miss = ray(&v, [-1.0, 0.5, 0.5], [1.0, 0.0, 0.0]).unwrap();
    assert_eq!((miss.solid_voxels, miss.entry), (0, None));
    let away = ray(&v, [-1.0, 3.5, 3.5], [-1.0, 0.0, 0.0]).unwrap();
    assert_eq!(away.solid_voxels, 0);
    assert!(ray(&v, [0.0; 3], [0.0; 3]).is_none());
    // Any finite non-zero direction is one: its squared length may overflow or vanish.
    for s in [1e300, -1e300, f64::MAX, 1e-300, f64::MIN_POSITIVE, 5e-324] {
        let h = ray(&v, [3.5, 3.5, 20.0], [0.0, 0.0, -s]).unwrap();
        let want = if s > 0.0 { 4 } else { 0 };
        assert_eq!(h.solid_voxels, want, "direction {s:e}");
    }
    // Starting inside the box.
    let h = ray(&v, [3.5, 3.5, 3.5], [1.0, 0.0, 0.0]).unwrap();
    assert_eq!(
        (h.solid_voxels, h.entry, h.exit, h.thickness),
        (3, Some(0.0), Some(2.5), 2.5)
    );
}

#[test]
fn random_rays_match_a_fine_march_and_points_match_indexing() {
    for seed in 0..30u64 {
        let mut rng = Rng::new(40 + seed);
        let g = Grid {
            origin: [rng.range(-2.0, 2.0), 1.0, -1.5],
            voxel_size: rng.range(0.3, 1.7),
            dims: [
                1 + rng.below(7) as u32,
                1 + rng.below(7) as u32,
                1 + rng.below(70) as u32,
            ],
        };
        let bits = random_fill(&mut rng, g);
        let v = Volume::Bits(bits.clone());
        let c = [0, 1, 2].map(|a| g.origin[a] + g.dims[a] as f64 * g.voxel_size / 2.0);
        for _ in 0..20 {
            let o = [0, 1, 2].map(|a| c[a] + rng.range(-60.0, 60.0));
            let dir = [0, 1, 2].map(|a| c[a] + rng.range(-1.0, 1.0) - o[a]);
            let h = ray(&v, o, dir).unwrap();
            // March in tiny steps, summing the length in solid voxels.
            let len = dir.iter().map(|x| x * x).sum::<f64>().sqrt();
            let step = g.voxel_size * 1e-3;
            let (mut thick, mut t) = (0.0, 0.0);
            let mut seen = std::collections::HashSet::new();
            while t < 200.0 {
                let p = [0, 1, 2].map(|a| o[a] + (t + step / 2.0) * dir[a] / len);
                if point_value(&v, p).0 {
                    thick += step;
                    seen.insert(
                        [0, 1, 2].map(|a| ((p[a] - g.origin[a]) / g.voxel_size).floor() as i64),
                    );
                }
                t += step;
            }
            assert!(
                (h.thickness - thick).abs() < 4.0 * step * (g.dims.iter().sum::<u32>() as f64),
                "seed {seed}: {} vs {thick}",
                h.thickness
            );
            assert!(
                h.solid_voxels >= seen.len() as u64 && h.solid_voxels <= seen.len() as u64 + 3,
                "seed {seed}: {} vs {}",
                h.solid_voxels,
                seen.len()
            );
        }
        for _ in 0..50 {
            let p = [0, 1, 2]
                .map(|a| g.origin[a] + rng.range(-1.0, g.dims[a] as f64 + 1.0) * g.voxel_size);
            let i = [0, 1, 2].map(|a| ((p[a] - g.origin[a]) / g.voxel_size).floor());
            let inside = (0..3).all(|a| i[a] >= 0.0 && i[a] < g.dims[a] as f64);
            let want = inside && bits.get(i[0] as u32, i[1] as u32, i[2] as u32);
            assert_eq!(point_value(&v, p), (want, VoxelValue::U8(want as u8)));
        }
    }
}

/// A point query answers in the voxel's own type (a distance as a number, a colour as four), and
/// an operation given a kind it does not take says `wrong-volume-kind`, naming both kinds.
#[test]
fn values_come_in_their_own_type_and_other_kinds_are_refused_by_name() {
    use voxd::app::{ErrorKind, PreviewRequest, PreviewView, QueryRequest, ops};
    use voxd::volume::Dense;
    let g = Grid {
        origin: [0.0; 3],
        voxel_size: 1.0,
        dims: [2, 2, 2],
    };
    let mut d = Dense::new(g, 1.5f32);
    d.set(1, 1, 1, -0.25);
    let v = Volume::Distance(d);
    let limits = voxd::limits::Limits::LOCAL;
    let q = QueryRequest {
        points: vec![[1.5, 1.5, 1.5], [0.5, 0.5, 0.5], [9.0, 0.0, 0.0]],
        rays: vec![],
    };
    let a = serde_json::to_value(ops::query(&v, &q, &limits).unwrap()).unwrap();
    assert_eq!(
        a["points"],
        serde_json::json!([
            // A dense distance volume reads +∞ outside the grid: no interpolation where a
            // sample is infinite (beside the top face), a flat field's value and zero gradient
            // at the first centre.
            {"inside": true, "value": -0.25},
            {"inside": false, "value": 1.5, "distance": 1.5, "gradient": [0.0, 0.0, 0.0]},
            {"inside": false, "value": null}
        ])
    );
    let mut colour = Dense::new(g, [0u8; 4]);
    colour.set(0, 0, 0, [10, 20, 30, 255]);
    let a = ops::query(&Volume::Colour(colour), &q, &limits).unwrap();
    assert_eq!(a.points[1].value, VoxelValue::Rgba8([10, 20, 30, 255]));
    let req = PreviewRequest {
        axis: 2,
        view: PreviewView::Slice(0),
    };
    let e = ops::preview_png(&v, &req, &limits).unwrap_err();
    assert_eq!(e.kind, ErrorKind::WrongVolumeKind);
    assert!(
        e.detail.contains("a distance volume") && e.detail.contains("density volumes"),
        "{}",
        e.detail
    );
    let e = ops::require_bits(v, "CSG").unwrap_err();
    assert_eq!(e.kind, ErrorKind::WrongVolumeKind);
    assert!(
        e.detail.contains("CSG works on bit volumes"),
        "{}",
        e.detail
    );
}
