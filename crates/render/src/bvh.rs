//! A bounding volume hierarchy built with the binned surface area heuristic (Wald 2007;
//! pbrt-v4 §7.3), flattened depth-first for an iterative, front-to-back traversal.

use crate::math::Vec3;
use crate::ray::Ray;
use crate::shape::{Aabb, Sphere, Triangle};

/// A primitive's geometry.
#[derive(Clone, Copy, Debug)]
pub enum Geom {
    /// A sphere.
    Sphere(Sphere),
    /// A triangle.
    Triangle(Triangle),
}

impl Geom {
    /// Bounds.
    pub fn bounds(&self) -> Aabb {
        match self {
            Geom::Sphere(s) => s.bounds(),
            Geom::Triangle(t) => t.bounds(),
        }
    }
    #[inline]
    fn intersect(&self, ray: &Ray, t_max: f64) -> Option<(f64, f64, f64)> {
        match self {
            Geom::Sphere(s) => s.intersect(ray, t_max).map(|t| (t, 0.0, 0.0)),
            Geom::Triangle(t) => t.intersect(ray, t_max),
        }
    }
}

/// The nearest hit: parameter, primitive index (in the order given to [`Bvh::build`]) and the
/// triangle barycentrics (b1, b2) on its edges.
#[derive(Clone, Copy, Debug)]
pub struct BvhHit {
    /// Ray parameter.
    pub t: f64,
    /// Index of the primitive in the input order.
    pub prim: u32,
    /// Barycentric along e1 (triangles).
    pub b1: f64,
    /// Barycentric along e2 (triangles).
    pub b2: f64,
}

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first primitive; interior: index of the second child (the first follows).
    offset: u32,
    /// Number of primitives; 0 for an interior node.
    count: u16,
    axis: u8,
}

/// A SAH BVH over spheres and triangles.
#[derive(Clone, Debug)]
pub struct Bvh {
    nodes: Vec<Node>,
    prims: Vec<Geom>,
    ids: Vec<u32>,
}

const BINS: usize = 16;
const MAX_LEAF: usize = 8;
const TRAVERSAL_COST: f64 = 1.0;

struct BuildPrim {
    bounds: Aabb,
    centroid: Vec3,
    id: u32,
}

impl Bvh {
    /// Builds the hierarchy. Primitive ids in hits are indices into `prims`.
    pub fn build(prims: &[Geom]) -> Bvh {
        let mut items: Vec<BuildPrim> = prims
            .iter()
            .enumerate()
            .map(|(i, g)| {
                let b = g.bounds();
                BuildPrim {
                    bounds: b,
                    centroid: b.centroid(),
                    id: i as u32,
                }
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * prims.len().max(1));
        if !items.is_empty() {
            let n = items.len();
            build_rec(&mut items, 0, n, &mut nodes);
        }
        let ids: Vec<u32> = items.iter().map(|p| p.id).collect();
        let ordered = ids.iter().map(|&i| prims[i as usize]).collect();
        Bvh {
            nodes,
            prims: ordered,
            ids,
        }
    }

    /// Bounds of everything.
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, |n| n.bounds)
    }

    /// The nearest intersection with t in (0, t_max).
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<BvhHit> {
        self.traverse::<false>(ray, t_max)
    }

    /// Whether anything intersects the ray in (0, t_max) (shadow rays; any hit).
    #[inline]
    pub fn occluded(&self, ray: &Ray, t_max: f64) -> bool {
        self.traverse::<true>(ray, t_max).is_some()
    }

    #[inline]
    fn traverse<const ANY: bool>(&self, ray: &Ray, t_max: f64) -> Option<BvhHit> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = Vec3::new(1.0 / ray.d.x, 1.0 / ray.d.y, 1.0 / ray.d.z);
        let neg = [inv.x < 0.0, inv.y < 0.0, inv.z < 0.0];
        let mut best: Option<BvhHit> = None;
        let mut t_max = t_max;
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut idx = 0usize;
        loop {
            let node = &self.nodes[idx];
            if slab(&node.bounds, ray, inv, t_max) {
                if node.count > 0 {
                    let start = node.offset as usize;
                    for i in start..start + node.count as usize {
                        if let Some((t, b1, b2)) = self.prims[i].intersect(ray, t_max) {
                            let hit = BvhHit {
                                t,
                                prim: self.ids[i],
                                b1,
                                b2,
                            };
                            if ANY {
                                return Some(hit);
                            }
                            t_max = t;
                            best = Some(hit);
                        }
                    }
                    if sp == 0 {
                        break;
                    }
                    sp -= 1;
                    idx = stack[sp] as usize;
                } else if neg[node.axis as usize] {
                    stack[sp] = idx as u32 + 1;
                    sp += 1;
                    idx = node.offset as usize;
                } else {
                    stack[sp] = node.offset;
                    sp += 1;
                    idx += 1;
                }
            } else {
                if sp == 0 {
                    break;
                }
                sp -= 1;
                idx = stack[sp] as usize;
            }
        }
        best
    }
}

