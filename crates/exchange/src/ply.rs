//! The point cloud as an ASCII PLY (x y z as doubles in the solve's world, sRGB colours when
//! known, and each point's RMS solve error over the observations the solve kept).

use std::fmt::Write as _;

use super::Shot;
use vfxgraph_geometry::error::{Result, VisionError};

/// The PLY text of the shot's cloud.
pub fn format(shot: &Shot) -> Result<String> {
    shot.validate()?;
    let cloud = shot
        .cloud
        .as_ref()
        .ok_or_else(|| VisionError::InvalidInput("the ply format needs the points input".into()))?;
    let mut s = String::new();
    let _ = write!(
        s,
        "ply\nformat ascii 1.0\ncomment vfxgraph point cloud, solve world and units\n\
         element vertex {}\nproperty double x\nproperty double y\nproperty double z\n",
        cloud.points.len()
    );
    if shot.colors.is_some() {
        s.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    s.push_str("property double error\nend_header\n");
    for (j, p) in cloud.points.iter().enumerate() {
        let _ = write!(s, "{} {} {}", p[0], p[1], p[2]);
        if let Some(c) = &shot.colors {
            let _ = write!(s, " {} {} {}", c[j][0], c[j][1], c[j][2]);
        }
        let e = cloud.errors.get(j).copied().unwrap_or(f64::NAN);
        let _ = writeln!(s, " {}", if e.is_finite() { e } else { -1.0 });
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::super::test_shot::shot;
    use super::*;

    #[test]
    fn header_and_rows() {
        let s = shot();
        let text = format(&s).unwrap();
        let (head, body) = text.split_once("end_header\n").unwrap();
        assert!(head.contains("element vertex 40\n") && head.contains("property uchar red"));
        let rows: Vec<Vec<f64>> = body
            .lines()
            .map(|l| l.split(' ').map(|t| t.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 40);
        let c = s.cloud.as_ref().unwrap();
        for (j, r) in rows.iter().enumerate() {
            assert_eq!(&r[..3], &c.points[j]);
            assert_eq!(r[3] as u8, s.colors.as_ref().unwrap()[j][0]);
        }
        let mut none = s.clone();
        none.cloud = None;
        assert!(format(&none).is_err());
    }
}
