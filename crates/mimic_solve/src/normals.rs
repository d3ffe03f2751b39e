//! Area-weighted vertex normals: the reference face-by-face pass ([`vertex_normals`]) and a
//! vertex-by-vertex gather over precomputed triangle fans ([`VertexFans`]) for the per-frame path.

use crate::kernel::VectorKernel;
use glam::{Vec3, Vec3A, Vec3Swizzles};

/// Area-weighted vertex normals: each vertex gets the normalised sum of the un-normalised normals
/// `(b - a) x (c - a)` of its triangles (counter-clockwise seen from outside points outwards).
///
/// Allocates nothing. Vertices in no triangle, or whose summed normal has zero length (e.g. only
/// degenerate triangles), get `Vec3::ZERO`. Triangles naming a vertex outside `positions` are skipped.
///
/// # Panics
/// If `out.len() != positions.len()`.
pub fn vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]], out: &mut [Vec3]) {
    assert_eq!(
        out.len(),
        positions.len(),
        "vertex_normals: output length differs from positions"
    );
    out.fill(Vec3::ZERO);
    for t in triangles {
        let (ia, ib, ic) = (t[0] as usize, t[1] as usize, t[2] as usize);
        let (Some(a), Some(b), Some(c)) = (positions.get(ia), positions.get(ib), positions.get(ic))
        else {
            continue;
        };
        let n = (*b - *a).cross(*c - *a);
        out[ia] += n;
        out[ib] += n;
        out[ic] += n;
    }
    for n in out.iter_mut() {
        *n = n.normalize_or_zero();
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2;

/// Vertices gathered together by [`VertexFans`]: two AVX registers of f32 lanes.
const GROUP: usize = 16;

/// Lanes of one AVX register of f32: the AVX2 path runs a group as two halves of this many.
#[cfg(target_arch = "x86_64")]
const HALF: usize = 8;

/// Triangle fans around the first `count` vertices of a mesh, for gathering their area-weighted
/// normals vertex by vertex (the same normals as [`vertex_normals`], up to f32 rounding).
///
/// Vertex `v`'s fan is a list of neighbours `w_0, w_1, ..., w_r` such that each consecutive pair
/// `(w_l, w_{l+1})` closes a triangle `(v, w_l, w_{l+1})` in the mesh's orientation. Where the
/// triangles around `v` do not form one chain (boundary, non-manifold), the chains are joined by
/// `v` itself, and a list that does not end at `w_0` ends with `v`: every list, closed by a last
/// edge back to `w_0`, is a closed polygon, each pair through `v` a degenerate triangle. The area
/// vector of a closed polygon, `sum_l (p[w_l] - o) x (p[w_{l+1}] - o)`, is the same for every
/// origin `o`: with `o = p[v]` it is the sum of the fan's triangles' cross products at `v`'s
/// corner (the area-weighted normal); the kernels take `o = p[w_0]`, whose difference vector is
/// zero, so they read no centre, skip the first edge's term and need no closing edge: a list
/// that ends at `w_0` (a closed fan) is stored without that last entry. Padding past a list's
/// end repeats `w_0` (zero difference vector, adds exactly nothing). A closed fan of `k`
/// triangles reads `k` neighbours for `k - 2` cross products, and no sum is scattered to memory.
///
/// Fans are stored in groups of 16 vertices of (nearly) equal fan length, step-major (entry `l`
/// of the 16 fans side by side), so that [`VertexFans::normals_packed`] can run the 16 fans in
/// the lanes of two AVX registers, with no data-dependent branch inside a group.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexFans {
    /// Per group: first entry in `entries`, steps (entries per lane), lanes in use (1..=16).
    groups: Vec<[u32; 3]>,
    /// 16 centre vertices per group (unused lanes repeat the first).
    centres: Vec<u32>,
    /// Per group, `steps * 16` neighbours, step-major.
    entries: Vec<u32>,
    /// `entries` times 3: each neighbour's offset (in floats) in positions packed 3 floats a
    /// vertex, read by the packed kernels with no multiply per load.
    offsets: Vec<u32>,
    /// Vertices with a fan.
    count: usize,
    /// Positions needed: one past the largest vertex any fan names.
    position_count: usize,
}

impl VertexFans {
    /// Fans of vertices `0..count` from `triangles` over `vertex_count` positions; triangles naming
    /// a vertex `>= vertex_count` are skipped, as in [`vertex_normals`].
    ///
    /// # Panics
    /// If the fans name a vertex past `u32::MAX / 3` (its packed offset would not fit a `u32`).
    pub fn new(count: usize, vertex_count: usize, triangles: &[[u32; 3]]) -> Self {
        let count = count.min(vertex_count);
        let fans = chain_fans(count, vertex_count, triangles);
        // Group by fan length (stable, so neighbouring vertices stay together).
        let mut order: Vec<usize> = (0..count).collect();
        order.sort_by_key(|&v| fans[v].len());
        let mut groups = Vec::with_capacity(count.div_ceil(GROUP));
        let mut centres = Vec::with_capacity(count.div_ceil(GROUP) * GROUP);
        let mut entries = Vec::new();
        for chunk in order.chunks(GROUP) {
            let steps = chunk.iter().map(|&v| fans[v].len()).max().unwrap_or(0);
            groups.push([entries.len() as u32, steps as u32, chunk.len() as u32]);
            let lane = |k: usize| chunk.get(k).copied().unwrap_or(chunk[0]);
            centres.extend((0..GROUP).map(|k| lane(k) as u32));
            for l in 0..steps {
                for k in 0..GROUP {
                    let v = lane(k);
                    // Past its end, a fan is padded with its first entry (its origin): zero
                    // difference vector; an empty fan with its own centre.
                    let pad = fans[v].first().copied().unwrap_or(v as u32);
                    entries.push(fans[v].get(l).copied().unwrap_or(pad));
                }
            }
        }
        let position_count = entries
            .iter()
            .map(|&w| w as usize + 1)
            .max()
            .unwrap_or(0)
            .max(count);
        assert!(
            3 * position_count <= u32::MAX as usize,
            "VertexFans::new: {position_count} positions: packed offsets past u32"
        );
        // u32 offsets always: packing them as u16 where every one fits (`ict-face-3k`) made no
        // difference to the step in `mimic bench`'s A/B on the CI machine class (AMD EPYC Zen 2,
        // 2026-12-07: 0.992-0.999x), under the 10 % a variant must buy (docs/performance.md).
        let offsets = entries.iter().map(|&w| 3 * w).collect();
        Self {
            groups,
            centres,
            entries,
            offsets,
            count,
            position_count,
        }
    }

    /// The same fans with each vertex `v`'s normal reported as `names[v]` instead of `v` (e.g.
    /// its index in the whole mesh, when the fans were built over a part of it): the normal
    /// passes then call `write(names[v], normal)`, saving the caller a lookup per vertex.
    ///
    /// # Panics
    /// If `names.len() < count()`.
    pub fn with_names(mut self, names: &[u32]) -> Self {
        assert!(
            names.len() >= self.count,
            "VertexFans::with_names: {} names for {} fans",
            names.len(),
            self.count
        );
        for c in &mut self.centres {
            *c = names[*c as usize];
        }
        self
    }

    /// Number of vertices with a fan (`0..count`).
    pub fn count(&self) -> usize {
        self.count
    }

    /// Number of positions [`VertexFans::normals_packed`] reads.
    pub fn position_count(&self) -> usize {
        self.position_count
    }

    /// Fan entries over all lanes, padding included: the neighbour reads of one call.
    pub fn entry_count(&self) -> usize {
        self.entries.len()
    }

    /// Calls `write(v, normal)` once for every vertex `v < count()` (in no particular order) with
    /// its normalised area-weighted normal, zero where the sum has no finite, non-zero length
    /// (as `normalize_or_zero`; the vectorised path also gives zero for sums whose squared length
    /// is subnormal, below 1.2e-38), on positions packed 3 floats a vertex (`positions[3 v..3 v +
    /// 3]`, one float of padding after the last), as
    /// [`crate::deform::MovingDeform::deform_packed`] writes them; allocates nothing. By
    /// [`VectorKernel::best_for_normals`]'s kernel: 8 fans at a time with AVX2 + FMA (each
    /// normalised by a Newton-refined reciprocal square root, within 4 eps), else one by one.
    ///
    /// # Panics
    /// If `positions.len() < 3 * position_count() + 1`.
    pub fn normals_packed(&self, positions: &[f32], write: impl FnMut(usize, Vec3)) {
        self.normals_packed_by(VectorKernel::best_for_normals(), positions, write);
    }

    /// [`VertexFans::normals_packed`] by a given kernel ([`VectorKernel::available`]: the
    /// portable one where the CPU lacks `kernel`), for A/B comparisons and tests.
    ///
    /// # Panics
    /// As [`VertexFans::normals_packed`].
    pub fn normals_packed_by(
        &self,
        kernel: VectorKernel,
        positions: &[f32],
        mut write: impl FnMut(usize, Vec3),
    ) {
        assert!(
            positions.len() > 3 * self.position_count,
            "VertexFans::normals_packed: {} floats, fans name {} positions (3 floats each and 1 of padding)",
            positions.len(),
            self.position_count
        );
        #[cfg(target_arch = "x86_64")]
        {
            let p = positions.as_ptr();
            let kernel = kernel.available();
            // SAFETY: the kernel's CPU features are checked by `available`; every centre and
            // entry v is below position_count, and the 4 floats at 3 v lie within positions
            // (asserted: 3 position_count + 1 floats); each group's entries lie in the offsets
            // by construction.
            let ran = unsafe { self.normals_packed_vector(kernel, &self.offsets, p, &mut write) };
            if ran {
                return;
            }
        }
        self.normals_packed_portable(positions, &mut write);
    }

    /// [`VertexFans::normals_packed_by`]'s vector kernels on the packed offsets;
    /// false (nothing done) for [`VectorKernel::Portable`].
    ///
    /// # Safety
    /// `kernel` must be one the CPU runs ([`VectorKernel::available`]); `offsets` are this
    /// fan set's packed offsets and `p` is valid for reading 4 floats at each of them.
    #[cfg(target_arch = "x86_64")]
    unsafe fn normals_packed_vector<E: Entry>(
        &self,
        kernel: VectorKernel,
        offsets: &[E],
        p: *const f32,
        write: &mut impl FnMut(usize, Vec3),
    ) -> bool {
        // SAFETY: as this function's contract.
        unsafe {
            match kernel {
                VectorKernel::Avx2 => self.normals_avx2(offsets, p, write),
                VectorKernel::Portable => return false,
            }
        }
        true
    }

    /// [`VertexFans::normals_packed`] one fan at a time, on any CPU.
    fn normals_packed_portable(&self, positions: &[f32], write: &mut impl FnMut(usize, Vec3)) {
        for (g, &[first, steps, lanes]) in self.groups.iter().enumerate() {
            let entries = &self.entries[first as usize..][..steps as usize * GROUP];
            let at = |v: usize| Vec3A::from_slice(&positions[3 * v..3 * v + 3]);
            for k in 0..lanes as usize {
                let v = self.centres[g * GROUP + k] as usize;
                let acc = fan_sum(entries.iter().skip(k).step_by(GROUP), at);
                write(v, Vec3::from(acc.normalize_or_zero()));
            }
        }
    }
}

/// A stored fan entry as the vector kernels read it: a packed position's float offset.
trait Entry: Copy {
    /// The entry as an index.
    fn index(self) -> usize;
}

impl Entry for u32 {
    #[inline(always)]
    fn index(self) -> usize {
        self as usize
    }
}

/// The un-normalised fan sum `sum_l (p[w_l] - p[w_0]) x (p[w_l+1] - p[w_0])`, the first entry as
/// origin (see [`VertexFans`]), one fan at a time (the portable paths), in x, y, z order.
fn fan_sum<'a>(mut fan: impl Iterator<Item = &'a u32>, at: impl Fn(usize) -> Vec3A) -> Vec3A {
    let mut acc = Vec3A::ZERO;
    // The first entry is the origin (its difference vector is zero), as in the vector kernels.
    if let (Some(&w0), Some(&w1)) = (fan.next(), fan.next()) {
        let c = at(w0 as usize);
        // a x b = (a * b.yzx - a.yzx * b).yzx: sum the inner vectors, rotate at the end. Each
        // term is added as the vector kernels add it, two fused multiply-adds into the sum
        // (`acc + a b_r`, rounded, then `- a_r b`, rounded).
        let mut a = at(w1 as usize) - c;
        let mut a_r = a.yzx();
        for &w in fan {
            let b = at(w as usize) - c;
            let b_r = b.yzx();
            acc = (-a_r).mul_add(b, a.mul_add(b_r, acc));
            a = b;
            a_r = b_r;
        }
    }
    acc.yzx()
}

