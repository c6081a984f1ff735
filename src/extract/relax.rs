//! Surface nets' constrained relaxation of a bit volume's vertices (the module doc of
//! [`surface_nets`](super::surface_nets) defines it): `rounds` of Taubin's two steps, each
//! step every vertex towards the mean of its quad neighbours (all read before any is moved:
//! a Jacobi step), clamped to its dual cell shrunk by 1/16 voxel.
//!
//! **Schedule.** A vertex's neighbours lie in its own and the two next lattice slabs (x ± 1),
//! and the vertices are numbered slab by slab, so step `p + 1` of slab `x` needs only step `p`
//! of slabs `x − 1 ..= x + 1`. The steps are therefore run as a wavefront over the slabs
//! (time skewing): in sweep `t`, step `p + 1` is computed for slab `t − 2p`, for every step
//! at once. The slabs a sweep touches, and the vertices' neighbour lists, stay in the caches
//! across all the steps, where step after step over the whole mesh streamed every array
//! through memory 24 times. Two arrays hold the positions, the even steps in one and the odd
//! in the other: the skew of two slabs per step is what lets step `p + 1` overwrite step
//! `p − 1` of its slab (every read of it is done by then).
//!
//! **Stages.** A slab's arrays are read again two sweeps after a step has read them, by the
//! next step, so a wavefront of `d` steps reads about `2d` slabs' arrays in between: deeper
//! than a core's cache holds, every step reads them from memory again. The steps are
//! therefore cut into consecutive *stages* of at most [`STAGE_CACHE`] / (2 × a slab's bytes)
//! steps each (igea-subdiv4 at 518³: 4 steps; one stage a thread, 12 steps each, took 20 %
//! longer), as many as the threads or a multiple of them, each at least a round.
//!
//! **Threads.** The stages run as a pipeline: each runs the wavefront of its steps, and before
//! its sweep `t` waits until the stage of the steps before has finished its last step on
//! slabs `..= t + 1` (a counter it publishes after each sweep). Nothing else needs waiting
//! for: what a stage overwrites was last read by its own earlier steps, or by the stages
//! before it, which are done with that slab by then. Each vertex's arithmetic is the same, in
//! the same order, as in step-by-step passes, so the result is too, bit for bit, on any number
//! of threads and of stages.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use rayon::prelude::*;

use crate::cancel::{Canceled, Control};

/// Taubin's λ and μ (λ = 0.5, 1/λ + 1/μ = 0.1: the pass band of his paper's examples).
const TAUBIN: (f64, f64) = (0.5, -0.5263157894736842);

/// The bytes of a wavefront's arrays a stage should keep in a core's cache (the L2 of the
/// processors this runs on holds 1–2 MiB): see the module doc's "Stages".
const STAGE_CACHE: usize = 1 << 20;

/// Bytes of the wavefront's arrays a vertex takes in one step: its neighbour slots (24), its
/// step sums (16), and its entries of the positions read and written (16 each).
const VERTEX_BYTES: usize = 24 + 16 + 16 + 16;

/// How many stages [`relax`] cuts `2 · rounds` steps into, for `n` vertices in `slabs` slabs
/// on `threads` threads (the module doc's "Stages").
fn stage_count(n: usize, slabs: usize, rounds: usize, threads: usize) -> usize {
    let slab_bytes = (n / slabs.max(1)).max(1) * VERTEX_BYTES;
    let depth = (STAGE_CACHE / (2 * slab_bytes)).max(2);
    let threads = threads.max(1);
    (2 * rounds)
        .div_ceil(depth)
        .div_ceil(threads)
        .saturating_mul(threads)
        .clamp(1, rounds.max(1))
}

/// Half the side of a vertex's box about its lattice point: the cell shrunk by 1/16 voxel.
const HALF: f32 = 0.5 - 1.0 / 16.0;

/// Neighbour slots per vertex held inline (a vertex has 3 to 6 on smooth surfaces; up to 12,
/// the internal faces of its block, in the rest).
const SLOTS: usize = 6;

