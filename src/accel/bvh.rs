//! Binned-SAH bounding volume hierarchy over spheres and triangles together,
//! with the CPU reference traversal that the GPU intersect kernel mirrors.
//!
//! Layout: [`Bvh::nodes`] is a flat array, root at index 0. A node with
//! `count > 0` is a leaf holding the primitives
//! `prim_order[left_or_first .. left_or_first + count]`; a node with
//! `count == 0` is interior and its children are the adjacent nodes
//! `left_or_first` and `left_or_first + 1`. [`Bvh::prim_order`] maps leaf
//! slots to original primitive indices.
//!
//! Guarantees: leaves hold between 1 and [`BVH_MAX_LEAF_PRIMS`] primitives,
//! every primitive is in exactly one leaf, each child box lies inside its
//! parent's, and [`Bvh::depth`] (nodes on the longest root-to-leaf path) is
//! at most `BVH_STACK_SIZE - 1`, so an ordered traversal that pushes the far
//! child and descends into the near one never overflows a stack of
//! [`BVH_STACK_SIZE`] entries. The build is deterministic: the same boxes
//! give the same nodes, whatever the thread count.

use glam::Vec3;

use crate::accel::geometry::{
    intersect_sphere, intersect_triangle, safe_inverse, slab_test, Aabb, Ray,
};
use crate::interface::{BVH_MAX_LEAF_PRIMS, BVH_STACK_SIZE};

/// Most levels (nodes on a root-to-leaf path) the tree may have.
const MAX_LEVELS: u32 = BVH_STACK_SIZE - 1;

/// SAH bins per axis (at most; see [`bins_for`]).
const BINS: usize = 32;

/// SAH bins per axis for nodes of at most [`SMALL_NODE`] primitives.
const SMALL_BINS: usize = 16;

/// Nodes up to this many primitives use [`SMALL_BINS`] bins.
const SMALL_NODE: usize = 256;

/// SAH cost of visiting an interior node, in units of one primitive test.
const TRAVERSAL_COST: f32 = 1.0;

/// Subtrees with more primitives than this are built in parallel.
const PARALLEL_MIN_PRIMS: usize = 10_000;

/// One node of the flattened BVH (see the module documentation for the layout).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhNode {
    /// Lower corner of the node's box.
    pub min: Vec3,
    /// Upper corner of the node's box.
    pub max: Vec3,
    /// Leaf: first slot in `prim_order`. Interior: index of the left child;
    /// the right child follows it.
    pub left_or_first: u32,
    /// Leaf: number of primitives (1..=`BVH_MAX_LEAF_PRIMS`). Interior: 0.
    pub count: u32,
}

impl BvhNode {
    /// Whether the node is a leaf.
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    /// The node's box.
    pub fn bounds(&self) -> Aabb {
        Aabb::new(self.min, self.max)
    }
}

/// A primitive as the CPU traversal sees it, indexed by its original index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Prim {
    /// A sphere.
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius.
        radius: f32,
    },
    /// A two-sided triangle.
    Triangle([Vec3; 3]),
}

impl Prim {
    /// The primitive's bounds, as [`build`] expects them.
    pub fn aabb(&self) -> Aabb {
        match *self {
            Prim::Sphere { center, radius } => Aabb::of_sphere(center, radius),
            Prim::Triangle([p0, p1, p2]) => Aabb::of_triangle(p0, p1, p2),
        }
    }

    /// Nearest hit in `(0, ray.tmax]` as `(t, b1, b2)`; the barycentrics are
    /// zero for spheres.
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, f32, f32)> {
        match *self {
            Prim::Sphere { center, radius } => {
                intersect_sphere(ray, center, radius).map(|t| (t, 0.0, 0.0))
            }
            Prim::Triangle([p0, p1, p2]) => {
                intersect_triangle(ray, p0, p1, p2).map(|h| (h.t, h.b1, h.b2))
            }
        }
    }
}

/// A closest hit found by [`Bvh::closest_hit`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Original index of the primitive hit.
    pub prim: u32,
    /// Barycentric weight of the triangle's second vertex (0 for spheres).
    pub b1: f32,
    /// Barycentric weight of the triangle's third vertex (0 for spheres).
    pub b2: f32,
}

/// A flattened bounding volume hierarchy (see the module documentation).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh {
    /// Nodes, root first; empty when built over no primitives.
    pub nodes: Vec<BvhNode>,
    /// Original primitive indices in leaf order.
    pub prim_order: Vec<u32>,
}

/// Builds a binned-SAH BVH over per-primitive boxes (same as [`Bvh::build`]).
///
/// Boxes must be free of NaN (the caller filters bad primitives); empty
/// boxes are not allowed, zero-extent ones are. Primitive `i` of the output
/// is `boxes[i]`.
pub fn build(boxes: &[Aabb]) -> Bvh {
    build_with_max_levels(boxes, MAX_LEVELS)
}

