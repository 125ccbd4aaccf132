//! Hand-written SVG plots of reports (no plotting crate: a few polylines and labels): the
//! solve-error plot of a matchmove report.

use std::fmt::Write as _;

/// One panel: a series of (x, y) drawn as a polyline with labelled axes.
struct Panel<'a> {
    title: &'a str,
    unit: &'a str,
    colour: &'a str,
    points: Vec<(f64, f64)>,
}

fn nice_max(v: f64) -> f64 {
    if v.is_nan() || v <= 0.0 || !v.is_finite() {
        return 1.0;
    }
    let e = 10f64.powf(v.log10().floor());
    for m in [1.0, 2.0, 2.5, 5.0, 10.0] {
        if m * e >= v {
            return m * e;
        }
    }
    10.0 * e
}

fn panel(svg: &mut String, p: &Panel<'_>, top: f64, x_range: (f64, f64)) {
    let (left, width, height) = (70.0, 860.0, 200.0);
    let ymax = nice_max(
        p.points
            .iter()
            .map(|q| q.1)
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max),
    );
    let sx = |x: f64| left + (x - x_range.0) / (x_range.1 - x_range.0).max(1e-9) * width;
    let sy = |y: f64| top + height - y / ymax * height;
    let _ = writeln!(
        svg,
        r##"<text x="{left}" y="{}" font-size="14" font-weight="bold">{}</text>"##,
        top - 8.0,
        p.title
    );
    let _ = writeln!(
        svg,
        r##"<rect x="{left}" y="{top}" width="{width}" height="{height}" fill="none" stroke="#888"/>"##
    );
    for i in 0..=4 {
        let y = ymax * i as f64 / 4.0;
        let _ = writeln!(
            svg,
            r##"<line x1="{left}" x2="{x2}" y1="{yl:.1}" y2="{yl:.1}" stroke="#ddd"/><text x="{xt}" y="{yt:.1}" font-size="11" text-anchor="end">{label}</text>"##,
            x2 = left + width,
            yl = sy(y),
            xt = left - 6.0,
            yt = sy(y) + 4.0,
            label = format_tick(y)
        );
    }
    let _ = writeln!(
        svg,
        r##"<text x="16" y="{:.1}" font-size="11" transform="rotate(-90 16 {:.1})" text-anchor="middle">{}</text>"##,
        top + height / 2.0,
        top + height / 2.0,
        p.unit
    );
    let mut path = String::new();
    let mut pen_up = true;
    for &(x, y) in &p.points {
        if !y.is_finite() {
            pen_up = true;
            continue;
        }
        let _ = write!(
            path,
            "{}{:.1},{:.1} ",
            if pen_up { "M" } else { "L" },
            sx(x),
            sy(y.min(ymax))
        );
        pen_up = false;
    }
    let _ = writeln!(
        svg,
        r##"<path d="{path}" fill="none" stroke="{}" stroke-width="1.5"/>"##,
        p.colour
    );
}

fn format_tick(v: f64) -> String {
    if v == v.round() {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}

/// The solve-error plot of a matchmove report (`frames[].frame/rms/inliers`): reprojection RMS
/// per frame and inliers per frame, with the overall RMS in the title.
pub fn solve_error_svg(report: &serde_json::Value) -> Result<String, String> {
    let frames = report["frames"]
        .as_array()
        .ok_or("the report has no `frames` list (is it a matchmove/relax report?)")?;
    if frames.is_empty() {
        return Err("the report has no frames".into());
    }
    let get = |f: &serde_json::Value, k: &str| f[k].as_f64().unwrap_or(f64::NAN);
    let rms: Vec<(f64, f64)> = frames
        .iter()
        .map(|f| (get(f, "frame"), get(f, "rms")))
        .collect();
    let inl: Vec<(f64, f64)> = frames
        .iter()
        .map(|f| (get(f, "frame"), get(f, "inliers")))
        .collect();
    let x0 = rms.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let x1 = rms.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    let overall = report["overall_rms"].as_f64().unwrap_or(f64::NAN);
    // A zoom's report carries every frame's focal length: a third panel.
    let focal: Vec<(f64, f64)> = frames
        .iter()
        .filter(|f| f["focal_px"].is_number())
        .map(|f| (get(f, "frame"), get(f, "focal_px")))
        .collect();
    let extra = if focal.is_empty() { 0.0 } else { 280.0 };
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="960" height="{h}" font-family="sans-serif"><rect width="960" height="{h}" fill="white"/>"##,
        h = 600.0 + extra
    );
    let title = format!("Reprojection error per frame (inliers; overall RMS {overall:.3} px)");
    panel(
        &mut svg,
        &Panel {
            title: &title,
            unit: "RMS (px)",
            colour: "#c0392b",
            points: rms,
        },
        40.0,
        (x0, x1),
    );
    panel(
        &mut svg,
        &Panel {
            title: "Inliers per frame",
            unit: "points",
            colour: "#2471a3",
            points: inl,
        },
        320.0,
        (x0, x1),
    );
    if !focal.is_empty() {
        panel(
            &mut svg,
            &Panel {
                title: "Focal length per frame (zoom)",
                unit: "focal length (px)",
                colour: "#1e8449",
                points: focal,
            },
            600.0,
            (x0, x1),
        );
    }
    for i in 0..=10 {
        let x = x0 + (x1 - x0) * i as f64 / 10.0;
        let px = 70.0 + 860.0 * i as f64 / 10.0;
        let _ = writeln!(
            svg,
            r##"<text x="{px:.1}" y="{y}" font-size="11" text-anchor="middle">{}</text>"##,
            x.round(),
            y = 540.0 + extra
        );
    }
    let _ = writeln!(
        svg,
        r##"<text x="500" y="{}" font-size="12" text-anchor="middle">frame</text>"##,
        565.0 + extra
    );
    if let Some(line) = solved_camera_line(report) {
        let _ = writeln!(
            svg,
            r##"<text x="480" y="{}" font-size="12" text-anchor="middle">{line}</text>"##,
            590.0 + extra
        );
    }
    svg.push_str("</svg>\n");
    Ok(svg)
}

