//! Light domes: equirectangular radiance maps around the scene (book 10.7–10.9), oriented by the
//! book's `orig`/`south` vectors or a calibrated camera, with bilinear lookup and importance
//! sampling by luminance × sin θ through a piecewise-constant 2-D distribution (Pharr, Jakob &
//! Humphreys, *Physically Based Rendering*, §13.6.7 "2D Sampling with Multidimensional
//! Transformations" and §14.2.4 "Infinite Area Lights").
//!
//! # Conventions
//!
//! - **Image.** Equirectangular, `w × h` (usually `w = 2h`): longitude across, latitude down.
//!   Continuous pixel coordinates `(x, y)` cover `[0, w) × [0, h)`; texel `(i, j)` covers
//!   `[i, i+1) × [j, j+1)` and its value sits at its centre `(i + ½, j + ½)`.
//! - **Basis** (book 10.7). From the two vectors of the book's `hdrdome{orig, south, …}`:
//!   `n = unit(south)`, `u = unit(orig − (orig·n) n)`, `v = n × u`. A direction `d` has
//!   `θ = acos(d·n)` and `φ = atan2(d·v, d·u)`, and lands at
//!   `x = (1 − φ/π) · w/2`, `y = (θ/π) · h`. So `south` is the direction shown on the **top row**
//!   (θ = 0), `−south` the bottom row, `orig` the **centre column** (φ = 0), and `v` the column at
//!   `x = w/4`.
//! - **World.** vfxgraph's world is y-up; [`Dome::y_up`] uses `south = +y`, `orig = −z`: the top
//!   row is the zenith, the centre column looks along −z, and +x is at `x = 3w/4` (to the right of
//!   the centre, as seen from inside the sphere) — the layout of ordinary latitude–longitude
//!   panoramas such as Poly Haven's.
//! - **Calibrated camera** (book 10.8): [`Dome::from_camera_rotation`] takes `south` = the second
//!   row of the camera's rotation `R` (the camera's image-down axis in world coordinates) and
//!   `orig` = minus the third row (minus the viewing direction), as the book's scene does.
//! - **Measures.** [`Dome::sample`] returns a pdf with respect to **solid angle** (sr⁻¹).
//!   Radiance is the image's linear RGB.

use std::f64::consts::PI;

use nalgebra::{Matrix3, Vector3};
use vfxgraph_imaging::color::luminance;
use vfxgraph_imaging::Image;

use crate::environment::{ConstantEnvironment, Environment, EnvironmentSample};
use crate::math::{Rgb, Vec3};
use crate::sampling::Distribution1D;
use crate::scene::Scene;

/// What can be wrong with a dome's image or orientation.
#[derive(thiserror::Error, Debug, Clone, PartialEq)]
pub enum DomeError {
    /// The image is empty, too small, or not gray/RGB(A).
    #[error("invalid dome image: {0}")]
    Image(String),
    /// `orig`/`south` (or the rotation) do not define a basis: zero, non-finite or parallel.
    #[error("invalid dome orientation: {0}")]
    Orientation(String),
}

/// A piecewise-constant 2-D distribution on `[0, 1)²` over a `w × h` grid: a marginal over rows
/// and one conditional per row (PBRT §13.6.7's `Distribution2D`).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// From `w × h` non-negative values, row-major.
    pub fn new(func: &[f64], w: usize, h: usize) -> Distribution2D {
        let rows: Vec<Distribution1D> = (0..h)
            .map(|j| Distribution1D::new(&func[j * w..(j + 1) * w]))
            .collect();
        let m: Vec<f64> = rows.iter().map(|r| r.integral()).collect();
        Distribution2D {
            marginal: Distribution1D::new(&m),
            rows,
        }
    }

    /// Maps `(u0, u1) ∈ [0, 1)²` to `((s, t), density over [0, 1)²)`: `t` (row) from the marginal,
    /// `s` (column) from that row's conditional.
    pub fn sample(&self, u0: f64, u1: f64) -> ((f64, f64), f64) {
        let (t, pt, j) = self.marginal.sample(u1);
        let (s, ps, _) = self.rows[j].sample(u0);
        ((s, t), ps * pt)
    }

    /// Density at `(s, t)`.
    pub fn pdf(&self, s: f64, t: f64) -> f64 {
        let h = self.rows.len();
        let j = ((t * h as f64) as usize).min(h - 1);
        let row = &self.rows[j];
        let i = ((s * row.len() as f64) as usize).min(row.len() - 1);
        row.value(i) / self.marginal.integral()
    }
}