/// [`build`] with a chosen level limit (tests lift it to see the pure SAH tree).
fn build_with_max_levels(boxes: &[Aabb], max_levels: u32) -> Bvh {
    assert!(
        boxes.len() < u32::MAX as usize,
        "too many primitives for 32-bit indices"
    );
    debug_assert!(
        boxes
            .iter()
            .all(|b| !b.min.is_nan() && !b.max.is_nan() && !b.is_empty()),
        "BVH input boxes must be non-empty and NaN-free"
    );
    if boxes.is_empty() {
        return Bvh::default();
    }
    let mut refs: Vec<PrimRef> = boxes
        .iter()
        .enumerate()
        .map(|(i, b)| PrimRef {
            bounds: *b,
            centroid: b.centroid(),
            index: i as u32,
        })
        .collect();
    let root = build_node(&mut refs, 0, 1, max_levels);
    let prim_order = refs.iter().map(|r| r.index).collect();

    // Flatten depth-first, children of each node in adjacent slots.
    let mut nodes = Vec::with_capacity(root.node_count);
    nodes.push(placeholder());
    flatten(root, &mut nodes, 0);
    let bvh = Bvh { nodes, prim_order };
    debug_assert!(
        max_levels != MAX_LEVELS || bvh.depth() <= MAX_LEVELS,
        "BVH deeper than the GPU traversal stack"
    );
    bvh
}

