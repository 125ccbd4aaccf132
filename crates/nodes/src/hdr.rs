//! HDR radiance maps and light domes (book chapter 10): `read_exposure_stack`,
//! `align_exposures`, `hdr_calibrate`, `hdr_merge`, `hdr_to_ldr`, `plot_response`,
//! `write_response`, `probe_to_equirect`, `dome`. The algorithms and their options live in
//! `vfxgraph_imaging::hdr` (Debevec & Malik 1997), `vfxgraph_imaging::draw` and
//! `vfxgraph_render::dome`.

use nalgebra::Vector3;
use vfxgraph_engine::artifact::codec::{put_bytes, put_f64, put_u64, Reader};
use vfxgraph_engine::{ArtifactType, Context, In, Mode, NodeError, NodeSpec, OptIn, Out, Registry};

use vfxgraph_imaging::draw::{plot_response, PlotOptions};
use vfxgraph_imaging::hdr::{
    align_exposures, align_report, calibrate_debevec, merge_debevec, photograph, probe_to_equirect,
    AlignOptions, CalibrateOptions, Exposure, ExposureStack, LdrOptions, ProbeOptions,
    ResponseCurve, StackFiles, StackOptions, LEVELS,
};
use vfxgraph_render::dome::{Dome, DomeOptions};

use crate::artifacts::{put_image, CameraArt, ImageArt, ReportArt};

/// An exposure stack (`exposure_stack`): 8-bit codes, exposure times, optional mask.
#[derive(Clone, Debug, PartialEq)]
pub struct StackArt(pub ExposureStack);

impl ArtifactType for StackArt {
    const NAME: &'static str = "exposure_stack";
    const DOC: &'static str = "Bracketed 8-bit photographs of one scene with their exposure times \
        (seconds) and an optional mask of ignored pixels (book 10.2).";
    fn encode(&self, out: &mut Vec<u8>) {
        let s = &self.0;
        put_u64(out, s.width() as u64);
        put_u64(out, s.height() as u64);
        put_u64(out, s.channels() as u64);
        put_u64(out, s.len() as u64);
        for e in s.exposures() {
            put_f64(out, e.time);
            put_bytes(out, &e.codes);
        }
        let mask: Vec<u8> = s
            .mask()
            .map_or(vec![], |m| m.iter().map(|&b| b as u8).collect());
        put_bytes(out, &mask);
    }
    fn decode(bytes: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(bytes);
        let (w, h, c, n) = (r.u64()?, r.u64()?, r.u64()?, r.u64()?);
        let mut exposures = Vec::new();
        for _ in 0..n {
            let (time, codes) = (r.f64()?, r.bytes()?.to_vec());
            exposures.push(Exposure { time, codes });
        }
        let mask = r.bytes()?.to_vec();
        r.finish()?;
        let s = ExposureStack::new(w as usize, h as usize, c as usize, exposures)
            .map_err(|e| e.to_string())?;
        let s = if mask.is_empty() {
            s
        } else {
            s.with_mask(mask.iter().map(|&b| b != 0).collect())
                .map_err(|e| e.to_string())?
        };
        Ok(StackArt(s))
    }
}

/// A camera response curve (`response_curve`): g = ln f⁻¹, 256 values per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct ResponseArt(pub ResponseCurve);

impl ArtifactType for ResponseArt {
    const NAME: &'static str = "response_curve";
    const DOC: &'static str = "A camera response g(z) = ln f⁻¹(z): 256 log exposures per channel, \
        g(128) = 0 (Debevec & Malik 1997; book 10.2).";
    fn encode(&self, out: &mut Vec<u8>) {
        put_u64(out, self.0.channels() as u64);
        for v in self.0.curves().iter().flatten() {
            put_f64(out, *v);
        }
    }
    fn decode(bytes: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(bytes);
        let c = r.u64()?;
        if !(1..=4).contains(&c) {
            return Err(format!("{c} channels"));
        }
        let mut g = Vec::new();
        for _ in 0..c {
            let mut a = [0.0; LEVELS];
            for v in a.iter_mut() {
                *v = r.f64()?;
            }
            g.push(a);
        }
        r.finish()?;
        ResponseCurve::new(g)
            .map(ResponseArt)
            .map_err(|e| e.to_string())
    }
}