/// One importance sample of a dome (pbrt-v4's `LightLiSample`, ch. 12: the value with its
/// pdf): a unit direction towards the dome, the radiance arriving from it, and the pdf in solid angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DomeSample {
    /// Unit world direction the light comes from.
    pub direction: Vector3<f64>,
    /// Linear RGB radiance along it (bilinear lookup).
    pub radiance: Vector3<f64>,
    /// Probability density of `direction`, per steradian.
    pub pdf_solid_angle: f64,
}

/// An oriented, importance-sampled equirectangular light dome (book 10.7–10.9). See the module
/// documentation for every convention.
#[derive(Clone, Debug)]
pub struct Dome {
    image: Image,
    orig: Vector3<f64>,
    south: Vector3<f64>,
    /// Rows: u, v, n (world → dome frame).
    frame: Matrix3<f64>,
    dist: Distribution2D,
    /// Every texel is black (nothing to sample).
    black: bool,
}

/// How a dome is oriented: `orig`/`south`, or a calibrated camera's rotation.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
#[param(check)]
pub struct DomeOptions {
    /// direction shown at the centre column (φ = 0)
    pub orig: [f64; 3],
    /// direction shown on the top row (θ = 0)
    pub south: [f64; 3],
    /// a camera rotation R (9 numbers, rows); overrides orig/south when given
    pub rotation: Vec<f64>,
}

/// vfxgraph's y-up world ([`Dome::y_up`]).
impl Default for DomeOptions {
    fn default() -> Self {
        DomeOptions {
            orig: [0.0, 0.0, -1.0],
            south: [0.0, 1.0, 0.0],
            rotation: Vec::new(),
        }
    }
}

impl DomeOptions {
    /// `rotation` is empty or 9 numbers.
    pub fn check(&self) -> Result<(), String> {
        match self.rotation.len() {
            0 | 9 => Ok(()),
            n => Err(format!(
                "rotation needs 9 numbers (3x3, row by row), got {n}"
            )),
        }
    }
}

impl Dome {
    /// A dome from an equirectangular image (gray → RGB, alpha dropped) and the book's `orig` and
    /// `south` vectors (book 10.7–10.8). Builds the sampling distribution: texel weight =
    /// (largest luminance among the texel and its 8 neighbours, since a bilinear lookup inside a
    /// texel reads them, + 10⁻⁴ × the mean luminance) × sin θ of the texel's row centre, so the
    /// pdf is positive wherever the radiance is.
    pub fn new(image: &Image, orig: Vector3<f64>, south: Vector3<f64>) -> Result<Dome, DomeError> {
        if image.width < 2 || image.height < 1 || image.is_empty() {
            return Err(DomeError::Image(format!(
                "{}x{} is too small for an equirectangular map",
                image.width, image.height
            )));
        }
        let image = match image.channels {
            1 | 2 => image.to_rgb(),
            3 => image.clone(),
            4 => image.without_alpha(),
            c => return Err(DomeError::Image(format!("{c} channels"))),
        };
        let frame = basis(&orig, &south)?;
        let (w, h) = (image.width, image.height);
        let lum: Vec<f64> = image
            .data
            .chunks_exact(3)
            .map(|p| {
                let l = luminance(p[0], p[1], p[2]) as f64;
                if l.is_finite() && l > 0.0 {
                    l
                } else {
                    0.0
                }
            })
            .collect();
        let mean = lum.iter().sum::<f64>() / lum.len() as f64;
        let mut func = vec![0.0; w * h];
        for j in 0..h {
            let sin_t = (PI * (j as f64 + 0.5) / h as f64).sin();
            for i in 0..w {
                let mut m = 0.0f64;
                for dj in [-1i64, 0, 1] {
                    let jj = (j as i64 + dj).clamp(0, h as i64 - 1) as usize;
                    for di in [w - 1, 0, 1] {
                        m = m.max(lum[jj * w + (i + di) % w]);
                    }
                }
                func[j * w + i] = (m + 1e-4 * mean) * sin_t;
            }
        }
        Ok(Dome {
            black: !image.data.iter().any(|&v| v > 0.0),
            dist: Distribution2D::new(&func, w, h),
            image,
            orig,
            south,
            frame,
        })
    }