impl Bvh {
    /// Builds a binned-SAH BVH over per-primitive boxes; see [`build`].
    pub fn build(boxes: &[Aabb]) -> Bvh {
        build(boxes)
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Levels of the tree: nodes on the longest root-to-leaf path (a lone
    /// leaf is 1, an empty tree 0). Never above `BVH_STACK_SIZE - 1`.
    pub fn depth(&self) -> u32 {
        if self.nodes.is_empty() {
            return 0;
        }
        let mut deepest = 0;
        let mut stack = vec![(0u32, 1u32)];
        while let Some((i, level)) = stack.pop() {
            let n = &self.nodes[i as usize];
            if n.is_leaf() {
                deepest = deepest.max(level);
            } else {
                stack.push((n.left_or_first, level + 1));
                stack.push((n.left_or_first + 1, level + 1));
            }
        }
        deepest
    }

    /// SAH cost of the tree, in units of one primitive test: the expected
    /// interior-node visits (each weighted by the build's traversal cost,
    /// which is one) and primitive tests of a ray that hits the root box, under the
    /// surface area heuristic: the sum over nodes of area / root area,
    /// times the traversal cost for an interior node and the primitive
    /// count for a leaf. 0 for an empty tree. Lower is better for the same
    /// primitives.
    pub fn sah_cost(&self) -> f64 {
        let Some(root) = self.nodes.first() else {
            return 0.0;
        };
        let root_area = f64::from(root.bounds().surface_area());
        if !(root_area > 0.0 && root_area.is_finite()) {
            return 0.0;
        }
        self.nodes
            .iter()
            .map(|n| {
                let weight = if n.is_leaf() {
                    f64::from(n.count)
                } else {
                    f64::from(TRAVERSAL_COST)
                };
                weight * f64::from(n.bounds().surface_area()) / root_area
            })
            .sum()
    }

    /// Closest hit of `ray` over `prims` (indexed by original index), by
    /// ordered stack traversal: near child first.
    ///
    /// Among hits at exactly the same `t` the lowest primitive index wins, as
    /// in a brute-force loop over all primitives (boxes are widened by a few
    /// ulps so rounding does not cull such ties).
    pub fn closest_hit(&self, ray: &Ray, prims: &[Prim]) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        self.traverse(ray, prims, |ray, prim, t, b1, b2| {
            let better = match best {
                None => true,
                Some(h) => t < h.t || (t == h.t && prim < h.prim),
            };
            if better {
                best = Some(Hit { t, prim, b1, b2 });
                ray.tmax = t;
            }
            false
        });
        best
    }

    /// Whether `ray` hits any primitive in `(0, ray.tmax]`; stops at the
    /// first hit found.
    pub fn any_hit(&self, ray: &Ray, prims: &[Prim]) -> bool {
        let mut found = false;
        self.traverse(ray, prims, |_, _, _, _, _| {
            found = true;
            true
        });
        found
    }

    /// Stack traversal shared by the queries. `on_hit(ray, prim, t, b1, b2)`
    /// may shorten `ray.tmax` and returns `true` to stop.
    fn traverse<F>(&self, ray: &Ray, prims: &[Prim], mut on_hit: F)
    where
        F: FnMut(&mut Ray, u32, f32, f32, f32) -> bool,
    {
        let Some(root) = self.nodes.first() else {
            return;
        };
        let mut ray = *ray;
        let inv_d = safe_inverse(ray.d);

        // Cull the whole scene against the root box
        if slab_test(ray.o, inv_d, ray.tmax, root.min, root.max).is_none() {
            return;
        }
        let mut stack = [0u32; BVH_STACK_SIZE as usize];
        let mut sp = 0usize;
        let mut node = 0u32;
        loop {
            let n = self.nodes[node as usize];
            if n.count > 0 {
                // Test the leaf's primitives, then resume from the stack
                for slot in n.left_or_first..n.left_or_first + n.count {
                    let prim = self.prim_order[slot as usize];
                    if let Some((t, b1, b2)) = prims[prim as usize].intersect(&ray) {
                        if on_hit(&mut ray, prim, t, b1, b2) {
                            return;
                        }
                    }
                }
                if sp == 0 {
                    return;
                }
                sp -= 1;
                node = stack[sp];
            } else {
                // Test both children and descend into the nearer, pushing the farther
                let (l, r) = (n.left_or_first, n.left_or_first + 1);
                let ln = &self.nodes[l as usize];
                let rn = &self.nodes[r as usize];
                let hl = slab_test(ray.o, inv_d, ray.tmax, ln.min, ln.max);
                let hr = slab_test(ray.o, inv_d, ray.tmax, rn.min, rn.max);
                match (hl, hr) {
                    (Some(tl), Some(tr)) => {
                        let (near, far) = if tr < tl { (r, l) } else { (l, r) };
                        stack[sp] = far;
                        sp += 1;
                        node = near;
                    }
                    (Some(_), None) => node = l,
                    (None, Some(_)) => node = r,
                    (None, None) => {
                        if sp == 0 {
                            return;
                        }
                        sp -= 1;
                        node = stack[sp];
                    }
                }
            }
        }
    }
}

/// A primitive during the build. The build partitions these records in
/// place, so every pass over a node reads memory in order.
#[derive(Clone, Copy)]
struct PrimRef {
    bounds: Aabb,
    centroid: Vec3,
    /// Original primitive index.
    index: u32,
}

/// A node of the temporary build tree.
struct BuildNode {
    bounds: Aabb,
    kind: BuildKind,
    /// Nodes in this subtree, itself included.
    node_count: usize,
}

enum BuildKind {
    Leaf { first: u32, count: u32 },
    Interior(Box<[BuildNode; 2]>),
}

/// A flat node to be overwritten.
fn placeholder() -> BvhNode {
    BvhNode {
        min: Vec3::ZERO,
        max: Vec3::ZERO,
        left_or_first: 0,
        count: 0,
    }
}

/// Writes `node` at `slot` and its subtree after the current end of `nodes`.
fn flatten(node: BuildNode, nodes: &mut Vec<BvhNode>, slot: usize) {
    let (left_or_first, count) = match node.kind {
        BuildKind::Leaf { first, count } => (first, count),
        BuildKind::Interior(children) => {
            let left = nodes.len();
            nodes.push(placeholder());
            nodes.push(placeholder());
            let [l, r] = *children;
            flatten(l, nodes, left);
            flatten(r, nodes, left + 1);
            (left as u32, 0)
        }
    };
    nodes[slot] = BvhNode {
        min: node.bounds.min,
        max: node.bounds.max,
        left_or_first,
        count,
    };
}

/// Levels a subtree of `n >= 1` primitives needs when split at the median
/// all the way down: `1 + ceil(log2(ceil(n / BVH_MAX_LEAF_PRIMS)))`.
fn levels_needed(n: usize) -> u32 {
    let leaves = n.div_ceil(BVH_MAX_LEAF_PRIMS as usize).max(1);
    1 + leaves.next_power_of_two().trailing_zeros()
}

/// Per-bin accumulation of the SAH sweep.
#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

/// The cheapest binned SAH split: axis, bin count, first bin of the right
/// side, and SAH cost.
struct Split {
    axis: usize,
    bins: usize,
    bin: usize,
    cost: f32,
}

/// Bins per axis for a node of `n` primitives: fewer for small nodes, where
/// the sweep over bins would cost more than binning itself.
fn bins_for(n: usize) -> usize {
    if n <= SMALL_NODE {
        SMALL_BINS
    } else {
        BINS
    }
}

/// Bin of centroid coordinate `c` among `bins` (shared by binning and
/// partitioning so the two always agree).
fn bin_of(c: f32, cmin: f32, scale: f32, bins: usize) -> usize {
    (((c - cmin) * scale) as usize).min(bins - 1)
}

/// Builds the subtree over `refs` (slots `first..first + refs.len()` of
/// `prim_order`) at `level` (the root is level 1) of a tree of at most
/// `max_levels` levels.
fn build_node(refs: &mut [PrimRef], first: u32, level: u32, max_levels: u32) -> BuildNode {
    let n = refs.len();

    // Bound the primitives and their centroids
    let mut bounds = Aabb::EMPTY;
    let mut cbounds = Aabb::EMPTY;
    for r in refs.iter() {
        bounds = bounds.union(r.bounds);
        cbounds.grow(r.centroid);
    }
    let leaf = |bounds| BuildNode {
        bounds,
        kind: BuildKind::Leaf {
            first,
            count: n as u32,
        },
        node_count: 1,
    };
    if n == 1 {
        return leaf(bounds);
    }

    // Find the cheapest binned SAH split, if any separates the centroids
    let split = sah_split(refs, &bounds, &cbounds);

    // Stop at a leaf when small enough and the SAH prefers it or no level is left
    let fits = n <= BVH_MAX_LEAF_PRIMS as usize;
    let budget = max_levels.saturating_sub(level);
    if fits && (budget == 0 || split.as_ref().is_none_or(|s| n as f32 <= s.cost)) {
        return leaf(bounds);
    }

    // Partition by the SAH split, or at the median when the depth budget needs it
    let mut mid = 0;
    if let Some(s) = &split {
        let scale = s.bins as f32 / (cbounds.max[s.axis] - cbounds.min[s.axis]);
        mid = partition(refs, |r| {
            bin_of(r.centroid[s.axis], cbounds.min[s.axis], scale, s.bins) < s.bin
        });
        if levels_needed(mid).max(levels_needed(n - mid)) > budget {
            mid = 0;
        }
    }
    if mid == 0 || mid == n {
        mid = median_split(refs, &cbounds);
    }

    // Build both children, in parallel for big subtrees
    let (lrefs, rrefs) = refs.split_at_mut(mid);
    let rfirst = first + mid as u32;
    let (l, r) = if n > PARALLEL_MIN_PRIMS {
        rayon::join(
            || build_node(lrefs, first, level + 1, max_levels),
            || build_node(rrefs, rfirst, level + 1, max_levels),
        )
    } else {
        (
            build_node(lrefs, first, level + 1, max_levels),
            build_node(rrefs, rfirst, level + 1, max_levels),
        )
    };
    BuildNode {
        bounds,
        node_count: 1 + l.node_count + r.node_count,
        kind: BuildKind::Interior(Box::new([l, r])),
    }
}

/// Evaluates `bins - 1` planes on each axis with a non-zero centroid extent
/// (`bins` from [`bins_for`]) and returns the cheapest split with primitives
/// on both sides. Ties go to the lower axis, then the lower plane, so the
/// result is deterministic.
fn sah_split(refs: &[PrimRef], bounds: &Aabb, cbounds: &Aabb) -> Option<Split> {
    let area = bounds.surface_area();
    if !(area > 0.0 && area.is_finite()) {
        return None;
    }

    // Bin the centroids along all three axes in one pass
    let nb = bins_for(refs.len());
    let extent = cbounds.max - cbounds.min;
    let usable = [0, 1, 2].map(|a| extent[a] > 0.0 && extent[a].is_finite());
    let scale = [0, 1, 2].map(|a| {
        if usable[a] {
            nb as f32 / extent[a]
        } else {
            0.0
        }
    });
    let empty = Bin {
        bounds: Aabb::EMPTY,
        count: 0,
    };
    let mut bins = [[empty; BINS]; 3];
    for r in refs {
        for axis in 0..3 {
            let k = bin_of(r.centroid[axis], cbounds.min[axis], scale[axis], nb);
            let b = &mut bins[axis][k];
            b.bounds = b.bounds.union(r.bounds);
            b.count += 1;
        }
    }

    // Sweep each axis from the right, then from the left, costing every plane
    // by the unnormalised SAH area-count sum
    let mut best: Option<(usize, usize, f32)> = None;
    for (axis, bins) in bins.iter().enumerate() {
        if !usable[axis] {
            continue;
        }
        let mut right_cost = [0.0f32; BINS];
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0u32;
        for k in (1..nb).rev() {
            acc = acc.union(bins[k].bounds);
            cnt += bins[k].count;
            right_cost[k] = if cnt > 0 {
                acc.surface_area() * cnt as f32
            } else {
                f32::NAN
            };
        }
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0u32;
        for k in 1..nb {
            acc = acc.union(bins[k - 1].bounds);
            cnt += bins[k - 1].count;
            if cnt == 0 || right_cost[k].is_nan() {
                continue;
            }
            let sum = acc.surface_area() * cnt as f32 + right_cost[k];
            if best.is_none_or(|b| sum < b.2) {
                best = Some((axis, k, sum));
            }
        }
    }
    best.map(|(axis, bin, sum)| Split {
        axis,
        bins: nb,
        bin,
        cost: TRAVERSAL_COST + sum / area,
    })
}

/// Splits `refs` by count along the widest centroid axis (ties broken by
/// primitive index), giving the left side half the leaves' worth of
/// primitives so leaves come out full; keeps the order when all centroids
/// coincide. Each side needs one level less than `refs` (see
/// [`levels_needed`]). `refs` must hold at least two primitives.
fn median_split(refs: &mut [PrimRef], cbounds: &Aabb) -> usize {
    let per_leaf = BVH_MAX_LEAF_PRIMS as usize;
    let n = refs.len();
    let mid = if n > per_leaf {
        n.div_ceil(per_leaf) / 2 * per_leaf
    } else {
        n / 2
    };
    let e = cbounds.extent();
    let axis = if e.x >= e.y && e.x >= e.z {
        0
    } else if e.y >= e.z {
        1
    } else {
        2
    };
    if e[axis] > 0.0 {
        refs.select_nth_unstable_by(mid, |a, b| {
            a.centroid[axis]
                .total_cmp(&b.centroid[axis])
                .then(a.index.cmp(&b.index))
        });
    }
    mid
}

/// Moves the records for which `left` holds to the front; returns how many.
fn partition(refs: &mut [PrimRef], left: impl Fn(&PrimRef) -> bool) -> usize {
    let (mut i, mut j) = (0, refs.len());
    while i < j {
        if left(&refs[i]) {
            i += 1;
        } else {
            j -= 1;
            refs.swap(i, j);
        }
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::geometry::test_util::{icosphere, lerp, Pcg32};
    use std::collections::HashMap;
    use std::time::Instant;

    /// Checks every structural guarantee; returns (leaves, depth).
    fn check_invariants(bvh: &Bvh, boxes: &[Aabb]) -> (usize, u32) {
        let n = boxes.len();
        assert_eq!(bvh.prim_order.len(), n);
        if n == 0 {
            assert!(bvh.nodes.is_empty());
            return (0, 0);
        }
        let mut seen_prim = vec![0u32; n];
        let mut seen_slot = vec![0u32; n];
        let mut seen_node = vec![0u32; bvh.nodes.len()];
        let mut leaves = 0;
        let mut stack = vec![(0usize, 1u32)];
        let mut depth = 0;
        seen_node[0] += 1;
        while let Some((i, level)) = stack.pop() {
            let node = bvh.nodes[i];
            assert!(node.min.cmple(node.max).all(), "inverted box at node {i}");
            if node.is_leaf() {
                leaves += 1;
                depth = depth.max(level);
                assert!(
                    node.count <= BVH_MAX_LEAF_PRIMS,
                    "leaf {i} holds {}",
                    node.count
                );
                for s in node.left_or_first..node.left_or_first + node.count {
                    seen_slot[s as usize] += 1;
                    let p = bvh.prim_order[s as usize] as usize;
                    seen_prim[p] += 1;
                    assert!(
                        node.bounds().contains(&boxes[p]),
                        "prim {p} outside leaf {i}"
                    );
                }
            } else {
                let l = node.left_or_first as usize;
                assert!(l > i && l + 1 < bvh.nodes.len(), "bad children of {i}");
                for c in [l, l + 1] {
                    seen_node[c] += 1;
                    assert!(
                        node.bounds().contains(&bvh.nodes[c].bounds()),
                        "child {c} outside parent {i}"
                    );
                    stack.push((c, level + 1));
                }
            }
        }
        assert!(
            seen_prim.iter().all(|&c| c == 1),
            "a primitive is not in exactly one leaf"
        );
        assert!(
            seen_slot.iter().all(|&c| c == 1),
            "leaf ranges overlap or leave gaps"
        );
        assert!(
            seen_node.iter().all(|&c| c == 1),
            "unreachable or shared nodes"
        );
        assert_eq!(depth, bvh.depth());
        assert!(depth < BVH_STACK_SIZE, "depth {depth}");
        (leaves, depth)
    }

    /// Brute force with the same tie rule: lowest (t, index).
    fn brute_force(ray: &Ray, prims: &[Prim]) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut r = *ray;
        for (i, p) in prims.iter().enumerate() {
            if let Some((t, b1, b2)) = p.intersect(&r) {
                if best.is_none_or(|h| t < h.t) {
                    best = Some(Hit {
                        t,
                        prim: i as u32,
                        b1,
                        b2,
                    });
                    r.tmax = t;
                }
            }
        }
        best
    }

    /// A mixed soup: random spheres and triangles, two icospheres with
    /// shared edges, axis-aligned quads and boxes with exact coordinates,
    /// zero-radius spheres and degenerate triangles.
    fn soup(rng: &mut Pcg32, n_random: usize) -> Vec<Prim> {
        let mut prims = Vec::new();
        for k in 0..n_random {
            let c = rng.in_cube(-10.0, 10.0);
            if k % 3 == 0 {
                prims.push(Prim::Sphere {
                    center: c,
                    radius: rng.range(0.02, 0.6),
                });
            } else {
                let s = rng.range(0.05, 1.5);
                prims.push(Prim::Triangle([c, c + rng.unit() * s, c + rng.unit() * s]));
            }
        }
        for (center, radius) in [
            (Vec3::new(2.0, 3.0, -4.0), 2.5f32),
            (Vec3::new(-6.0, -1.0, 5.0), 1.0),
        ] {
            let (v, tris) = icosphere(2, center, radius);
            for t in tris {
                prims.push(Prim::Triangle([
                    v[t[0] as usize],
                    v[t[1] as usize],
                    v[t[2] as usize],
                ]));
            }
        }
        // Axis-aligned quads (two triangles each) on integer coordinates.
        for k in 0..40 {
            let axis = k % 3;
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut p = [Vec3::ZERO; 4];
            let base = Vec3::new(
                rng.below(16) as f32 - 8.0,
                rng.below(16) as f32 - 8.0,
                rng.below(16) as f32 - 8.0,
            );
            let (w, h) = (1.0 + rng.below(3) as f32, 1.0 + rng.below(3) as f32);
            for (j, (u, v)) in [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
                .into_iter()
                .enumerate()
            {
                p[j] = base;
                p[j][a] += u;
                p[j][b] += v;
            }
            prims.push(Prim::Triangle([p[0], p[1], p[2]]));
            prims.push(Prim::Triangle([p[0], p[2], p[3]]));
        }
        // Degenerate primitives: a zero-radius sphere and collapsed triangles.
        prims.push(Prim::Sphere {
            center: Vec3::new(1.0, 1.0, 1.0),
            radius: 0.0,
        });
        prims.push(Prim::Triangle([Vec3::ONE, Vec3::ONE, Vec3::ONE]));
        prims.push(Prim::Triangle([Vec3::ZERO, Vec3::X, Vec3::X * 2.0]));
        prims
    }

    /// The soup scaled by `s` and moved by `off` (in f32, as a loader would).
    fn transform(prims: &[Prim], s: f32, off: Vec3) -> Vec<Prim> {
        prims
            .iter()
            .map(|p| match *p {
                Prim::Sphere { center, radius } => Prim::Sphere {
                    center: center * s + off,
                    radius: radius * s,
                },
                Prim::Triangle(v) => Prim::Triangle(v.map(|v| v * s + off)),
            })
            .collect()
    }

    /// Edges shared by two or more triangles (same vertex values).
    fn shared_edges(prims: &[Prim]) -> Vec<(Vec3, Vec3)> {
        type Key = [u32; 3];
        let key = |v: Vec3| -> Key { v.to_array().map(f32::to_bits) };
        let mut count: HashMap<(Key, Key), (u32, Vec3, Vec3)> = HashMap::new();
        for p in prims {
            if let Prim::Triangle(v) = p {
                for k in 0..3 {
                    let (a, b) = (v[k], v[(k + 1) % 3]);
                    let (ka, kb) = (key(a), key(b));
                    let e = if ka < kb { (ka, kb) } else { (kb, ka) };
                    count.entry(e).or_insert((0, a, b)).0 += 1;
                }
            }
        }
        let mut shared: Vec<_> = count.into_iter().filter(|e| e.1 .0 >= 2).collect();
        shared.sort_by_key(|e| e.0);
        shared.into_iter().map(|e| (e.1 .1, e.1 .2)).collect()
    }

    /// Random and adversarial rays for a soup scaled by `s` and moved by `off`.
    fn test_rays(
        rng: &mut Pcg32,
        bvh: &Bvh,
        prims: &[Prim],
        s: f32,
        off: Vec3,
    ) -> Vec<(Ray, &'static str)> {
        let world = |p: Vec3| p * s + off;
        let signed_zeros = |rng: &mut Pcg32| {
            Vec3::new(
                if rng.below(2) == 0 { 0.0 } else { -0.0 },
                if rng.below(2) == 0 { 0.0 } else { -0.0 },
                if rng.below(2) == 0 { 0.0 } else { -0.0 },
            )
        };
        let sign = |rng: &mut Pcg32| if rng.below(2) == 0 { 1.0 } else { -1.0 };
        let nodes = &bvh.nodes;
        let mut rays = Vec::new();
        // Random rays.
        for _ in 0..12_000 {
            let o = world(rng.in_cube(-12.0, 12.0));
            rays.push((Ray::new(o, rng.unit(), f32::INFINITY), "random"));
        }
        // Axis-aligned rays with +0.0/-0.0 in the other components.
        for _ in 0..3000 {
            let mut d = signed_zeros(rng);
            d[rng.below(3)] = sign(rng);
            let o = world(rng.in_cube(-12.0, 12.0));
            rays.push((Ray::new(o, d, f32::INFINITY), "axis-aligned"));
        }
        // Origins exactly on node box faces, random or axis-aligned directions.
        for k in 0..4000 {
            let b = nodes[rng.below(nodes.len())].bounds();
            let mut o = b.min + (b.max - b.min) * Vec3::new(rng.f32(), rng.f32(), rng.f32());
            let axis = rng.below(3);
            o[axis] = if rng.below(2) == 0 {
                b.min[axis]
            } else {
                b.max[axis]
            };
            let d = if k % 2 == 0 {
                rng.unit()
            } else {
                let mut d = signed_zeros(rng);
                d[rng.below(3)] = sign(rng);
                d
            };
            rays.push((Ray::new(o, d, f32::INFINITY), "origin on box face"));
        }
        // Rays along box edges: origin on an edge line (before, inside or at
        // the end of the box), direction along the edge, signed zeros elsewhere.
        for _ in 0..4000 {
            let b = nodes[rng.below(nodes.len())].bounds();
            let axis = rng.below(3);
            let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
            let dir = sign(rng);
            let mut o = Vec3::ZERO;
            o[a1] = if rng.below(2) == 0 {
                b.min[a1]
            } else {
                b.max[a1]
            };
            o[a2] = if rng.below(2) == 0 {
                b.min[a2]
            } else {
                b.max[a2]
            };
            o[axis] = match rng.below(3) {
                0 => b.min[axis] - dir * rng.range(0.0, 5.0) * s,
                1 => lerp(b.min, b.max, rng.f32())[axis],
                _ => {
                    if dir > 0.0 {
                        b.min[axis]
                    } else {
                        b.max[axis]
                    }
                }
            };
            let mut d = signed_zeros(rng);
            d[axis] = dir;
            rays.push((Ray::new(o, d, f32::INFINITY), "along box edge"));
        }
        // Shared triangle edges and vertices: origins on them, rays aimed at them.
        let shared = shared_edges(prims);
        for _ in 0..4000 {
            let (a, b) = shared[rng.below(shared.len())];
            let on_edge = lerp(a, b, rng.f32());
            rays.push((
                Ray::new(on_edge, rng.unit(), f32::INFINITY),
                "origin on shared edge",
            ));
            let o = world(rng.in_cube(-12.0, 12.0));
            let target = if rng.below(4) == 0 { a } else { on_edge };
            rays.push((
                Ray::new(o, target - o, f32::INFINITY),
                "aimed at shared edge/vertex",
            ));
        }
        // Rays lying in the plane of axis-aligned quads.
        let flat: Vec<(usize, f32)> = prims
            .iter()
            .filter_map(|p| match *p {
                Prim::Triangle([p0, p1, p2]) => {
                    let b = Aabb::of_triangle(p0, p1, p2);
                    (0..3)
                        .find(|&k| b.min[k] == b.max[k] && b.extent()[(k + 1) % 3] > 0.0)
                        .map(|k| (k, b.min[k]))
                }
                _ => None,
            })
            .collect();
        for _ in 0..2000 {
            let (axis, plane) = flat[rng.below(flat.len())];
            let mut o = world(rng.in_cube(-12.0, 12.0));
            o[axis] = plane;
            let mut d = rng.unit();
            d[axis] = if rng.below(2) == 0 { 0.0 } else { -0.0 };
            rays.push((
                Ray::new(o, d, f32::INFINITY),
                "in plane of axis-aligned quad",
            ));
        }
        // Finite tmax.
        for _ in 0..2000 {
            let o = world(rng.in_cube(-12.0, 12.0));
            rays.push((
                Ray::new(o, rng.unit(), rng.range(0.0, 8.0) * s),
                "finite tmax",
            ));
        }
        rays
    }

    #[test]
    fn closest_hit_matches_brute_force() {
        let mut rng = Pcg32::new(1);
        let base = soup(&mut rng, 3000);
        let mut total_rays = 0;
        // The soup as built, tiny near the origin, and large far from it.
        for (s, off) in [
            (1.0f32, Vec3::ZERO),
            (1.0e-3, Vec3::ZERO),
            (1.0e2, Vec3::new(1.0e4, -3.0e4, 2.0e4)),
        ] {
            let prims = transform(&base, s, off);
            let boxes: Vec<Aabb> = prims.iter().map(Prim::aabb).collect();
            let bvh = build(&boxes);
            let (leaves, depth) = check_invariants(&bvh, &boxes);
            let rays = test_rays(&mut rng, &bvh, &prims, s, off);

            let (mut hits, mut mismatches, mut ties, mut any_disagree) = (0, 0, 0, 0);
            let mut by_kind: Vec<(&str, usize, usize)> = Vec::new();
            for (ray, kind) in &rays {
                let got = bvh.closest_hit(ray, &prims);
                let want = brute_force(ray, &prims);
                let bad = match (got, want) {
                    (None, None) => false,
                    (Some(g), Some(w)) => {
                        hits += 1;
                        let close = (g.t - w.t).abs() <= 1.0e-5 * w.t.abs();
                        // An equally near hit on another primitive: a tie resolved
                        // differently, still a mismatch for this test.
                        ties += usize::from(g.prim != w.prim && close);
                        g.prim != w.prim || !close
                    }
                    _ => true,
                };
                if bad {
                    eprintln!("mismatch ({kind}): {ray:?} bvh {got:?} brute force {want:?}");
                }
                mismatches += usize::from(bad);
                any_disagree += usize::from(bvh.any_hit(ray, &prims) != want.is_some());
                match by_kind.iter_mut().find(|e| e.0 == *kind) {
                    Some(e) => {
                        e.1 += 1;
                        e.2 += usize::from(want.is_some());
                    }
                    None => by_kind.push((kind, 1, usize::from(want.is_some()))),
                }
            }
            println!(
                "closest hit vs brute force, scale {s:e} offset {off}: {} prims, {} nodes, \
                 {leaves} leaves, depth {depth}; {} rays ({hits} hits), {mismatches} mismatches \
                 ({ties} of them equal-t ties on another prim), {any_disagree} any_hit \
                 disagreements",
                prims.len(),
                bvh.node_count(),
                rays.len()
            );
            for (kind, n, h) in by_kind {
                println!("  {kind}: {n} rays, {h} hits");
            }
            total_rays += rays.len();
            assert_eq!(mismatches, 0);
            assert_eq!(any_disagree, 0);
        }
        assert!(total_rays >= 100_000);
    }

    #[test]
    fn sah_cost_is_the_area_weighted_sum() {
        let node = |min: Vec3, max: Vec3, left_or_first, count| BvhNode {
            min,
            max,
            left_or_first,
            count,
        };
        let (two, one) = (Vec3::new(2.0, 1.0, 1.0), Vec3::ONE);
        // Two unit cubes side by side: root 2x1x1 (area 10) over two leaves
        // of one cube each (area 6): 1 + 2 * 6 / 10
        let split = Bvh {
            nodes: vec![
                node(Vec3::ZERO, two, 1, 0),
                node(Vec3::ZERO, one, 0, 1),
                node(Vec3::X, two, 1, 1),
            ],
            prim_order: vec![0, 1],
        };
        assert!(
            (split.sah_cost() - 2.2).abs() < 1e-6,
            "{}",
            split.sah_cost()
        );
        // The same two in one leaf: two tests per ray, which the builder
        // prefers
        let leaf = Bvh {
            nodes: vec![node(Vec3::ZERO, two, 0, 2)],
            prim_order: vec![0, 1],
        };
        assert_eq!(leaf.sah_cost(), 2.0);
        let built = build(&[Aabb::new(Vec3::ZERO, one), Aabb::new(Vec3::X, two)]);
        assert_eq!(built.sah_cost(), 2.0);
        assert_eq!(Bvh::default().sah_cost(), 0.0);
    }

    #[test]
    fn degenerate_inputs() {
        // No primitives.
        let bvh = build(&[]);
        assert!(bvh.nodes.is_empty() && bvh.depth() == 0);
        let ray = Ray::new(Vec3::ZERO, Vec3::Z, f32::INFINITY);
        assert!(bvh.closest_hit(&ray, &[]).is_none() && !bvh.any_hit(&ray, &[]));
        // One primitive.
        let one = [Aabb::of_sphere(Vec3::ZERO, 1.0)];
        let bvh = build(&one);
        assert_eq!(check_invariants(&bvh, &one), (1, 1));
        // All centroids identical, boxes of zero extent (points).
        let points = vec![Aabb::new(Vec3::ONE, Vec3::ONE); 1000];
        let bvh = build(&points);
        let (leaves, depth) = check_invariants(&bvh, &points);
        println!("1000 identical points: {leaves} leaves, depth {depth}");
        assert_eq!(leaves, 250);
        // Identical centroids, different sizes (nested spheres).
        let nested: Vec<Aabb> = (1..=777)
            .map(|k| Aabb::of_sphere(Vec3::splat(-3.0), k as f32))
            .collect();
        check_invariants(&build(&nested), &nested);
        // Flat boxes on one plane, and collinear ones.
        let flat: Vec<Aabb> = (0..500)
            .map(|k| {
                Aabb::new(
                    Vec3::new(k as f32, 0.0, 2.0),
                    Vec3::new(k as f32 + 3.0, 1.0, 2.0),
                )
            })
            .collect();
        check_invariants(&build(&flat), &flat);
        // Huge coordinates: centroid extent and areas overflow f32.
        let huge = vec![
            Aabb::new(Vec3::splat(-f32::MAX), Vec3::splat(-f32::MAX / 2.0)),
            Aabb::new(Vec3::splat(f32::MAX / 2.0), Vec3::splat(f32::MAX)),
            Aabb::new(Vec3::ZERO, Vec3::ONE),
            Aabb::new(Vec3::ONE, Vec3::splat(2.0)),
            Aabb::new(Vec3::splat(3.0), Vec3::splat(4.0)),
            Aabb::new(Vec3::splat(5.0), Vec3::splat(6.0)),
        ];
        check_invariants(&build(&huge), &huge);
    }

    #[test]
    fn depth_limit_forces_median_splits() {
        // Geometrically spaced boxes make SAH peel off a few at a time.
        let boxes: Vec<Aabb> = (0..4000)
            .map(|k| {
                let x = 1.02f32.powi(k);
                Aabb::new(Vec3::new(x, 0.0, 0.0), Vec3::new(x * 1.001, 1.0, 1.0))
            })
            .collect();
        let unlimited = build_with_max_levels(&boxes, u32::MAX);
        let limited = build(&boxes);
        let (_, depth) = check_invariants(&limited, &boxes);
        println!(
            "geometric spacing: SAH depth without limit {}, with limit {depth} (max {MAX_LEVELS})",
            unlimited.depth()
        );
        assert!(unlimited.depth() > MAX_LEVELS, "test scene no longer deep");
        assert!(depth <= MAX_LEVELS);
    }

    #[test]
    fn build_is_deterministic() {
        let mut rng = Pcg32::new(99);
        let prims = soup(&mut rng, 40_000);
        let boxes: Vec<Aabb> = prims.iter().map(Prim::aabb).collect();
        let a = build(&boxes);
        let b = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| build(&boxes));
        assert!(a == b);
        check_invariants(&a, &boxes);
    }

    /// 300,000 boxes, a third with a coordinate of each signed zero.
    fn signed_zero_boxes() -> Vec<Aabb> {
        let mut rng = Pcg32::new(7);
        (0..300_000)
            .map(|k| {
                let mut c = rng.in_cube(-50.0, 50.0);
                if k % 3 == 0 {
                    c[k % 2] = if k % 2 == 0 { 0.0 } else { -0.0 };
                }
                Aabb::of_triangle(c, c + rng.unit(), c + rng.unit() * 0.5)
            })
            .collect()
    }

    /// A node's figures as bits, so that -0.0 and 0.0 differ.
    fn node_bits(bvh: &Bvh) -> Vec<[u32; 8]> {
        (bvh.nodes.iter())
            .map(|n| {
                let (a, b) = (n.min.to_array(), n.max.to_array());
                [a[0], a[1], a[2], b[0], b[1], b[2]]
                    .map(f32::to_bits)
                    .into_iter()
                    .chain([n.left_or_first, n.count])
                    .collect::<Vec<u32>>()
                    .try_into()
                    .unwrap()
            })
            .collect()
    }

    /// The same boxes give the same tree, bit for bit, on one thread and
    /// on four (subtrees build in parallel with `rayon::join`).
    #[test]
    fn build_is_bit_identical_on_one_thread_and_many() {
        let boxes = signed_zero_boxes();
        let on = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| build(&boxes))
        };
        let (one, four) = (on(1), on(4));
        assert!(node_bits(&one) == node_bits(&four));
        assert!(one.prim_order == four.prim_order);
        check_invariants(&one, &boxes);
    }

    /// User + system CPU seconds of this process (Linux; NaN elsewhere).
    fn cpu_seconds() -> f64 {
        let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
        let fields: Vec<&str> = stat
            .rsplit(')')
            .next()
            .unwrap_or("")
            .split_whitespace()
            .collect();
        match (fields.get(11), fields.get(12)) {
            (Some(u), Some(s)) => {
                (u.parse::<f64>().unwrap_or(f64::NAN) + s.parse::<f64>().unwrap_or(f64::NAN))
                    / 100.0
            }
            _ => f64::NAN,
        }
    }

    /// Build time for a million triangles (run with `--ignored --nocapture`).
    #[test]
    #[ignore]
    fn build_one_million_triangles() {
        let mut rng = Pcg32::new(4);
        let prims: Vec<Prim> = (0..1_000_000)
            .map(|_| {
                let c = rng.in_cube(-100.0, 100.0);
                Prim::Triangle([c, c + rng.unit() * 0.5, c + rng.unit() * 0.5])
            })
            .collect();
        let boxes: Vec<Aabb> = prims.iter().map(Prim::aabb).collect();
        let (start, cpu0) = (Instant::now(), cpu_seconds());
        let bvh = build(&boxes);
        let build_s = start.elapsed().as_secs_f64();
        let build_cpu = cpu_seconds() - cpu0;
        let (leaves, depth) = check_invariants(&bvh, &boxes);
        let rays: Vec<Ray> = (0..100_000)
            .map(|_| Ray::new(rng.in_cube(-100.0, 100.0), rng.unit(), f32::INFINITY))
            .collect();
        let start = Instant::now();
        let hits = rays
            .iter()
            .filter(|r| bvh.closest_hit(r, &prims).is_some())
            .count();
        let trace_s = start.elapsed().as_secs_f64();
        println!(
            "1M triangles: build {build_s:.3} s wall ({build_cpu:.2} s CPU) on {} threads, {} nodes, {leaves} leaves, depth {depth}, SAH cost {:.2}; \
             {} rays in {trace_s:.3} s ({:.2} Mrays/s single thread), {hits} hits",
            rayon::current_num_threads(),
            bvh.node_count(),
            bvh.sah_cost(),
            rays.len(),
            rays.len() as f64 / trace_s / 1e6
        );
    }
}
