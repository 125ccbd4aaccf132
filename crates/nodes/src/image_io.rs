//! Image file nodes: `read_image`, `write_image`, `read_image_sequence`,
//! `write_image_sequence`. Formats: PNG, JPEG (sRGB, decoded to linear), OpenEXR, PFM and
//! Radiance .hdr (linear), chosen by the file extension.

use vfxgraph_engine::node::has_frame_pattern;
use vfxgraph_engine::{Context, Mode, NodeError, NodeSpec, Registry, Threads};
use vfxgraph_imaging::{read_image, write_image};

use crate::artifacts::ImageArt;

const FORMATS: &str = "PNG, JPEG, EXR, PFM or HDR, by extension";

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "read_image",
            "Reads one image file (PNG, JPEG, OpenEXR, PFM, Radiance HDR) into linear f32. \
             sRGB files are decoded to linear light; float formats are read as they are.",
        )
        .mode(Mode::Once)
        .threads(vfxgraph_engine::Threads::One)
        .uncached()
        .input_file_param("path", "the image file, relative to the graph file")
        .output_of::<ImageArt>("image", "the image, linear light"),
        run_read_image,
    );
    r.register_fn(
        NodeSpec::new(
            "write_image",
            "Writes an image file; the format comes from the extension (PNG/JPEG are sRGB \
             encoded, EXR float ZIP, PFM, HDR RLE). The write is atomic.",
        )
        .threads(vfxgraph_engine::Threads::One)
        .output_file_param("path", FORMATS)
        .input_of::<ImageArt>("image", "the image to write"),
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
        .output_of::<ImageArt>("sequence", "the frame's image"),
        run_read_image,
    );
    r.register_fn(
        NodeSpec::new(
            "write_image_sequence",
            "Writes one image file per frame; the path holds a frame pattern (`%04d` or `####`).",
        )
        .threads(Threads::One)
        .mode(Mode::PerFrame)
        .output_file_param("path", "file pattern, e.g. out/frame.%04d.exr")
        .input_of::<ImageArt>("sequence", "the frame's image"),
        run_write_image,
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

fn run_read_image(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    check_pattern(ctx)?;
    let img = read_image(&ctx.path("path"))?;
    let port = ctx.output_port(0);
    ctx.output(port, ImageArt(img));
    Ok(())
}

fn run_write_image(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    check_pattern(ctx)?;
    let port = ctx.input_port(0);
    let img = &ctx.input::<ImageArt>(port)?.0;
    Ok(write_image(&crate::output_path(ctx, "path")?, img)?)
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
        Params::new([("path".to_string(), ParamValue::Str(path.into()))].into())
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
        run_read_image(&mut ctx).unwrap();
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
            run_write_image(&mut ctx).unwrap();
        }
        assert!(dir.path().join("out/f.0003.pfm").is_file());
        assert!(dir.path().join("out/f.0004.pfm").is_file());
        let rs = spec("read_image_sequence");
        let p = params("out/f.%04d.pfm");
        let mut ctx = Context::for_test(&rs, &p, dir.path(), Some(4), vec![]);
        run_read_image(&mut ctx).unwrap();
        assert_eq!(ctx.take_output::<ImageArt>("sequence").unwrap().0, img);
        // No pattern: a clear error.
        let p = params("out/f.pfm");
        let mut ctx = Context::for_test(&rs, &p, dir.path(), Some(4), vec![]);
        let e = run_read_image(&mut ctx).unwrap_err();
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
            let e = run_read_image(&mut ctx).unwrap_err();
            assert!(e.message.contains(name), "{e}");
        }
    }
}