    /// A dome in vfxgraph's y-up world: `south = +y` (zenith on the top row), `orig = −z`
    /// (the centre column). See the module documentation.
    pub fn y_up(image: &Image) -> Result<Dome, DomeError> {
        Dome::new(image, -Vector3::z(), Vector3::y())
    }

    /// A dome oriented by the rotation `R` of the calibrated camera that photographed the light
    /// probe (book 10.8): `south` = 2nd row of `R`, `orig` = −(3rd row of `R`).
    pub fn from_camera_rotation(image: &Image, r: &Matrix3<f64>) -> Result<Dome, DomeError> {
        if r.iter().any(|v| !v.is_finite()) {
            return Err(DomeError::Orientation("the rotation is not finite".into()));
        }
        let south = r.row(1).transpose();
        let orig = -r.row(2).transpose();
        Dome::new(image, orig, south)
    }

    /// The dome of `image` oriented by `camera_rotation` (the rotation of the camera that
    /// photographed the probe, [`Dome::from_camera_rotation`]), else by `o.rotation`, else by
    /// `o.orig`/`o.south`. Giving both a camera and `o.rotation` is an error.
    pub fn oriented(
        image: &Image,
        o: &DomeOptions,
        camera_rotation: Option<&Matrix3<f64>>,
    ) -> Result<Dome, DomeError> {
        o.check().map_err(DomeError::Orientation)?;
        match (camera_rotation, o.rotation.is_empty()) {
            (Some(_), false) => Err(DomeError::Orientation(
                "give the rotation by the `camera` input or the `rotation` param, not both".into(),
            )),
            (Some(r), true) => Dome::from_camera_rotation(image, r),
            (None, false) => {
                Dome::from_camera_rotation(image, &Matrix3::from_row_slice(&o.rotation))
            }
            (None, true) => Dome::new(image, o.orig.into(), o.south.into()),
        }
    }

    /// The equirectangular image (RGB, linear).
    pub fn image(&self) -> &Image {
        &self.image
    }
    /// The `orig` vector as given.
    pub fn orig(&self) -> Vector3<f64> {
        self.orig
    }
    /// The `south` vector as given.
    pub fn south(&self) -> Vector3<f64> {
        self.south
    }

    /// Continuous pixel coordinates `(x, y)` of a world direction (book 10.7; need not be unit,
    /// must be non-zero).
    pub fn direction_to_pixel(&self, d: &Vector3<f64>) -> (f64, f64) {
        let l = self.frame * d;
        let l = l / l.norm();
        let theta = l.z.clamp(-1.0, 1.0).acos();
        let phi = l.y.atan2(l.x);
        let (w, h) = (self.image.width as f64, self.image.height as f64);
        let x = ((1.0 - phi / PI) * w / 2.0).rem_euclid(w);
        (x, (theta / PI * h).min(h))
    }

    /// The unit world direction at continuous pixel coordinates `(x, y)` (inverse of
    /// [`Dome::direction_to_pixel`]).
    pub fn pixel_to_direction(&self, x: f64, y: f64) -> Vector3<f64> {
        let (w, h) = (self.image.width as f64, self.image.height as f64);
        let theta = PI * y / h;
        let phi = PI * (1.0 - 2.0 * x / w);
        let (st, ct) = theta.sin_cos();
        let local = Vector3::new(st * phi.cos(), st * phi.sin(), ct);
        self.frame.transpose() * local
    }

    /// Radiance arriving from world direction `d`, bilinear between texel centres (wrapping in
    /// longitude, clamped at the poles).
    pub fn radiance(&self, d: &Vector3<f64>) -> Vector3<f64> {
        let (x, y) = self.direction_to_pixel(d);
        self.lookup(x, y)
    }

