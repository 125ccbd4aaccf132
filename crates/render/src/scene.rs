//! The scene model (book §9, §10; the S3D scene language's concepts): a camera, objects
//! (shape + material), polygonal area lights, a constant background or an HDR dome, and
//! shadow catchers. It is plain data (serde), independent of any file format; readers
//! ([`crate::scn`]) fill it and [`crate::World`] compiles it for rendering.

use serde::{Deserialize, Serialize};

use crate::brdf::Brdf;
use crate::camera::Camera;
use crate::math::{Rgb, Vec3};
use crate::shape::Sphere;
use crate::texture::Texture;

/// A shape (S3D `sphere{…}` or `trilist{…}`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Shape {
    /// A sphere.
    Sphere(Sphere),
    /// A triangle mesh as a list of triangles (vertices counter-clockwise around the normal;
    /// surfaces are two-sided anyway).
    Triangles {
        /// The triangles.
        triangles: Vec<[Vec3; 3]>,
    },
}

/// A surface with a material (S3D `primobj` / `polyobj`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Object {
    /// Geometry.
    pub shape: Shape,
    /// Reflectance.
    pub material: Brdf,
    /// A shadow catcher (S3D `plshadow`, book §10.10): a stand-in for real geometry of the
    /// photographed set (the ground under a dome). The path tracer shades it like any object;
    /// differential rendering renders the scene with and without the synthetic objects and
    /// keeps the catchers' change (see [`Scene::without_synthetic_objects`]).
    #[serde(default)]
    pub catcher: bool,
    /// A solid texture modulating the material's diffuse albedo ([`crate::texture`]); `None`
    /// for a uniform material.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texture: Option<Texture>,
}

impl Object {
    /// An ordinary (non-catcher) object.
    pub fn new(shape: Shape, material: Brdf) -> Object {
        Object {
            shape,
            material,
            catcher: false,
            texture: None,
        }
    }

    /// This object with a solid texture on its diffuse albedo.
    pub fn with_texture(mut self, texture: Texture) -> Object {
        self.texture = Some(texture);
        self
    }
}

/// A polygonal area light (S3D `polylight`, book §9.11): triangles emitting a constant
/// radiance from both faces (the book uses |cos θ| at the light). Emitters reflect nothing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AreaLight {
    /// Emitted radiance (W·sr⁻¹·m⁻² per channel, linear).
    pub radiance: Rgb,
    /// The emitting triangles.
    pub triangles: Vec<[Vec3; 3]>,
}

/// An HDR light dome (S3D `hdrdome{orig, south, hdrimg}`, book §10): an equirectangular
/// image and its orientation (see [`crate::dome`] for the conventions). Readers keep the file
/// name; the caller loads the image and builds a [`crate::dome::Dome`], the scene's
/// [`crate::Environment`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DomeSpec {
    /// The `orig` direction (the dome's u axis before orthogonalization).
    pub orig: Vec3,
    /// The `south` direction (the dome's n axis).
    pub south: Vec3,
    /// The image file, as written in the scene (relative to the scene file's folder).
    pub image: String,
    /// Radiance scale applied to the image (1 for `.scn`).
    #[serde(default = "one")]
    pub scale: f64,
}

/// A whole scene (book §9.13).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// The camera (from `view{…}` or a calibrated K[R|t]); `None` for a YAML scene without
    /// `camera:`, which is seen only through cameras from elsewhere (a solved camera path).
    #[serde(default)]
    pub camera: Option<Camera>,
    /// Reflecting objects.
    pub objects: Vec<Object>,
    /// Area lights.
    pub lights: Vec<AreaLight>,
    /// Radiance of a constant environment (black for the book's `scene{…}`).
    pub background: Rgb,
    /// The HDR dome of an `hdrscene{…}` or a YAML scene, if any. When present it replaces
    /// `background`.
    pub dome: Option<DomeSpec>,
}

impl Scene {
    /// The shadow catchers (objects with [`Object::catcher`]).
    pub fn catchers(&self) -> impl Iterator<Item = &Object> {
        self.objects.iter().filter(|o| o.catcher)
    }

    /// The scene without its synthetic objects: only the shadow catchers, lights and dome
    /// remain — the "empty set" render of differential rendering (book §10.10; Debevec 1998).
    pub fn without_synthetic_objects(&self) -> Scene {
        let mut s = self.clone();
        s.objects.retain(|o| o.catcher);
        s
    }
}

fn one() -> f64 {
    1.0
}
