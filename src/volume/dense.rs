//! Dense typed volumes: [`Dense<T>`] holds one `T` per voxel in C order of an (X, Y, Z) array,
//! voxel (x, y, z) at `(x·Y + y)·Z + z`; [`DensityVolume`] is a `Dense<u8>` with its scale (the
//! value of a full voxel). Not here: bit volumes (`mod.rs`) and sparse bricks (`sparse.rs`).

use super::kind::Voxel;
use crate::grid::Grid;

/// One `T` per voxel, C order of (X, Y, Z).
#[derive(Clone, Debug, PartialEq)]
pub struct Dense<T> {
    grid: Grid,
    data: Vec<T>,
}

impl<T: Voxel> Dense<T> {
    /// A volume on `grid` with every voxel `fill`.
    pub fn new(grid: Grid, fill: T) -> Dense<T> {
        Dense {
            grid,
            data: vec![fill; grid.voxel_count() as usize],
        }
    }

    /// Wraps values in C order; fails when their count is not the grid's.
    pub fn from_data(grid: Grid, data: Vec<T>) -> Result<Dense<T>, String> {
        if data.len() as u64 != grid.voxel_count() {
            return Err(format!(
                "expected {} values for dims {:?}, got {}",
                grid.voxel_count(),
                grid.dims,
                data.len()
            ));
        }
        Ok(Dense { grid, data })
    }

    pub fn grid(&self) -> &Grid {
        &self.grid
    }
    pub fn dims(&self) -> [u32; 3] {
        self.grid.dims
    }
    pub fn data(&self) -> &[T] {
        &self.data
    }
    pub fn data_mut(&mut self) -> &mut [T] {
        &mut self.data
    }
    pub fn into_data(self) -> Vec<T> {
        self.data
    }

    /// The position of voxel (x, y, z) in [`Dense::data`]; panics outside the grid.
    pub fn index(&self, x: u32, y: u32, z: u32) -> usize {
        let [nx, ny, nz] = self.grid.dims;
        assert!(x < nx && y < ny && z < nz, "voxel outside the grid");
        (x as usize * ny as usize + y as usize) * nz as usize + z as usize
    }
    pub fn get(&self, x: u32, y: u32, z: u32) -> T {
        self.data[self.index(x, y, z)]
    }
    pub fn set(&mut self, x: u32, y: u32, z: u32, v: T) {
        let i = self.index(x, y, z);
        self.data[i] = v;
    }
    /// The value of points outside the grid: [`Voxel::EMPTY`].
    pub fn outside(&self) -> T {
        T::EMPTY
    }
    /// Voxels whose value is occupied ([`Voxel::occupied`]).
    pub fn count_occupied(&self) -> u64 {
        self.data.iter().filter(|v| v.occupied()).count() as u64
    }
}

/// One byte per voxel, values `0..=max` (a full voxel is `max`: 8 for 2× supersampling, 64 for
/// 4×). A [`Dense<u8>`] with its scale; the values are checked against it.
#[derive(Clone, Debug, PartialEq)]
pub struct DensityVolume {
    max: u8,
    values: Dense<u8>,
}

impl DensityVolume {
    pub fn new(grid: Grid, max: u8) -> DensityVolume {
        DensityVolume {
            max,
            values: Dense::new(grid, 0),
        }
    }
    pub fn from_data(grid: Grid, max: u8, data: Vec<u8>) -> Result<DensityVolume, String> {
        if data.len() as u64 != grid.voxel_count() {
            return Err(format!(
                "expected {} density bytes for dims {:?}, got {}",
                grid.voxel_count(),
                grid.dims,
                data.len()
            ));
        }
        if let Some(v) = data.iter().find(|&&v| v > max) {
            return Err(format!("density value {v} exceeds the maximum {max}"));
        }
        Ok(DensityVolume {
            max,
            values: Dense::from_data(grid, data)?,
        })
    }
    pub fn grid(&self) -> &Grid {
        self.values.grid()
    }
    pub fn max(&self) -> u8 {
        self.max
    }
    pub fn data(&self) -> &[u8] {
        self.values.data()
    }
    /// The values as a dense `u8` volume (without the scale).
    pub fn dense(&self) -> &Dense<u8> {
        &self.values
    }
    pub fn get(&self, x: u32, y: u32, z: u32) -> u8 {
        self.values.get(x, y, z)
    }
    pub fn set(&mut self, x: u32, y: u32, z: u32, v: u8) {
        assert!(v <= self.max);
        self.values.set(x, y, z, v)
    }
    /// Voxels with any occupancy.
    pub fn count_nonzero(&self) -> u64 {
        self.values.count_occupied()
    }
    /// Sum of occupancies divided by `max`: the occupied volume in voxels.
    pub fn occupied_voxels(&self) -> f64 {
        self.data().iter().map(|&v| v as u64).sum::<u64>() as f64 / self.max as f64
    }
}