/// The mesh the steps run on.
///
/// * `adj[v]`: vertex v's first [`SLOTS`] neighbours, in the order of its quads, the unused
///   slots holding `n` (the vertex count), whose entry in the position arrays is kept zero, so
///   every vertex adds the same number of entries and no loop's length depends on its valence
///   (a branch per vertex the processor could not predict: valences 3, 4, 5 and 6 are all
///   common);
/// * `extra`: the vertices with more neighbours, in order, with the rest of them;
/// * `steps[v]`: the sum of its neighbours' lattice points less its own (at most 12 × ±1 on an
///   axis, exact in f32), and in `steps[v][3]` 1 / its valence;
/// * `slabs`: the first vertex of each lattice slab, then the vertex count.
pub(super) struct Graph {
    adj: Vec<[u32; SLOTS]>,
    extra: Vec<(u32, Vec<u32>)>,
    steps: Vec<[f32; 4]>,
    slabs: Vec<usize>,
}

impl Graph {
    /// The graph of a closed, consistently oriented quad mesh whose vertices are numbered
    /// slab by slab (`cells`: each vertex's lattice point): each edge v → w is in exactly one
    /// quad, so each neighbour is counted once. `by_plane`: the quads are in order of their
    /// corners' lowest lattice x and each lies in two consecutive slabs (a net's are: a face's
    /// corners are on its plane and the next), so each thread's part reads only the quads of
    /// its slabs, not all of them.
    pub(super) fn of(quads: &[[u32; 4]], cells: &[[u32; 3]], by_plane: bool) -> Graph {
        let n = cells.len();
        let pad = u32::try_from(n).expect("vertex numbers fit in u32");
        // Not zeroed (a block the allocator kept would be cleared by one thread): each part
        // fills its own with `pad`, in parallel, and writes its steps.
        let mut adj: Vec<[u32; SLOTS]> = Vec::with_capacity(n);
        let mut steps: Vec<[f32; 4]> = Vec::with_capacity(n);
        // The vertices in one part per thread, each part reading all the quads for its own
        // vertices' corners.
        let parts = rayon::current_num_threads().clamp(1, n.max(1));
        let mut jobs = Vec::with_capacity(parts);
        let (mut adj_rest, mut steps_rest) = (
            &mut adj.spare_capacity_mut()[..n],
            &mut steps.spare_capacity_mut()[..n],
        );
        for r in 0..parts {
            let (lo, hi) = (n * r / parts, n * (r + 1) / parts);
            let (a, ar) = std::mem::take(&mut adj_rest).split_at_mut(hi - lo);
            let (s, sr) = std::mem::take(&mut steps_rest).split_at_mut(hi - lo);
            (adj_rest, steps_rest) = (ar, sr);
            jobs.push((lo, a, s));
        }
        let extras: Vec<Vec<(u32, Vec<u32>)>> = jobs
            .into_par_iter()
            .map(|(lo, adj, steps)| {
                let mut mine = quads;
                if by_plane && !adj.is_empty() {
                    // A vertex of slab x is a corner of the faces of planes x − 1 and x only.
                    let low = |q: &[u32; 4]| q.iter().map(|&v| cells[v as usize][0]).min();
                    let (xa, xb) = (cells[lo][0], cells[lo + adj.len() - 1][0]);
                    let a = quads.partition_point(|q| low(q) < Some(xa.saturating_sub(1)));
                    let b = quads.partition_point(|q| low(q) <= Some(xb));
                    mine = &quads[a..b.max(a)];
                }
                let adj = crate::fill_uninit(adj, [pad; SLOTS]);
                part(mine, cells, lo, adj, steps)
            })
            .collect();
        // SAFETY: the parts cover the first n entries of both; each part filled its entries
        // of `adj` and wrote every one of its `steps` (`part` asserts their lengths agree).
        unsafe {
            adj.set_len(n);
            steps.set_len(n);
        }
        let extra = extras.concat();
        // The first vertex of each lattice slab (the wavefront's unit).
        let slab_count = cells.last().map_or(0, |c| c[0] as usize + 1);
        let mut slabs = vec![0usize; slab_count + 1];
        for (v, c) in cells.iter().enumerate() {
            assert!(
                v == 0 || cells[v - 1][0] <= c[0],
                "vertices numbered slab by slab"
            );
            slabs[c[0] as usize + 1] = v + 1;
        }
        for x in 1..=slab_count {
            slabs[x] = slabs[x].max(slabs[x - 1]);
        }
        Graph {
            adj,
            extra,
            steps,
            slabs,
        }
    }
}

