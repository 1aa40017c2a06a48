//! The BVH as the device reads it: sibling pairs with boxes quantised to 16
//! bits on a grid over the scene's box.
//!
//! On llvmpipe every texel fetch of a per-lane address is a gather, and the
//! traversal is bound by them. A full-precision node pair takes four texels;
//! quantised, a pair takes two (one per child: box and reference), and a
//! deferred child is pushed as its reference, so popping it reads nothing.
//!
//! Each quantised box contains the exact box: corners are rounded outwards
//! and checked against the decoding the kernels do (`origin + q * scale` in
//! f32, a multiply then an add, no fused multiply-add), so traversal never
//! culls a box the ray touches; it may visit a box the exact tree would skip.
//! Hits are tested on the exact primitives, so a closest hit is the same.

use glam::Vec3;

use super::structs::{GpuBvhGrid, GpuBvhPair};
use crate::accel::bvh::Bvh;
use crate::accel::geometry::Aabb;
use crate::interface::{BVH_REF_COUNT_BITS, BVH_REF_INDEX_LIMIT};

/// Largest quantised coordinate.
const Q_MAX: u32 = u16::MAX as u32;

/// The grid boxes are quantised on: `origin + q * scale` for q in 0..=65535.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Lower corner of the scene's box.
    pub origin: Vec3,
    /// Step per axis; 0 on an axis the scene is flat along.
    pub scale: Vec3,
}

/// Decodes one quantised coordinate exactly as the kernels do.
fn decode(origin: f32, scale: f32, q: u32) -> f32 {
    // Multiply, round, add, round: what `precise` asks of the kernel
    let step = q as f32 * scale;
    origin + step
}

impl Grid {
    /// The grid over `bounds`, with its last step reaching `bounds.max`.
    pub fn over(bounds: Aabb) -> Grid {
        let mut scale = Vec3::ZERO;
        for axis in 0..3 {
            let (lo, hi) = (bounds.min[axis], bounds.max[axis]);
            let mut s = ((hi as f64 - lo as f64) / Q_MAX as f64) as f32;
            // Widen the step until the top of the grid covers the box
            while decode(lo, s, Q_MAX) < hi {
                s = f32::from_bits(s.to_bits() + 1);
            }
            scale[axis] = s;
        }
        Grid {
            origin: bounds.min,
            scale,
        }
    }

    /// The smallest grid box that contains `b` (corners rounded outwards).
    pub fn quantize(&self, b: Aabb) -> ([u32; 3], [u32; 3]) {
        let mut qmin = [0u32; 3];
        let mut qmax = [Q_MAX; 3];
        for axis in 0..3 {
            let (o, s) = (self.origin[axis], self.scale[axis]);
            if s == 0.0 {
                // A flat axis: every coordinate is the origin
                qmin[axis] = 0;
                qmax[axis] = 0;
                continue;
            }
            let guess = |x: f32| ((x as f64 - o as f64) / s as f64).clamp(0.0, Q_MAX as f64);
            let mut lo = guess(b.min[axis]).floor() as u32;
            while lo > 0 && decode(o, s, lo) > b.min[axis] {
                lo -= 1;
            }
            let mut hi = guess(b.max[axis]).ceil() as u32;
            while hi < Q_MAX && decode(o, s, hi) < b.max[axis] {
                hi += 1;
            }
            qmin[axis] = lo;
            qmax[axis] = hi;
        }
        (qmin, qmax)
    }

    /// The box the kernels decode from quantised corners.
    #[cfg(test)]
    pub fn decode(&self, qmin: [u32; 3], qmax: [u32; 3]) -> Aabb {
        let corner = |q: [u32; 3]| {
            Vec3::from_array(std::array::from_fn(|a| {
                decode(self.origin[a], self.scale[a], q[a])
            }))
        };
        Aabb::new(corner(qmin), corner(qmax))
    }
}

/// Packs quantised corners as three words of 16-bit pairs: min.x | min.y,
/// min.z | max.x, max.y | max.z (low half first).
fn pack_box(qmin: [u32; 3], qmax: [u32; 3]) -> [u32; 3] {
    [
        qmin[0] | qmin[1] << 16,
        qmin[2] | qmax[0] << 16,
        qmax[1] | qmax[2] << 16,
    ]
}

/// Reference to a node as the kernels hold it: for a leaf its first
/// primitive and count, for an interior node its children's pair and count 0.
fn node_ref(bvh: &Bvh, node: usize) -> anyhow::Result<u32> {
    let n = &bvh.nodes[node];
    let index = if n.is_leaf() {
        n.left_or_first
    } else {
        // Siblings are stored together, the first at an odd node index
        anyhow::ensure!(
            n.left_or_first % 2 == 1,
            "BVH node {node}: children at {} do not start a pair",
            n.left_or_first
        );
        (n.left_or_first - 1) / 2
    };
    anyhow::ensure!(
        index < BVH_REF_INDEX_LIMIT,
        "the BVH has more than {BVH_REF_INDEX_LIMIT} nodes or primitives; split the scene"
    );
    Ok(index << BVH_REF_COUNT_BITS | n.count)
}

