//! Normalization of point sets before the DLT and the 8-point algorithm (book §4.2 and §5.7,
//! Hartley 1997): translate the centroid to the origin and scale so that the RMS distance to the
//! origin is √2 (2D) or √3 (3D).

use nalgebra::{Matrix3, Matrix4, Point2, Point3};

use crate::error::{Result, VisionError};

/// The 2D normalizing similarity H, its inverse and the normalized points.
pub type Normalized2d = (Matrix3<f64>, Matrix3<f64>, Vec<Point2<f64>>);

/// The 2D normalizing similarity H (and H⁻¹) of book §4.2 (`calib_get_normalize_transform`).
pub fn normalize_2d(points: &[Point2<f64>]) -> Result<Normalized2d> {
    let n = points.len() as f64;
    if points.is_empty() {
        return Err(VisionError::TooFewPoints { needed: 1, got: 0 });
    }
    let c = points
        .iter()
        .fold(nalgebra::Vector2::zeros(), |a, p| a + p.coords)
        / n;
    let d: f64 = points.iter().map(|p| (p.coords - c).norm_squared()).sum();
    if !(d > 0.0) || !d.is_finite() {
        return Err(VisionError::Degenerate("all 2D points coincide".into()));
    }
    let s = (2.0 * n / d).sqrt();
    let h = Matrix3::new(s, 0.0, -s * c.x, 0.0, s, -s * c.y, 0.0, 0.0, 1.0);
    let hinv = Matrix3::new(1.0 / s, 0.0, c.x, 0.0, 1.0 / s, c.y, 0.0, 0.0, 1.0);
    let out = points
        .iter()
        .map(|p| Point2::from((p.coords - c) * s))
        .collect();
    Ok((h, hinv, out))
}

/// The 3D normalizing similarity T of book §4.2 (`calib_get_3dnormalize_transform`).
pub fn normalize_3d(points: &[Point3<f64>]) -> Result<(Matrix4<f64>, Vec<Point3<f64>>)> {
    let n = points.len() as f64;
    if points.is_empty() {
        return Err(VisionError::TooFewPoints { needed: 1, got: 0 });
    }
    let c = points
        .iter()
        .fold(nalgebra::Vector3::zeros(), |a, p| a + p.coords)
        / n;
    let d: f64 = points.iter().map(|p| (p.coords - c).norm_squared()).sum();
    if !(d > 0.0) || !d.is_finite() {
        return Err(VisionError::Degenerate("all 3D points coincide".into()));
    }
    let s = (3.0 * n / d).sqrt();
    let mut t = Matrix4::identity() * s;
    t[(3, 3)] = 1.0;
    t[(0, 3)] = -s * c.x;
    t[(1, 3)] = -s * c.y;
    t[(2, 3)] = -s * c.z;
    let out = points
        .iter()
        .map(|p| Point3::from((p.coords - c) * s))
        .collect();
    Ok((t, out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rms_distances() {
        let pts: Vec<_> = (0..10)
            .map(|i| Point2::new(100.0 + i as f64 * 3.0, 50.0 - (i * i) as f64))
            .collect();
        let (h, hinv, out) = normalize_2d(&pts).unwrap();
        let rms = (out.iter().map(|p| p.coords.norm_squared()).sum::<f64>() / 10.0).sqrt();
        assert!((rms - 2f64.sqrt()).abs() < 1e-12);
        assert!((h * hinv - Matrix3::identity()).norm() < 1e-12);
        let p = h * pts[3].to_homogeneous();
        assert!((p.xy() / p.z - out[3].coords).norm() < 1e-12);
        let pts3: Vec<_> = (0..10)
            .map(|i| Point3::new(i as f64, (i * 2) as f64, -(i as f64).sqrt()))
            .collect();
        let (_, out3) = normalize_3d(&pts3).unwrap();
        let rms3 = (out3.iter().map(|p| p.coords.norm_squared()).sum::<f64>() / 10.0).sqrt();
        assert!((rms3 - 3f64.sqrt()).abs() < 1e-12);
        assert!(normalize_2d(&[Point2::new(1.0, 1.0); 3]).is_err());
    }
}
