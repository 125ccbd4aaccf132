//! The scene model (book §9, §10; the S3D scene language's concepts): a camera, objects
//! (shape + material), polygonal area lights, a constant background or an HDR dome, and
//! shadow catchers. It is plain data (serde), independent of any file format; readers
//! ([`crate::scn`]) fill it and [`crate::World`] compiles it for rendering.

use serde::{Deserialize, Serialize};

use crate::brdf::Brdf;
use crate::camera::Camera;
use crate::math::{Rgb, Vec3};
use crate::shape::Sphere;

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
/// image and its orientation. Rendering with it needs the dome module's `Environment`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DomeSpec {
    /// The `orig` direction (the dome's u axis before orthogonalization).
    pub orig: Vec3,
    /// The `south` direction (the dome's n axis).
    pub south: Vec3,
    /// The image file, as written in the scene (resolved against the scene file's folder).
    pub image: String,
}

/// A whole scene (book §9.13).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// The camera (from `view{…}` or a calibrated K[R|t]).
    pub camera: Camera,
    /// Reflecting objects.
    pub objects: Vec<Object>,
    /// Area lights.
    pub lights: Vec<AreaLight>,
    /// Radiance of a constant environment (black for the book's `scene{…}`).
    pub background: Rgb,
    /// The HDR dome of an `hdrscene{…}`, if any.
    pub dome: Option<DomeSpec>,
    /// Shadow catchers (S3D `plshadow`): rendered as ordinary objects by the path tracer;
    /// differential rendering (book §10) treats them specially.
    pub shadow_catchers: Vec<Object>,
}
