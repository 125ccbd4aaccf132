//! Solid (3-D, world-space) procedural textures that modulate a material's diffuse albedo (book
//! §9.5: the albedo ρ of a Lambertian or Blinn–Phong surface becomes ρ·τ(p) at the hit point p).
//!
//! A solid texture needs no surface parametrization: the pattern is a function of the point in
//! space, so planes, boxes and meshes get it without UV coordinates (Peachey 1985, Perlin 1985).
//! The textures here exist to give a synthetic plate something to track (book ch. 6: KLT needs
//! texture): `cells` paints each cell of a 3-D grid with a random level, so every face of a
//! plane or a box gets sharp-cornered random patches — ideal Shi–Tomasi corners — and
//! `checker` alternates two levels.
//!
//! The factor τ is in [1 − contrast, 1]: a textured material's albedo is the material's albedo
//! darkened per cell, never raised (albedos stay ≤ 1). The grid is shifted by a seeded
//! fraction of a cell on every axis so that axis-aligned faces at whole multiples of the cell
//! size (a ground plane at y = 0) do not sit on a cell boundary, where round-off would pick
//! either side.

use serde::{Deserialize, Serialize};

use crate::math::{Rgb, Vec3};

/// A solid texture: a factor on the diffuse albedo at each world point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Texture {
    /// Random per-cell levels on a 3-D grid of cubes of side `size`: τ = 1 − contrast·u with
    /// u uniform in [0, 1) per cell (per channel if `color`), so the mean of τ is
    /// 1 − contrast/2.
    Cells {
        /// Cell side, scene units (> 0).
        size: f64,
        /// Depth of the modulation in [0, 1].
        contrast: f64,
        /// Seed of the cell levels and of the grid's offset.
        seed: u64,
        /// Independent levels per channel (coloured patches) instead of grey ones.
        #[serde(default)]
        color: bool,
    },
    /// A 3-D checkerboard of cubes of side `size`: τ = 1 and 1 − contrast alternately (mean
    /// 1 − contrast/2).
    Checker {
        /// Cell side, scene units (> 0).
        size: f64,
        /// Depth of the modulation in [0, 1].
        contrast: f64,
    },
    /// An image in a plane: a factor per texel, looked up bilinearly at the point's projection
    /// onto the map's rectangle, 1 outside it (the textured catcher of
    /// [`crate::catcher_texture`]).
    Planar(PlanarMap),
}

/// A texture image over a rectangle of a plane: texel (i, j) covers
/// `origin + (i + [0, 1))/width · u + (j + [0, 1))/height · v` (u, v the rectangle's edges,
/// perpendicular); points are projected onto the plane along its normal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanarMap {
    /// The rectangle's corner.
    pub origin: Vec3,
    /// Its first edge (texel columns run along it).
    pub u: Vec3,
    /// Its second edge (texel rows), perpendicular to `u`.
    pub v: Vec3,
    /// Texels along `u`.
    pub width: usize,
    /// Texels along `v`.
    pub height: usize,
    /// RGB factors, row-major (row j along `v`), `3 · width · height` values.
    pub texels: Vec<f32>,
}

impl PlanarMap {
    /// The map's (s, t) ∈ [0, 1]² coordinates of `p` (outside the square when off the map).
    #[inline]
    pub fn coords(&self, p: Vec3) -> (f64, f64) {
        let d = p - self.origin;
        (
            d.dot(self.u) / self.u.dot(self.u),
            d.dot(self.v) / self.v.dot(self.v),
        )
    }

    /// The world point at map coordinates (s, t).
    #[inline]
    pub fn point(&self, s: f64, t: f64) -> Vec3 {
        self.origin + self.u * s + self.v * t
    }

    /// Texel (i, j).
    #[inline]
    pub fn texel(&self, i: usize, j: usize) -> Rgb {
        let k = 3 * (j * self.width + i);
        Rgb::new(
            self.texels[k] as f64,
            self.texels[k + 1] as f64,
            self.texels[k + 2] as f64,
        )
    }