#[inline]
fn slab(b: &Aabb, ray: &Ray, inv: Vec3, t_max: f64) -> bool {
    let tx0 = (b.min.x - ray.o.x) * inv.x;
    let tx1 = (b.max.x - ray.o.x) * inv.x;
    let ty0 = (b.min.y - ray.o.y) * inv.y;
    let ty1 = (b.max.y - ray.o.y) * inv.y;
    let tz0 = (b.min.z - ray.o.z) * inv.z;
    let tz1 = (b.max.z - ray.o.z) * inv.z;
    let t_enter = tx0.min(tx1).max(ty0.min(ty1)).max(tz0.min(tz1)).max(0.0);
    let t_exit = tx0.max(tx1).min(ty0.max(ty1)).min(tz0.max(tz1)).min(t_max);
    // Slightly widened (pbrt-v4's 1 + 2γ₃) so rays grazing a flat box are not lost.
    t_enter <= t_exit * (1.0 + 4.0 * f64::EPSILON)
}

fn build_rec(items: &mut [BuildPrim], start: usize, end: usize, nodes: &mut Vec<Node>) -> usize {
    let me = nodes.len();
    let slice = &mut items[start..end];
    let bounds = slice.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds));
    let cb = slice.iter().fold(Aabb::EMPTY, |b, p| b.grow(p.centroid));
    let n = slice.len();
    nodes.push(Node {
        bounds,
        offset: start as u32,
        count: n as u16,
        axis: 0,
    });
    if n == 1 {
        return me;
    }
    let ext = cb.max - cb.min;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let (lo, span) = (cb.min[axis], ext[axis]);
    let mid = if span <= 0.0 || !span.is_finite() {
        if n <= MAX_LEAF {
            return me;
        }
        n / 2
    } else {
        let bin_of = |c: f64| (((c - lo) / span * BINS as f64) as usize).min(BINS - 1);
        let mut bins = [(Aabb::EMPTY, 0usize); BINS];
        for p in slice.iter() {
            let b = &mut bins[bin_of(p.centroid[axis])];
            b.0 = b.0.union(p.bounds);
            b.1 += 1;
        }
        // Sweep: costs of splitting after bin i.
        let mut right = [(0.0, 0usize); BINS];
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for i in (1..BINS).rev() {
            acc = acc.union(bins[i].0);
            cnt += bins[i].1;
            right[i] = (acc.area(), cnt);
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        let (mut best, mut best_cost) = (0, f64::INFINITY);
        for i in 0..BINS - 1 {
            acc = acc.union(bins[i].0);
            cnt += bins[i].1;
            let (ra, rc) = right[i + 1];
            if cnt == 0 || rc == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST + (acc.area() * cnt as f64 + ra * rc as f64) / bounds.area();
            if cost < best_cost {
                best_cost = cost;
                best = i;
            }
        }
        if best_cost >= n as f64 && n <= MAX_LEAF {
            return me;
        }
        if best_cost.is_finite() {
            // Partition in place by bin.
            let mut i = 0;
            let mut j = n;
            while i < j {
                if bin_of(slice[i].centroid[axis]) <= best {
                    i += 1;
                } else {
                    j -= 1;
                    slice.swap(i, j);
                }
            }
            if i == 0 || i == n {
                n / 2
            } else {
                i
            }
        } else {
            slice.sort_by(|a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
            n / 2
        }
    };
    build_rec(items, start, start + mid, nodes);
    let second = build_rec(items, start + mid, end, nodes);
    nodes[me] = Node {
        bounds,
        offset: second as u32,
        count: 0,
        axis: axis as u8,
    };
    me
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::{RngCore, SeedableRng};

    fn unit(rng: &mut rand_pcg::Pcg32) -> f64 {
        (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    #[test]
    fn bvh_agrees_with_brute_force() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(9);
        let mut prims = Vec::new();
        for i in 0..500 {
            let c = Vec3::new(unit(&mut rng), unit(&mut rng), unit(&mut rng)) * 10.0;
            if i % 5 == 0 {
                prims.push(Geom::Sphere(Sphere {
                    center: c,
                    radius: 0.1 + 0.3 * unit(&mut rng),
                }));
            } else {
                let d = |rng: &mut rand_pcg::Pcg32| {
                    Vec3::new(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5)
                };
                let (a, b) = (d(&mut rng), d(&mut rng));
                if let Some(t) = Triangle::new(c, c + a, c + b) {
                    prims.push(Geom::Triangle(t));
                }
            }
        }
        let bvh = Bvh::build(&prims);
        for _ in 0..2000 {
            let o = Vec3::new(unit(&mut rng), unit(&mut rng), unit(&mut rng)) * 14.0
                - Vec3::new(2.0, 2.0, 2.0);
            let d = Vec3::new(
                unit(&mut rng) - 0.5,
                unit(&mut rng) - 0.5,
                unit(&mut rng) - 0.5,
            )
            .normalized();
            let ray = Ray::new(o, d);
            let brute = prims
                .iter()
                .enumerate()
                .filter_map(|(i, g)| g.intersect(&ray, f64::INFINITY).map(|h| (h.0, i)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let got = bvh.intersect(&ray, f64::INFINITY);
            match (brute, got) {
                (None, None) => {}
                (Some((t, i)), Some(h)) => {
                    assert!((t - h.t).abs() < 1e-12, "{t} vs {}", h.t);
                    assert_eq!(i as u32, h.prim);
                }
                (a, b) => panic!("brute {a:?} bvh {b:?}"),
            }
            assert_eq!(bvh.occluded(&ray, f64::INFINITY), brute.is_some());
        }
        assert!(Bvh::build(&[])
            .intersect(&Ray::new(Vec3::ZERO, Vec3::new(0.0, 0.0, 1.0)), 1.0)
            .is_none());
    }
}