/// What the solve found of the camera besides its poses, for the plot's last line: the
/// intrinsics it refined with their standard deviations, and whether it was a nodal pan.
fn solved_camera_line(report: &serde_json::Value) -> Option<String> {
    let mut parts = Vec::new();
    for p in report["intrinsics"].as_array().into_iter().flatten() {
        let (Some(name), Some(v)) = (p["name"].as_str(), p["value"].as_f64()) else {
            continue;
        };
        let digits = if name == "focal_px" { 1 } else { 4 };
        parts.push(match p["sd"].as_f64() {
            Some(sd) => format!("{name} {v:.digits$} ± {sd:.digits$}"),
            None if p["held"].as_bool() == Some(true) => format!("{name} {v:.digits$} (held)"),
            None => format!("{name} {v:.digits$}"),
        });
    }
    if report["rotation_only"].as_bool() == Some(true) {
        parts.push("rotation-only solve (nodal pan)".into());
    }
    (!parts.is_empty()).then(|| format!("Solved: {}", parts.join(", ")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plots_every_frame_and_rejects_other_reports() {
        let report = serde_json::json!({
            "overall_rms": 0.5,
            "frames": (0..50).map(|f| serde_json::json!({"frame": f, "rms": 0.4 + f as f64 * 0.01, "inliers": 100 - f})).collect::<Vec<_>>()
        });
        let svg = solve_error_svg(&report).unwrap();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        // Two polylines of 50 points each: 1 move + 49 line commands per panel.
        assert_eq!(svg.matches(" L").count() + svg.matches("\"L").count(), 98);
        assert!(svg.contains("overall RMS 0.500 px"));
        assert!(solve_error_svg(&serde_json::json!({"cost": 1})).is_err());
        assert!(!svg.contains("Solved:"));
    }

    /// A lens solve's intrinsics (with standard deviations) and a nodal pan are written under
    /// the panels.
    #[test]
    fn plots_the_solved_intrinsics_and_a_pan() {
        let report = serde_json::json!({
            "overall_rms": 0.5,
            "frames": [{"frame": 0, "rms": 0.4, "inliers": 90}, {"frame": 1, "rms": 0.5, "inliers": 80}],
            "rotation_only": true,
            "intrinsics": [
                {"name": "focal_px", "value": 918.04, "held": false, "sd": 1.26},
                {"name": "k1", "value": -0.16123, "held": false, "sd": 0.0021},
            ]
        });
        let svg = solve_error_svg(&report).unwrap();
        assert!(
            svg.contains("Solved: focal_px 918.0 ± 1.3, k1 -0.1612 ± 0.0021, rotation-only"),
            "{svg}"
        );
        assert!(svg.trim_end().ends_with("</svg>"));
    }

    /// A zoom's report (a focal length per frame) gets a third panel of the focal lengths.
    #[test]
    fn plots_a_zoom_frame_by_frame() {
        let frames: Vec<serde_json::Value> = (0..20)
            .map(|i| serde_json::json!({"frame": i, "rms": 0.4, "inliers": 90, "focal_px": 900.0 + 25.0 * i as f64}))
            .collect();
        let report = serde_json::json!({"overall_rms": 0.4, "frames": frames});
        let svg = solve_error_svg(&report).unwrap();
        assert!(svg.contains("Focal length per frame (zoom)"));
        assert!(svg.contains("height=\"880\""));
        // Three polylines of 20 points each.
        assert_eq!(svg.matches(" L").count() + svg.matches("\"L").count(), 57);
        let plain = serde_json::json!({"overall_rms": 0.4, "frames": [{"frame": 0, "rms": 0.4, "inliers": 9}]});
        assert!(!solve_error_svg(&plain).unwrap().contains("Focal length"));
    }
}