    /// Bilinear lookup at continuous pixel coordinates.
    pub fn lookup(&self, x: f64, y: f64) -> Vector3<f64> {
        let (w, h) = (self.image.width, self.image.height);
        let (px, py) = (x - 0.5, y - 0.5);
        let (fx, fy) = (px - px.floor(), py - py.floor());
        let x0 = (px.floor() as i64).rem_euclid(w as i64) as usize;
        let x1 = (x0 + 1) % w;
        let y0 = (py.floor() as i64).clamp(0, h as i64 - 1) as usize;
        let y1 = (py.floor() as i64 + 1).clamp(0, h as i64 - 1) as usize;
        // The image is RGB (see `Dome::new`).
        let data = &self.image.data;
        let px_ = |x: usize, y: usize| {
            let i = (y * w + x) * 3;
            Vector3::new(data[i] as f64, data[i + 1] as f64, data[i + 2] as f64)
        };
        px_(x0, y0) * ((1.0 - fx) * (1.0 - fy))
            + px_(x1, y0) * (fx * (1.0 - fy))
            + px_(x0, y1) * ((1.0 - fx) * fy)
            + px_(x1, y1) * (fx * fy)
    }

    /// Importance-samples a direction by luminance × sin θ from two uniform numbers in `[0, 1)`
    /// (PBRT §14.2.4): the density over the image square divided by the Jacobian `2π² sin θ`
    /// gives the pdf in solid angle.
    pub fn sample(&self, u: [f64; 2]) -> DomeSample {
        let ((s, t), pdf_st) = self.dist.sample(u[0], u[1]);
        let (w, h) = (self.image.width as f64, self.image.height as f64);
        let (x, y) = (s * w, t * h);
        let sin_t = (PI * t).sin();
        let direction = self.pixel_to_direction(x, y);
        let pdf_solid_angle = if sin_t > 0.0 {
            pdf_st / (2.0 * PI * PI * sin_t)
        } else {
            0.0
        };
        DomeSample {
            direction,
            radiance: self.lookup(x, y),
            pdf_solid_angle,
        }
    }

    /// The solid-angle pdf with which [`Dome::sample`] returns direction `d` (for multiple
    /// importance sampling).
    pub fn pdf(&self, d: &Vector3<f64>) -> f64 {
        let (x, y) = self.direction_to_pixel(d);
        self.pdf_at_pixel(x, y)
    }

    /// [`Dome::radiance`] and [`Dome::pdf`] of one direction, mapping it to the image once.
    pub fn radiance_and_pdf(&self, d: &Vector3<f64>) -> (Vector3<f64>, f64) {
        let (x, y) = self.direction_to_pixel(d);
        (self.lookup(x, y), self.pdf_at_pixel(x, y))
    }

    /// The solid-angle pdf at continuous pixel coordinates.
    fn pdf_at_pixel(&self, x: f64, y: f64) -> f64 {
        let (w, h) = (self.image.width as f64, self.image.height as f64);
        let (s, t) = (x / w, y / h);
        let sin_t = (PI * t).sin();
        if sin_t <= 0.0 {
            return 0.0;
        }
        self.dist.pdf(s, t) / (2.0 * PI * PI * sin_t)
    }

    /// Irradiance `∫ L(ω) max(0, n·ω) dω` at a surface with unit normal `n`, by brute force over
    /// every texel (texel centre direction, exact solid angle of the texel,
    /// `(2π/w)(cos θ_top − cos θ_bottom)`). The reference for Monte Carlo estimates.
    pub fn irradiance_brute_force(&self, n: &Vector3<f64>) -> Vector3<f64> {
        let (w, h) = (self.image.width, self.image.height);
        let mut e = Vector3::zeros();
        for j in 0..h {
            let t0 = PI * j as f64 / h as f64;
            let t1 = PI * (j + 1) as f64 / h as f64;
            let d_omega = 2.0 * PI / w as f64 * (t0.cos() - t1.cos());
            let mut row = Vector3::zeros();
            for i in 0..w {
                let d = self.pixel_to_direction(i as f64 + 0.5, j as f64 + 0.5);
                let c = n.dot(&d);
                if c > 0.0 {
                    let p = self.image.pixel(i, j);
                    row += Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64) * c;
                }
            }
            e += row * d_omega;
        }
        e
    }
}