/// `Graph::of` for the vertices `lo..lo + adj.len()`: their neighbour slots and step sums into
/// `adj` and `steps`; returns their extra neighbours.
fn part(
    quads: &[[u32; 4]],
    cells: &[[u32; 3]],
    lo: usize,
    adj: &mut [[u32; SLOTS]],
    steps: &mut [std::mem::MaybeUninit<[f32; 4]>],
) -> Vec<(u32, Vec<u32>)> {
    let hi = lo + adj.len();
    let mut sums = vec![[0i8; 4]; adj.len()];
    let mut more: Vec<(u32, u32)> = Vec::new();
    for q in quads {
        // The corners' lattice points, read once for the quad's four edges.
        let c = q.map(|v| cells[v as usize]);
        for j in 0..4 {
            let (v, w) = (q[j] as usize, q[(j + 1) % 4]);
            if v < lo || v >= hi {
                continue;
            }
            let step = &mut sums[v - lo];
            let k = step[3] as usize;
            assert!(k < 12, "at most 12 neighbours");
            if k < SLOTS {
                adj[v - lo][k] = w;
            } else {
                more.push((v as u32, w));
            }
            step[3] += 1;
            for a in 0..3 {
                // Wrapping: a neighbour's lattice point is at most one step away on each axis.
                let d = c[(j + 1) % 4][a].wrapping_sub(c[j][a]);
                assert!(d.wrapping_add(1) <= 2, "a neighbour in the next cells");
                step[a] = step[a].wrapping_add(d as i8);
            }
        }
    }
    assert_eq!(steps.len(), sums.len(), "a step for every vertex");
    for (out, s) in steps.iter_mut().zip(&sums) {
        assert!(s[3] > 0, "every vertex in a quad");
        out.write([
            f32::from(s[0]),
            f32::from(s[1]),
            f32::from(s[2]),
            1.0 / f32::from(s[3]),
        ]);
    }
    // By vertex, each vertex's in the order of its quads (a stable sort).
    more.sort_by_key(|&(v, _)| v);
    let mut extra: Vec<(u32, Vec<u32>)> = Vec::new();
    for (v, w) in more {
        match extra.last_mut() {
            Some((u, ws)) if *u == v => ws.push(w),
            _ => extra.push((v, vec![w])),
        }
    }
    extra
}

/// The positions of one step, shared by the threads.
#[derive(Clone, Copy)]
struct Buffer(*mut [f32; 4]);
// SAFETY: the threads write and read disjoint parts, in the order the module doc gives.
unsafe impl Sync for Buffer {}
unsafe impl Send for Buffer {}

