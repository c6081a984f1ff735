//! Solid fills for meshes that are not watertight (`docs/methods.md`, "Meshes that are not
//! watertight"). `parity` is the solid method itself. `vote` runs parity along z, along x and
//! along y — the same exact rule on axis-rotated coordinates, on whichever engine — and keeps a
//! voxel where at least two agree. `flood` marks the conservative surface, floods the exterior
//! from the grid's border through unmarked voxels (6-connected), and calls everything unreached
//! solid (so the surface voxels are solid too). The generalised winding number (`winding`,
//! `auto`) is not here yet.

use std::collections::VecDeque;
use std::str::FromStr;

use super::{Engine, EngineError, GridMesh, Method};
use crate::grid::Grid;
use crate::mesh::Mesh;
use crate::volume::BitVolume;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fill {
    Parity,
    Vote,
    Flood,
}

impl FromStr for Fill {
    type Err = String;
    fn from_str(s: &str) -> Result<Fill, String> {
        match s {
            "parity" => Ok(Fill::Parity),
            "vote" => Ok(Fill::Vote),
            "flood" => Ok(Fill::Flood),
            "winding" | "auto" => Err(format!(
                "fill={s} is not available yet; use parity, vote or flood"
            )),
            _ => Err(format!(
                "unknown fill {s:?}; expected parity, vote or flood"
            )),
        }
    }
}

/// `method` with its solid part computed under `fill` (conservative = filled solid ∪ surface,
/// interior = filled solid − surface). `surface` has no solid part, so its fill must be parity.
pub fn voxelize(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    method: Method,
    fill: Fill,
) -> Result<BitVolume, EngineError> {
    if fill == Fill::Parity {
        return engine.voxelize(&GridMesh::new(mesh, grid)?, method);
    }
    let mut s = solid(engine, mesh, grid, fill)?;
    match method {
        Method::Solid => {}
        Method::Surface => return engine.voxelize(&GridMesh::new(mesh, grid)?, Method::Surface),
        Method::Conservative => {
            s.union_with(&engine.voxelize(&GridMesh::new(mesh, grid)?, Method::Surface)?)
        }
        Method::Interior => {
            s.subtract(&engine.voxelize(&GridMesh::new(mesh, grid)?, Method::Surface)?)
        }
    }
    Ok(s)
}

/// The solid of `mesh` on `grid` under `fill`.
pub fn solid(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    fill: Fill,
) -> Result<BitVolume, EngineError> {
    match fill {
        Fill::Parity => engine.voxelize(&GridMesh::new(mesh, grid)?, Method::Solid),
        Fill::Vote => vote(engine, mesh, grid),
        Fill::Flood => {
            let surface = engine.voxelize(&GridMesh::new(mesh, grid)?, Method::Surface)?;
            Ok(flood(&surface))
        }
    }
}

/// Parity along the axis that `rot` moves to z: `rot` maps output axis a to input axis rot[a].
fn parity_along(
    engine: &dyn Engine,
    mesh: &Mesh,
    grid: &Grid,
    rot: [usize; 3],
) -> Result<BitVolume, EngineError> {
    let positions = mesh.positions().iter().map(|p| rot.map(|a| p[a])).collect();
    let rotated = Mesh::new(positions, mesh.triangles().to_vec())
        .expect("a permutation of a valid mesh is valid");
    let g = Grid {
        origin: rot.map(|a| grid.origin[a]),
        voxel_size: grid.voxel_size,
        dims: rot.map(|a| grid.dims[a]),
    };
    let r = engine.voxelize(&GridMesh::new(&rotated, &g)?, Method::Solid)?;
    // Back to the grid's own axes: voxel (x, y, z) is r at its rotated index.
    let mut out = BitVolume::new(*grid);
    for p in r.iter_ones() {
        let mut q = [0u32; 3];
        for a in 0..3 {
            q[rot[a]] = p[a];
        }
        out.set(q[0], q[1], q[2], true);
    }
    Ok(out)
}

fn vote(engine: &dyn Engine, mesh: &Mesh, grid: &Grid) -> Result<BitVolume, EngineError> {
    let z = parity_along(engine, mesh, grid, [0, 1, 2])?;
    let x = parity_along(engine, mesh, grid, [1, 2, 0])?;
    let y = parity_along(engine, mesh, grid, [2, 0, 1])?;
    let mut out = z.clone();
    for ((o, (a, b)), c) in out
        .words_mut()
        .iter_mut()
        .zip(x.words().iter().zip(y.words()))
        .zip(z.words())
    {
        *o = (a & b) | (b & c) | (a & c);
    }
    Ok(out)
}

/// Everything not reachable from the border through voxels that are not in `walls` (6-connected).
pub fn flood(walls: &BitVolume) -> BitVolume {
    let [nx, ny, nz] = walls.dims();
    let mut reached = BitVolume::new(*walls.grid());
    let mut queue = VecDeque::new();
    let visit = |p: [u32; 3], reached: &mut BitVolume, queue: &mut VecDeque<[u32; 3]>| {
        if !walls.get(p[0], p[1], p[2]) && !reached.get(p[0], p[1], p[2]) {
            reached.set(p[0], p[1], p[2], true);
            queue.push_back(p);
        }
    };
    for x in 0..nx {
        for y in 0..ny {
            for z in 0..nz {
                if x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1 {
                    visit([x, y, z], &mut reached, &mut queue);
                }
            }
        }
    }
    while let Some(p) = queue.pop_front() {
        for a in 0..3 {
            for step in [-1i64, 1] {
                let v = p[a] as i64 + step;
                if v >= 0 && v < walls.dims()[a] as i64 {
                    let mut q = p;
                    q[a] = v as u32;
                    visit(q, &mut reached, &mut queue);
                }
            }
        }
    }
    // Solid = not reached.
    let tail = reached.tail_mask();
    let wpc = reached.words_per_column();
    for col in reached.words_mut().chunks_exact_mut(wpc) {
        for w in col.iter_mut() {
            *w = !*w;
        }
        if let Some(l) = col.last_mut() {
            *l &= tail;
        }
    }
    reached
}
