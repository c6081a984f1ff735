//! Device buffers kept from one job for the next: a small job otherwise spends much of its time
//! creating and freeing its slabs, readback buffer, triangles, work items and parameters.
//!
//! Buffers come in size classes (powers of two from 256 bytes, at most the device's largest
//! buffer) per usage; a job leases what it needs and, once the device has finished with them,
//! gives them back. The pool keeps at most its byte budget of idle buffers; what does not fit
//! is freed. Buffers of a job that failed are never given back: after a device error their state
//! is not known.

use std::collections::HashMap;
use std::sync::Mutex;

use super::PoolStats;

type Class = (u32, u64);

pub(super) struct BufferPool {
    idle: Mutex<(HashMap<Class, Vec<wgpu::Buffer>>, PoolStats)>,
    budget: u64,
    max_buffer: u64,
}

impl BufferPool {
    pub fn new(budget: u64, max_buffer: u64) -> BufferPool {
        BufferPool {
            idle: Mutex::new((HashMap::new(), PoolStats::default())),
            budget,
            max_buffer,
        }
    }

    pub fn stats(&self) -> PoolStats {
        self.idle.lock().unwrap_or_else(|e| e.into_inner()).1
    }

    /// The class a buffer of `size` bytes comes from: the next power of two from 256, capped at
    /// the device's largest buffer (the size itself never exceeds it).
    fn class(&self, usage: wgpu::BufferUsages, size: u64) -> Class {
        debug_assert!(size <= self.max_buffer, "{size} > {}", self.max_buffer);
        let class = size.max(256).next_power_of_two().min(self.max_buffer);
        (usage.bits(), class.max(size))
    }
}

/// The buffers one job holds. Dropped, they are freed; [`Leases::recycle`] gives them back to
/// the pool instead, and is for a job whose device work is finished and went well.
pub(super) struct Leases<'p> {
    pool: &'p BufferPool,
    held: Vec<(Class, wgpu::Buffer)>,
}

impl<'p> Leases<'p> {
    pub fn new(pool: &'p BufferPool) -> Leases<'p> {
        Leases {
            pool,
            held: Vec::new(),
        }
    }

    /// A buffer of at least `size` bytes with `usage`: an idle one of its class, else a new one.
    /// Its contents are whatever its last job left: callers clear or overwrite what they use.
    pub fn take(
        &mut self,
        device: &wgpu::Device,
        label: &str,
        usage: wgpu::BufferUsages,
        size: u64,
    ) -> wgpu::Buffer {
        let class = self.pool.class(usage, size);
        let found = {
            let mut idle = self.pool.idle.lock().unwrap_or_else(|e| e.into_inner());
            let (free, stats) = &mut *idle;
            let found = free.get_mut(&class).and_then(Vec::pop);
            match &found {
                Some(_) => {
                    stats.reused += 1;
                    stats.idle -= 1;
                    stats.idle_bytes -= class.1;
                }
                None => stats.created += 1,
            }
            found
        };
        let buffer = found.unwrap_or_else(|| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: class.1,
                usage,
                mapped_at_creation: false,
            })
        });
        self.held.push((class, buffer.clone()));
        buffer
    }

    /// [`Leases::take`] for exactly `contents`, written into it (the write lands before the next
    /// submission).
    pub fn filled(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        label: &str,
        usage: wgpu::BufferUsages,
        contents: &[u8],
    ) -> wgpu::Buffer {
        let buffer = self.take(device, label, usage, contents.len() as u64);
        queue.write_buffer(&buffer, 0, contents);
        buffer
    }

    /// Gives the buffers back to the pool, as far as its budget allows.
    pub fn recycle(mut self) {
        let mut idle = self.pool.idle.lock().unwrap_or_else(|e| e.into_inner());
        let (free, stats) = &mut *idle;
        for (class, buffer) in self.held.drain(..) {
            if stats.idle_bytes + class.1 <= self.pool.budget {
                stats.idle += 1;
                stats.idle_bytes += class.1;
                free.entry(class).or_default().push(buffer);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classes_are_powers_of_two_from_256_within_the_largest_buffer() {
        let pool = BufferPool::new(1 << 20, 1000 * 1024);
        let s = wgpu::BufferUsages::STORAGE;
        let class = |n| pool.class(s, n).1;
        assert_eq!(
            [1, 256, 257, 4096, 4097].map(class),
            [256, 256, 512, 4096, 8192]
        );
        // Near the largest buffer the class is that size, never below the request.
        assert_eq!(class(600 * 1024), 1000 * 1024);
        assert_eq!(class(1000 * 1024), 1000 * 1024);
        assert_ne!(
            pool.class(s, 64),
            pool.class(s | wgpu::BufferUsages::COPY_DST, 64)
        );
    }
}