/// An oriented light dome (`dome`): an equirectangular image plus `orig`/`south`.
#[derive(Clone, Debug)]
pub struct DomeArt(pub Dome);

impl ArtifactType for DomeArt {
    const NAME: &'static str = "dome";
    const DOC: &'static str = "An equirectangular light dome oriented by orig/south, importance \
        sampled by luminance × sin θ (book 10.7–10.9).";
    fn encode(&self, out: &mut Vec<u8>) {
        put_image(out, self.0.image());
        for v in self.0.orig().iter().chain(self.0.south().iter()) {
            put_f64(out, *v);
        }
    }
    fn decode(bytes: &[u8]) -> Result<Self, String> {
        let n = bytes.len().checked_sub(48).ok_or("truncated dome")?;
        let img = ImageArt::decode(&bytes[..n])?.0;
        let mut r = Reader::new(&bytes[n..]);
        let mut v = [0.0; 6];
        for x in v.iter_mut() {
            *x = r.f64()?;
        }
        let orig = Vector3::new(v[0], v[1], v[2]);
        let south = Vector3::new(v[3], v[4], v[5]);
        Dome::new(&img, orig, south)
            .map(DomeArt)
            .map_err(|e| e.to_string())
    }
}

/// `read_exposure_stack`'s params: the files (a list file or the photographs), then
/// [`StackOptions`].
#[derive(Default, vfxgraph_params::Options)]
struct ReadStackOptions {
    /// the exposure list file (or give `paths`)
    #[param(path = "input")]
    list: String,
    /// the photographs, when no `list` is given
    #[param(path = "input")]
    paths: Vec<String>,
    #[param(flatten)]
    stack: StackOptions,
}

const STACK_READ: Out<StackArt> = Out::new("stack", "the exposure stack");
const STACK: In<StackArt> = In::new("stack", "the exposure stack");
const ALIGNED: Out<StackArt> = Out::new("stack", "the aligned stack");
const REPORT: Out<ReportArt> = Out::new(
    "report",
    "{\"reference\": r, \"shifts\": [[dx, dy], ...]}: aligned(x, y) = exposure(x - dx, y - dy)",
);
const RESPONSE_OUT: Out<ResponseArt> = Out::new("response", "the response curve");
const RESPONSE: In<ResponseArt> = In::new("response", "the response curve");
const RADIANCE: Out<ImageArt> = Out::new("image", "the radiance map, linear");
const HDR_IMAGE: In<ImageArt> = In::new("image", "linear HDR image");
const PHOTO_RESPONSE: OptIn<ResponseArt> = OptIn::new("response", "response curve");
const PHOTOGRAPH: Out<ImageArt> = Out::new("image", "the simulated photograph");
const CURVE: In<ResponseArt> = In::new("response", "the curve");
const PLOT: Out<ImageArt> = Out::new("image", "the plot (write it as PNG)");
const PROBE: In<ImageArt> = In::new("image", "the probe photograph, linear");
const EQUIRECT: Out<ImageArt> = Out::new("image", "equirectangular image");
const RADIANCE_MAP: In<ImageArt> = In::new("image", "equirectangular radiance map");
const CAMERA: OptIn<CameraArt> = OptIn::new(
    "camera",
    "the camera that photographed the probe (its R orients the dome)",
);
const DOME: Out<DomeArt> = Out::new("dome", "the oriented dome");