/// One Jacobi step of slab `vertices` from `from` into `to`, moving by `factor`.
///
/// # Safety
/// `from` and `to` hold `graph.steps.len() + 1` entries, the last zero; `vertices` is a slab,
/// every entry of `from` at the slab's vertices' neighbours and at the slab itself holds its
/// step and no thread writes it meanwhile, and no thread reads or writes `to` at the slab
/// meanwhile.
unsafe fn step(
    graph: &Graph,
    vertices: std::ops::Range<usize>,
    from: Buffer,
    to: Buffer,
    factor: f32,
) {
    let first = vertices.start;
    // The vertices of the slab with more than SLOTS neighbours.
    let mut extra = graph.extra[graph.extra.partition_point(|&(v, _)| (v as usize) < first)..]
        .iter()
        .peekable();
    let slab = graph.adj[vertices.clone()]
        .iter()
        .zip(&graph.steps[vertices]);
    for (i, (adj, steps)) in slab.enumerate() {
        let v = first + i;
        // The neighbours' offsets summed as a tree (three levels where one after another took
        // six: each vertex's work is a chain of dependent additions), the extra ones after
        // them, then their lattice points' from this one's. All four lanes are computed alike
        // (so each line is one vector operation), the fourth from zeros: it stays zero (left
        // to the neighbours' sums it grew into subnormal numbers, which took the pass twice
        // as long).
        // SAFETY: a neighbour's entry of `from` (or the zero one), as the caller promises.
        let at = |i: usize| unsafe { *from.0.add(adj[i] as usize) };
        let (n0, n1, n2, n3, n4, n5) = (at(0), at(1), at(2), at(3), at(4), at(5));
        let mut t = [0.0f32; 4];
        for k in 0..4 {
            t[k] = ((n0[k] + n1[k]) + (n2[k] + n3[k])) + (n4[k] + n5[k]);
        }
        if extra.peek().is_some_and(|(u, _)| *u as usize == v) {
            let (_, more) = extra.next().expect("peeked");
            for &w in more {
                // SAFETY: as above.
                let p = unsafe { *from.0.add(w as usize) };
                for k in 0..4 {
                    t[k] += p[k];
                }
            }
        }
        // p + f·(s/valence − p), as p·(1 − f) + s·(f/valence): two dependent operations after
        // the sum instead of four.
        let (keep, by) = (1.0 - factor, factor * steps[3]);
        // SAFETY: the vertex's own entries, as the caller promises.
        let p = unsafe { *from.0.add(v) };
        let mut out = [0.0f32; 4];
        for k in 0..4 {
            // Lane 3 of `steps` (1 / valence) times zero: one load of the four lanes.
            let s = t[k] + steps[k] * [1.0, 1.0, 1.0, 0.0][k];
            out[k] = (p[k] * keep + s * by).clamp(-HALF, HALF);
        }
        // SAFETY: as the caller promises.
        unsafe { *to.0.add(v) = out };
    }
}

/// What the threads of [`relax`] share: each thread's count of slabs its last step has done,
/// and whether a thread has stopped early (canceled, or panicking).
struct Pipeline {
    done: Vec<AtomicUsize>,
    stopped: AtomicBool,
}

/// Sets `stopped` unless disarmed: a thread that returns early or unwinds must not leave the
/// next waiting for ever.
struct StopOnDrop<'a>(&'a AtomicBool, bool);

impl Drop for StopOnDrop<'_> {
    fn drop(&mut self) {
        if self.1 {
            self.0.store(true, Ordering::Release);
        }
    }
}

/// `rounds` rounds of Taubin's two steps on `now` (each vertex's offset from its lattice
/// point), run as the module doc's wavefront, pipelined over up to `threads` threads of the
/// rayon pool.
pub(super) fn relax(
    graph: &Graph,
    now: &mut Vec<[f32; 4]>,
    rounds: usize,
    threads: usize,
    ctl: &Control,
) -> Result<(), Canceled> {
    let stages = stage_count(now.len(), graph.slabs.len() - 1, rounds, threads);
    relax_in_stages(graph, now, rounds, stages, ctl)
}

