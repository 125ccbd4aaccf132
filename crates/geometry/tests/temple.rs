//! Middlebury templeSparseRing: relative pose between neighbouring views with the given K,
//! from correspondences found by a minimal corner matcher written here for the test (Shi–Tomasi
//! corners, normalized cross-correlation of patches, mutual best match with a ratio test). The
//! project's KLT tracker (a later issue) will replace it. The rotation error against the given
//! R is reported and bounded.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Point2, Vector3};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use vfxgraph_geometry::rotation::rotation_angle_between;
use vfxgraph_geometry::two_view::{reconstruct_two_view, TwoViewOptions};
use vfxgraph_geometry::{Intrinsics, Pose, VisionError};

const HALF: i64 = 7; // 15×15 patches

struct Grey {
    w: usize,
    h: usize,
    v: Vec<f64>,
}

impl Grey {
    fn at(&self, x: i64, y: i64) -> f64 {
        let x = x.clamp(0, self.w as i64 - 1) as usize;
        let y = y.clamp(0, self.h as i64 - 1) as usize;
        self.v[y * self.w + x]
    }
}

fn load(path: &Path) -> Grey {
    let img = image::open(path).expect("decode image").to_luma8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    Grey {
        w,
        h,
        v: img.pixels().map(|p| p.0[0] as f64 / 255.0).collect(),
    }
}

/// Shi–Tomasi corners: minimum eigenvalue of the 5×5 box-summed structure tensor, local maxima
/// in a 9×9 window, strongest first, at most `max` corners.
fn corners(g: &Grey, max: usize) -> Vec<Point2<f64>> {
    let (w, h) = (g.w as i64, g.h as i64);
    let mut ix = vec![0.0; g.w * g.h];
    let mut iy = vec![0.0; g.w * g.h];
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            ix[i] = 0.5 * (g.at(x + 1, y) - g.at(x - 1, y));
            iy[i] = 0.5 * (g.at(x, y + 1) - g.at(x, y - 1));
        }
    }
    let mut score = vec![0.0; g.w * g.h];
    for y in HALF + 2..h - HALF - 2 {
        for x in HALF + 2..w - HALF - 2 {
            let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
            for dy in -2..=2 {
                for dx in -2..=2 {
                    let i = ((y + dy) * w + x + dx) as usize;
                    a += ix[i] * ix[i];
                    b += ix[i] * iy[i];
                    c += iy[i] * iy[i];
                }
            }
            score[(y * w + x) as usize] = 0.5 * (a + c) - (0.25 * (a - c) * (a - c) + b * b).sqrt();
        }
    }
    let mut cands = Vec::new();
    for y in HALF + 2..h - HALF - 2 {
        for x in HALF + 2..w - HALF - 2 {
            let s = score[(y * w + x) as usize];
            if s <= 1e-4 {
                continue;
            }
            let mut is_max = true;
            'win: for dy in -4..=4 {
                for dx in -4..=4 {
                    let (xx, yy) = (x + dx, y + dy);
                    if (dx != 0 || dy != 0)
                        && xx >= 0
                        && yy >= 0
                        && xx < w
                        && yy < h
                        && score[(yy * w + xx) as usize] > s
                    {
                        is_max = false;
                        break 'win;
                    }
                }
            }
            if is_max {
                cands.push((s, x, y));
            }
        }
    }
    cands.sort_by(|a, b| b.0.total_cmp(&a.0));
    cands
        .into_iter()
        .take(max)
        .map(|(_, x, y)| Point2::new(x as f64, y as f64))
        .collect()
}

/// Zero-mean unit-norm patch (None for a flat patch).
fn patch(g: &Grey, p: &Point2<f64>) -> Option<Vec<f64>> {
    let (cx, cy) = (p.x as i64, p.y as i64);
    let mut v = Vec::with_capacity(((2 * HALF + 1) * (2 * HALF + 1)) as usize);
    for dy in -HALF..=HALF {
        for dx in -HALF..=HALF {
            v.push(g.at(cx + dx, cy + dy));
        }
    }
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    v.iter_mut().for_each(|x| *x -= mean);
    let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    (n > 1e-3).then(|| v.into_iter().map(|x| x / n).collect())
}

fn best_matches(
    pa: &[(Point2<f64>, Vec<f64>)],
    pb: &[(Point2<f64>, Vec<f64>)],
    radius: f64,
) -> Vec<Option<usize>> {
    pa.iter()
        .map(|(xa, da)| {
            let (mut best, mut second, mut idx) = (-1.0, -1.0, None);
            for (j, (xb, db)) in pb.iter().enumerate() {
                if (xa - xb).norm() > radius {
                    continue;
                }
                let c: f64 = da.iter().zip(db).map(|(a, b)| a * b).sum();
                if c > best {
                    second = best;
                    best = c;
                    idx = Some(j);
                } else if c > second {
                    second = c;
                }
            }
            (best > 0.85 && (1.0 - best) < 0.8 * (1.0 - second))
                .then_some(idx)
                .flatten()
        })
        .collect()
}

/// NCC of the patch `da` against the patch of `g` centred at integer (x, y).
fn ncc_at(g: &Grey, da: &[f64], x: i64, y: i64) -> f64 {
    patch(g, &Point2::new(x as f64, y as f64))
        .map_or(-1.0, |db| da.iter().zip(&db).map(|(a, b)| a * b).sum())
}

