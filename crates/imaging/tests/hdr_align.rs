//! Ward's MTB alignment (book 10.x; Ward 2003) against known translations: a synthetic bracket
//! cut from one scene at known offsets, and the real Memorial stack (`../shared/data`) cut the
//! same way. The recovered shifts must be exact.

use vfxgraph_imaging::hdr::{
    align_exposures, read_exposure_list, AlignChain, AlignOptions, Exposure, ExposureStack,
};

/// Cuts a `w × h` window at (`m − dx`, `m − dy`) from every exposure of `full`: the content of
/// exposure k then sits (dx, dy) further right/down than in a window at (m, m), so the shift that
/// aligns it is (−dx, −dy).
fn cut(full: &ExposureStack, m: usize, offsets: &[(i64, i64)]) -> ExposureStack {
    let (fw, fh, c) = (full.width(), full.height(), full.channels());
    let (w, h) = (fw - 2 * m, fh - 2 * m);
    let exposures = full
        .exposures()
        .iter()
        .zip(offsets)
        .map(|(e, &(dx, dy))| {
            let (x0, y0) = ((m as i64 - dx) as usize, (m as i64 - dy) as usize);
            let mut codes = Vec::with_capacity(w * h * c);
            for y in 0..h {
                let s = ((y0 + y) * fw + x0) * c;
                codes.extend_from_slice(&e.codes[s..s + w * c]);
            }
            Exposure {
                time: e.time,
                codes,
            }
        })
        .collect();
    ExposureStack::new(w, h, c, exposures).unwrap()
}

/// A random scene with edges, as photographs have: log radiance = a gradient plus 150 seeded
/// hard-edged discs of ±1.5 (radius 3–30 px),
/// photographed at `times` through a gamma-2.2 camera .
fn synthetic(w: usize, h: usize, times: &[f64]) -> ExposureStack {
    let mut s = 7u64;
    let mut rnd = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let bumps: Vec<[f64; 4]> = (0..150)
        .map(|_| {
            [
                rnd() * w as f64,
                rnd() * h as f64,
                3.0 + 25.0 * rnd(),
                3.0 * rnd() - 1.5,
            ]
        })
        .collect();
    let radiance: Vec<f64> = (0..w * h)
        .map(|p| {
            let (x, y) = ((p % w) as f64, (p / w) as f64);
            let mut l = -2.5 + x / w as f64;
            for b in &bumps {
                if (x - b[0]).powi(2) + (y - b[1]).powi(2) < b[2] * b[2] {
                    l += b[3];
                }
            }
            l.exp()
        })
        .collect();
    let exposures = times
        .iter()
        .map(|&t| Exposure {
            time: t,
            codes: radiance
                .iter()
                .map(|&e| (255.0 * (e * t).min(1.0).powf(1.0 / 2.2)).round() as u8)
                .collect(),
        })
        .collect();
    ExposureStack::new(w, h, 1, exposures).unwrap()
}

fn expected(offsets: &[(i64, i64)], r: usize) -> Vec<(i64, i64)> {
    offsets
        .iter()
        .map(|&(dx, dy)| (offsets[r].0 - dx, offsets[r].1 - dy))
        .collect()
}

#[test]
fn synthetic_bracket_shifts_are_recovered_exactly() {
    let times = [1.0 / 16.0, 0.25, 1.0, 4.0, 16.0];
    let full = synthetic(400, 300, &times);
    let offsets = [(5, -3), (-17, 2), (0, 0), (1, 1), (30, -21)];
    let stack = cut(&full, 40, &offsets);
    for chain in [AlignChain::Neighbours, AlignChain::Reference] {
        let opts = AlignOptions {
            chain,
            ..Default::default()
        };
        let (aligned, shifts) = align_exposures(&stack, &opts).unwrap();
        assert_eq!(shifts, expected(&offsets, 2), "{chain:?}");
        // The aligned exposures agree with the reference window wherever they have data.
        let r = &stack.exposures()[2].codes;
        for (k, e) in aligned.exposures().iter().enumerate() {
            let t = stack.exposures()[k].time / stack.exposures()[2].time;
            for (p, (&a, &b)) in e.codes.iter().zip(r).enumerate() {
                if !aligned.is_masked(p) && (20..200).contains(&b) && (20..200).contains(&a) {
                    // Same radiance: codes related by the gamma curve and the time ratio.
                    let pred = 255.0 * ((b as f64 / 255.0).powf(2.2) * t).powf(1.0 / 2.2);
                    assert!((pred - a as f64).abs() <= 2.5, "exposure {k} pixel {p}");
                }
            }
        }
        // Exactly the pixels brought in from outside the frame are masked.
        let (w, h) = (aligned.width() as i64, aligned.height() as i64);
        for p in 0..aligned.pixel_count() {
            let (x, y) = (p as i64 % w, p as i64 / w);
            let outside = shifts.iter().any(|&(dx, dy)| {
                let (xs, ys) = (x - dx, y - dy);
                xs < 0 || ys < 0 || xs >= w || ys >= h
            });
            assert_eq!(aligned.is_masked(p), outside, "pixel {p}");
        }
    }
    // An impossible reference is an error, not a panic.
    let bad = AlignOptions {
        reference: Some(9),
        ..Default::default()
    };
    assert!(align_exposures(&stack, &bad).is_err());
}

fn memorial() -> Option<ExposureStack> {
    let dir = vfxgraph_testdata::path("debevec_memorial")?;
    let list = dir.join("memorial.hdr_image_list.txt");
    Some(read_exposure_list(&list).unwrap().0)
}

#[test]
fn memorial_exposures_shifted_by_known_offsets_are_realigned_exactly() {
    let Some(full) = memorial() else { return };
    // The published stack is registered: MTB finds no shift in it.
    let (_, shifts) = align_exposures(&full, &AlignOptions::default()).unwrap();
    assert_eq!(shifts, vec![(0, 0); full.len()]);
    let offsets: Vec<(i64, i64)> = (0..full.len() as i64)
        .map(|k| (((k * 7) % 23) - 11, ((k * 5) % 17) - 8))
        .collect();
    let stack = cut(&full, 24, &offsets);
    let truth = expected(&offsets, full.len() / 2);
    let (_, shifts) = align_exposures(&stack, &AlignOptions::default()).unwrap();
    assert_eq!(shifts, truth, "neighbour chain");
    // Direct comparison with the reference (1/8 s), OpenCV's way, is exact from 32 s (8 stops
    // brighter) to 1/64 s (3 stops darker); darker exposures are nearly black (their 99th
    // percentile is code 20 or less) and may miss by a pixel.
    let opts = AlignOptions {
        chain: AlignChain::Reference,
        ..Default::default()
    };
    let (_, shifts) = align_exposures(&stack, &opts).unwrap();
    assert_eq!(shifts[..12], truth[..12], "direct");
}
