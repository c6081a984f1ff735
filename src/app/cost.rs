//! Estimates of the peak memory each volume operation and job will use, read from the stored
//! volumes' metadata (grid, kind, stored size) before anything is loaded, so that the work can
//! be admitted by the process-wide [`super::memory::MemoryBudget`] before it starts.
//!
//! Every operation on a stored volume first reads its `.vxl` (the stored bytes) and decodes it
//! (the decoded volume), both alive at once while it decodes; then it works, and a derived
//! volume is encoded again before it is stored. The estimates add those up, plus what each
//! operation allocates on the side. Measured against peak RSS in `bench/hostile/memory.py`
//! (figures in `docs/security.md`, "Memory").

use std::collections::HashMap;

use crate::grid::Grid;
use crate::volume::{VolumeKind, csg};

use super::request::{CsgExpr, MethodSpec};
use super::store::VolumeMeta;

/// Bytes a bit volume on `grid` takes in memory: one u64 word per 64 voxels of a column.
pub fn bits_bytes(grid: &Grid) -> u64 {
    let [nx, ny, nz] = grid.dims.map(u64::from);
    nx.saturating_mul(ny)
        .saturating_mul(nz.div_ceil(64))
        .saturating_mul(8)
}

/// Bytes a volume of `kind` on `grid` takes decoded (bit kinds padded to whole words).
pub fn decoded_bytes(kind: VolumeKind, grid: &Grid) -> u64 {
    match kind {
        VolumeKind::Bits | VolumeKind::Channels => bits_bytes(grid),
        k => k.decoded_bytes(grid.voxel_count()),
    }
}

/// Loading a stored volume: its stored bytes and the decoded volume twice (the `.vxl` payload
/// is decompressed whole, then copied into the volume's words: both are alive for a moment).
/// Counted once, 11 slow `.npy` readers of a 108 MB volume peaked 31 MiB over a 1 GiB budget
/// plus the idle server (bench/hostile, docs/security.md).
pub fn load(meta: &VolumeMeta) -> u64 {
    meta.bytes
        .saturating_add(stored_decoded_bytes(meta).saturating_mul(2))
}

/// Bytes a stored volume takes decoded: [`decoded_bytes`], except a sparse distance volume
/// whose metadata counts its bricks, which takes its bricks (512 f32 and the map's entry each)
/// and its tile bits, not the dense grid (a 2048³ band is ~0.7 GB, its grid 32 GiB).
pub fn stored_decoded_bytes(meta: &VolumeMeta) -> u64 {
    match (meta.kind, meta.distance.as_ref().and_then(|d| d.bricks)) {
        (VolumeKind::SparseDistance, Some(bricks)) => {
            let positions: u64 = meta
                .grid
                .dims
                .iter()
                .map(|&d| u64::from(d.div_ceil(8)))
                .product();
            bricks
                .saturating_mul(SPARSE_BRICK_BYTES)
                .saturating_add(positions.div_ceil(8))
                .min(decoded_bytes(meta.kind, &meta.grid).saturating_add(positions / 8))
        }
        // The bits, each set voxel's values, and the rank of each column's first one.
        (VolumeKind::Channels, _) => {
            let [nx, ny, _] = meta.grid.dims.map(u64::from);
            decoded_bytes(meta.kind, &meta.grid)
                .saturating_add(meta.solid_voxels.saturating_mul(CHANNEL_BYTES))
                .saturating_add(nx.saturating_mul(ny).saturating_mul(8))
        }
        _ => decoded_bytes(meta.kind, &meta.grid),
    }
}

/// One stored brick of a sparse f32 volume decoded: its 512 values and its map entry (key,
/// pointer and the map's node share, generously).
pub const SPARSE_BRICK_BYTES: u64 = 512 * 4 + 64;

/// Runs of set voxels along z that statistics' component labelling is estimated to keep: at
/// most one per set voxel, and assumed at most this many per column (a column crossing a
/// solid more often than that is rare; the estimate is not a bound for such volumes).
const RUNS_PER_COLUMN: u64 = 4;

/// `GET /v1/volumes/{id}/stats`: the loaded volume, and the component labelling's run table
/// (8 bytes a run, up to twice that while it grows, and a parent index of 8 bytes a run) and
/// column index (8 bytes a column).
pub fn stats(meta: &VolumeMeta) -> u64 {
    let [nx, ny, _] = meta.grid.dims.map(u64::from);
    let columns = nx * ny;
    let runs = meta
        .solid_voxels
        .min(columns.saturating_mul(RUNS_PER_COLUMN));
    load(meta)
        .saturating_add(columns.saturating_mul(8))
        .saturating_add(runs.saturating_mul(24))
}

