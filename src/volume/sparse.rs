//! Sparse volumes of 8³ bricks ([`Sparse<T>`]), OpenVDB's leaf nodes without the tree above
//! them: a background value, and a table of the occupied bricks, each holding its 512 values.
//! Voxel (x, y, z) lies in brick (x/8, y/8, z/8) at offset `((x%8)·8 + y%8)·8 + z%8` (OpenVDB's
//! leaf order, so a `.vdb` leaf is one brick). Bricks at the grid's high faces extend past it;
//! their voxels outside the grid always hold the background. A voxel in no brick is the tile
//! value when its brick is a tile, else the background. Meant for narrow-band distance fields (`Sparse<f32>`, background +∞ or the band's
//! width) and other mostly-uniform volumes. Not here: the `.vxl` layout (`codec::vxl`).

use std::collections::{BTreeMap, HashMap};

use super::dense::Dense;
use super::kind::Voxel;
use crate::grid::Grid;

/// Voxels along a brick's edge.
pub const BRICK: u32 = 8;
/// Voxels in a brick.
pub const BRICK_VOXELS: usize = (BRICK * BRICK * BRICK) as usize;

/// 8³ bricks around a background value.
#[derive(Clone, Debug, PartialEq)]
pub struct Sparse<T> {
    grid: Grid,
    background: T,
    /// Keyed by brick coordinates, in (x, y, z) order: the order `.vxl` stores them in.
    bricks: BTreeMap<[u32; 3], Box<[T; BRICK_VOXELS]>>,
    /// The value of every voxel (inside the grid) of a tile.
    tile_value: T,
    /// One bit per brick position, `(bx · BY + by) · BZ + bz`: set where the position is a tile.
    /// Empty when there are no tiles. A stored brick is never a tile.
    tiles: Vec<u64>,
}

/// The offset of voxel (x, y, z) in its brick.
fn offset(x: u32, y: u32, z: u32) -> usize {
    (((x % BRICK) * BRICK + y % BRICK) * BRICK + z % BRICK) as usize
}

impl<T: Voxel> Sparse<T> {
    /// Every voxel the background; no bricks.
    pub fn new(grid: Grid, background: T) -> Sparse<T> {
        Sparse {
            grid,
            background,
            bricks: BTreeMap::new(),
            tile_value: background,
            tiles: Vec::new(),
        }
    }
    /// No bricks; the tiles (none yet) will hold `tile_value`.
    pub fn with_tile_value(grid: Grid, background: T, tile_value: T) -> Sparse<T> {
        Sparse {
            tile_value,
            ..Sparse::new(grid, background)
        }
    }
    pub fn tile_value(&self) -> T {
        self.tile_value
    }

    fn tile_bit(&self, at: [u32; 3]) -> usize {
        let bd = self.brick_dims();
        ((at[0] as usize * bd[1] as usize) + at[1] as usize) * bd[2] as usize + at[2] as usize
    }

    /// Is brick position `at` a tile?
    pub fn is_tile(&self, at: [u32; 3]) -> bool {
        let i = self.tile_bit(at);
        self.tiles
            .get(i / 64)
            .is_some_and(|w| w >> (i % 64) & 1 == 1)
    }

    /// Makes brick position `at` a tile (dropping its brick) or not. Fails when `at` is outside
    /// the brick grid.
    pub fn set_tile(&mut self, at: [u32; 3], tile: bool) -> Result<(), String> {
        let bd = self.brick_dims();
        if (0..3).any(|a| at[a] >= bd[a]) {
            return Err(format!("tile {at:?} is outside the brick grid {bd:?}"));
        }
        let i = self.tile_bit(at);
        if tile {
            if self.tiles.is_empty() {
                let n = bd.iter().map(|&d| d as usize).product::<usize>();
                self.tiles = vec![0; n.div_ceil(64)];
            }
            self.tiles[i / 64] |= 1 << (i % 64);
            self.bricks.remove(&at);
        } else if let Some(w) = self.tiles.get_mut(i / 64) {
            *w &= !(1 << (i % 64));
        }
        Ok(())
    }