/// [`relax`] cut into `stages` stages (at most `rounds`).
fn relax_in_stages(
    graph: &Graph,
    now: &mut Vec<[f32; 4]>,
    rounds: usize,
    stages: usize,
    ctl: &Control,
) -> Result<(), Canceled> {
    let n = now.len();
    assert_eq!(graph.steps.len(), n, "a step sum per vertex");
    assert_eq!(graph.adj.len(), n, "neighbour slots per vertex");
    assert_eq!(
        graph.slabs.last().copied(),
        Some(n),
        "slabs cover the vertices"
    );
    let slabs = graph.slabs.len() - 1;
    let passes = 2 * rounds;
    if passes == 0 || n == 0 {
        return Ok(());
    }
    // Each array with the zero entry the unused neighbour slots point to. The other array's
    // entries are each written by the first step before any is read (the schedule above), so
    // it starts as zeros (fresh pages, not a copy).
    now.push([0.0; 4]);
    let mut other = vec![[0.0f32; 4]; now.len()];
    let buffers = [Buffer(now.as_mut_ptr()), Buffer(other.as_mut_ptr())];
    // Consecutive runs of steps (a stage with less than a round would wait more than it
    // works).
    let stages = stages.clamp(1, rounds);
    let cut = |k: usize| passes * k / stages;
    let shared = Pipeline {
        done: (0..stages).map(|_| AtomicUsize::new(0)).collect(),
        stopped: AtomicBool::new(false),
    };
    // Stage k runs slabs + 2·(its steps − 1) sweeps.
    let counter = ctl.counter((stages * slabs + 2 * (passes - stages)) as u64);
    let stage = |k: usize| -> Result<(), Canceled> {
        let mut guard = StopOnDrop(&shared.stopped, true);
        let (a, b) = (cut(k), cut(k + 1));
        let sweeps = slabs + 2 * (b - a - 1);
        for t in 0..sweeps {
            counter.check()?;
            if k > 0 {
                // Steps a − 1 of slabs ..= t + 1, from the thread before.
                let need = (t + 2).min(slabs);
                let mut spins = 0u32;
                while shared.done[k - 1].load(Ordering::Acquire) < need {
                    if shared.stopped.load(Ordering::Acquire) {
                        return Err(Canceled::Canceled);
                    }
                    spins += 1;
                    if spins < 256 {
                        std::hint::spin_loop();
                    } else {
                        std::thread::yield_now();
                    }
                }
            }
            // Step p + 1 of slab t − 2(p − a), for the p with that slab in the grid.
            let lo = a + (t + 1).saturating_sub(slabs).div_ceil(2);
            let hi = (a + t / 2).min(b - 1);
            for p in lo..=hi {
                let x = t - 2 * (p - a);
                // SAFETY: step p of slabs x − 1 ..= x + 1 is in buffer p % 2: from this
                // thread's sweeps before, or (p = a) from the thread before, waited for above;
                // no thread writes it now (the next step to be written there, p + 2, is this
                // thread's or a later one's, after its own reads of step p + 1 of slab x); and
                // buffer (p + 1) % 2 at slab x is written by step p alone (module doc).
                unsafe {
                    step(
                        graph,
                        graph.slabs[x]..graph.slabs[x + 1],
                        buffers[p % 2],
                        buffers[(p + 1) % 2],
                        [TAUBIN.0 as f32, TAUBIN.1 as f32][p % 2],
                    )
                };
            }
            // Slabs done by the last step, b − 1.
            let last = (t + 1).saturating_sub(2 * (b - 1 - a)).min(slabs);
            shared.done[k].store(last, Ordering::Release);
            counter.add(1);
        }
        guard.1 = false;
        Ok(())
    };
    // Stage k on this thread, the later ones offered to the pool's other threads (rayon's
    // join): a stage waits only for the one before, which has started by then (stage 0 never
    // waits), so no wait can be for a stage that never runs; a stage no other thread takes
    // runs here after the one before has finished, without waiting.
    fn from<F: Fn(usize) -> Result<(), Canceled> + Sync>(
        k: usize,
        stages: usize,
        stage: &F,
    ) -> Result<(), Canceled> {
        if k + 1 == stages {
            return stage(k);
        }
        let (r, rest) = rayon::join(|| stage(k), || from(k + 1, stages, stage));
        r.and(rest)
    }
    let result = from(0, stages, &stage);
    drop(other);
    now.pop();
    result
}

/// Each of the `n` vertices' neighbours in `quads`, in the order of the quads: `w` follows `v`
/// in a quad (the tests' references).
#[cfg(test)]
pub(super) fn quad_neighbours(quads: &[[u32; 4]], n: usize) -> Vec<Vec<usize>> {
    let mut nb = vec![Vec::new(); n];
    for q in quads {
        for j in 0..4 {
            nb[q[j] as usize].push(q[(j + 1) % 4] as usize);
        }
    }
    nb
}