/// Queries, normals and previews: the loaded volume and their answer (bounded by the request
/// limits, `answer` bytes).
pub fn read_only(meta: &VolumeMeta, answer: u64) -> u64 {
    load(meta).saturating_add(answer)
}

/// A derived bit volume on `grid`: the result, one working copy, and its encoding before it
/// is stored (at most about the result's size).
fn derived(grid: &Grid) -> u64 {
    bits_bytes(grid).saturating_mul(3)
}

/// Morphology of `meta` onto `out` (the result grid). A volume with channels also takes, per
/// voxel of `out`, the nearest-source transform's index (4 bytes), each set voxel's source (4)
/// and its channel values (at most 6: rgba and a material id), and the source's bits moved onto
/// `out` (`app::carry`).
pub fn morphology(meta: &VolumeMeta, out: &Grid) -> u64 {
    let carry = if meta.kind == VolumeKind::Channels {
        out.voxel_count()
            .saturating_mul(4 + 4 + CHANNEL_BYTES)
            .saturating_add(bits_bytes(out))
    } else {
        0
    };
    load(meta)
        .saturating_add(derived(out))
        .saturating_add(carry)
}

/// A CSG expression over the volumes `metas` (by id): every operand loaded once, each
/// operation's result alive until its parent combines it, and the final result with a working
/// copy and its encoding.
pub fn csg(metas: &HashMap<String, VolumeMeta>, expr: &CsgExpr) -> u64 {
    // (the node's grid, the bytes of its operation results)
    fn walk(e: &CsgExpr, metas: &HashMap<String, VolumeMeta>) -> (Option<Grid>, u64) {
        match e {
            CsgExpr::Volume(id) => (metas.get(id).map(|m| m.grid), 0),
            CsgExpr::Op { op, operands } => {
                let mut grids = vec![];
                let mut bytes = 0u64;
                for o in operands {
                    let (g, b) = walk(o, metas);
                    grids.extend(g);
                    bytes = bytes.saturating_add(b);
                }
                let g = csg::result_grid(*op, &grids).ok();
                let own = g.as_ref().map_or(0, bits_bytes);
                (g, bytes.saturating_add(own))
            }
        }
    }
    let loads = metas.values().map(load).fold(0, u64::saturating_add);
    // With channels (`app::carry`): every operand again (its material ids remapped), and for
    // each operation's result, per set voxel (at most all the operands' set voxels) its source
    // (24 bytes) and channel values.
    let carry = if metas.values().any(|m| m.kind == VolumeKind::Channels) {
        fn ops(e: &CsgExpr) -> u64 {
            match e {
                CsgExpr::Volume(_) => 0,
                CsgExpr::Op { operands, .. } => 1 + operands.iter().map(ops).sum::<u64>(),
            }
        }
        let set: u64 = metas
            .values()
            .map(|m| m.solid_voxels)
            .fold(0, u64::saturating_add);
        loads.saturating_add(
            set.saturating_mul(24 + CHANNEL_BYTES)
                .saturating_mul(ops(expr)),
        )
    } else {
        0
    };
    let (top, nodes) = walk(expr, metas);
    let top = match expr {
        CsgExpr::Volume(_) => 0,
        _ => top.as_ref().map_or(0, bits_bytes).saturating_mul(2),
    };
    loads
        .saturating_add(nodes)
        .saturating_add(top)
        .saturating_add(carry)
}

/// The overlap of two stored volumes (nothing stored): both loaded (once when they are one).
pub fn intersect(a: &VolumeMeta, b: &VolumeMeta) -> u64 {
    if a.id == b.id {
        load(a)
    } else {
        load(a).saturating_add(load(b))
    }
}

/// A download converted to another format: the loaded volume for as long as the download lasts
/// (the encoder runs a few 256 KiB chunks ahead of the client). A `.vxl` download streams the
/// stored bytes and holds nothing.
pub fn conversion(meta: &VolumeMeta) -> u64 {
    load(meta).saturating_add(4 * (256 << 10))
}

/// Bytes per set voxel of a channel volume's values: a colour (4) and a material id (2).
pub const CHANNEL_BYTES: u64 = 6;

