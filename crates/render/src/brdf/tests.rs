//! BRDF checks by numeric integration: energy conservation, reciprocity, pdfs integrate to one,
//! and sampled histograms match the pdfs (chi-square).

use std::f64::consts::PI;

use rand_core::{RngCore, SeedableRng};

use super::*;

fn unit(rng: &mut rand_pcg::Pcg32) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

fn dir(theta: f64, phi: f64) -> Vec3 {
    Vec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// ∫ over the sphere of g(ω) dω by the midpoint rule in (θ, φ).
fn integrate_sphere(nt: usize, np: usize, g: impl Fn(Vec3) -> f64) -> f64 {
    let (dt, dp) = (PI / nt as f64, 2.0 * PI / np as f64);
    let mut s = 0.0;
    for i in 0..nt {
        let th = (i as f64 + 0.5) * dt;
        let w = th.sin() * dt * dp;
        for j in 0..np {
            s += g(dir(th, (j as f64 + 0.5) * dp)) * w;
        }
    }
    s
}

fn brdfs() -> Vec<(&'static str, Brdf)> {
    let bp = |d: f64, s: f64, e: f64| {
        Brdf::BlinnPhong(BlinnPhong {
            diffuse: Rgb::splat(d),
            specular: Rgb::splat(s),
            exponent: e,
        })
    };
    vec![
        (
            "lambert",
            Brdf::Lambert(Lambert {
                albedo: Rgb::new(0.9, 0.5, 0.1),
            }),
        ),
        ("lobe e=1", bp(0.0, 1.0, 1.0)),
        ("lobe e=10", bp(0.0, 1.0, 10.0)),
        ("lobe e=60", bp(0.0, 1.0, 60.0)),
        ("mix e=10", bp(0.4, 0.3, 10.0)),
        ("mix e=0", bp(0.5, 0.5, 0.0)),
    ]
}

fn wos() -> Vec<Vec3> {
    [0.0, 0.3, 0.8, 1.2, 1.5]
        .iter()
        .map(|&t| dir(t, 0.7))
        .collect()
}

#[test]
fn energy_is_conserved() {
    for (name, b) in brdfs() {
        for wo in wos() {
            let albedo = integrate_sphere(600, 300, |wi| b.eval(wo, wi).g * wi.z.max(0.0));
            let bound = match b {
                Brdf::Lambert(l) => l.albedo.g,
                Brdf::BlinnPhong(p) => p.diffuse.g + p.specular.g,
                Brdf::Mirror(_) => unreachable!(),
            };
            assert!(
                albedo <= bound * (1.0 + 2e-3),
                "{name} wo={wo:?}: albedo {albedo} > {bound}"
            );
            if wo.z == 1.0 {
                // At normal incidence the bound is reached (the normalization is tight).
                assert!(
                    (albedo - bound).abs() < 5e-3 * bound,
                    "{name}: {albedo} vs {bound}"
                );
            }
        }
    }
}

#[test]
fn brdfs_are_reciprocal() {
    let mut rng = rand_pcg::Pcg32::seed_from_u64(3);
    for (name, b) in brdfs() {
        for _ in 0..200 {
            let a = dir(unit(&mut rng) * 1.5, unit(&mut rng) * 6.0);
            let c = dir(unit(&mut rng) * 1.5, unit(&mut rng) * 6.0);
            let (f1, f2) = (b.eval(a, c), b.eval(c, a));
            assert!(
                (f1 - f2).max_component().abs() <= 1e-12 * f1.max_component().max(1.0),
                "{name}"
            );
        }
    }
}

#[test]
fn mirror_reflects_with_its_reflectance() {
    let m = Brdf::Mirror(Mirror {
        reflectance: Rgb::new(0.9, 0.8, 0.7),
    });
    let wo = dir(0.4, 1.0);
    let s = m.sample(wo, [0.3, 0.3], 0.5).unwrap();
    assert!(s.specular);
    assert!((s.wi - Vec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-15);
    let w = s.f * (s.wi.z / s.pdf);
    assert!((w - Rgb::new(0.9, 0.8, 0.7)).max_component().abs() < 1e-12);
    assert_eq!(m.pdf(wo, s.wi), 0.0);
    assert!(m.eval(wo, s.wi).is_black());
}

/// Probability that a sample fails (returns `None`), by numeric integration of the half-vector
/// density over the half vectors that give wo·h ≤ 0.
fn failure_probability(b: &Brdf, wo: Vec3) -> f64 {
    match b {
        Brdf::BlinnPhong(p) => {
            let (d, s) = (p.diffuse.luminance(), p.specular.luminance());
            let ps = s / (d + s);
            let e = p.exponent;
            ps * integrate_sphere(1200, 600, |h| {
                if h.z > 0.0 && wo.dot(h) <= 0.0 {
                    (e + 1.0) / (2.0 * PI) * h.z.powf(e)
                } else {
                    0.0
                }
            })
        }
        _ => 0.0,
    }
}

#[test]
fn pdfs_integrate_to_one() {
    // The lobe's density in wi has an integrable singularity at wi = −wo (below the surface);
    // the midpoint rule handles it while wo is not too close to grazing.
    for (name, b) in brdfs() {
        for wo in wos().into_iter().filter(|w| w.z > 0.3) {
            let total = integrate_sphere(1200, 600, |wi| b.pdf(wo, wi));
            let fail = failure_probability(&b, wo);
            assert!(
                (total + fail - 1.0).abs() < 3e-3,
                "{name} wo={wo:?}: ∫pdf {total} + fail {fail}"
            );
        }
    }
}

/// Inverse of the chi-square survival function is not in std; use the Wilson–Hilferty normal
/// approximation: returns the z-score of statistic `x` with `k` degrees of freedom.
fn chi2_z(x: f64, k: f64) -> f64 {
    let m = 1.0 - 2.0 / (9.0 * k);
    ((x / k).cbrt() - m) / (2.0 / (9.0 * k)).sqrt()
}

#[test]
fn samples_follow_their_pdf_chi_square() {
    let (nz, np) = (20usize, 40usize);
    let n = 200_000usize;
    for (name, b) in brdfs() {
        for wo in wos() {
            let mut rng = rand_pcg::Pcg32::seed_from_u64(11);
            let mut counts = vec![0f64; nz * np + 1];
            for _ in 0..n {
                let u = [unit(&mut rng), unit(&mut rng)];
                match b.sample(wo, u, unit(&mut rng)) {
                    Some(s) => {
                        // The sample's pdf is the pdf function's value.
                        let p = b.pdf(wo, s.wi);
                        assert!((p - s.pdf).abs() <= 1e-9 * p, "{name}: {} vs {p}", s.pdf);
                        if s.wi.z <= 0.0 {
                            counts[nz * np] += 1.0;
                            continue;
                        }
                        let zi = ((s.wi.z * nz as f64) as usize).min(nz - 1);
                        let phi = s.wi.y.atan2(s.wi.x).rem_euclid(2.0 * PI);
                        let pi = ((phi / (2.0 * PI) * np as f64) as usize).min(np - 1);
                        counts[zi * np + pi] += 1.0;
                    }
                    None => counts[nz * np] += 1.0,
                }
            }
            // Expected counts: integrate the pdf over each cell (z, φ) of the upper hemisphere
            // with a sub-grid; the last cell pools samples below the surface (they carry no
            // energy) and failed samples, expected n·(1 − ∫_upper pdf).
            let mut expected = vec![0f64; nz * np + 1];
            let sub = 12;
            for zi in 0..nz {
                for pi in 0..np {
                    let mut s = 0.0;
                    for a in 0..sub {
                        for c in 0..sub {
                            let z = (zi as f64 + (a as f64 + 0.5) / sub as f64) / nz as f64;
                            let phi =
                                2.0 * PI * (pi as f64 + (c as f64 + 0.5) / sub as f64) / np as f64;
                            let r = (1.0 - z * z).max(0.0).sqrt();
                            s += b.pdf(wo, Vec3::new(r * phi.cos(), r * phi.sin(), z));
                        }
                    }
                    let area = (1.0 / nz as f64) * (2.0 * PI / np as f64);
                    expected[zi * np + pi] = s / (sub * sub) as f64 * area * n as f64;
                }
            }
            let upper: f64 = expected[..nz * np].iter().sum();
            expected[nz * np] = n as f64 - upper;
            // Pool the cells with small expectations.
            let (mut chi2, mut dof, mut pool_o, mut pool_e) = (0.0, 0usize, 0.0, 0.0);
            for (o, e) in counts.iter().zip(&expected) {
                if *e < 5.0 {
                    pool_o += o;
                    pool_e += e;
                } else {
                    chi2 += (o - e).powi(2) / e;
                    dof += 1;
                }
            }
            if pool_e > 0.0 {
                chi2 += (pool_o - pool_e).powi(2) / pool_e.max(1.0);
                dof += 1;
            }
            let z = chi2_z(chi2, (dof - 1) as f64);
            assert!(
                z < 3.5,
                "{name} wo={wo:?}: chi2 {chi2:.1} with {} dof (z = {z:.2})",
                dof - 1
            );
        }
    }
}