/// The dome as the path tracer's environment (book 10.9: image-based lighting): escaped paths
/// read [`Dome::radiance`], next-event estimation draws [`Dome::sample`] and weighs it against
/// BRDF sampling with [`Dome::pdf`] (all in solid angle).
impl Environment for Dome {
    fn radiance(&self, dir: Vec3) -> Rgb {
        let v = Dome::radiance(self, &Vector3::new(dir.x, dir.y, dir.z));
        Rgb::new(v.x, v.y, v.z)
    }
    fn sample(&self, u: [f64; 2]) -> Option<EnvironmentSample> {
        let s = Dome::sample(self, u);
        if s.pdf_solid_angle.is_nan() || s.pdf_solid_angle <= 0.0 || s.pdf_solid_angle.is_infinite()
        {
            return None;
        }
        let d = s.direction;
        Some(EnvironmentSample {
            wi: Vec3::new(d.x, d.y, d.z),
            radiance: Rgb::new(s.radiance.x, s.radiance.y, s.radiance.z),
            pdf_solid_angle: s.pdf_solid_angle,
        })
    }
    fn pdf(&self, dir: Vec3) -> f64 {
        Dome::pdf(self, &Vector3::new(dir.x, dir.y, dir.z))
    }
    fn radiance_and_pdf(&self, dir: Vec3) -> (Rgb, f64) {
        let (v, pdf) = Dome::radiance_and_pdf(self, &Vector3::new(dir.x, dir.y, dir.z));
        (Rgb::new(v.x, v.y, v.z), pdf)
    }
    fn is_black(&self) -> bool {
        self.black
    }
}

/// The book's dome basis (10.7) as the rows (u, v, n) of a rotation.
fn basis(orig: &Vector3<f64>, south: &Vector3<f64>) -> Result<Matrix3<f64>, DomeError> {
    if orig.iter().chain(south.iter()).any(|v| !v.is_finite()) {
        return Err(DomeError::Orientation(
            "orig and south must be finite".into(),
        ));
    }
    let ns = south.norm();
    if ns < 1e-12 {
        return Err(DomeError::Orientation("south is zero".into()));
    }
    let n = south / ns;
    let u = orig - n * orig.dot(&n);
    if u.norm() < 1e-9 * orig.norm().max(1e-300) || u.norm() < 1e-12 {
        return Err(DomeError::Orientation(
            "orig is zero or parallel to south".into(),
        ));
    }
    let u = u / u.norm();
    let v = n.cross(&u);
    Ok(Matrix3::from_rows(&[
        u.transpose(),
        v.transpose(),
        n.transpose(),
    ]))
}

/// The light of a render: a dome, or a constant background.
pub enum Light<'a> {
    /// An image-based dome.
    Dome(&'a Dome),
    /// A constant radiance from every direction.
    Constant(ConstantEnvironment),
}

impl<'a> Light<'a> {
    /// The environment to render with.
    pub fn env(&self) -> &dyn Environment {
        match self {
            Light::Dome(d) => *d,
            Light::Constant(c) => c,
        }
    }