/// Registers the artifact and node types of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "read_exposure_stack",
            "Reads bracketed 8-bit PNG/JPEG photographs as raw codes (book 10.2), named either \
             by `list`, a list file in Debevec's format (`#` comments, the count, then `file \
             seconds` lines, seconds like 1/250; names relative to the list; a missing .ppm \
             falls back to the .png/.jpg with the same stem), or by `paths` with `times` in \
             seconds — or without `times`, from each photograph's EXIF ExposureTime (× ISO / \
             FNumber² relative to the first photograph when recorded). Validates sizes and \
             distinct times. The images are part of the cache key: editing one reruns the node.",
        )
        .version(2)
        .mode(Mode::Once)
        .options::<ReadStackOptions>()
        .output(STACK_READ),
        run_read_stack,
    );
    r.register_fn(
        NodeSpec::new(
            "align_exposures",
            "Aligns a hand-held bracket by Ward's median threshold bitmaps (Ward 2003; book \
             10.x): per pair of exposures, bitmaps of pixels above a shared percentile (the \
             median unless clipping makes it useless), an exclusion band around it, and an XOR \
             + popcount search of ±1 px per pyramid level. Translations only. Pixels shifted in \
             from outside the frame get code 0 (ignored by the merge) and join the mask.",
        )
        .options::<AlignOptions>()
        .input(STACK)
        .output(ALIGNED)
        .output(REPORT),
        run_align,
    );
    r.register_fn(
        NodeSpec::new(
            "hdr_calibrate",
            "Recovers the camera response g = ln f⁻¹ per channel by Debevec & Malik's weighted \
             least squares with smoothness λ, hat weights and g(128) = 0 (book 10.2–10.4), \
             constrained to be non-decreasing unless `monotonic: false`.",
        )
        .version(2)
        .mode(Mode::Once)
        .seeded()
        .options::<CalibrateOptions>()
        .input(STACK)
        .output(RESPONSE_OUT),
        run_calibrate,
    );
    r.register_fn(
        NodeSpec::new(
            "hdr_merge",
            "Assembles the linear radiance map ln E = Σ w(Z)(g(Z) − ln Δt)/Σ w(Z) (book 10.4); \
             pixels clipped in every exposure take the stack's bound; g(128) = 0 per channel \
             keeps the camera's mid-grey white balance.",
        )
        .input(STACK)
        .input(RESPONSE)
        .output(RADIANCE),
        run_merge,
    );
    r.register_fn(
        NodeSpec::new(
            "hdr_to_ldr",
            "Simulates a photograph of an HDR image (book 10.6): code = g⁻¹(ln(E·time)) through \
             the connected response curve, or through a gamma curve when none is connected. \
             The output, written to PNG/JPEG, stores those codes exactly.",
        )
        .options::<LdrOptions>()
        .input(HDR_IMAGE)
        .input(PHOTO_RESPONSE)
        .output(PHOTOGRAPH),
        run_to_ldr,
    );
    r.register_fn(
        NodeSpec::new(
            "plot_response",
            "Plots a response curve as Debevec & Malik's figure: pixel value z (up) against log \
             exposure g(z) (across), one line per channel (red, green, blue), on white with a \
             grid at every unit of ln exposure and every 32 codes.",
        )
        .options::<PlotOptions>()
        .input(CURVE)
        .output(PLOT),
        run_plot,
    );
    r.register_fn(
        NodeSpec::new(
            "write_response",
            "Writes a response curve as CSV: 256 rows (z = 0…255), one column per channel \
             (R,G,B), holding the linear exposure f⁻¹(z) = exp(g(z)) — OpenCV's debevec.csv \
             layout in RGB order, no header. The write is atomic.",
        )
        .output_file_param("path", "the CSV file")
        .input(CURVE),
        run_write_response,
    );
    r.register_fn(
        NodeSpec::new(
            "probe_to_equirect",
            "Unwraps a mirror-ball light probe (camera looking along −z, +y up, orthographic) \
             into a width × width/2 equirectangular image in the dome's y-up layout (top row \
             +y, centre column −z), bilinear (book 10.7). The rim (−z) is singular.",
        )
        .options::<ProbeOptions>()
        .input(PROBE)
        .output(EQUIRECT),
        run_probe,
    );
    r.register_fn(
        NodeSpec::new(
            "dome",
            "Makes a light dome of an equirectangular image (book 10.7–10.8): oriented by \
             `orig` (centre column) and `south` (top row), or by a calibrated camera's rotation \
             R — from a connected `camera` or the `rotation` param (9 numbers, row by row): \
             south = 2nd row, orig = −3rd row. The default is vfxgraph's y-up world: south = \
             +y, orig = −z.",
        )
        .version(2)
        .options::<DomeOptions>()
        .input(RADIANCE_MAP)
        .input(CAMERA)
        .output(DOME),
        run_dome,
    );
}