    /// The tiles' brick coordinates, in (x, y, z) order.
    pub fn tiles(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        let [_, by, bz] = self.brick_dims().map(|d| d as usize);
        self.tiles
            .iter()
            .enumerate()
            .filter(|(_, w)| **w != 0)
            .flat_map(move |(wi, &w)| {
                (0..64).filter(move |b| w >> b & 1 == 1).map(move |b| {
                    let i = wi * 64 + b;
                    [
                        (i / (by * bz)) as u32,
                        (i / bz % by) as u32,
                        (i % bz) as u32,
                    ]
                })
            })
    }
    pub fn tile_count(&self) -> usize {
        self.tiles.iter().map(|w| w.count_ones() as usize).sum()
    }
    pub fn grid(&self) -> &Grid {
        &self.grid
    }
    pub fn background(&self) -> T {
        self.background
    }
    /// Bricks along each axis: `ceil(dims / 8)`.
    pub fn brick_dims(&self) -> [u32; 3] {
        self.grid.dims.map(|d| d.div_ceil(BRICK))
    }
    /// The occupied bricks, by brick coordinates in (x, y, z) order, with their values.
    pub fn bricks(&self) -> impl Iterator<Item = ([u32; 3], &[T; BRICK_VOXELS])> {
        self.bricks.iter().map(|(k, v)| (*k, &**v))
    }
    /// Brick `at`'s values, if it is stored.
    pub fn brick(&self, at: [u32; 3]) -> Option<&[T; BRICK_VOXELS]> {
        self.bricks.get(&at).map(|b| &**b)
    }
    pub fn brick_count(&self) -> usize {
        self.bricks.len()
    }

    /// [`Sparse::insert_brick`] of a boxed brick, kept as it is (no copy).
    pub fn insert_boxed(
        &mut self,
        at: [u32; 3],
        values: Box<[T; BRICK_VOXELS]>,
    ) -> Result<(), String> {
        self.check_brick(at, &values)?;
        self.bricks.insert(at, values);
        Ok(())
    }

    /// Adds (or replaces) brick `at` whole. Fails when `at` is outside the brick grid or a value
    /// outside the grid is not the background.
    pub fn insert_brick(&mut self, at: [u32; 3], values: [T; BRICK_VOXELS]) -> Result<(), String> {
        self.insert_boxed(at, Box::new(values))
    }

    /// Checks brick `at` and clears a tile there.
    fn check_brick(&mut self, at: [u32; 3], values: &[T; BRICK_VOXELS]) -> Result<(), String> {
        let bd = self.brick_dims();
        if (0..3).any(|a| at[a] >= bd[a]) {
            return Err(format!("brick {at:?} is outside the brick grid {bd:?}"));
        }
        let d = self.grid.dims;
        for (i, v) in values.iter().enumerate() {
            let (bx, by, bz) = (i as u32 / 64, i as u32 / 8 % 8, i as u32 % 8);
            let p = [at[0] * BRICK + bx, at[1] * BRICK + by, at[2] * BRICK + bz];
            if (0..3).any(|a| p[a] >= d[a]) && *v != self.background {
                return Err(format!(
                    "brick {at:?} holds a value other than the background outside the grid"
                ));
            }
        }
        if self.is_tile(at) {
            self.set_tile(at, false)?;
        }
        Ok(())
    }

    pub fn get(&self, x: u32, y: u32, z: u32) -> T {
        self.value_by([x, y, z], |at| self.brick(at))
    }