/// The steps one after another, each over every vertex, each vertex's neighbours taken from
/// the quads ([`quad_neighbours`]): the definition the wavefront must equal (the tests'
/// reference).
#[cfg(test)]
pub(super) fn relax_in_passes(
    quads: &[[u32; 4]],
    cells: &[[u32; 3]],
    now: &mut Vec<[f32; 4]>,
    rounds: usize,
) {
    let nb = quad_neighbours(quads, now.len());
    for _ in 0..rounds {
        for factor in [TAUBIN.0 as f32, TAUBIN.1 as f32] {
            let mut next = now.clone();
            for (v, out) in next.iter_mut().enumerate() {
                // Step's order: the first six neighbours (zeros for missing ones) as a tree,
                // the rest one by one, then the lattice sum.
                let nbs: Vec<[f32; 4]> = (0..nb[v].len().max(6))
                    .map(|i| nb[v].get(i).map_or([0.0; 4], |&w| now[w]))
                    .collect();
                let mut t = [0.0f32; 3];
                for k in 0..3 {
                    t[k] = ((nbs[0][k] + nbs[1][k]) + (nbs[2][k] + nbs[3][k]))
                        + (nbs[4][k] + nbs[5][k]);
                    for n in &nbs[6..] {
                        t[k] += n[k];
                    }
                }
                let inv = 1.0 / nb[v].len() as f32;
                let p = now[v];
                for k in 0..3 {
                    let lattice: i64 = nb[v]
                        .iter()
                        .map(|&w| i64::from(cells[w][k]) - i64::from(cells[v][k]))
                        .sum();
                    let s = t[k] + lattice as f32;
                    out[k] = (p[k] * (1.0 - factor) + s * (factor * inv)).clamp(-HALF, HALF);
                }
            }
            *now = next;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testkit::Rng;

    /// Random quads on random vertices numbered slab by slab, each quad's consecutive corners
    /// in the next cells (what `Graph::of` requires of a net), valences up to 12, so the
    /// neighbour slots, the extra lists and the zero entry are all used.
    /// `flat`: each quad's corners in two consecutive slabs, as a net's faces' are.
    fn random_net(
        rng: &mut Rng,
        n: usize,
        slabs: u32,
        flat: bool,
    ) -> (Vec<[u32; 4]>, Vec<[u32; 3]>) {
        let mut cells: Vec<[u32; 3]> = (0..n)
            .map(|_| {
                [
                    rng.below(slabs as usize) as u32,
                    rng.below(3) as u32,
                    rng.below(3) as u32,
                ]
            })
            .collect();
        cells.sort_unstable();
        let near = |a: [u32; 3], b: [u32; 3]| (0..3).all(|k| a[k].abs_diff(b[k]) <= 1);
        let mut valence = vec![0usize; n];
        let mut quads = Vec::new();
        for _ in 0..40 * n {
            let q: [u32; 4] = std::array::from_fn(|_| rng.below(n) as u32);
            let c = q.map(|v| cells[v as usize]);
            let distinct = (0..4).all(|i| (0..i).all(|j| q[i] != q[j]));
            let xs = c.map(|c| c[0]);
            let (lo, hi) = (xs.iter().min().unwrap(), xs.iter().max().unwrap());
            if distinct
                && (0..4).all(|j| near(c[j], c[(j + 1) % 4]))
                && (!flat || hi - lo <= 1)
                && q.iter().all(|&v| valence[v as usize] < 12)
            {
                for &v in &q {
                    valence[v as usize] += 1;
                }
                quads.push(q);
            }
        }
        // Only the vertices in a quad (a net's every vertex is), numbered in the same order.
        let mut number = vec![u32::MAX; n];
        let mut kept = Vec::new();
        for v in 0..n {
            if valence[v] > 0 {
                number[v] = kept.len() as u32;
                kept.push(cells[v]);
            }
        }
        for q in &mut quads {
            *q = q.map(|v| number[v as usize]);
        }
        (quads, kept)
    }

    #[test]
    fn the_pipelined_wavefront_equals_the_steps_one_after_another() {
        let mut rng = Rng::new(33);
        let mut saw_extra = false;
        for case in 0..40 {
            let n = 20 + rng.below(200);
            let (quads, cells) = random_net(&mut rng, n, 1 + (case % 9) as u32, false);
            let n = cells.len();
            let graph = Graph::of(&quads, &cells, false);
            saw_extra |= !graph.extra.is_empty();
            let start: Vec<[f32; 4]> = (0..n)
                .map(|_| {
                    let o = rng.point(-f64::from(HALF), f64::from(HALF));
                    [o[0] as f32, o[1] as f32, o[2] as f32, 0.0]
                })
                .collect();
            let rounds = 1 + case % 7;
            let mut want = start.clone();
            relax_in_passes(&quads, &cells, &mut want, rounds);
            // Stages on as many threads, and more stages than threads (each thread then runs
            // several, one after another).
            for (stages, threads) in [(1, 1), (2, 2), (3, 3), (5, 5), (3, 1), (4, 2), (7, 2)] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let mut got = start.clone();
                pool.install(|| {
                    relax_in_stages(&graph, &mut got, rounds, stages, &Control::none())
                })
                .unwrap();
                assert_eq!(got.len(), n);
                for (v, (g, w)) in got.iter().zip(&want).enumerate() {
                    for k in 0..3 {
                        assert_eq!(
                            g[k].to_bits(),
                            w[k].to_bits(),
                            "case {case}, {stages} stages, {threads} threads, vertex {v}, axis {k}"
                        );
                    }
                }
                // Something moved (the test would pass on a no-op otherwise).
                assert!(rounds == 0 || got != start || quads.is_empty());
            }
        }
        assert!(saw_extra, "no vertex had more than SLOTS neighbours");
    }

    #[test]
    fn stages_are_as_deep_as_the_cache_holds_and_a_multiple_of_the_threads() {
        // igea-subdiv4 at 518³: 916,884 vertices in 519 slabs, 127 KB a slab: 4 steps a stage.
        assert_eq!(stage_count(916_884, 519, 12, 2), 6);
        assert_eq!(stage_count(916_884, 519, 12, 4), 8);
        // At 262³: 8 steps a stage, 3 stages, rounded up to 4 for 2 threads.
        assert_eq!(stage_count(229_022, 263, 12, 2), 4);
        // Small nets: a stage a thread; never more stages than rounds, nor fewer than one.
        assert_eq!(stage_count(200, 9, 12, 2), 2);
        assert_eq!(stage_count(200, 9, 3, 8), 3);
        assert_eq!(stage_count(0, 0, 0, 2), 1);
        // Huge slabs: a round a stage.
        assert_eq!(stage_count(1 << 30, 1024, 12, 2), 12);
    }

    #[test]
    fn a_graph_of_quads_by_plane_reads_only_its_slabs_quads_and_is_the_same() {
        let mut rng = Rng::new(5);
        for case in 0..30 {
            let n = 50 + rng.below(300);
            let (mut quads, cells) = random_net(&mut rng, n, 2 + (case % 11) as u32, true);
            // In order of their lowest lattice x, as a net's are.
            quads.sort_by_key(|q| q.iter().map(|&v| cells[v as usize][0]).min());
            let all = Graph::of(&quads, &cells, false);
            for threads in [1, 2, 3, 5] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let got = pool.install(|| Graph::of(&quads, &cells, true));
                assert_eq!(got.adj, all.adj, "case {case}, {threads} threads");
                assert_eq!(got.extra, all.extra, "case {case}");
                assert_eq!(got.steps, all.steps, "case {case}");
                assert_eq!(got.slabs, all.slabs, "case {case}");
            }
        }
    }

    #[test]
    fn a_canceled_relaxation_stops_with_the_positions_it_was_given_back() {
        let mut rng = Rng::new(7);
        let (quads, cells) = random_net(&mut rng, 300, 20, false);
        let n = cells.len();
        let graph = Graph::of(&quads, &cells, false);
        let ctl = Control::new();
        ctl.cancel();
        for threads in [1, 2, 4] {
            let mut now = vec![[0.1f32, 0.0, 0.0, 0.0]; n];
            assert!(relax(&graph, &mut now, 12, threads, &ctl).is_err());
            assert_eq!(now.len(), n, "the zero entry is taken off again");
        }
    }
}
