//! Image operations: `exposure`, `tonemap`, and the `constant` image generator.

use vfxgraph_engine::{
    ArtifactType, Context, NodeError, NodeSpec, ParamSpec, ParamType, ParamValue, PortSpec,
    Registry, Threads,
};
use vfxgraph_imaging::{exposure, tonemap, Image, Operator};

use crate::artifacts::ImageArt;
use crate::FnNode;

const STOPS: ParamType = ParamType::Float {
    min: -64.0,
    max: 64.0,
};

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_node(FnNode::new(
        NodeSpec::new(
            "exposure",
            "Scales linear light by 2^stops (photographic exposure, book §10.2); alpha is kept.",
        )
        .threads(Threads::One)
        .param(ParamSpec::optional(
            "stops",
            STOPS,
            ParamValue::Float(0.0),
            "exposure change in stops",
        ))
        .input(PortSpec::one("image", ImageArt::NAME, "linear image"))
        .output(PortSpec::one("image", ImageArt::NAME, "exposed image")),
        run_exposure,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "tonemap",
            "Maps linear HDR light to displayable [0, 1] linear light: `srgb` clips, \
             `reinhard` applies L/(1+L) on luminance (Reinhard et al. 2002). Write the result \
             to PNG/JPEG for the sRGB curve.",
        )
        .threads(Threads::One)
        .param(ParamSpec::optional(
            "operator",
            ParamType::Enum(&["srgb", "reinhard"]),
            ParamValue::Str("srgb".into()),
            "tone curve",
        ))
        .param(ParamSpec::optional(
            "exposure",
            STOPS,
            ParamValue::Float(0.0),
            "exposure in stops applied before the curve",
        ))
        .input(PortSpec::one("image", ImageArt::NAME, "linear HDR image"))
        .output(PortSpec::one(
            "image",
            ImageArt::NAME,
            "tone-mapped linear image",
        )),
        run_tonemap,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "constant",
            "An image of one colour (RGB), plus `ramp` × x/width on every channel: test \
             patterns, backgrounds, benchmarks.",
        )
        .param(ParamSpec::optional(
            "width",
            ParamType::Int { min: 1, max: 65536 },
            ParamValue::Int(64),
            "pixels",
        ))
        .param(ParamSpec::optional(
            "height",
            ParamType::Int { min: 1, max: 65536 },
            ParamValue::Int(64),
            "pixels",
        ))
        .param(ParamSpec::optional(
            "color",
            ParamType::FloatList { len: Some(3) },
            ParamValue::List(vec![ParamValue::Float(0.18); 3]),
            "linear RGB",
        ))
        .param(ParamSpec::optional(
            "ramp",
            ParamType::Float {
                min: -1e6,
                max: 1e6,
            },
            ParamValue::Float(0.0),
            "added × x/width",
        ))
        .output(PortSpec::one("image", ImageArt::NAME, "the image")),
        run_constant,
    ));
}

fn run_exposure(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let stops = ctx.params().f64("stops") as f32;
    let out = exposure(&ctx.input::<ImageArt>("image")?.0, stops);
    ctx.output("image", ImageArt(out));
    Ok(())
}

fn run_tonemap(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let op: Operator = ctx
        .params()
        .str("operator")
        .parse()
        .map_err(NodeError::msg)?;
    let stops = ctx.params().f64("exposure") as f32;
    let out = tonemap(&ctx.input::<ImageArt>("image")?.0, op, stops);
    ctx.output("image", ImageArt(out));
    Ok(())
}

fn run_constant(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let p = ctx.params();
    let (w, h) = (p.i64("width") as usize, p.i64("height") as usize);
    let color = p.f64s("color");
    let ramp = p.f64("ramp");
    let img = Image::try_new(w, h, 3)?;
    let img = Image::from_fn(img.width, img.height, 3, |x, _, c| {
        (color[c] + ramp * x as f64 / w as f64) as f32
    });
    ctx.output("image", ImageArt(img));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;
    use vfxgraph_engine::{InputValue, Params, Value};

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
                spec.param_spec(k).unwrap().ty.check(v.clone()).unwrap(),
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
}
