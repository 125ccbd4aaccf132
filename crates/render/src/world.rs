//! A scene compiled for rendering: primitives under a BVH, their materials, the light set.

use crate::brdf::Brdf;
use crate::bvh::{Bvh, Geom};
use crate::light::{LightSampling, LightSet};
use crate::math::{Rgb, Vec3};
use crate::ray::Ray;
use crate::scene::{Scene, Shape};
use crate::shape::Triangle;
use crate::texture::Texture;

/// What a primitive is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Surface {
    /// A reflecting surface with material index.
    Material(u32),
    /// An emitting light triangle with index into the light set.
    Emitter(u32),
}

/// A ray–surface intersection (pbrt-v4 `SurfaceInteraction`, reduced).
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    /// Ray parameter.
    pub t: f64,
    /// The point, reconstructed on the surface (barycentrics / sphere reprojection).
    pub p: Vec3,
    /// Unit geometric normal (the shape's orientation; not flipped towards the ray).
    pub ng: Vec3,
    /// What was hit.
    pub surface: Surface,
}

/// The compiled scene.
#[derive(Clone, Debug)]
pub struct World {
    bvh: Bvh,
    geoms: Vec<Geom>,
    surfaces: Vec<Surface>,
    materials: Vec<Brdf>,
    /// The solid texture of each material, if any (parallel to `materials`).
    textures: Vec<Option<Texture>>,
    /// The area lights.
    pub lights: LightSet,
    /// Degenerate or non-finite triangles and spheres that were skipped.
    pub skipped: usize,
}

impl World {
    /// Compiles a scene: objects (shadow catchers included) and light triangles become primitives of one
    /// BVH. Degenerate triangles (zero area), non-positive or non-finite spheres are skipped
    /// and counted in [`World::skipped`].
    pub fn new(scene: &Scene) -> World {
        World::with_light_sampling(scene, LightSampling::default())
    }

    /// [`World::new`] with the area lights sampled by `mode`.
    pub fn with_light_sampling(scene: &Scene, mode: LightSampling) -> World {
        let mut geoms = Vec::new();
        let mut surfaces = Vec::new();
        let mut materials = Vec::new();
        let mut textures = Vec::new();
        let mut skipped = 0;
        // Material m is object m of `scene.objects` (differential rendering tells catchers
        // from objects by it).
        for obj in &scene.objects {
            let m = materials.len() as u32;
            materials.push(obj.material);
            textures.push(obj.texture.clone());
            match &obj.shape {
                Shape::Sphere(s) => {
                    if s.radius > 0.0 && s.radius.is_finite() && s.center.is_finite() {
                        geoms.push(Geom::Sphere(*s));
                        surfaces.push(Surface::Material(m));
                    } else {
                        skipped += 1;
                    }
                }
                Shape::Triangles { triangles } => {
                    for t in triangles {
                        match Triangle::new(t[0], t[1], t[2]) {
                            Some(tri) => {
                                geoms.push(Geom::Triangle(tri));
                                surfaces.push(Surface::Material(m));
                            }
                            None => skipped += 1,
                        }
                    }
                }
            }
        }
        let mut light_items = Vec::new();
        for light in &scene.lights {
            if !(light.radiance.is_finite()) {
                skipped += light.triangles.len();
                continue;
            }
            for t in &light.triangles {
                match Triangle::new(t[0], t[1], t[2]) {
                    Some(tri) => {
                        surfaces.push(Surface::Emitter(light_items.len() as u32));
                        geoms.push(Geom::Triangle(tri));
                        light_items.push((tri, light.radiance));
                    }
                    None => skipped += 1,
                }
            }
        }
        World {
            bvh: Bvh::build(&geoms),
            geoms,
            surfaces,
            materials,
            textures,
            lights: LightSet::new(light_items).with_sampling(mode),
            skipped,
        }
    }

    /// The nearest intersection in (0, t_max).
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<SurfaceHit> {
        let h = self.bvh.intersect(ray, t_max)?;
        let (p, ng) = match &self.geoms[h.prim as usize] {
            Geom::Triangle(tri) => (tri.point(h.b1, h.b2), tri.n),
            Geom::Sphere(s) => {
                let d = ray.at(h.t) - s.center;
                let n = d.normalized();
                (s.center + n * s.radius, n)
            }
        };
        Some(SurfaceHit {
            t: h.t,
            p,
            ng,
            surface: self.surfaces[h.prim as usize],
        })
    }

    /// Whether anything blocks the ray in (0, t_max).
    #[inline]
    pub fn occluded(&self, ray: &Ray, t_max: f64) -> bool {
        self.bvh.occluded(ray, t_max)
    }

    /// Material `i`.
    #[inline]
    pub fn material(&self, i: u32) -> &Brdf {
        &self.materials[i as usize]
    }

    /// The solid texture of material `i`, if any.
    #[inline]
    pub fn texture(&self, i: u32) -> Option<&Texture> {
        self.textures[i as usize].as_ref()
    }

    /// Material `i` as seen at point `p`: its diffuse albedo modulated by its texture.
    #[inline]
    pub fn material_at(&self, i: u32, p: Vec3) -> Brdf {
        let b = self.materials[i as usize];
        match &self.textures[i as usize] {
            None => b,
            Some(t) => b.with_diffuse_scaled(t.factor(p)),
        }
    }

    /// Radiance of light triangle `i`.
    #[inline]
    pub fn emitted(&self, i: u32) -> Rgb {
        self.lights.radiance(i as usize)
    }

    /// Number of primitives.
    pub fn primitive_count(&self) -> usize {
        self.geoms.len()
    }
}