    /// The light of `scene`: dome `replacing` if given, else the scene's `loaded` dome, else its
    /// background colour. An error when the scene names a dome image that was not loaded.
    pub fn pick(
        replacing: Option<&'a Dome>,
        loaded: Option<&'a Dome>,
        scene: &Scene,
    ) -> Result<Light<'a>, String> {
        match (replacing, loaded, &scene.dome) {
            (Some(d), _, _) | (None, Some(d), _) => Ok(Light::Dome(d)),
            (None, None, Some(spec)) => Err(format!(
                "the scene's dome image `{}` was not found when the scene was read: connect a \
                 `dome` input (e.g. read_image → dome)",
                spec.image
            )),
            (None, None, None) => Ok(Light::Constant(ConstantEnvironment {
                radiance: scene.background,
            })),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn ramp(w: usize, h: usize) -> Image {
        Image::from_fn(w, h, 3, |x, y, c| (x + 3 * y + c) as f32 * 0.01)
    }

    #[test]
    fn y_up_layout_and_round_trip() {
        let dome = Dome::y_up(&ramp(64, 32)).unwrap();
        let (x, y) = dome.direction_to_pixel(&Vector3::y());
        assert!(y.abs() < 1e-9, "zenith on the top row: {x} {y}");
        let (x, y) = dome.direction_to_pixel(&-Vector3::z());
        assert!(
            (x - 32.0).abs() < 1e-9 && (y - 16.0).abs() < 1e-9,
            "{x} {y}"
        );
        let (x, y) = dome.direction_to_pixel(&Vector3::x());
        assert!(
            (x - 48.0).abs() < 1e-9 && (y - 16.0).abs() < 1e-9,
            "+x at 3w/4: {x}"
        );
        let (_, y) = dome.direction_to_pixel(&-Vector3::y());
        assert!((y - 32.0).abs() < 1e-9);
        let mut rng = Pcg64::seed_from_u64(1);
        for _ in 0..1000 {
            let (x, y) = (
                rng.random::<f64>() * 64.0,
                0.01 + rng.random::<f64>() * 31.98,
            );
            let d = dome.pixel_to_direction(x, y);
            assert!((d.norm() - 1.0).abs() < 1e-12);
            let (x2, y2) = dome.direction_to_pixel(&d);
            let dx = (x2 - x).abs().min(64.0 - (x2 - x).abs());
            assert!(dx < 1e-9 && (y2 - y).abs() < 1e-9, "{x} {y} → {x2} {y2}");
        }
    }

    #[test]
    fn orientation_from_orig_south_and_camera() {
        let img = ramp(64, 32);
        // A dome whose top row looks along +x and whose centre column looks along +y.
        let dome = Dome::new(
            &img,
            Vector3::new(1.5, 2.0, 0.0),
            Vector3::new(5.0, 0.0, 0.0),
        )
        .unwrap();
        let (_, y) = dome.direction_to_pixel(&Vector3::x());
        assert!(y.abs() < 1e-9);
        let (x, y) = dome.direction_to_pixel(&Vector3::y());
        assert!(
            (x - 32.0).abs() < 1e-9 && (y - 16.0).abs() < 1e-9,
            "{x} {y}"
        );
        // The camera rule: south = R row 2, orig = −R row 3.
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1).into_inner();
        let a = Dome::from_camera_rotation(&img, &r).unwrap();
        let b = Dome::new(&img, -r.row(2).transpose(), r.row(1).transpose()).unwrap();
        let d = Vector3::new(0.2, -0.5, 0.8);
        assert_eq!(a.direction_to_pixel(&d), b.direction_to_pixel(&d));
        let (_, y) = a.direction_to_pixel(&r.row(1).transpose());
        assert!(y.abs() < 1e-6);
        // Radiance follows the orientation: looking along the direction of texel (9, 5) of
        // the rotated dome returns that texel.
        let d = a.pixel_to_direction(9.5, 5.5);
        assert!((a.radiance(&d).x - img.get(9, 5, 0) as f64).abs() < 1e-6);
        // Degenerate orientations are errors.
        for (o, s) in [
            (Vector3::x(), Vector3::zeros()),
            (Vector3::x(), Vector3::x() * 3.0),
            (Vector3::zeros(), Vector3::y()),
            (Vector3::new(f64::NAN, 0.0, 0.0), Vector3::y()),
        ] {
            assert!(Dome::new(&img, o, s).is_err(), "{o:?} {s:?}");
        }
        assert!(Dome::y_up(&Image::new(1, 1, 3)).is_err());
    }

    #[test]
    fn bilinear_lookup_hits_texel_centres_and_wraps() {
        let img = ramp(8, 4);
        let dome = Dome::y_up(&img).unwrap();
        let v = dome.lookup(2.5, 1.5);
        assert!((v.x - img.get(2, 1, 0) as f64).abs() < 1e-6);
        // Halfway between the last and the first column: the mean of both (longitude wraps).
        let v = dome.lookup(8.0, 1.5);
        let want = 0.5 * (img.get(7, 1, 0) + img.get(0, 1, 0)) as f64;
        assert!((v.x - want).abs() < 1e-6, "{} {want}", v.x);
    }

