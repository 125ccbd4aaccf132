//! Image operations: `exposure`, `tonemap`, `blur`, and the `constant` image generator.

use vfxgraph_engine::{Context, In, NodeError, NodeSpec, Out, Registry, Threads};
use vfxgraph_imaging::{
    blur, constant, exposure, tonemap, BlurOptions, ConstantOptions, ExposureOptions,
    TonemapOptions,
};

use crate::artifacts::ImageArt;

const LINEAR: In<ImageArt> = In::new("image", "linear image");
const EXPOSED: Out<ImageArt> = Out::new("image", "exposed image");
const HDR: In<ImageArt> = In::new("image", "linear HDR image");
const TONEMAPPED: Out<ImageArt> = Out::new("image", "tone-mapped linear image");
const BLURRED: Out<ImageArt> = Out::new("image", "blurred image");
const CONSTANT: Out<ImageArt> = Out::new("image", "the image");

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "exposure",
            "Scales linear light by 2^stops (photographic exposure, book §10.2); alpha is kept.",
        )
        .threads(Threads::One)
        .options::<ExposureOptions>()
        .input(LINEAR)
        .output(EXPOSED),
        run_exposure,
    );
    r.register_fn(
        NodeSpec::new(
            "tonemap",
            "Maps linear HDR light to displayable [0, 1] linear light: `srgb` clips, \
             `reinhard` applies L/(1+L) on luminance (Reinhard et al. 2002). Write the result \
             to PNG/JPEG for the sRGB curve.",
        )
        .threads(Threads::One)
        .options::<TonemapOptions>()
        .input(HDR)
        .output(TONEMAPPED),
        run_tonemap,
    );
    r.register_fn(
        NodeSpec::new(
            "blur",
            "Blurs as a camera does: a Gaussian of `sigma` px (a soft or defocused lens), then \
             a straight streak of `streak` px at `angle` degrees (motion blur); edges repeat.",
        )
        .options::<BlurOptions>()
        .input(LINEAR)
        .output(BLURRED),
        run_blur,
    );
    r.register_fn(
        NodeSpec::new(
            "constant",
            "An image of one colour (RGB), plus `ramp` × x/width on every channel: test \
             patterns, backgrounds, benchmarks.",
        )
        .options::<ConstantOptions>()
        .output(CONSTANT),
        run_constant,
    );
}

fn run_exposure(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: ExposureOptions = ctx.options()?;
    let out = exposure(&ctx.get(LINEAR)?.0, o.stops as f32);
    ctx.set(EXPOSED, ImageArt(out));
    Ok(())
}

fn run_tonemap(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: TonemapOptions = ctx.options()?;
    let out = tonemap(&ctx.get(HDR)?.0, o.operator, o.exposure as f32);
    ctx.set(TONEMAPPED, ImageArt(out));
    Ok(())
}

fn run_blur(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: BlurOptions = ctx.options()?;
    let out = blur(&ctx.get(LINEAR)?.0, &o)?;
    ctx.set(BLURRED, ImageArt(out));
    Ok(())
}

fn run_constant(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: ConstantOptions = ctx.options()?;
    ctx.set(CONSTANT, ImageArt(constant(&o)?));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;
    use vfxgraph_engine::{InputValue, ParamValue, Params, Value};
    use vfxgraph_imaging::Image;

    fn run_node(
        name: &str,
        params: &[(&str, ParamValue)],
        input: Option<Image>,
        f: fn(&mut Context<'_>) -> Result<(), NodeError>,
    ) -> Image {
        let r = crate::registry();
        let spec = r.node(name).unwrap().spec().clone();
        let mut values: std::collections::BTreeMap<String, ParamValue> = spec
            .params
            .iter()
            .map(|p| (p.name.to_string(), p.default.clone().unwrap()))
            .collect();
        for (k, v) in params {
            values.insert(
                k.to_string(),
                vfxgraph_engine::param::check(&spec.param_desc(k).unwrap().kind, v.clone())
                    .unwrap(),
            );
        }
        let params = Params::new(values);
        let inputs = input
            .map(|i| vec![("image", InputValue::One(Value::new(ImageArt(i))))])
            .unwrap_or_default();
        let mut ctx = Context::for_test(&spec, &params, Path::new("."), None, inputs);
        f(&mut ctx).unwrap();
        ctx.take_output::<ImageArt>("image").unwrap().0
    }

    #[test]
    fn exposure_doubles_per_stop() {
        let img = Image::from_vec(1, 1, 3, vec![0.25, 0.5, 1.0]).unwrap();
        let out = run_node(
            "exposure",
            &[("stops", ParamValue::Int(2))],
            Some(img),
            run_exposure,
        );
        assert_eq!(out.data, vec![1.0, 2.0, 4.0]);
    }

    #[test]
    fn reinhard_maps_luminance_one_to_half() {
        let img = Image::from_vec(1, 1, 3, vec![1.0, 1.0, 1.0]).unwrap();
        let out = run_node(
            "tonemap",
            &[("operator", ParamValue::Str("reinhard".into()))],
            Some(img.clone()),
            run_tonemap,
        );
        for v in out.data {
            assert!((v - 0.5).abs() < 1e-6, "{v}");
        }
        let out = run_node(
            "tonemap",
            &[("exposure", ParamValue::Int(1))],
            Some(img),
            run_tonemap,
        );
        assert_eq!(out.data, vec![1.0, 1.0, 1.0], "srgb clips 2.0 to 1.0");
    }

    #[test]
    fn constant_has_its_colour_and_ramp() {
        let out = run_node(
            "constant",
            &[
                ("width", ParamValue::Int(4)),
                ("height", ParamValue::Int(2)),
                ("ramp", ParamValue::Float(1.0)),
            ],
            None,
            run_constant,
        );
        assert_eq!((out.width, out.height, out.channels), (4, 2, 3));
        assert!((out.get(0, 1, 0) - 0.18).abs() < 1e-6);
        assert!((out.get(2, 0, 2) - 0.68).abs() < 1e-6);
    }

    #[test]
    fn blur_streaks_a_bright_column_along_its_angle() {
        // A vertical line streaked sideways by 4 px: spread over x, each row alike.
        let img = Image::from_fn(11, 5, 3, |x, _, _| if x == 5 { 1.0 } else { 0.0 });
        let out = run_node(
            "blur",
            &[
                ("sigma", ParamValue::Int(0)),
                ("streak", ParamValue::Int(4)),
            ],
            Some(img),
            run_blur,
        );
        let row: Vec<f32> = (0..11).map(|x| out.get(x, 2, 1)).collect();
        assert!((row.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert_eq!((row[2], row[8]), (0.0, 0.0));
        // A box 4 px wide (its flat top over x 4..6), its ends softened by the sampling.
        assert!((row[4] - 0.25).abs() < 1e-6 && (row[5] - 0.25).abs() < 1e-6);
        assert!((row[3] - 0.125).abs() < 1e-6 && (row[7] - 0.125).abs() < 1e-6);
        assert!((0..5).all(|y| (out.get(4, y, 0) - row[4]).abs() < 1e-7));
    }
}
