//! Image file nodes: `read_image`, `write_image`, `read_image_sequence`,
//! `write_image_sequence`. Formats: PNG, JPEG, TIFF (sRGB, decoded to linear), DPX (its
//! header's transfer), OpenEXR, PFM and Radiance .hdr (linear), chosen by the file extension.
//! Colour management ([`vfxgraph_imaging::colour`]): a reader takes the file's colour space and
//! a writer the file's colour space or a display/view, by their OpenColorIO names, converting
//! from and to the graph's scene-linear working space.

use vfxgraph_engine::node::has_frame_pattern;
use vfxgraph_engine::{Context, In, Mode, NodeError, NodeSpec, Out, Registry, Threads};
use vfxgraph_imaging::colour::{KeepPlate, ReadColour, WriteColour};

use crate::artifacts::ImageArt;

const FORMATS: &str = "PNG, JPEG, EXR, PFM or HDR, by extension";

const READ_IMAGE: Out<ImageArt> = Out::new("image", "the image, linear light");
const IMAGE_TO_WRITE: In<ImageArt> = In::new("image", "the image to write");
const READ_FRAME: Out<ImageArt> = Out::new("sequence", "the frame's image");
const FRAME_TO_WRITE: In<ImageArt> = In::new("sequence", "the frame's image");

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "read_image",
            "Reads one image file (PNG, JPEG, OpenEXR, PFM, Radiance HDR) into linear f32. \
             sRGB files are decoded to linear light; float formats are read as they are. With \
             `colour_space` (an OpenColorIO name), the file's code values are converted from \
             it to the working space.",
        )
        .mode(Mode::Once)
        .threads(vfxgraph_engine::Threads::One)
        .uncached()
        .input_file_param("path", "the image file, relative to the graph file")
        .options::<ReadColour>()
        .output(READ_IMAGE),
        |ctx| read_image(ctx, READ_IMAGE),
    );
    r.register_fn(
        NodeSpec::new(
            "write_image",
            "Writes an image file; the format comes from the extension (PNG/JPEG are sRGB \
             encoded, EXR float ZIP, PFM, HDR RLE). With `colour_space` the working space is \
             converted to it and its code values written; with `view`, a display/view \
             transform's (a preview). The write is atomic.",
        )
        .threads(vfxgraph_engine::Threads::One)
        .output_file_param("path", FORMATS)
        .options::<WriteColour>()
        .options::<KeepPlate>()
        .input(IMAGE_TO_WRITE),
        run_write_image,
    );
    r.register_fn(
        NodeSpec::new(
            "read_image_sequence",
            "Reads one image file per frame of the graph's range; the path holds a frame \
             pattern (`%04d` or `####`). Each frame is cached on its own file's content.",
        )
        .mode(Mode::PerFrame)
        .uncached()
        .input_file_param("path", "file pattern, e.g. plate/frame.%04d.png")
        .options::<ReadColour>()
        .output(READ_FRAME),
        |ctx| read_image(ctx, READ_FRAME),
    );
    r.register_fn(
        NodeSpec::new(
            "write_image_sequence",
            "Writes one image file per frame; the path holds a frame pattern (`%04d` or `####`).",
        )
        .threads(Threads::One)
        .mode(Mode::PerFrame)
        .output_file_param("path", "file pattern, e.g. out/frame.%04d.exr")
        .options::<WriteColour>()
        .options::<KeepPlate>()
        .input(FRAME_TO_WRITE),
        |ctx| write_image(ctx, FRAME_TO_WRITE),
    );
}

/// Per frame, path param `path` must hold a frame pattern (else every frame would use one file).
pub(crate) fn check_pattern(ctx: &Context<'_>) -> Result<(), NodeError> {
    if ctx.frame().is_some() && !has_frame_pattern(ctx.params().str("path")) {
        return Err(NodeError::msg(format!(
            "path `{}` has no frame pattern (`%04d` or `####`): every frame would use one file",
            ctx.params().str("path")
        )));
    }
    Ok(())
}

/// The OpenColorIO config file param `ocio_config`, resolved (None when empty).
pub(crate) fn ocio_config(ctx: &Context<'_>) -> Option<std::path::PathBuf> {
    (!ctx.params().str("ocio_config").is_empty()).then(|| ctx.path("ocio_config"))
}