    /// Voxel `v`'s value, its stored brick (if any) found by `brick` from the brick position.
    fn value_by<'a>(
        &self,
        v: [u32; 3],
        brick: impl FnOnce([u32; 3]) -> Option<&'a [T; BRICK_VOXELS]>,
    ) -> T
    where
        T: 'a,
    {
        let d = self.grid.dims;
        assert!((0..3).all(|a| v[a] < d[a]), "voxel outside the grid");
        let at = v.map(|c| c / BRICK);
        match brick(at) {
            Some(b) => b[offset(v[0], v[1], v[2])],
            None if self.is_tile(at) => self.tile_value,
            None => self.background,
        }
    }

    /// Sets a voxel, making its brick when it has none (unless `v` is already its value): a
    /// tile becomes a brick of the tile value inside the grid (the background past it).
    pub fn set(&mut self, x: u32, y: u32, z: u32, v: T) {
        let d = self.grid.dims;
        assert!(x < d[0] && y < d[1] && z < d[2], "voxel outside the grid");
        let key = [x / BRICK, y / BRICK, z / BRICK];
        if !self.bricks.contains_key(&key) {
            if v == self.get(x, y, z) {
                return;
            }
            let mut brick = Box::new([self.background; BRICK_VOXELS]);
            if self.is_tile(key) {
                for (i, b) in brick.iter_mut().enumerate() {
                    let (bx, by, bz) = (i as u32 / 64, i as u32 / 8 % 8, i as u32 % 8);
                    let p = [
                        key[0] * BRICK + bx,
                        key[1] * BRICK + by,
                        key[2] * BRICK + bz,
                    ];
                    if (0..3).all(|a| p[a] < d[a]) {
                        *b = self.tile_value;
                    }
                }
                self.set_tile(key, false).expect("inside the brick grid");
            }
            self.bricks.insert(key, brick);
        }
        self.bricks.get_mut(&key).expect("made above")[offset(x, y, z)] = v;
    }

    /// Drops the bricks that hold only the background.
    pub fn prune(&mut self) {
        let bg = self.background;
        self.bricks.retain(|_, b| b.iter().any(|v| *v != bg));
    }

    /// The bricks of `d` that hold anything but `background`.
    pub fn from_dense(d: &Dense<T>, background: T) -> Sparse<T> {
        let mut s = Sparse::new(*d.grid(), background);
        let [nx, ny, nz] = d.dims();
        let bd = s.brick_dims();
        for bx in 0..bd[0] {
            for by in 0..bd[1] {
                for bz in 0..bd[2] {
                    let mut brick = [background; BRICK_VOXELS];
                    let mut any = false;
                    for x in bx * BRICK..(bx * BRICK + BRICK).min(nx) {
                        for y in by * BRICK..(by * BRICK + BRICK).min(ny) {
                            for z in bz * BRICK..(bz * BRICK + BRICK).min(nz) {
                                let v = d.get(x, y, z);
                                any |= v != background;
                                brick[offset(x, y, z)] = v;
                            }
                        }
                    }
                    if any {
                        s.bricks.insert([bx, by, bz], Box::new(brick));
                    }
                }
            }
        }
        s
    }

    /// Every voxel, densely.
    pub fn to_dense(&self) -> Dense<T> {
        let mut d = Dense::new(self.grid, self.background);
        let [nx, ny, nz] = self.grid.dims;
        for [bx, by, bz] in self.tiles() {
            for x in bx * BRICK..(bx * BRICK + BRICK).min(nx) {
                for y in by * BRICK..(by * BRICK + BRICK).min(ny) {
                    for z in bz * BRICK..(bz * BRICK + BRICK).min(nz) {
                        d.set(x, y, z, self.tile_value);
                    }
                }
            }
        }
        for (&[bx, by, bz], b) in &self.bricks {
            for x in bx * BRICK..(bx * BRICK + BRICK).min(nx) {
                for y in by * BRICK..(by * BRICK + BRICK).min(ny) {
                    for z in bz * BRICK..(bz * BRICK + BRICK).min(nz) {
                        d.set(x, y, z, b[offset(x, y, z)]);
                    }
                }
            }
        }
        d
    }

    /// The value of points outside the grid: the background.
    pub fn outside(&self) -> T {
        self.background
    }

    /// Voxels whose value is occupied ([`Voxel::occupied`]).
    pub fn count_occupied(&self) -> u64 {
        let [nx, ny, nz] = self.grid.dims.map(u64::from);
        let in_bricks: u64 = self.bricks.len() as u64 * BRICK_VOXELS as u64;
        let inside_bricks: u64 = self
            .bricks
            .keys()
            .map(|&[bx, by, bz]| {
                let e = |b: u32, n: u64| (n - b as u64 * 8).min(8);
                e(bx, nx) * e(by, ny) * e(bz, nz)
            })
            .sum();
        let background = if self.background.occupied() {
            nx * ny * nz - inside_bricks
        } else {
            0
        };
        // Voxels past the grid's faces hold the background: not counted.
        let past = if self.background.occupied() {
            in_bricks - inside_bricks
        } else {
            0
        };
        let occupied: u64 = self
            .bricks
            .values()
            .map(|b| b.iter().filter(|v| v.occupied()).count() as u64)
            .sum();
        // Tiles: their voxels inside the grid hold the tile value, not the background.
        let e = |b: u32, n: u64| (n - b as u64 * 8).min(8);
        let tiles: u64 = self
            .tiles()
            .map(|[bx, by, bz]| e(bx, nx) * e(by, ny) * e(bz, nz))
            .sum();
        let tiles_occupied = if self.tile_value.occupied() { tiles } else { 0 };
        let tiles_background = if self.background.occupied() { tiles } else { 0 };
        background + occupied + tiles_occupied - past - tiles_background
    }
}

/// [`Sparse::get`] for many lookups ([`Sparse::reader`]): the bricks found through a hash
/// table instead of the B-tree, whose search took most of a mesh extraction's reads of a
/// narrow band's values (two a boundary face). Its table is one entry a brick.
pub struct Reader<'a, T> {
    sparse: &'a Sparse<T>,
    bricks: HashMap<[u32; 3], &'a [T; BRICK_VOXELS], foldhash::fast::FixedState>,
}

impl<T: Voxel> Sparse<T> {
    /// A [`Reader`] of this volume.
    pub fn reader(&self) -> Reader<'_, T> {
        let mut bricks = HashMap::with_capacity_and_hasher(
            self.bricks.len(),
            foldhash::fast::FixedState::default(),
        );
        for (&at, b) in &self.bricks {
            bricks.insert(at, &**b);
        }
        Reader {
            sparse: self,
            bricks,
        }
    }
}

