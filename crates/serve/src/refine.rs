//! Sub-pixel refinement of a definer click (the studio's "snap"): the corner nearest the
//! click, found as the point that every image gradient in a small window points away from
//! (Förstner 1987; what OpenCV's `cornerSubPix` does): q = (Σ w g gᵀ)⁻¹ Σ w g gᵀ p, iterated
//! with the window centred on the last q. A window without a corner (flat, or one straight
//! edge: the gradient tensor has one small eigenvalue) gives no refinement and the click stays.
//!
//! Coordinates have pixel centres at integers (the definer's and the book's convention).

use vfxgraph_imaging::Image;

/// Most window half-size a request may ask for.
pub const MAX_RADIUS: usize = 15;

/// The corner within `radius` px of (x, y), refined to sub-pixel precision, or `None` when the
/// window holds no corner (or the iteration leaves the window).
pub fn refine_corner(img: &Image, x: f64, y: f64, radius: usize) -> Option<(f64, f64)> {
    let (w, h) = (img.width as i64, img.height as i64);
    let cc = img.color_channels().max(1);
    let lum = |i: i64, j: i64| -> f64 {
        let px = img.pixel(i.clamp(0, w - 1) as usize, j.clamp(0, h - 1) as usize);
        px[..cc.min(px.len())]
            .iter()
            .map(|&v| v as f64)
            .sum::<f64>()
            / cc as f64
    };
    let r = radius.max(1) as i64;
    let sigma = radius.max(1) as f64 / 1.5;
    let (x0, y0) = (x, y);
    let (mut qx, mut qy) = (x, y);
    for _ in 0..40 {
        let (ci, cj) = (qx.round() as i64, qy.round() as i64);
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        // Gradients at the pixel corners (i + ½, j + ½) from 2×2 differences, weighted by their
        // magnitude (g gᵀ / |g|): across an anti-aliased edge the differences' centroid is the
        // edge itself, so the solve is unbiased (g gᵀ weighting pulls it by ~0.1 px).
        for j in (cj - r).max(0)..(cj + r).min(h - 1) {
            for i in (ci - r).max(0)..(ci + r).min(w - 1) {
                let (l00, l10, l01, l11) =
                    (lum(i, j), lum(i + 1, j), lum(i, j + 1), lum(i + 1, j + 1));
                let gx = (l10 + l11 - l00 - l01) / 2.0;
                let gy = (l01 + l11 - l00 - l10) / 2.0;
                let m = gx.hypot(gy);
                if m <= 0.0 {
                    continue;
                }
                let (px, py) = (i as f64 + 0.5, j as f64 + 0.5);
                let (dx, dy) = (px - qx, py - qy);
                let wt = (-(dx * dx + dy * dy) / (2.0 * sigma * sigma)).exp() / m;
                let (gxx, gxy, gyy) = (wt * gx * gx, wt * gx * gy, wt * gy * gy);
                a11 += gxx;
                a12 += gxy;
                a22 += gyy;
                b1 += gxx * px + gxy * py;
                b2 += gxy * px + gyy * py;
            }
        }
        // A corner has two strong gradient directions: the tensor's smaller eigenvalue is a
        // good part of the larger one (an edge: ~0).
        let tr = a11 + a22;
        let det = a11 * a22 - a12 * a12;
        let disc = ((a11 - a22).powi(2) + 4.0 * a12 * a12).sqrt();
        let (lmax, lmin) = ((tr + disc) / 2.0, (tr - disc) / 2.0);
        if !(lmax > 1e-12 && lmin > 0.05 * lmax) || det <= 0.0 {
            return None;
        }
        let nx = (a22 * b1 - a12 * b2) / det;
        let ny = (a11 * b2 - a12 * b1) / det;
        if !(nx.is_finite() && ny.is_finite()) || (nx - x0).hypot(ny - y0) > radius as f64 {
            return None;
        }
        let step = (nx - qx).hypot(ny - qy);
        qx = nx;
        qy = ny;
        if step < 1e-3 {
            break;
        }
    }
    Some((qx, qy))
}

/// An anti-aliased checkerboard corner at (cx, cy) (pixel centres at integers): `hi` where
/// exactly one of x < cx, y < cy holds, else `lo`; each pixel the mean of 16×16 samples.
pub fn checker_corner(w: usize, h: usize, cx: f64, cy: f64, lo: f32, hi: f32) -> Image {
    const S: usize = 16;
    Image::from_fn(w, h, 3, |i, j, _| {
        let mut n = 0;
        for a in 0..S {
            for b in 0..S {
                let x = i as f64 - 0.5 + (a as f64 + 0.5) / S as f64;
                let y = j as f64 - 0.5 + (b as f64 + 0.5) / S as f64;
                if (x < cx) != (y < cy) {
                    n += 1;
                }
            }
        }
        lo + (hi - lo) * n as f32 / (S * S) as f32
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snaps_to_a_checker_corner_and_not_to_an_edge() {
        let (cx, cy) = (20.3, 15.7);
        let img = checker_corner(48, 32, cx, cy, 0.1, 0.8);
        for (dx, dy) in [
            (1.5, -1.2),
            (-2.0, 0.0),
            (0.0, 2.0),
            (-1.4, -1.4),
            (0.3, 0.2),
        ] {
            let (x, y) = refine_corner(&img, cx + dx, cy + dy, 5).unwrap();
            let e = (x - cx).hypot(y - cy);
            assert!(e < 0.05, "from ({dx}, {dy}): ({x}, {y}), {e} px off");
        }
        // One straight edge, and a flat patch: no corner, no snap.
        let edge = Image::from_fn(48, 32, 1, |i, _, _| if i < 20 { 0.1 } else { 0.8 });
        assert_eq!(refine_corner(&edge, 20.0, 15.0, 5), None);
        let flat = Image::from_fn(48, 32, 1, |_, _, _| 0.5);
        assert_eq!(refine_corner(&flat, 20.0, 15.0, 5), None);
    }
}