/// The colour and material channels of a voxelization (`engine::colour`) on `grid`: per set
/// voxel its values (rgba 4, material 2), its nearest-source index and proposal (8) and the
/// copy made of them for the volume (6); per surface voxel its sums and map entry (about 96);
/// per triangle part of two batches of 2¹⁵ triangles (one is added up while the next is cut)
/// its record (56 bytes). Set voxels are not known
/// before the bits are: the grid's voxels bound them. Surface voxels and parts are bounded by
/// the voxels of the triangles' bounding boxes (within the grid's).
pub fn colour_job(grid: &Grid, want: crate::engine::colour::Want, mesh: &crate::mesh::Mesh) -> u64 {
    if !want.any() {
        return 0;
    }
    let boxes = |tris: &[[u32; 3]]| -> u64 {
        tris.iter()
            .map(|t| {
                let p = t.map(|i| grid.index_of(mesh.positions()[i as usize]));
                (0..3)
                    .map(|k| {
                        let lo = p[0][k].min(p[1][k]).min(p[2][k]).floor();
                        let hi = p[0][k].max(p[1][k]).max(p[2][k]).floor();
                        ((hi - lo + 1.0).clamp(1.0, f64::from(grid.dims[k]))) as u64
                    })
                    .product::<u64>()
            })
            .fold(0u64, u64::saturating_add)
    };
    let tris = mesh.triangles();
    let surface = boxes(tris).min(grid.voxel_count());
    let batches: Vec<u64> = tris
        .chunks(crate::engine::colour::BATCH)
        .map(boxes)
        .collect();
    let two = batches
        .windows(2)
        .map(|w| w[0].saturating_add(w[1]))
        .chain(batches.first().copied())
        .max()
        .unwrap_or(0);
    grid.voxel_count()
        .saturating_mul(6 + 8 + 6)
        .saturating_add(surface.saturating_mul(96))
        .saturating_add(two.saturating_mul(crate::engine::colour::PIECE_BYTES))
}

/// A voxelization job on `grid` (not counting the mesh, which its loading admits): the
/// surface and solid bit grids and the encoded result for bit methods; for density, the fine
/// bit grid (`factor`³ voxels a voxel) and the byte-per-voxel result with its encoding.
///
/// sdf: the solid's bit grid twice (the fill's working copy), and per candidate brick
/// (`candidate_bricks`) its 2 KiB of values twice (computed, then in the volume) with 2 KiB
/// for its encoding, plus the triangle bins (16 bytes a pair, counted as 64 a brick).
pub fn voxelize_job(grid: &Grid, method: &MethodSpec, candidate_bricks: u64) -> u64 {
    match method {
        MethodSpec::Bits(_) | MethodSpec::Distance { .. } => bits_bytes(grid).saturating_mul(3),
        MethodSpec::Sdf { .. } => bits_bytes(grid)
            .saturating_mul(2)
            .saturating_add(candidate_bricks.saturating_mul(3 * 2048 + 64)),
        MethodSpec::Density { factor } => {
            let f = u64::from(*factor).pow(3);
            let voxels = grid.voxel_count();
            (voxels.saturating_mul(f) / 8).saturating_add(voxels.saturating_mul(2))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sparse distance volume's load counts its bricks, not its grid: a 2048³ band of
    /// 300,000 bricks is ~1.3 GB to load, where its dense grid would be 64 GiB.
    #[test]
    fn a_sparse_distance_volume_loads_its_bricks() {
        let json = |distance: &str| {
            format!(
                r#"{{"id":"8cdf143699eff06e","name":"s","kind":"sparse-distance","method":"sdf","grid":{{"origin":[0,0,0],"voxel_size":1,"dims":[2048,2048,2048]}},"solid_voxels":1,"volume":1,"source":{{"format":"obj","sha256":"ab12","triangles":1}},"diagnostics":null,"engine":"cpu","created":"2026-01-02T03:04:05Z","bytes":1000,"sha256":"cd34"{distance}}}"#
            )
        };
        let m: VolumeMeta =
            serde_json::from_str(&json(r#","distance":{"bricks":300000}"#)).unwrap();
        let bricks = 300_000 * SPARSE_BRICK_BYTES + (256u64 * 256 * 256) / 8;
        assert_eq!(load(&m), 1000 + 2 * bricks);
        assert!(load(&m) < 1_400_000_000);
        // Without the count (metadata from before it): the dense bound.
        let m: VolumeMeta = serde_json::from_str(&json("")).unwrap();
        assert_eq!(load(&m), 1000 + 2 * (4u64 << 33));
    }

    fn grid(n: u32) -> Grid {
        Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [n, n, n],
        }
    }

    #[test]
    fn bit_grids_count_whole_words_per_column() {
        assert_eq!(bits_bytes(&grid(64)), 64 * 64 * 8);
        assert_eq!(bits_bytes(&grid(65)), 65 * 65 * 2 * 8);
        assert_eq!(
            voxelize_job(&grid(1024), &MethodSpec::Density { factor: 2 }, 0),
            (1u64 << 30) + (2u64 << 30)
        );
    }
}