impl<T: Voxel> Reader<'_, T> {
    /// [`Sparse::get`].
    pub fn get(&self, x: u32, y: u32, z: u32) -> T {
        self.sparse
            .value_by([x, y, z], |at| self.bricks.get(&at).copied())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bricks_hold_what_differs_from_the_background() {
        let g = Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [9, 17, 3],
        };
        let mut s = Sparse::new(g, f32::INFINITY);
        s.set(8, 16, 2, -1.0);
        s.set(0, 0, 0, 0.5);
        s.set(4, 4, 1, f32::INFINITY);
        assert_eq!(s.brick_count(), 2);
        assert_eq!(s.get(8, 16, 2), -1.0);
        assert_eq!(s.get(1, 1, 1), f32::INFINITY);
        assert_eq!(s.count_occupied(), 1);
        let d = s.to_dense();
        assert_eq!(d.count_occupied(), 1);
        assert_eq!(Sparse::from_dense(&d, f32::INFINITY), s);
        s.set(0, 0, 0, f32::INFINITY);
        s.prune();
        assert_eq!(s.brick_count(), 1);
        let mut bad = [f32::INFINITY; BRICK_VOXELS];
        bad[offset(1, 7, 3)] = 1.0; // y = 15: inside; z = 3 is past the grid's 3
        assert!(s.clone().insert_brick([0, 1, 0], bad).is_err());
        assert!(
            s.insert_brick([2, 0, 0], [f32::INFINITY; BRICK_VOXELS])
                .is_err()
        );
    }

    #[test]
    fn tiles_hold_their_value_until_a_voxel_is_set() {
        let g = Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [12, 8, 8],
        };
        let mut s = Sparse::with_tile_value(g, 3.0f32, -3.0);
        s.set_tile([1, 0, 0], true).unwrap();
        assert!(s.is_tile([1, 0, 0]) && !s.is_tile([0, 0, 0]));
        assert_eq!(s.tiles().collect::<Vec<_>>(), vec![[1, 0, 0]]);
        assert_eq!(s.get(9, 3, 3), -3.0);
        assert_eq!(s.get(2, 3, 3), 3.0);
        assert_eq!(s.count_occupied(), 4 * 8 * 8);
        assert_eq!(s.to_dense().count_occupied(), 4 * 8 * 8);
        s.set(9, 3, 3, -1.0);
        assert_eq!((s.tile_count(), s.brick_count()), (0, 1));
        assert_eq!(s.get(10, 3, 3), -3.0);
        assert_eq!(s.get(9, 3, 3), -1.0);
        assert_eq!(s.count_occupied(), 4 * 8 * 8);
        assert!(s.set_tile([2, 0, 0], true).is_err());
    }

    #[test]
    fn an_occupied_background_counts_the_grid_not_the_bricks_past_it() {
        let g = Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [3, 3, 3],
        };
        let mut s = Sparse::new(g, 1u16);
        assert_eq!(s.count_occupied(), 27);
        s.set(1, 1, 1, 0);
        assert_eq!(s.count_occupied(), 26);
        assert_eq!(s.to_dense().count_occupied(), 26);
    }

    #[test]
    fn a_reader_reads_what_get_reads() {
        // Bricks, tiles and background, on a grid whose high bricks pass its faces; every
        // voxel read both ways.
        let g = Grid {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [21, 10, 27],
        };
        let mut s = Sparse::with_tile_value(g, 2.5f32, -2.5);
        let mut rng = crate::testkit::Rng::new(19);
        for _ in 0..300 {
            let (x, y, z) = (rng.below(21), rng.below(10), rng.below(27));
            s.set(x as u32, y as u32, z as u32, rng.below(1000) as f32 - 500.0);
        }
        s.set_tile([2, 0, 3], true).unwrap();
        s.set_tile([0, 1, 0], true).unwrap();
        assert!(s.brick_count() > 10 && s.tile_count() == 2);
        let r = s.reader();
        let mut kinds = [0; 3];
        for x in 0..21 {
            for y in 0..10 {
                for z in 0..27 {
                    let v = s.get(x, y, z);
                    assert_eq!(r.get(x, y, z).to_bits(), v.to_bits(), "({x}, {y}, {z})");
                    kinds[if v == 2.5 {
                        0
                    } else if v == -2.5 {
                        1
                    } else {
                        2
                    }] += 1;
                }
            }
        }
        assert!(kinds.iter().all(|&k| k > 0), "{kinds:?}");
    }
}
