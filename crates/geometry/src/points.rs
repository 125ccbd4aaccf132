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

    /// A cloud without inlier marks (older JSON) counts every observation; with marks, only
    /// the listed frames; lists that disagree are named.
    #[test]
    fn inlier_marks() {
        let mut c: PointCloud = serde_json::from_str(
            r#"{"points": [[0,0,1],[1,0,1]], "track_ids": [4, 9], "errors": []}"#,
        )
        .unwrap();
        assert!(c.inlier_frames.is_empty() && c.is_inlier(1, 77));
        assert!(!serde_json::to_string(&c).unwrap().contains("inlier"));
        c.inlier_frames = vec![vec![3, 5, 8], vec![]];
        c.validate().unwrap();
        assert!(c.is_inlier(0, 5) && !c.is_inlier(0, 4) && !c.is_inlier(1, 3));
        let back: PointCloud = serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
        assert_eq!(back, c);
        c.inlier_frames[0] = vec![5, 3];
        assert!(c.validate().unwrap_err().contains("track 4"));
        c.inlier_frames.pop();
        assert!(c.validate().unwrap_err().contains("1 inlier lists"));
    }
}

/// A reconstructed point cloud (book §7.14): positions with the id of the feature track each
/// point was triangulated from, its RMS reprojection error in pixels (NaN when unknown), and —
/// from a solve that rejects outliers — which observations of its track the solve kept.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PointCloud {
    /// World positions.
    pub points: Vec<[f64; 3]>,
    /// The track id of each point (see `klt::Track::id`).
    pub track_ids: Vec<u64>,
    /// RMS reprojection error of each point over its inlier observations (all of them when
    /// `inlier_frames` is empty), pixels.
    pub errors: Vec<f64>,
    /// Per point, the frame numbers (ascending) of the observations the solve kept as inliers;
    /// the track's observations in other frames are outliers. Empty when the producer made no
    /// such decision (a plain bundle adjustment, a cloud read from a file): then every
    /// observation counts.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inlier_frames: Vec<Vec<i64>>,
}

impl PointCloud {
    /// Whether the observation of point `point` in frame `frame` is one the solve kept (always
    /// true for a cloud without inlier marks).
    pub fn is_inlier(&self, point: usize, frame: i64) -> bool {
        self.inlier_frames
            .get(point)
            .is_none_or(|f| f.binary_search(&frame).is_ok())
    }

    /// Checks that the lists agree: one track id per point, one error per point (or none), one
    /// inlier list per point (or none), each ascending.
    pub fn validate(&self) -> Result<(), String> {
        let n = self.points.len();
        if self.track_ids.len() != n
            || !(self.errors.is_empty() || self.errors.len() == n)
            || !(self.inlier_frames.is_empty() || self.inlier_frames.len() == n)
        {
            return Err(format!(
                "point cloud: {n} points, {} track ids, {} errors, {} inlier lists",
                self.track_ids.len(),
                self.errors.len(),
                self.inlier_frames.len()
            ));
        }
        if let Some(j) = self
            .inlier_frames
            .iter()
            .position(|f| f.windows(2).any(|w| w[0] >= w[1]))
        {
            return Err(format!(
                "point cloud: the inlier frames of point {j} (track {}) are not ascending",
                self.track_ids[j]
            ));
        }
        Ok(())
    }
}