/// Per vertex `v < count`, its triangles `(v, w1, w2)` chained into fans `w_0, w_1, ...` (see
/// [`VertexFans`]), chains joined by `v` itself.
fn chain_fans(count: usize, vertex_count: usize, triangles: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut pairs: Vec<Vec<(u32, u32)>> = vec![Vec::new(); count];
    let valid = |t: &&[u32; 3]| t.iter().all(|&v| (v as usize) < vertex_count);
    for t in triangles.iter().filter(valid) {
        for c in 0..3 {
            if let Some(p) = pairs.get_mut(t[c] as usize) {
                p.push((t[(c + 1) % 3], t[(c + 2) % 3]));
            }
        }
    }
    let mut used = Vec::new();
    pairs
        .iter()
        .enumerate()
        .map(|(v, mine)| {
            let mut fan = Vec::with_capacity(mine.len() + 1);
            used.clear();
            used.resize(mine.len(), false);
            loop {
                // Start an open chain where one begins (a first neighbour that closes no other
                // unused triangle), else anywhere (a closed fan).
                let open = (0..mine.len()).find(|&a| {
                    !used[a]
                        && !(0..mine.len()).any(|b| !used[b] && b != a && mine[b].1 == mine[a].0)
                });
                let Some(a) = open.or_else(|| (0..mine.len()).find(|&a| !used[a])) else {
                    break;
                };
                if !fan.is_empty() {
                    fan.push(v as u32); // separator: zero difference vector
                }
                used[a] = true;
                fan.push(mine[a].0);
                fan.push(mine[a].1);
                let mut cur = mine[a].1;
                while let Some(b) = (0..mine.len()).find(|&b| !used[b] && mine[b].0 == cur) {
                    used[b] = true;
                    cur = mine[b].1;
                    fan.push(cur);
                }
            }
            // A list that does not end where it starts (an open chain, or several) ends with `v`
            // itself, so that it is a closed polygon whose sum does not depend on the origin.
            // One that does (a closed fan) drops its last entry, `w_0` again: with `p[w_0]` as
            // origin, the edge back to `w_0` adds exactly zero, so the kernels leave it implicit.
            if fan.first() != fan.last() {
                fan.push(v as u32);
            } else if fan.len() > 1 {
                fan.pop();
            }
            fan
        })
        .collect()
}

#[cfg(test)]
mod tests;