/// The grid header and the sibling pairs of `bvh`: pair k holds nodes
/// 2k + 1 and 2k + 2. `bvh` must have a root.
pub fn pack(bvh: &Bvh) -> anyhow::Result<(GpuBvhGrid, Vec<GpuBvhPair>)> {
    let root = &bvh.nodes[0];
    let grid = Grid::over(root.bounds());
    let header = GpuBvhGrid {
        origin: grid.origin.to_array(),
        root_ref: node_ref(bvh, 0)?,
        scale: grid.scale.to_array(),
        pad: 0,
    };
    let child = |i: usize| -> anyhow::Result<([u32; 3], u32)> {
        let (qmin, qmax) = grid.quantize(bvh.nodes[i].bounds());
        Ok((pack_box(qmin, qmax), node_ref(bvh, i)?))
    };
    let pairs = (1..bvh.nodes.len())
        .step_by(2)
        .map(|i| {
            let (left, left_ref) = child(i)?;
            let (right, right_ref) = child(i + 1)?;
            Ok(GpuBvhPair {
                left,
                left_ref,
                right,
                right_ref,
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok((header, pairs))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift), for reproducible boxes.
    fn rng(seed: &mut u64) -> f32 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (*seed >> 40) as f32 / (1u64 << 24) as f32
    }

    fn contains(outer: Aabb, inner: Aabb) -> bool {
        outer.min.cmple(inner.min).all() && outer.max.cmpge(inner.max).all()
    }

    #[test]
    fn quantised_boxes_contain_the_exact_ones_at_every_scale() {
        let mut seed = 0x9e3779b97f4a7c15u64;
        for exp in [-8i32, -3, 0, 2, 5, 8, 12] {
            let size = 10f32.powi(exp);
            for offset in [0.0f32, -3.7 * size, 1.5e5, -2.2e5, 1e8] {
                let base = Vec3::new(offset, -offset * 0.5, offset * 0.25);
                let scene = Aabb::new(base, base + Vec3::new(size, size * 0.3, size * 2.0));
                let grid = Grid::over(scene);
                assert!(contains(grid.decode([0; 3], [Q_MAX; 3]), scene));
                for _ in 0..500 {
                    let a = scene.min
                        + (scene.max - scene.min)
                            * Vec3::new(rng(&mut seed), rng(&mut seed), rng(&mut seed));
                    let b = scene.min
                        + (scene.max - scene.min)
                            * Vec3::new(rng(&mut seed), rng(&mut seed), rng(&mut seed));
                    let exact = Aabb::new(a.min(b), a.max(b));
                    let (qmin, qmax) = grid.quantize(exact);
                    let decoded = grid.decode(qmin, qmax);
                    assert!(contains(decoded, exact), "{exact:?} not inside {decoded:?}");
                    // Tight: at most two steps of slack on each side
                    let slack = grid.scale * 2.0
                        + (decoded.max.abs() + decoded.min.abs()) * 4.0 * f32::EPSILON;
                    assert!(
                        (exact.min - decoded.min).cmple(slack).all(),
                        "{exact:?} {decoded:?}"
                    );
                    assert!(
                        (decoded.max - exact.max).cmple(slack).all(),
                        "{exact:?} {decoded:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn flat_axes_and_points_decode_exactly() {
        let scene = Aabb::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0));
        let grid = Grid::over(scene);
        assert_eq!(grid.scale.y, 0.0);
        let (qmin, qmax) = grid.quantize(scene);
        assert_eq!(grid.decode(qmin, qmax), scene);
        let point = Aabb::new(Vec3::new(0.25, 0.0, 0.5), Vec3::new(0.25, 0.0, 0.5));
        let (qmin, qmax) = grid.quantize(point);
        assert!(contains(grid.decode(qmin, qmax), point));
    }

    #[test]
    fn pairs_hold_every_node_once_with_its_reference() {
        let boxes: Vec<Aabb> = (0..100)
            .map(|i| {
                let c = Vec3::new(i as f32, (i * 7 % 13) as f32, (i * 3 % 5) as f32);
                Aabb::new(c, c + Vec3::splat(0.5))
            })
            .collect();
        let bvh = crate::accel::bvh::build(&boxes);
        let (header, pairs) = pack(&bvh).unwrap();
        assert_eq!(pairs.len() * 2 + 1, bvh.nodes.len());
        let grid = Grid {
            origin: Vec3::from_array(header.origin),
            scale: Vec3::from_array(header.scale),
        };
        let unpack = |w: [u32; 3]| {
            let h = |x: u32| [x & 0xffff, x >> 16];
            let [a, b] = h(w[0]);
            let [c, d] = h(w[1]);
            let [e, f] = h(w[2]);
            ([a, b, c], [d, e, f])
        };
        for (k, p) in pairs.iter().enumerate() {
            for (node, (w, r)) in [
                (2 * k + 1, (p.left, p.left_ref)),
                (2 * k + 2, (p.right, p.right_ref)),
            ] {
                let n = &bvh.nodes[node];
                let (qmin, qmax) = unpack(w);
                assert!(contains(grid.decode(qmin, qmax), n.bounds()));
                assert_eq!(r & ((1 << BVH_REF_COUNT_BITS) - 1), n.count);
                let index = r >> BVH_REF_COUNT_BITS;
                let expected = if n.is_leaf() {
                    n.left_or_first
                } else {
                    (n.left_or_first - 1) / 2
                };
                assert_eq!(index, expected);
            }
        }
    }
}