fn run_read_stack(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let ReadStackOptions { list, stack: o, .. } = ctx.options()?;
    // The names as written; the context resolves them against the graph file.
    let list = (!list.is_empty()).then(|| ctx.path("list"));
    let files = StackFiles::resolve(list.as_deref(), ctx.paths("paths"), &o.times)?;
    // The listed images are inputs too: declare them so an edit reruns the node.
    for path in files.listed() {
        ctx.declare_input_file(path)
            .map_err(|e| NodeError::msg(format!("param `list`: {e}")))?;
    }
    ctx.set(STACK_READ, StackArt(files.read(&o)?));
    Ok(())
}

fn run_align(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: AlignOptions = ctx.options()?;
    let stack = &ctx.get(STACK)?.0;
    let (aligned, shifts) = align_exposures(stack, &o)?;
    let report = align_report(&o, stack.len(), &shifts);
    ctx.set(ALIGNED, StackArt(aligned));
    ctx.set(REPORT, ReportArt::of(&report)?);
    Ok(())
}

fn run_calibrate(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o = CalibrateOptions {
        seed: ctx.seed(),
        ..ctx.options()?
    };
    let curve = calibrate_debevec(&ctx.get(STACK)?.0, &o)?;
    ctx.set(RESPONSE_OUT, ResponseArt(curve));
    Ok(())
}

fn run_merge(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let img = merge_debevec(&ctx.get(STACK)?.0, &ctx.get(RESPONSE)?.0)?;
    ctx.set(RADIANCE, ImageArt(img));
    Ok(())
}

fn run_to_ldr(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: LdrOptions = ctx.options()?;
    let img = &ctx.get(HDR_IMAGE)?.0;
    let response = ctx.get(PHOTO_RESPONSE)?.map(|r| &r.0);
    ctx.set(PHOTOGRAPH, ImageArt(photograph(img, response, &o)?));
    Ok(())
}

fn run_write_response(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let curve = &ctx.get(CURVE)?.0;
    let csv = curve.to_csv();
    Ok(vfxgraph_imaging::io::write_atomic(
        &ctx.path("path"),
        csv.as_bytes(),
    )?)
}

fn run_plot(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: PlotOptions = ctx.options()?;
    let img = plot_response(&ctx.get(CURVE)?.0, &o);
    ctx.set(PLOT, ImageArt(img));
    Ok(())
}

fn run_probe(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: ProbeOptions = ctx.options()?;
    let img = &ctx.get(PROBE)?.0;
    let out = probe_to_equirect(img, &o.circle_in(img.width, img.height), o.width)?;
    ctx.set(EQUIRECT, ImageArt(out));
    Ok(())
}

