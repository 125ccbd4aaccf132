//! Point sets carried between nodes: 2D projections (pixels) and 3D scene points.

use nalgebra::{Point2, Point3};
use serde::{Deserialize, Serialize};

/// A list of 2D points in pixels (JSON: `[[x, y], …]`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Points2d(pub Vec<Point2<f64>>);

/// A list of 3D points (JSON: `[[x, y, z], …]`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Points3d(pub Vec<Point3<f64>>);

impl Points2d {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.0.len()
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl Points3d {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.0.len()
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl From<Vec<Point2<f64>>> for Points2d {
    fn from(v: Vec<Point2<f64>>) -> Self {
        Points2d(v)
    }
}

impl From<Vec<Point3<f64>>> for Points3d {
    fn from(v: Vec<Point3<f64>>) -> Self {
        Points3d(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_is_list_of_coordinate_lists() {
        let p = Points2d(vec![Point2::new(1.0, 2.5)]);
        assert_eq!(serde_json::to_string(&p).unwrap(), "[[1.0,2.5]]");
        let q: Points3d = serde_json::from_str("[[1,2,3],[4,5,6]]").unwrap();
        assert_eq!(q.0[1], Point3::new(4.0, 5.0, 6.0));
    }
}

/// A reconstructed point cloud (book §7.14): positions with the id of the feature track each
/// point was triangulated from, and its RMS reprojection error in pixels (NaN when unknown).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PointCloud {
    /// World positions.
    pub points: Vec<[f64; 3]>,
    /// The track id of each point (see `klt::Track::id`).
    pub track_ids: Vec<u64>,
    /// RMS reprojection error of each point over its observations, pixels.
    pub errors: Vec<f64>,
}
