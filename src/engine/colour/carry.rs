//! Attribute channels through CSG and morphology (`docs/methods.md`, "Colour and material"):
//!
//! * **CSG**: a voxel of the result takes each channel's value from the **first operand, in the
//!   expression's order, that has the voxel set and has the channel** (so where several are set
//!   the first wins: union and intersection take the first operand's, difference the first's,
//!   xor the one operand set there). A voxel no such operand covers (a bit operand's voxel in a
//!   union with a coloured one) gets the channel's `missing` value (`rgba` (0, 0, 0, 0), the
//!   material table's "none" entry). The result's channels are all the operands' channels, in
//!   the order first met. Material ids must index one table: the caller maps each operand's ids
//!   onto the merged table first ([`remap`]).
//! * **Morphology**: a voxel of the result that is set in the source keeps its values; any other
//!   (what a dilation or closing adds) takes those of the **nearest set source voxel**
//!   (Euclidean, centre to centre, ties as the propagation meets them: `propagate.rs`), the same
//!   feature transform that colours a solid's inside.

use super::propagate;
use crate::cancel::{Canceled, Control};
use crate::grid::Grid;
use crate::volume::csg::{self, CsgError, CsgOp};
use crate::volume::{Attributed, BitVolume, ChannelValues};

/// Why attributes could not be carried.
#[derive(Debug, thiserror::Error)]
pub enum CarryError {
    #[error(transparent)]
    Csg(#[from] CsgError),
    #[error(transparent)]
    Canceled(#[from] Canceled),
    #[error("channel {0:?} has different value types in the operands")]
    ChannelTypes(String),
}

/// A channel value for a voxel no operand covers: per channel name.
pub type Missing<'a> = &'a dyn Fn(&str) -> Option<crate::volume::kind::VoxelValue>;

/// `a` with its `material` channel's ids replaced by `map[id]` (ids past `map` unchanged).
pub fn remap(a: &Attributed, channel: &str, map: &[u16]) -> Attributed {
    let mut out = Attributed::new(a.bits().clone());
    for c in a.channels() {
        let values = match (&c.values, c.name == channel) {
            (ChannelValues::U16(v), true) => ChannelValues::U16(
                v.iter()
                    .map(|&id| map.get(usize::from(id)).copied().unwrap_or(id))
                    .collect(),
            ),
            (v, _) => v.clone(),
        };
        out.add(&c.name, values).expect("the same set voxels");
    }
    out
}

/// Per set voxel, the (operand, rank) it takes a channel from, `None` where no operand has it.
type Sources = Vec<Option<(usize, usize)>>;

/// The operand and rank each set voxel of `bits` (on `grid`) takes a channel from, by the rule
/// of the module docs; `None` where no operand with the channel covers it.
fn sources(
    bits: &BitVolume,
    operands: &[&Attributed],
    has: &[bool],
    offsets: &[[i64; 3]],
) -> Sources {
    let mut out = Vec::with_capacity(bits.count_ones() as usize);
    for [x, y, z] in bits.iter_ones() {
        let mut found = None;
        for (i, a) in operands.iter().enumerate() {
            if !has[i] {
                continue;
            }
            let p = [x, y, z].map(i64::from);
            let q = [0, 1, 2].map(|k| p[k] - offsets[i][k]);
            let d = a.bits().dims();
            if (0..3).any(|k| q[k] < 0 || q[k] >= i64::from(d[k])) {
                continue;
            }
            if let Some(r) = a.rank(q[0] as u32, q[1] as u32, q[2] as u32) {
                found = Some((i, r));
                break;
            }
        }
        out.push(found);
    }
    out
}

/// Gathers one channel's values for `n` voxels, voxel k's from `from(k)` (operand, rank),
/// `missing` where none.
fn gather(
    name: &str,
    operands: &[&Attributed],
    n: usize,
    from: impl Fn(usize) -> Option<(usize, usize)>,
    missing: crate::volume::kind::VoxelValue,
) -> ChannelValues {
    use crate::volume::kind::VoxelValue as V;
    let value = |k: &usize| match from(*k) {
        Some((i, r)) => operands[i]
            .channel(name)
            .expect("the operand has the channel")
            .values
            .get(r),
        None => missing,
    };
    let from = 0..n;
    // One arm a value type: the values of that type, in order.
    macro_rules! typed {
        ($($variant:ident),*) => {
            match missing {
                $(V::$variant(_) => ChannelValues::$variant(
                    from.clone()
                        .map(|f| match value(&f) {
                            V::$variant(v) => v,
                            _ => unreachable!("one type a channel"),
                        })
                        .collect(),
                ),)*
            }
        };
    }
    typed!(U8, U16, F32, Rgba8)
}

/// The zero of a value type (the missing value of a channel `missing` does not name).
fn zero(v: &ChannelValues) -> crate::volume::kind::VoxelValue {
    use crate::volume::kind::VoxelValue as V;
    match v {
        ChannelValues::U8(_) => V::U8(0),
        ChannelValues::U16(_) => V::U16(0),
        ChannelValues::F32(_) => V::F32(0.0),
        ChannelValues::Rgba8(_) => V::Rgba8([0; 4]),
    }
}

/// `op` over `operands` (bits as [`csg::apply_with`] combines them) with their channels carried
/// by the module's rule; `missing` gives a channel's value where no operand covers a voxel
/// (zeros where it says nothing).
pub fn csg(
    op: CsgOp,
    operands: &[&Attributed],
    missing: Missing,
    ctl: &Control,
) -> Result<Attributed, CarryError> {
    let bits: Vec<&BitVolume> = operands.iter().map(|a| a.bits()).collect();
    let out = csg::apply_with::<CarryError>(op, &bits, &ctl.stage(0.0, 0.5))?;
    let grid: Grid = *out.grid();
    let offsets: Vec<[i64; 3]> = operands
        .iter()
        .map(|a| {
            grid.offset_to(a.bits().grid())
                .expect("the operands are aligned with the result (apply checked)")
        })
        .collect();
    // Channel names in the order first met, with a value of their type.
    let mut names: Vec<(String, crate::volume::kind::VoxelValue)> = vec![];
    for a in operands {
        for c in a.channels() {
            match names.iter().find(|(n, _)| *n == c.name) {
                Some((_, v))
                    if std::mem::discriminant(v) != std::mem::discriminant(&zero(&c.values)) =>
                {
                    return Err(CarryError::ChannelTypes(c.name.clone()));
                }
                Some(_) => {}
                None => {
                    let m = missing(&c.name)
                        .filter(|m| {
                            std::mem::discriminant(m) == std::mem::discriminant(&zero(&c.values))
                        })
                        .unwrap_or_else(|| zero(&c.values));
                    names.push((c.name.clone(), m));
                }
            }
        }
    }
    let mut result = Attributed::new(out);
    // A channel that the same operands have as the one before shares its sources (rgba and
    // material, mostly): the voxels' lookups are made once. One list is held at a time.
    let mut found: Option<(Vec<bool>, Sources)> = None;
    for (k, (name, m)) in names.iter().enumerate() {
        ctl.check()?;
        ctl.set(0.5 + 0.5 * k as f64 / names.len() as f64);
        let has: Vec<bool> = operands.iter().map(|a| a.channel(name).is_some()).collect();
        if found.as_ref().is_none_or(|(h, _)| *h != has) {
            drop(found.take()); // the previous list freed before the next is made
            let from = sources(result.bits(), operands, &has, &offsets);
            found = Some((has, from));
        }
        let from = &found.as_ref().expect("just set").1;
        let values = gather(name, operands, from.len(), |k| from[k], *m);
        result.add(name, values).expect("one value a set voxel");
    }
    ctl.complete();
    Ok(result)
}

/// The channels of `source` carried onto `result`, a morphology of its bits on an aligned grid
/// that contains the source's (the same grid, or grown), by the module's rule.
pub fn morphology(
    source: &Attributed,
    result: BitVolume,
    ctl: &Control,
) -> Result<Attributed, CarryError> {
    let grid = *result.grid();
    let on_result = csg::regrid(source.bits(), &grid)?;
    debug_assert_eq!(
        on_result.count_ones(),
        source.len(),
        "the result grid holds the source"
    );
    let dims = grid.dims;
    let keys: Vec<u64> = on_result.iter_ones().map(|v| super::key(v, dims)).collect();
    drop(on_result);
    let mut out = Attributed::new(result);
    if keys.is_empty() || out.is_empty() {
        // No source voxel (so no result voxel either): empty channels.
        for c in source.channels() {
            let empty = gather(&c.name, &[source], 0, |_| None, zero(&c.values));
            out.add(&c.name, empty).expect("no set voxels");
        }
        return Ok(out);
    }
    // The source rank of each result voxel's nearest source (keys are in rank order).
    let nearest = propagate::nearest(out.bits(), &keys, ctl)?;
    drop(keys);
    for c in source.channels() {
        let values = gather(
            &c.name,
            &[source],
            nearest.len(),
            |k| Some((0, nearest[k] as usize)),
            zero(&c.values),
        );
        out.add(&c.name, values).expect("one value a set voxel");
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::kind::VoxelValue;
    use crate::volume::morph::{self, Kernel, MorphOp};

    fn grid(origin: [f64; 3], dims: [u32; 3]) -> Grid {
        Grid {
            origin,
            voxel_size: 1.0,
            dims,
        }
    }

    /// A volume with voxels `pts`, each coloured (i, 0, 0, 255) and of material `mat + i`.
    fn coloured(g: Grid, pts: &[[u32; 3]], mat: u16) -> Attributed {
        let mut b = BitVolume::new(g);
        for p in pts {
            b.set(p[0], p[1], p[2], true);
        }
        let mut a = Attributed::new(b);
        // Rank order is column order: sort the points as iter_ones visits them.
        let order: Vec<[u32; 3]> = a.bits().iter_ones().collect();
        let idx = |p: &[u32; 3]| pts.iter().position(|q| q == p).unwrap();
        a.add(
            "rgba",
            ChannelValues::Rgba8(order.iter().map(|p| [idx(p) as u8, 0, 0, 255]).collect()),
        )
        .unwrap();
        a.add(
            "material",
            ChannelValues::U16(order.iter().map(|p| mat + idx(p) as u16).collect()),
        )
        .unwrap();
        a
    }

    /// Union, intersection, difference and xor of two overlapping coloured volumes and a plain
    /// one on shifted aligned grids: each result voxel's values, checked against the rule read
    /// directly (world positions, the first operand set there with the channel).
    #[test]
    fn csg_takes_the_first_operand_set_there() {
        let a = coloured(
            grid([0.0; 3], [4, 4, 4]),
            &[[1, 1, 1], [2, 1, 1], [3, 3, 3]],
            10,
        );
        let b = coloured(
            grid([1.0, 0.0, 0.0], [4, 4, 4]),
            &[[0, 1, 1], [1, 1, 1], [0, 0, 0]],
            20,
        );
        let mut plain = BitVolume::new(grid([2.0, 0.0, 0.0], [3, 3, 3]));
        plain.set(0, 1, 1, true);
        plain.set(2, 2, 2, true);
        let plain = Attributed::new(plain);
        let missing = |n: &str| (n == "material").then_some(VoxelValue::U16(999));
        let world = |a: &Attributed, w: [i64; 3]| {
            let o = a.bits().grid().origin.map(|c| c as i64);
            let q = [0, 1, 2].map(|k| w[k] - o[k]);
            let d = a.bits().dims();
            if (0..3).any(|k| q[k] < 0 || q[k] >= i64::from(d[k])) {
                return None;
            }
            a.rank(q[0] as u32, q[1] as u32, q[2] as u32)
                .map(|_| q.map(|c| c as u32))
        };
        for op in [
            CsgOp::Union,
            CsgOp::Intersection,
            CsgOp::Difference,
            CsgOp::Xor,
        ] {
            for ops in [vec![&a, &b, &plain], vec![&plain, &b, &a], vec![&b, &a]] {
                let r = csg(op, &ops, &missing, &Control::none()).unwrap();
                let bits: Vec<&BitVolume> = ops.iter().map(|o| o.bits()).collect();
                assert_eq!(r.bits(), &csg::apply(op, &bits).unwrap());
                assert_eq!(
                    r.channels()
                        .iter()
                        .map(|c| c.name.as_str())
                        .collect::<Vec<_>>(),
                    ["rgba", "material"]
                );
                let o = r.bits().grid().origin.map(|c| c as i64);
                for [x, y, z] in r.bits().iter_ones() {
                    let w = [
                        i64::from(x) + o[0],
                        i64::from(y) + o[1],
                        i64::from(z) + o[2],
                    ];
                    let want = ops
                        .iter()
                        .find_map(|v| {
                            let q = world(v, w)?;
                            v.channel("rgba")?;
                            Some((
                                v.value("rgba", q[0], q[1], q[2])?,
                                v.value("material", q[0], q[1], q[2])?,
                            ))
                        })
                        .unwrap_or((VoxelValue::Rgba8([0; 4]), VoxelValue::U16(999)));
                    assert_eq!(r.value("rgba", x, y, z), Some(want.0), "{op:?} at {w:?}");
                    assert_eq!(
                        r.value("material", x, y, z),
                        Some(want.1),
                        "{op:?} at {w:?}"
                    );
                }
            }
        }
        // A coloured voxel where the plain operand comes first and both are set: the coloured
        // one's values (the plain one has no channel). World (2, 1, 1) is a's [2,1,1] (index 1);
        // the result's grid starts at a's origin. World (4, 2, 2) is the plain one's alone.
        let r = csg(CsgOp::Union, &[&plain, &a], &missing, &Control::none()).unwrap();
        assert_eq!(r.bits().grid().origin, [0.0; 3]);
        assert_eq!(
            r.value("rgba", 2, 1, 1),
            Some(VoxelValue::Rgba8([1, 0, 0, 255]))
        );
        assert_eq!(r.value("rgba", 4, 2, 2), Some(VoxelValue::Rgba8([0; 4])));
        assert_eq!(r.value("material", 4, 2, 2), Some(VoxelValue::U16(999)));
    }

    /// Dilation (grown), erosion and closing: voxels of the source keep their values, the
    /// others take their nearest source voxel's (checked by brute force; the sources here are
    /// never equally near).
    #[test]
    fn morphology_copies_the_nearest_source_voxel() {
        let pts = [[2, 2, 2], [2, 3, 2], [7, 7, 6], [4, 8, 1]];
        let src = coloured(grid([0.0; 3], [10, 11, 9]), &pts, 0);
        for (op, grow) in [
            (MorphOp::Dilate, true),
            (MorphOp::Dilate, false),
            (MorphOp::Close, true),
            (MorphOp::Erode, false),
        ] {
            let bits = morph::apply(src.bits(), op, 2, Kernel::Sphere, grow);
            let r = morphology(&src, bits, &Control::none()).unwrap();
            let o = r.bits().grid().origin.map(|c| c as i64);
            for [x, y, z] in r.bits().iter_ones() {
                let w = [
                    i64::from(x) + o[0],
                    i64::from(y) + o[1],
                    i64::from(z) + o[2],
                ];
                let d2 =
                    |p: &[u32; 3]| (0..3).map(|k| (i64::from(p[k]) - w[k]).pow(2)).sum::<i64>();
                let mut near: Vec<(i64, usize)> =
                    pts.iter().enumerate().map(|(i, p)| (d2(p), i)).collect();
                near.sort();
                assert!(near.len() < 2 || near[0].0 < near[1].0, "a tie at {w:?}");
                let i = near[0].1;
                assert_eq!(
                    r.value("rgba", x, y, z),
                    Some(VoxelValue::Rgba8([i as u8, 0, 0, 255])),
                    "{op:?} {w:?}"
                );
                assert_eq!(
                    r.value("material", x, y, z),
                    Some(VoxelValue::U16(i as u16))
                );
            }
            if op == MorphOp::Dilate {
                assert!(r.len() > 4 * 20, "{op:?}: {} voxels", r.len());
            }
        }
    }
}
