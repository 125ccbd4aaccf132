//! Modeling tools (book chapter 8): measuring the scene from points a person marked on several
//! solved frames.

pub mod point_cloud;

pub use point_cloud::{point_cloud_calibrate, PointCloudReport};