/// `read_image` and `read_image_sequence`: the file of param `path` into output `port`.
fn read_image(ctx: &mut Context<'_>, port: Out<ImageArt>) -> Result<(), NodeError> {
    check_pattern(ctx)?;
    let o: ReadColour = ctx.options()?;
    let img = o.read(&ctx.path("path"), ocio_config(ctx).as_deref())?;
    ctx.set(port, ImageArt(img));
    Ok(())
}

/// `write_image`.
pub(crate) fn run_write_image(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    write_image(ctx, IMAGE_TO_WRITE)
}

/// `write_image` and `write_image_sequence`: input `port` to the file of param `path`.
fn write_image(ctx: &mut Context<'_>, port: In<ImageArt>) -> Result<(), NodeError> {
    check_pattern(ctx)?;
    let img = &ctx.get(port)?.0;
    let o: WriteColour = ctx.options()?;
    let config = ocio_config(ctx);
    let plate = (!ctx.params().str("plate").is_empty()).then(|| ctx.path("plate"));
    Ok(o.write_keeping(
        &crate::output_path(ctx, "path")?,
        img,
        config.as_deref(),
        plate.as_deref(),
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use vfxgraph_engine::{InputValue, ParamValue, Params, Value};
    use vfxgraph_imaging::Image;

    fn spec(name: &str) -> NodeSpec {
        let r = crate::registry();
        r.node(name).unwrap().spec().clone()
    }

    fn params(path: &str) -> Params {
        params_with(path, &[])
    }

    /// The defaults of the readers' and writers' params (one set: they share their names),
    /// `path` and `set`.
    fn params_with(path: &str, set: &[(&str, &str)]) -> Params {
        let mut m: std::collections::BTreeMap<String, ParamValue> =
            ["colour_space", "view", "display", "ocio_config", "plate"]
                .iter()
                .map(|k| (k.to_string(), ParamValue::Str(String::new())))
                .collect();
        m.insert(
            "working_space".into(),
            ParamValue::Str("linear_rec709".into()),
        );
        m.insert("path".into(), ParamValue::Str(path.into()));
        for (k, v) in set {
            m.insert(k.to_string(), ParamValue::Str(v.to_string()));
        }
        Params::new(m)
    }

    fn gradient() -> Image {
        Image::from_fn(8, 4, 3, |x, y, c| (x + 2 * y + c) as f32 / 20.0)
    }

    #[test]
    fn write_then_read_exr_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let img = gradient();
        let (ws, p) = (spec("write_image"), params("a.exr"));
        let mut ctx = Context::for_test(
            &ws,
            &p,
            dir.path(),
            None,
            vec![("image", InputValue::One(Value::new(ImageArt(img.clone()))))],
        );
        run_write_image(&mut ctx).unwrap();
        let rs = spec("read_image");
        let mut ctx = Context::for_test(&rs, &p, dir.path(), None, vec![]);
        read_image(&mut ctx, READ_IMAGE).unwrap();
        assert_eq!(ctx.take_output::<ImageArt>("image").unwrap().0, img);
    }

    #[test]
    fn sequences_use_the_frame_pattern() {
        let dir = tempfile::tempdir().unwrap();
        let img = gradient();
        let (ws, p) = (spec("write_image_sequence"), params("out/f.####.pfm"));
        for f in [3, 4] {
            let mut ctx = Context::for_test(
                &ws,
                &p,
                dir.path(),
                Some(f),
                vec![(
                    "sequence",
                    InputValue::One(Value::new(ImageArt(img.clone()))),
                )],
            );
            write_image(&mut ctx, FRAME_TO_WRITE).unwrap();
        }
        assert!(dir.path().join("out/f.0003.pfm").is_file());
        assert!(dir.path().join("out/f.0004.pfm").is_file());
        let rs = spec("read_image_sequence");
        let p = params("out/f.%04d.pfm");
        let mut ctx = Context::for_test(&rs, &p, dir.path(), Some(4), vec![]);
        read_image(&mut ctx, READ_FRAME).unwrap();
        assert_eq!(ctx.take_output::<ImageArt>("sequence").unwrap().0, img);
        // No pattern: a clear error.
        let p = params("out/f.pfm");
        let mut ctx = Context::for_test(&rs, &p, dir.path(), Some(4), vec![]);
        let e = read_image(&mut ctx, READ_FRAME).unwrap_err();
        assert!(e.message.contains("frame pattern"), "{e}");
    }

    #[test]
    fn missing_and_corrupt_files_name_the_path() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("bad.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
        let rs = spec("read_image");
        for name in ["missing.png", "bad.png"] {
            let p = params(name);
            let mut ctx = Context::for_test(&rs, &p, dir.path(), None, vec![]);
            let e = read_image(&mut ctx, READ_IMAGE).unwrap_err();
            assert!(e.message.contains(name), "{e}");
        }
    }

    /// Writes `img` with `set` params to `file`, then reads it with `read` params.
    fn write_read(
        dir: &std::path::Path,
        file: &str,
        img: &Image,
        set: &[(&str, &str)],
        read: &[(&str, &str)],
    ) -> Result<Image, NodeError> {
        let (ws, p) = (spec("write_image"), params_with(file, set));
        let mut ctx = Context::for_test(
            &ws,
            &p,
            dir,
            None,
            vec![("image", InputValue::One(Value::new(ImageArt(img.clone()))))],
        );
        run_write_image(&mut ctx)?;
        let (rs, p) = (spec("read_image"), params_with(file, read));
        let mut ctx = Context::for_test(&rs, &p, dir, None, vec![]);
        read_image(&mut ctx, READ_IMAGE)?;
        Ok(ctx.take_output::<ImageArt>("image").unwrap().0)
    }

    /// A LogC3 DPX: written from the working space in ARRI LogC3 (EI 800) code values, read
    /// back to within the 10-bit quantisation, its codes those of the LogC3 curve (18% grey
    /// at 0.391 — ARRI's table — is code 400 of 1023).
    #[test]
    fn a_logc3_dpx_round_trips_through_its_colour_space() {
        let dir = tempfile::tempdir().unwrap();
        let img = Image::from_fn(8, 4, 3, |x, y, c| {
            0.01 + (x + 8 * y) as f32 * 0.05 + c as f32 * 0.01
        });
        let logc = [("colour_space", "ARRI LogC3 (EI800)")];
        let back = write_read(dir.path(), "p.dpx", &img, &logc, &logc).unwrap();
        for (p, q) in img.data.chunks(3).zip(back.data.chunks(3)) {
            // A 10-bit LogC3 step is 0.94% of the value (a stop is 0.0734 of the range), half
            // a step 0.47%; the gamut matrices spread a channel's rounding into the others, so
            // the bound is on the pixel's largest channel.
            let top = p.iter().fold(0.0f32, |m, v| m.max(*v));
            let worst = (0..3).map(|k| (p[k] - q[k]).abs()).fold(0.0f32, f32::max);
            assert!(worst <= 0.01 * top, "{p:?} -> {q:?}");
        }
        let grey = Image::from_fn(2, 2, 3, |_, _, _| 0.18);
        let (ws, p) = (spec("write_image"), params_with("g.dpx", &logc));
        let mut ctx = Context::for_test(
            &ws,
            &p,
            dir.path(),
            None,
            vec![("image", InputValue::One(Value::new(ImageArt(grey))))],
        );
        run_write_image(&mut ctx).unwrap();
        let bytes = std::fs::read(dir.path().join("g.dpx")).unwrap();
        let (codes, info) = vfxgraph_imaging::io::dpx::decode_codes(&bytes).unwrap();
        assert_eq!(info.transfer, 0, "user defined");
        assert!(
            codes.data.iter().all(|&v| (v * 1023.0).round() == 400.0),
            "{:?}",
            &codes.data[..3]
        );
    }

    /// The defaults read and write as the format always did, bit for bit; naming the sRGB
    /// colour space explicitly gives the same values within f32 rounding; an ACEScg working
    /// space converts on read and back on write.
    #[test]
    fn default_named_and_acescg_reads_agree() {
        let dir = tempfile::tempdir().unwrap();
        let img = gradient();
        let plain = write_read(dir.path(), "a.png", &img, &[], &[]).unwrap();
        let mut want = img.clone();
        for v in &mut want.data {
            *v = vfxgraph_imaging::color::srgb8_to_linear(
                vfxgraph_imaging::color::linear_to_srgb8(*v),
            );
        }
        assert_eq!(plain, want);
        let srgb = [("colour_space", "sRGB Encoded Rec.709 (sRGB)")];
        let named = write_read(dir.path(), "b.png", &img, &[], &srgb).unwrap();
        let worst = plain
            .data
            .iter()
            .zip(&named.data)
            .map(|(a, b)| (a - b).abs() / a.max(1e-3))
            .fold(0.0f32, f32::max);
        eprintln!("named sRGB vs the format's sRGB: {worst:e} relative");
        assert!(worst < 5e-5, "{worst}");
        let cg = [("working_space", "acescg")];
        let aces = write_read(dir.path(), "c.exr", &img, &[], &cg).unwrap();
        let t = vfxgraph_imaging::colour::ColourConfig::builtin()
            .transform("Linear Rec.709 (sRGB)", "ACEScg")
            .unwrap();
        let px = t.apply_rgb([img.data[9], img.data[10], img.data[11]]);
        assert_eq!(&aces.data[9..12], &px);
        // Written from ACEScg back to the format's own linear Rec. 709: the original values.
        let back = write_read(dir.path(), "d.exr", &aces, &cg, &[]).unwrap();
        for (a, b) in img.data.iter().zip(&back.data) {
            assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        }
    }

    /// A preview through a display/view: the ACES 2.0 SDR view's sRGB display codes.
    #[test]
    fn a_preview_writes_the_display_view() {
        let dir = tempfile::tempdir().unwrap();
        let img = Image::from_fn(4, 2, 3, |x, _, _| [0.0, 0.18, 1.0, 16.0][x]);
        let view = [("view", "ACES 2.0 - SDR 100 nits (Rec.709)")];
        let raw = [("colour_space", "Raw")];
        let codes = write_read(dir.path(), "v.png", &img, &view, &raw).unwrap();
        let t = vfxgraph_imaging::colour::ColourConfig::builtin()
            .display_view(
                "Linear Rec.709 (sRGB)",
                "sRGB - Display",
                "ACES 2.0 - SDR 100 nits (Rec.709)",
            )
            .unwrap();
        for x in 0..4 {
            let want = t.apply_rgb([img.get(x, 0, 0); 3]);
            let got = codes.get(x, 0, 0);
            assert!(
                (got - want[0]).abs() <= 0.5 / 255.0 + 1e-6,
                "{x}: {got} vs {want:?}"
            );
        }
        // Tone mapped: 16 is below display white, 0 black.
        assert!(codes.get(3, 0, 0) < 1.0 && codes.get(0, 0, 0) == 0.0);
    }

    #[test]
    fn unknown_colour_names_and_bad_configs_are_errors_naming_file_and_name() {
        let dir = tempfile::tempdir().unwrap();
        let img = gradient();
        let e =
            write_read(dir.path(), "a.exr", &img, &[("colour_space", "LogC")], &[]).unwrap_err();
        assert!(
            e.message.contains("a.exr") && e.message.contains("`LogC`"),
            "{e}"
        );
        write_read(dir.path(), "b.exr", &img, &[], &[]).unwrap();
        let e = write_read(
            dir.path(),
            "c.exr",
            &img,
            &[],
            &[("colour_space", "S-Log9")],
        )
        .unwrap_err();
        assert!(
            e.message.contains("c.exr") && e.message.contains("S-Log9"),
            "{e}"
        );
        std::fs::write(dir.path().join("studio.ocio"), "ocio_profile_version: [").unwrap();
        let e = write_read(
            dir.path(),
            "d.exr",
            &img,
            &[],
            &[("colour_space", "ACEScg"), ("ocio_config", "studio.ocio")],
        )
        .unwrap_err();
        assert!(e.message.contains("studio.ocio"), "{e}");
        let e = write_read(
            dir.path(),
            "e.png",
            &img,
            &[("display", "sRGB - Display")],
            &[],
        )
        .unwrap_err();
        assert!(e.message.contains("without a `view`"), "{e}");
    }
}