fn run_dome(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: DomeOptions = ctx.options()?;
    let img = &ctx.get(RADIANCE_MAP)?.0;
    let camera = ctx.get(CAMERA)?;
    let dome = Dome::oriented(img, &o, camera.map(|c| &c.0.pose.r))?;
    ctx.set(DOME, DomeArt(dome));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use nalgebra::Matrix3;
    use std::path::Path;
    use vfxgraph_engine::ParamValue;
    use vfxgraph_engine::{InputValue, Value};
    use vfxgraph_imaging::Image;

    /// A synthetic 3-exposure stack of a horizontal radiance ramp through a gamma-2 camera.
    fn synthetic_stack(dir: &Path) {
        let (w, h) = (64usize, 16usize);
        let mut list = String::from("# test\n3\n");
        for (k, t) in [0.25f64, 1.0, 4.0].iter().enumerate() {
            // Codes z stored exactly: the PNG writer sRGB-encodes srgb8_to_linear(z) back to z.
            let img = Image::from_fn(w, h, 3, |x, y, c| {
                let e = 0.02 * 1.08f64.powi(x as i32) * (1.0 + 0.01 * y as f64);
                let s = [1.0, 0.8, 0.6][c];
                let z = (255.0 * (e * t * s).min(1.0).sqrt()).round() as u8;
                vfxgraph_imaging::color::srgb8_to_linear(z)
            });
            vfxgraph_imaging::write_image(&dir.join(format!("e{k}.png")), &img).unwrap();
            list.push_str(&format!("e{k}.ppm {t}\n"));
        }
        std::fs::write(dir.join("list.txt"), list).unwrap();
    }

    #[test]
    fn stack_calibrate_merge_and_write() {
        let dir = tempfile::tempdir().unwrap();
        synthetic_stack(dir.path());
        let s = spec("read_exposure_stack");
        let p = params(&s, &[("list", ParamValue::Str("list.txt".into()))]);
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, vec![]);
        run_read_stack(&mut ctx).unwrap();
        let stack = ctx.take_output::<StackArt>("stack").unwrap();
        assert_eq!((stack.0.width(), stack.0.len()), (64, 3));
        // Artifact round trip.
        let mut bytes = Vec::new();
        stack.encode(&mut bytes);
        assert_eq!(StackArt::decode(&bytes).unwrap(), stack);
        assert!(StackArt::decode(&bytes[..bytes.len() - 1]).is_err());

        let s = spec("hdr_calibrate");
        let p = params(&s, &[("samples", ParamValue::Int(300))]);
        let input = vec![("stack", InputValue::One(Value::new(stack.clone())))];
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, input);
        run_calibrate(&mut ctx).unwrap();
        let resp = ctx.take_output::<ResponseArt>("response").unwrap();
        let mut bytes = Vec::new();
        resp.encode(&mut bytes);
        assert_eq!(ResponseArt::decode(&bytes).unwrap(), resp);

        let s = spec("hdr_merge");
        let p = params(&s, &[]);
        let input = vec![
            ("stack", InputValue::One(Value::new(stack.clone()))),
            ("response", InputValue::One(Value::new(resp.clone()))),
        ];
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, input);
        run_merge(&mut ctx).unwrap();
        let img = ctx.take_output::<ImageArt>("image").unwrap().0;
        // Radiance ratios along the ramp: ×1.08 per column (well-exposed middle columns).
        let r = img.get(30, 8, 1) / img.get(20, 8, 1);
        assert!((r as f64 / 1.08f64.powi(10) - 1.0).abs() < 0.05, "{r}");

        let s = spec("write_response");
        let p = params(&s, &[("path", ParamValue::Str("out/curve.csv".into()))]);
        let input = vec![("response", InputValue::One(Value::new(resp.clone())))];
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, input);
        run_write_response(&mut ctx).unwrap();
        let csv = std::fs::read_to_string(dir.path().join("out/curve.csv")).unwrap();
        assert_eq!(csv.lines().count(), 256);
        let row128: Vec<f64> = csv
            .lines()
            .nth(128)
            .unwrap()
            .split(',')
            .map(|v| v.parse().unwrap())
            .collect();
        assert_eq!(row128, vec![1.0, 1.0, 1.0], "exp(g(128)) = 1");

        let s = spec("plot_response");
        let p = params(&s, &[]);
        let input = vec![("response", InputValue::One(Value::new(resp)))];
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, input);
        run_plot(&mut ctx).unwrap();
        let plot = ctx.take_output::<ImageArt>("image").unwrap().0;
        assert_eq!((plot.width, plot.height), (640, 480));
        assert!(
            plot.data.chunks(3).any(|p| p[0] > 0.7 && p[1] < 0.1),
            "a red curve"
        );
    }

    #[test]
    fn bad_list_and_bad_mask_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("list.txt"), "2\na.png 1\n").unwrap();
        let s = spec("read_exposure_stack");
        let p = params(&s, &[("list", ParamValue::Str("list.txt".into()))]);
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, vec![]);
        let e = run_read_stack(&mut ctx).unwrap_err();
        assert!(e.message.contains("list.txt:2"), "{e}");
        synthetic_stack(dir.path());
        let bad = ParamValue::List(vec![
            ParamValue::Float(0.5),
            ParamValue::Float(0.0),
            ParamValue::Float(255.0),
        ]);
        let p = params(
            &s,
            &[
                ("list", ParamValue::Str("list.txt".into())),
                ("mask_color", bad),
            ],
        );
        let mut ctx = Context::for_test(&s, &p, dir.path(), None, vec![]);
        assert!(run_read_stack(&mut ctx).is_err());
    }

    fn strs(v: &[&str]) -> ParamValue {
        ParamValue::List(v.iter().map(|s| ParamValue::Str(s.to_string())).collect())
    }
    fn floats(v: &[f64]) -> ParamValue {
        ParamValue::List(v.iter().map(|&x| ParamValue::Float(x)).collect())
    }
    fn read_stack(dir: &Path, set: &[(&str, ParamValue)]) -> Result<StackArt, NodeError> {
        let s = spec("read_exposure_stack");
        let p = params(&s, set);
        let mut ctx = Context::for_test(&s, &p, dir, None, vec![]);
        run_read_stack(&mut ctx)?;
        Ok(ctx.take_output::<StackArt>("stack").unwrap())
    }

    #[test]
    fn paths_and_times_read_the_same_stack_as_the_list_and_errors_name_params() {
        let dir = tempfile::tempdir().unwrap();
        synthetic_stack(dir.path());
        let d = dir.path();
        let from_list = read_stack(d, &[("list", ParamValue::Str("list.txt".into()))]).unwrap();
        let files = ["e0.png", "e1.png", "e2.png"];
        let from_paths = read_stack(
            d,
            &[
                ("paths", strs(&files)),
                ("times", floats(&[0.25, 1.0, 4.0])),
            ],
        )
        .unwrap();
        assert_eq!(from_list, from_paths);
        // The list form declares the images it reads (so the engine hashes them).
        let s = spec("read_exposure_stack");
        let p = params(&s, &[("list", ParamValue::Str("list.txt".into()))]);
        let mut ctx = Context::for_test(&s, &p, d, None, vec![]);
        run_read_stack(&mut ctx).unwrap();
        let declared: Vec<_> = ctx
            .declared_input_files()
            .iter()
            .map(|(p, _)| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(declared, files);

        let err = |set: &[(&str, ParamValue)]| read_stack(d, set).unwrap_err().message;
        let e = err(&[("paths", strs(&files)), ("times", floats(&[0.25, 1.0]))]);
        assert!(e.contains("`paths` names 3 files but `times` has 2"), "{e}");
        let e = err(&[
            ("paths", strs(&files)),
            ("times", floats(&[0.25, 1.0, 0.25])),
        ]);
        assert!(
            e.contains("`times`") && e.contains("e0.png and e2.png have the same exposure"),
            "{e}"
        );
        let e = err(&[
            ("paths", strs(&["e0.png", "nope.png"])),
            ("times", floats(&[1.0, 2.0])),
        ]);
        assert!(e.contains("`paths`") && e.contains("nope.png"), "{e}");
        std::fs::write(d.join("bad.txt"), "2\ne0.png 1\nmissing.png 2\n").unwrap();
        let e = err(&[("list", ParamValue::Str("bad.txt".into()))]);
        assert!(e.contains("`list`") && e.contains("missing.png"), "{e}");
        let e = err(&[]);
        assert!(e.contains("`list`") && e.contains("`paths`"), "{e}");
        let e = err(&[
            ("list", ParamValue::Str("list.txt".into())),
            ("paths", strs(&files)),
        ]);
        assert!(e.contains("not both"), "{e}");
        let e = err(&[
            ("list", ParamValue::Str("list.txt".into())),
            ("times", floats(&[1.0])),
        ]);
        assert!(e.contains("`times` goes with `paths`"), "{e}");
        // PNGs carry no EXIF: without times, the error names the file.
        let e = err(&[("paths", strs(&files))]);
        assert!(e.contains("e0.png") && e.contains("EXIF"), "{e}");
    }

    #[test]
    fn exif_times_of_jpegs_replace_the_times_param() {
        use vfxgraph_imaging::hdr::{with_exposure_exif, ExposureSettings};
        let dir = tempfile::tempdir().unwrap();
        // Bracketed by shutter and aperture: 1/60 s f/8, 1/15 s f/8, 1/15 s f/4 (ISO 200).
        let shots = [(1.0 / 60.0, 8.0), (1.0 / 15.0, 8.0), (1.0 / 15.0, 4.0)];
        let mut names = Vec::new();
        for (k, &(t, n)) in shots.iter().enumerate() {
            let img = Image::from_fn(32, 16, 3, |x, y, c| {
                (((x + 2 * y + c) as f64 / 80.0) * t * 64.0 / (n * n) * 8.0).min(1.0) as f32
            });
            let jpeg = vfxgraph_imaging::encode(&img, vfxgraph_imaging::Format::Jpeg).unwrap();
            let tagged = with_exposure_exif(
                &jpeg,
                &ExposureSettings {
                    time: t,
                    f_number: Some(n),
                    iso: Some(200.0),
                },
            )
            .unwrap();
            let name = format!("shot{k}.jpg");
            std::fs::write(dir.path().join(&name), tagged).unwrap();
            names.push(name);
        }
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let stack = read_stack(dir.path(), &[("paths", strs(&names))])
            .unwrap()
            .0;
        let times: Vec<f64> = stack.exposures().iter().map(|e| e.time).collect();
        // Seconds at the first photograph's f/8: f/4 gathers 4× the light of f/8.
        let want = [1.0 / 60.0, 1.0 / 15.0, 4.0 / 15.0];
        for (t, w) in times.iter().zip(want) {
            assert!((t / w - 1.0).abs() < 1e-9, "{times:?}");
        }
        // Explicit times win over EXIF.
        let stack = read_stack(
            dir.path(),
            &[("paths", strs(&names)), ("times", floats(&[1.0, 2.0, 3.0]))],
        )
        .unwrap()
        .0;
        assert_eq!(stack.exposures()[2].time, 3.0);
    }

    #[test]
    fn align_node_reports_the_shifts_and_masks_the_borders() {
        // Three exposures of a scene of random 4×4 blocks; the last one moved 3 px right, 2 up.
        let (w, h) = (96usize, 64usize);
        let scene = |x: i64, y: i64| -> f64 {
            let k = (x.div_euclid(4) * 7919 + y.div_euclid(4) * 104729) as u64;
            let r = k.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
            0.05 + 0.9 * (r as f64 / (1u64 << 24) as f64)
        };
        let exposures: Vec<Exposure> = [(0.5, (0i64, 0i64)), (1.0, (0, 0)), (2.0, (3, -2))]
            .iter()
            .map(|&(t, (dx, dy))| Exposure {
                time: t,
                codes: (0..w * h)
                    .map(|p| {
                        let (x, y) = ((p % w) as i64 - dx, (p / w) as i64 - dy);
                        (255.0 * (scene(x, y) * t).min(1.0).sqrt()).round() as u8
                    })
                    .collect(),
            })
            .collect();
        let stack = ExposureStack::new(w, h, 1, exposures).unwrap();
        let s = spec("align_exposures");
        let p = params(&s, &[]);
        let input = vec![(
            "stack",
            InputValue::One(Value::new(StackArt(stack.clone()))),
        )];
        let mut ctx = Context::for_test(&s, &p, Path::new("."), None, input);
        run_align(&mut ctx).unwrap();
        let report: vfxgraph_imaging::hdr::AlignReport = ctx
            .take_output::<ReportArt>("report")
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(report.reference, 1);
        assert_eq!(report.shifts, [[0, 0], [0, 0], [-3, 2]]);
        let aligned = ctx.take_output::<StackArt>("stack").unwrap().0;
        assert!(aligned.is_masked(w - 1) && !aligned.is_masked(w * 10 + 10));
        let p = params(&s, &[("reference", ParamValue::Int(3))]);
        let input = vec![("stack", InputValue::One(Value::new(StackArt(stack))))];
        let mut ctx = Context::for_test(&s, &p, Path::new("."), None, input);
        let e = run_align(&mut ctx).unwrap_err();
        assert!(e.message.contains("`reference`"), "{e}");
    }

    #[test]
    fn dome_node_orients_and_round_trips() {
        let img = Image::from_fn(16, 8, 3, |x, y, c| (x + y + c) as f32);
        let s = spec("dome");
        let rot: Vec<ParamValue> = [1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0]
            .iter()
            .map(|&v| ParamValue::Float(v))
            .collect();
        let p = params(&s, &[("rotation", ParamValue::List(rot))]);
        let input = vec![("image", InputValue::One(Value::new(ImageArt(img.clone()))))];
        let mut ctx = Context::for_test(&s, &p, Path::new("."), None, input);
        run_dome(&mut ctx).unwrap();
        let dome = ctx.take_output::<DomeArt>("dome").unwrap();
        assert_eq!(dome.0.south(), Vector3::new(0.0, 0.0, -1.0));
        assert_eq!(dome.0.orig(), Vector3::new(0.0, -1.0, 0.0));
        let mut bytes = Vec::new();
        dome.encode(&mut bytes);
        let back = DomeArt::decode(&bytes).unwrap();
        assert_eq!(back.0.image(), &img);
        assert_eq!(back.0.south(), dome.0.south());
        // The same rotation from a connected camera.
        let cam = vfxgraph_geometry::Camera::new(
            vfxgraph_geometry::Intrinsics::new(500.0, 500.0, 320.0, 240.0),
            Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0),
            Vector3::zeros(),
        );
        let p0 = params(&s, &[]);
        let input = vec![
            ("image", InputValue::One(Value::new(ImageArt(img.clone())))),
            ("camera", InputValue::One(Value::new(CameraArt(cam)))),
        ];
        let mut ctx = Context::for_test(&s, &p0, Path::new("."), None, input);
        run_dome(&mut ctx).unwrap();
        let from_cam = ctx.take_output::<DomeArt>("dome").unwrap();
        assert_eq!(from_cam.0.south(), dome.0.south());
        assert_eq!(from_cam.0.orig(), dome.0.orig());
        let bad = ParamValue::List(vec![ParamValue::Float(1.0); 4]);
        let p = params(&s, &[("rotation", bad)]);
        let input = vec![("image", InputValue::One(Value::new(ImageArt(img))))];
        let mut ctx = Context::for_test(&s, &p, Path::new("."), None, input);
        assert!(run_dome(&mut ctx).is_err());
    }
}
