//! # vfxgraph-render
//!
//! Physically based path tracing for the book's chapter 9 (Madeira & Velho, *Introduction to
//! Visual Effects*): a scene model ([`Scene`]) with the book's `.scn` reader ([`scn`]) and a YAML reader
//! ([`yaml_scene`], with Wavefront OBJ meshes: [`obj`]), a
//! calibrated pinhole [`Camera`] (K[R|t], book §2.8), spheres and triangles under a SAH
//! [`bvh::Bvh`], the BRDFs of §9.5 with importance sampling ([`brdf`]), polygonal area lights
//! ([`light`]), an [`Environment`] at infinity, and a path tracer with next-event estimation,
//! multiple importance sampling and Russian roulette ([`integrator`]), rendered in tiles on
//! rayon with one random stream per pixel ([`render()`]).
//!
//! Conventions: f64 geometry with the crate's own small [`Vec3`] (see [`math`]); linear RGB;
//! camera x ~ K(RX + t) looking down +z, pixel origin at the top-left pixel's centre, y down;
//! every sampling routine returns its pdf and states its measure (solid angle unless said).

pub mod brdf;
pub mod bvh;
pub mod camera;
pub mod catcher_fit;
pub mod catcher_texture;
pub mod differential;
pub mod dome;
pub mod environment;
pub mod integrator;
pub mod light;
pub mod local_scene;
pub mod math;
pub mod obj;
pub mod placement;
pub mod plate;
pub mod proxy;
pub mod ray;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod scene_file;
pub mod scn;
pub mod shape;
pub mod shot_camera;
pub mod spherical_triangle;
pub mod texture;
pub mod world;
pub mod yaml_scene;

pub use brdf::{BlinnPhong, Brdf, Lambert, Mirror};
pub use camera::{Camera, CameraError, ImageSize};
pub use environment::{ConstantEnvironment, Environment, EnvironmentSample};
pub use integrator::{PathTracer, Strategy};
pub use math::{Rgb, Vec3};
pub use render::{
    mix_seed, render, with_sync_progress, Objects, RenderError, RenderOptions, RenderOutput,
    RenderSettings, RenderStats,
};
pub use scene::{AreaLight, DomeSpec, Object, Scene, Shape};
pub use scene_file::{read_scene_file, SceneFile, SceneFileError};
pub use scn::{parse_scn, ScnError};
pub use shot_camera::{camera_for_frame, PathPose, ShotCameraError, SolvedK};
pub use texture::Texture;
pub use world::World;
pub use yaml_scene::{parse_yaml_scene, YamlScene, YamlSceneError};
