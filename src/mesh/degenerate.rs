//! Degenerate triangles dropped at load: a triangle whose corners repeat a position (a repeated
//! vertex index, or two corners at the same point) is a segment or a point. It adds nothing to
//! `solid` (zero projected area: no column is covered) nor to the winding number (zero solid
//! angle), but `surface` (and every method built on it) still marks the voxels its segment or
//! point touches (docs/methods.md), so one copy of each such segment or point is kept and every
//! later one is dropped: the voxels marked are a union, and a copy adds none. A file of millions
//! of identical degenerate triangles (a few megabytes of gzip) so costs one triangle, not
//! gigabytes. Collinear triangles of three distinct points are kept as they are.

use std::collections::HashSet;

/// A position as a key: its bits, with -0.0 taken as 0.0 (equal positions, equal keys).
fn key(p: &[f64; 3]) -> [u64; 3] {
    p.map(|c| if c == 0.0 { 0 } else { c.to_bits() })
}

/// Whether two of the three corners are the same point (exact equality, -0.0 = 0.0).
#[inline]
pub(super) fn repeats_a_point(t: &[[f64; 3]; 3]) -> bool {
    t[0] == t[1] || t[1] == t[2] || t[0] == t[2]
}

/// The degenerate triangles kept so far, by the segment or point they are, and how many were
/// dropped as copies of one of them.
#[derive(Default)]
pub(super) struct Repeats {
    kept: HashSet<[[u64; 3]; 2]>,
    pub(super) dropped: u64,
}

impl Repeats {
    /// Whether to keep triangle `t`: yes unless it repeats a point and the same segment or point
    /// (whatever the order and multiplicity of its corners) was kept before.
    #[inline]
    pub(super) fn keep(&mut self, t: &[[f64; 3]; 3]) -> bool {
        if !repeats_a_point(t) {
            return true;
        }
        let mut k = [key(&t[0]), key(&t[1]), key(&t[2])];
        k.sort_unstable();
        // The two distinct points (a point: twice the same), in order.
        let seg = if k[0] == k[1] {
            [k[0], k[2]]
        } else {
            [k[0], k[1]]
        };
        if self.kept.insert(seg) {
            true
        } else {
            self.dropped += 1;
            false
        }
    }

    /// Drops from `triangles` (indices into `positions`, all in range) every degenerate one that
    /// [`Repeats::keep`] would, keeping the order of the rest; the same from `material` (one
    /// id per triangle) and `uv` (corner texture coordinates per triangle) when there are.
    pub(super) fn filter(
        &mut self,
        positions: &[[f64; 3]],
        triangles: &mut Vec<[u32; 3]>,
        material: Option<&mut Vec<u16>>,
        uv: Option<&mut Vec<[[f32; 2]; 3]>>,
    ) {
        let corners = |t: &[u32; 3]| t.map(|i| positions[i as usize]);
        // Most meshes have no triangle that repeats a point: nothing to copy then.
        if !triangles.iter().any(|t| repeats_a_point(&corners(t))) {
            return;
        }
        let keep: Vec<bool> = triangles.iter().map(|t| self.keep(&corners(t))).collect();
        let mut k = keep.iter();
        triangles.retain(|_| *k.next().expect("one a triangle"));
        if let Some(m) = material {
            let mut k = keep.iter();
            m.retain(|_| *k.next().expect("one a triangle"));
        }
        if let Some(uv) = uv {
            let mut k = keep.iter();
            uv.retain(|_| *k.next().expect("one a triangle"));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: [f64; 3] = [0.0, 0.0, 0.0];
    const B: [f64; 3] = [1.0, 0.0, 0.0];
    const C: [f64; 3] = [2.0, 0.0, 0.0];
    const D: [f64; 3] = [0.0, 1.0, 0.0];

    #[test]
    fn copies_of_a_segment_or_point_are_dropped_one_is_kept() {
        let mut r = Repeats::default();
        assert!(r.keep(&[A, B, D]), "a real triangle");
        assert!(
            r.keep(&[A, B, D]),
            "real triangles are never dropped, even copies"
        );
        assert!(r.keep(&[A, B, C]), "collinear, three distinct points: kept");
        assert!(r.keep(&[A, B, C]));
        assert!(r.keep(&[A, A, B]), "the first copy of segment AB");
        assert!(!r.keep(&[B, A, A]));
        assert!(
            !r.keep(&[A, B, B]),
            "the same segment, the other end doubled"
        );
        assert!(r.keep(&[B, B, B]), "the first copy of point B");
        assert!(!r.keep(&[B, B, B]));
        assert!(!r.keep(&[[-0.0, 0.0, -0.0], A, B]), "-0.0 is 0.0");
        assert!(r.keep(&[A, A, A]), "point A is not segment AB");
        assert_eq!(r.dropped, 4);
    }

    #[test]
    fn filter_by_index_and_by_position() {
        // Vertex 3 is at A's position: [0, 3, 1] repeats a point without repeating an index.
        let p = vec![A, B, D, A];
        let mut t = vec![
            [0, 1, 2],
            [0, 0, 1],
            [0, 3, 1],
            [1, 0, 0],
            [2, 2, 2],
            [2, 2, 2],
        ];
        let mut t2 = t.clone();
        let mut r = Repeats::default();
        r.filter(&p, &mut t, None, None);
        assert_eq!(t, vec![[0, 1, 2], [0, 0, 1], [2, 2, 2]]);
        // The materials of the dropped triangles go with them.
        let mut material = vec![10, 11, 12, 13, 14, 15];
        let mut uv = vec![[[0.0f32; 2]; 3]; 6];
        uv[4][0][0] = 4.0;
        Repeats::default().filter(&p, &mut t2, Some(&mut material), Some(&mut uv));
        assert_eq!(uv.len(), 3);
        assert_eq!(
            uv[2][0][0], 4.0,
            "the kept triangles' coordinates stay theirs"
        );
        assert_eq!(t2, t);
        assert_eq!(material, vec![10, 11, 14]);
        assert_eq!(r.dropped, 3);
    }
}