/// Sub-pixel position of the NCC peak near `p` in `g`: a parabola through the scores at −1, 0, +1
/// in x and in y.
fn subpixel(g: &Grey, da: &[f64], p: &Point2<f64>) -> Point2<f64> {
    let (x, y) = (p.x as i64, p.y as i64);
    let c = ncc_at(g, da, x, y);
    let peak = |m: f64, p: f64| {
        let den = m - 2.0 * c + p;
        if den < 0.0 {
            (0.5 * (m - p) / den).clamp(-0.5, 0.5)
        } else {
            0.0
        }
    };
    let dx = peak(ncc_at(g, da, x - 1, y), ncc_at(g, da, x + 1, y));
    let dy = peak(ncc_at(g, da, x, y - 1), ncc_at(g, da, x, y + 1));
    Point2::new(x as f64 + dx, y as f64 + dy)
}

fn matches(a: &Grey, b: &Grey) -> (Vec<Point2<f64>>, Vec<Point2<f64>>) {
    let describe = |g: &Grey| -> Vec<(Point2<f64>, Vec<f64>)> {
        corners(g, 3000)
            .into_iter()
            .filter_map(|p| patch(g, &p).map(|d| (p, d)))
            .collect()
    };
    let (da, db) = (describe(a), describe(b));
    let ab = best_matches(&da, &db, 150.0);
    let ba = best_matches(&db, &da, 150.0);
    let (mut xa, mut xb) = (Vec::new(), Vec::new());
    for (i, m) in ab.iter().enumerate() {
        if let Some(j) = *m {
            if ba[j] == Some(i) {
                xa.push(da[i].0);
                xb.push(subpixel(b, &da[i].1, &db[j].0));
            }
        }
    }
    (xa, xb)
}

fn data_dir() -> Option<PathBuf> {
    vfxgraph_testdata::path("middlebury_mview_templeSparseRing")
}

#[allow(clippy::type_complexity)]
fn read_par(dir: &Path) -> Vec<(String, Intrinsics, Pose)> {
    let text = std::fs::read_to_string(dir.join("templeSR_par.txt")).unwrap();
    text.lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let t: Vec<&str> = l.split_whitespace().collect();
            let v: Vec<f64> = t[1..].iter().map(|s| s.parse().unwrap()).collect();
            let k = Intrinsics::from_k(&Matrix3::from_row_slice(&v[0..9])).unwrap();
            let r = Matrix3::from_row_slice(&v[9..18]);
            (
                t[0].to_string(),
                k,
                Pose::new(r, Vector3::new(v[18], v[19], v[20])),
            )
        })
        .collect()
}

#[test]
fn temple_relative_pose_between_neighbouring_views() {
    let Some(dir) = data_dir() else { return };
    let views = read_par(&dir);
    let mut errors = Vec::new();
    let mut zero_baseline_pairs = 0;
    // Pairs of views about 23° apart on the ring (the file order is not the ring order).
    let mut pairs = Vec::new();
    for ia in 0..views.len() {
        for ib in ia + 1..views.len() {
            let rel = views[ib].2.relative_to(&views[ia].2);
            if rotation_angle_between(&rel.r, &Matrix3::identity()).to_degrees() < 30.0 {
                pairs.push((ia, ib));
            }
        }
    }
    for &(ia, ib) in &pairs {
        let (na, ka, pa) = &views[ia];
        let (nb, kb, pb) = &views[ib];
        let (a, b) = matches(&load(&dir.join(na)), &load(&dir.join(nb)));
        let gt = pb.relative_to(pa);
        if (pa.center() - pb.center()).norm() < 1e-9 {
            // The data set has two shots from the same pose: the library must say so.
            let e = reconstruct_two_view(
                &a,
                &b,
                ka,
                kb,
                &TwoViewOptions::default(),
                &mut Pcg64::seed_from_u64(1),
            );
            println!(
                "temple {na}-{nb}: same pose in the ground truth, {} matches: {e:?}",
                a.len()
            );
            assert!(matches!(e, Err(VisionError::ZeroBaseline)), "{e:?}");
            zero_baseline_pairs += 1;
            continue;
        }
        let rec = match reconstruct_two_view(
            &a,
            &b,
            ka,
            kb,
            &TwoViewOptions::default(),
            &mut Pcg64::seed_from_u64(1),
        ) {
            Ok(r) => r,
            Err(e) => {
                println!(
                    "temple {na}-{nb}: {} matches, reconstruction failed: {e}",
                    a.len()
                );
                continue;
            }
        };
        let rot = rotation_angle_between(&rec.camera_b.pose.r, &gt.r).to_degrees();
        let t_angle = (rec.camera_b.pose.t.dot(&gt.t) / gt.t.norm())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        println!(
            "temple {na}-{nb}: {} matches, {} inliers, rotation error {rot:.3}° (GT relative rotation {:.1}°), \
             t direction error {t_angle:.2}°, reprojection RMS {:.3} px",
            a.len(),
            rec.report.num_inliers,
            rotation_angle_between(&gt.r, &Matrix3::identity()).to_degrees(),
            rec.report.reprojection_rms
        );
        errors.push(rot);
    }
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    println!(
        "temple: {} of {} neighbouring pairs reconstructed, rotation error median {median:.3}°, max {:.3}°",
        errors.len(),
        pairs.len() - zero_baseline_pairs,
        errors[errors.len() - 1]
    );
    assert!(
        errors.len() * 3 >= (pairs.len() - zero_baseline_pairs) * 2,
        "too few pairs reconstructed"
    );
    assert!(median < 1.5, "median rotation error {median}°");
}
