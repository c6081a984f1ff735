//! voxd: exact voxelization of triangle meshes.
//!
//! Data moves one way: [`mesh`] loads and validates a triangle mesh, [`grid`] fits the grid the
//! caller asked for, an [`engine`] turns the two into a [`volume`], and [`codec`] writes volumes as
//! bytes. The definitions every engine must meet are in `docs/methods.md`.
//!
//! Above them, [`app`] is the application layer every front shares (typed requests, the
//! voxelize pipeline, volume operations, metadata, errors), with volumes kept through
//! [`app::store::VolumeStore`] and jobs through [`app::queue::JobQueue`], traits the
//! application declares and the adapters in [`store`] and [`queue`] implement (they never call
//! back into the application); [`limits`] holds every default and cap. [`service`] is the HTTP front; the command line is the `voxd` binary.

#[cfg(not(target_endian = "little"))]
compile_error!(
    "voxd stores bit volumes as little-endian words and runs on little-endian targets only"
);

pub mod alloc;
pub mod app;
pub mod atomic;
pub mod cancel;
pub mod codec;
pub mod engine;
pub mod extract;
pub mod grid;
pub mod limits;
pub mod mesh;
pub mod names;
pub mod queue;
pub mod service;
pub mod store;
#[cfg(test)]
pub(crate) mod testkit;
pub mod volume;

/// The fewest items (positions, triangles) one parallel task takes in the passes over a mesh:
/// a small mesh, a service's typical job, goes in one piece on one thread, since splitting it
/// among threads busy with other jobs only adds hand-offs.
pub(crate) const PAR_PIECE: usize = 1 << 12;

/// `s` cut into consecutive parts of the lengths `lens` (whose sum is at most `s.len()`; the
/// rest is left out), to be handed to threads one part each.
pub(crate) fn split_lengths<T>(
    s: &mut [T],
    lens: impl IntoIterator<Item = usize>,
) -> Vec<&mut [T]> {
    let mut rest = s;
    lens.into_iter()
        .map(|len| {
            let (part, tail) = std::mem::take(&mut rest).split_at_mut(len);
            rest = tail;
            part
        })
        .collect()
}

/// `s` with every entry set to `v`, as an initialised slice (for arrays taken from a vector's
/// spare capacity, so not zeroed first).
pub(crate) fn fill_uninit<T: Copy>(s: &mut [std::mem::MaybeUninit<T>], v: T) -> &mut [T] {
    for x in s.iter_mut() {
        x.write(v);
    }
    // SAFETY: every entry was written just above, and `MaybeUninit<T>` has `T`'s layout.
    unsafe { &mut *(s as *mut [std::mem::MaybeUninit<T>] as *mut [T]) }
}

pub use engine::Method;
pub use grid::{Grid, GridLimits, GridSpec};
pub use mesh::Mesh;
pub use volume::{Attributed, BitVolume, Dense, DensityVolume, Sparse, Volume, VolumeKind};

#[cfg(test)]
mod tests {
    #[test]
    fn split_lengths_cuts_consecutive_parts() {
        let mut v: Vec<u32> = (0..10).collect();
        let parts = super::split_lengths(&mut v, [3, 0, 4]);
        let got: Vec<Vec<u32>> = parts.iter().map(|p| p.to_vec()).collect();
        assert_eq!(got, vec![vec![0, 1, 2], vec![], vec![3, 4, 5, 6]]);
    }

    #[test]
    fn fill_uninit_sets_every_entry_of_spare_capacity() {
        let mut v: Vec<[u32; 2]> = Vec::with_capacity(7);
        let got = super::fill_uninit(&mut v.spare_capacity_mut()[..5], [9, 4]);
        got[1][0] = 1;
        assert_eq!(got, &[[9, 4], [1, 4], [9, 4], [9, 4], [9, 4]]);
        // SAFETY: the first five entries were written just above.
        unsafe { v.set_len(5) };
        assert_eq!(v, [[9, 4], [1, 4], [9, 4], [9, 4], [9, 4]]);
    }
}