    #[test]
    fn pdf_matches_sample_and_integrates_to_one() {
        let mut img = ramp(32, 16);
        img.set(5, 3, 1, 500.0); // a "sun"
        let dome = Dome::y_up(&img).unwrap();
        let mut rng = Pcg64::seed_from_u64(3);
        for _ in 0..500 {
            let s = dome.sample([rng.random(), rng.random()]);
            let p = dome.pdf(&s.direction);
            assert!(
                (p / s.pdf_solid_angle - 1.0).abs() < 1e-6,
                "{p} {}",
                s.pdf_solid_angle
            );
        }
        // ∫ pdf dω = 1 (uniform sphere estimate).
        let n = 200_000;
        let mut acc = 0.0;
        for _ in 0..n {
            let z: f64 = rng.random_range(-1.0..1.0);
            let phi: f64 = rng.random_range(0.0..2.0 * PI);
            let r = (1.0 - z * z).sqrt();
            acc += dome.pdf(&Vector3::new(r * phi.cos(), z, r * phi.sin())) * 4.0 * PI;
        }
        assert!((acc / n as f64 - 1.0).abs() < 0.02, "{}", acc / n as f64);
    }

    /// Per-sample mean and variance of the luminance of `f(sample)`.
    fn stats(v: &[f64]) -> (f64, f64) {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (
            m,
            v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64,
        )
    }

    #[test]
    fn irradiance_of_poly_haven_domes_matches_brute_force() {
        let Some(dir) = vfxgraph_testdata::path("polyhaven_hdri_1k") else {
            return;
        };
        let names = [
            "venice_sunset_1k.hdr",
            "studio_small_03_1k.hdr",
            "empty_warehouse_01_1k.hdr",
            "potsdamer_platz_1k.hdr",
        ];
        let normals = [
            Vector3::y(),
            Vector3::new(1.0, 0.2, 0.0).normalize(),
            Vector3::new(-0.3, 0.4, -1.0).normalize(),
            Vector3::new(0.5, -0.2, 0.7).normalize(),
        ];
        let n = 400_000;
        for name in names {
            let img = vfxgraph_imaging::read_image(&dir.join(name)).unwrap();
            let dome = Dome::y_up(&img).unwrap();
            let mut rng = Pcg64::seed_from_u64(11);
            let imp: Vec<DomeSample> = (0..n)
                .map(|_| dome.sample([rng.random(), rng.random()]))
                .collect();
            let uni: Vec<(Vector3<f64>, Vector3<f64>)> = (0..n)
                .map(|_| {
                    let z: f64 = rng.random_range(-1.0..1.0);
                    let phi: f64 = rng.random_range(0.0..2.0 * PI);
                    let r = (1.0 - z * z).sqrt();
                    let d = Vector3::new(r * phi.cos(), z, r * phi.sin());
                    (d, dome.radiance(&d))
                })
                .collect();
            let (mut sum_vu, mut sum_vi) = (0.0, 0.0);
            let lum = |v: &Vector3<f64>| 0.2126 * v.x + 0.7152 * v.y + 0.0722 * v.z;
            for nn in &normals {
                let truth = dome.irradiance_brute_force(nn);
                let mut est = Vector3::zeros();
                let mut li = Vec::with_capacity(n);
                for s in &imp {
                    let c = nn.dot(&s.direction).max(0.0);
                    let f = s.radiance * (c / s.pdf_solid_angle);
                    est += f;
                    li.push(lum(&f));
                }
                est /= n as f64;
                let lu: Vec<f64> = uni
                    .iter()
                    .map(|(d, l)| lum(&(l * (nn.dot(d).max(0.0) * 4.0 * PI))))
                    .collect();
                let (_, var_i) = stats(&li);
                let (_, var_u) = stats(&lu);
                let rel = (est - truth).component_div(&truth).abs().max();
                eprintln!(
                    "{name} n={nn:.2?}: E={:.4?} brute={:.4?} rel.err {:.3}% var ratio (uniform/importance) {:.1}",
                    est.as_slice(),
                    truth.as_slice(),
                    rel * 100.0,
                    var_u / var_i
                );
                assert!(rel < 0.01, "{name}: {rel}");
                sum_vu += var_u;
                sum_vi += var_i;
            }
            // Luminance (not cosine) importance: a sun behind the surface wastes samples, so a
            // single normal may gain nothing; over the normals the gain must be large.
            eprintln!("{name}: total variance ratio {:.1}", sum_vu / sum_vi);
            assert!(sum_vu > 3.0 * sum_vi, "{name}: {sum_vu} vs {sum_vi}");
        }
    }
}