    /// The bilinear lookup at `p` (texel centres at half-integers; clamped at the edges), 1
    /// off the rectangle.
    pub fn lookup(&self, p: Vec3) -> Rgb {
        let (s, t) = self.coords(p);
        if !(0.0..=1.0).contains(&s) || !(0.0..=1.0).contains(&t) || self.texels.is_empty() {
            return Rgb::WHITE;
        }
        let x = (s * self.width as f64 - 0.5).clamp(0.0, (self.width - 1) as f64);
        let y = (t * self.height as f64 - 0.5).clamp(0.0, (self.height - 1) as f64);
        let (i0, j0) = (x.floor() as usize, y.floor() as usize);
        let (i1, j1) = ((i0 + 1).min(self.width - 1), (j0 + 1).min(self.height - 1));
        let (fx, fy) = (x - i0 as f64, y - j0 as f64);
        let a = self.texel(i0, j0) * (1.0 - fx) + self.texel(i1, j0) * fx;
        let b = self.texel(i0, j1) * (1.0 - fx) + self.texel(i1, j1) * fx;
        a * (1.0 - fy) + b * fy
    }
}

/// SplitMix64's finalizer: a well-mixed 64-bit hash of `x`.
#[inline]
fn mix(mut x: u64) -> u64 {
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// A uniform number in [0, 1) from a hash.
#[inline]
fn unit(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The grid's offset along each axis, a fraction of a cell in [0.1, 0.9) (seeded).
#[inline]
fn offset(seed: u64, axis: u64) -> f64 {
    0.1 + 0.8 * unit(mix(seed ^ mix(0xA5A5_0000 + axis)))
}

impl Texture {
    /// Checks the parameters: a positive finite cell size and a contrast in [0, 1].
    pub fn validate(&self) -> Result<(), String> {
        let (size, contrast) = match *self {
            Texture::Cells { size, contrast, .. } | Texture::Checker { size, contrast } => {
                (size, contrast)
            }
            Texture::Planar(ref m) => {
                let ok = m.width > 0
                    && m.height > 0
                    && m.texels.len() == 3 * m.width * m.height
                    && m.texels.iter().all(|t| t.is_finite() && *t >= 0.0)
                    && m.u.length() > 0.0
                    && m.v.length() > 0.0;
                return if ok {
                    Ok(())
                } else {
                    Err("planar texture: empty, degenerate or non-finite".into())
                };
            }
        };
        if !(size > 0.0 && size.is_finite()) {
            return Err(format!("texture size must be > 0, found {size}"));
        }
        if !(0.0..=1.0).contains(&contrast) {
            return Err(format!(
                "texture contrast must be in [0, 1], found {contrast}"
            ));
        }
        Ok(())
    }

    /// The mean of the factor over space (per channel): 1 − contrast/2 for both kinds.
    pub fn mean_factor(&self) -> f64 {
        match *self {
            Texture::Cells { contrast, .. } | Texture::Checker { contrast, .. } => {
                1.0 - contrast / 2.0
            }
            Texture::Planar(ref m) => {
                let n = (m.width * m.height).max(1) as f64;
                m.texels.iter().map(|&t| t as f64).sum::<f64>() / (3.0 * n)
            }
        }
    }

    /// The factor τ(p) on the diffuse albedo at world point `p`.
    #[inline]
    pub fn factor(&self, p: Vec3) -> Rgb {
        match *self {
            Texture::Planar(ref m) => m.lookup(p),
            Texture::Cells {
                size,
                contrast,
                seed,
                color,
            } => {
                let inv = 1.0 / size;
                let c = [
                    (p.x * inv + offset(seed, 0)).floor() as i64,
                    (p.y * inv + offset(seed, 1)).floor() as i64,
                    (p.z * inv + offset(seed, 2)).floor() as i64,
                ];
                let h = mix(
                    mix(mix(seed ^ 0x5EED) ^ c[0] as u64).wrapping_add(c[1] as u64)
                        ^ mix(c[2] as u64),
                );
                let level = |h: u64| 1.0 - contrast * unit(h);
                if color {
                    Rgb::new(level(h), level(mix(h ^ 1)), level(mix(h ^ 2)))
                } else {
                    Rgb::splat(level(h))
                }
            }
            Texture::Checker { size, contrast } => {
                let inv = 1.0 / size;
                // A fixed quarter-cell shift keeps faces at whole multiples of `size` inside
                // a cell (module docs).
                let s = (p.x * inv + 0.25).floor() as i64
                    + (p.y * inv + 0.25).floor() as i64
                    + (p.z * inv + 0.25).floor() as i64;
                Rgb::splat(if s.rem_euclid(2) == 0 {
                    1.0
                } else {
                    1.0 - contrast
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cells(color: bool) -> Texture {
        Texture::Cells {
            size: 0.2,
            contrast: 0.8,
            seed: 7,
            color,
        }
    }

    /// Mean of the factor at points spread over many cells (a fine lattice, off the cell grid).
    fn mean_over(t: &Texture) -> Rgb {
        let mut sum = Rgb::BLACK;
        let mut n = 0;
        for i in 0..40 {
            for j in 0..40 {
                for k in 0..40 {
                    let p = Vec3::new(i as f64 * 0.137, j as f64 * 0.311, k as f64 * 0.259);
                    sum += t.factor(p);
                    n += 1;
                }
            }
        }
        sum / n as f64
    }

    #[test]
    fn mean_factor_matches_the_analytic_mean() {
        for t in [
            cells(false),
            cells(true),
            Texture::Checker {
                size: 0.2,
                contrast: 0.8,
            },
        ] {
            let m = mean_over(&t);
            let want = t.mean_factor();
            assert!((want - 0.6).abs() < 1e-12);
            // 64 000 points over ~10⁵ cells: the mean of uniform levels (σ = 0.8/√12 ≈ 0.23)
            // is within ~0.001 (1σ); allow 5σ.
            for c in [m.r, m.g, m.b] {
                assert!((c - want).abs() < 0.005, "{t:?}: {c} vs {want}");
            }
        }
    }

    #[test]
    fn factor_is_in_range_deterministic_and_piecewise_constant() {
        let t = cells(true);
        let p = Vec3::new(0.3, -1.7, 2.2);
        assert_eq!(t.factor(p), t.factor(p));
        assert_eq!(t.factor(p), cells(true).factor(p));
        for i in 0..1000 {
            let q = Vec3::new(
                i as f64 * 0.0731,
                (i as f64 * 0.013).sin(),
                -(i as f64) * 0.021,
            );
            let f = t.factor(q);
            for c in [f.r, f.g, f.b] {
                assert!((0.2..=1.0).contains(&c), "{c}");
            }
        }
        // Constant within a cell, different across many cells; another seed, another pattern.
        let Texture::Cells { size, .. } = t else {
            unreachable!()
        };
        let o = [offset(7, 0), offset(7, 1), offset(7, 2)];
        let corner =
            |i: f64| Vec3::new((i - o[0]) * size, (0.0 - o[1]) * size, (3.0 - o[2]) * size);
        let inside = |i: f64, d: f64| corner(i) + Vec3::new(d, d, d) * size;
        assert_eq!(t.factor(inside(5.0, 0.01)), t.factor(inside(5.0, 0.98)));
        let levels: Vec<f64> = (0..50).map(|i| t.factor(inside(i as f64, 0.5)).r).collect();
        let distinct = levels
            .iter()
            .filter(|a| levels.iter().filter(|b| (*a - *b).abs() < 1e-12).count() == 1)
            .count();
        assert!(distinct > 45, "{levels:?}");
        let other = Texture::Cells {
            size: 0.2,
            contrast: 0.8,
            seed: 8,
            color: true,
        };
        let same = (0..50)
            .filter(|&i| other.factor(inside(i as f64, 0.5)) == t.factor(inside(i as f64, 0.5)))
            .count();
        assert!(same < 3, "{same}");
        // A plane at y = 0 lies inside one layer of cells: no speckle from round-off.
        let a = t.factor(Vec3::new(0.05, 1e-17, 0.05));
        assert_eq!(a, t.factor(Vec3::new(0.05, -1e-17, 0.05)));
    }

    #[test]
    fn validate_rejects_bad_parameters() {
        assert!(cells(false).validate().is_ok());
        for (size, contrast) in [
            (0.0, 0.5),
            (-1.0, 0.5),
            (f64::NAN, 0.5),
            (1.0, 1.5),
            (1.0, -0.1),
        ] {
            assert!(Texture::Checker { size, contrast }.validate().is_err());
        }
    }

    #[test]
    fn serde_form_is_tagged() {
        let t: Texture =
            serde_json::from_str(r#"{"type":"cells","size":0.2,"contrast":0.8,"seed":1}"#).unwrap();
        assert_eq!(
            t,
            Texture::Cells {
                size: 0.2,
                contrast: 0.8,
                seed: 1,
                color: false
            }
        );
    }
}
