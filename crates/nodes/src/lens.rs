//! Lens nodes: `undistort`, `redistort` (plates through the lens model, with overscan) and
//! `write_st_map` (the same warps as Nuke ST-maps). The algorithms and their options live in
//! `vfxgraph_geometry::undistort` and `vfxgraph_geometry::st_map`.

use vfxgraph_engine::{Context, In, Mode, NodeError, NodeSpec, OptIn, Out, Registry, Threads};
use vfxgraph_geometry::st_map::{st_map, StMapOptions};
use vfxgraph_geometry::undistort::{LensWarp, UndistortOptions};
use vfxgraph_imaging::io::write_image;

use crate::artifacts::{CameraPathArt, ImageArt, IntrinsicsArt};

/// The lens warp of node `node`: K with its lens from the `intrinsics` input, else from the
/// `cameras` path (a solve's).
fn warp_of(ctx: &Context<'_>, node: &str, o: &UndistortOptions) -> Result<LensWarp, NodeError> {
    let path = ctx.get(CAMERAS)?.map(|p| &p.0);
    let k = crate::intrinsics_or_path_k(ctx, INTRINSICS, path)?.ok_or_else(|| match path {
        Some(_) => format!("{node}: the `cameras` path carries no K (connect `intrinsics`)"),
        None => format!(
            "{node}: no lens: connect `intrinsics` (K with its lens and image size) or a solved \
             `cameras` path"
        ),
    });
    let k = k.map_err(NodeError::msg)?;
    LensWarp::new(k, o).map_err(|e| NodeError::msg(format!("{node}: {e}")))
}

/// `undistort` or `redistort` (`node`): the image of input `image` through the lens warp, to
/// output `out`; `undistort` also outputs K′.
fn run_warp(
    ctx: &mut Context<'_>,
    node: &str,
    image: In<ImageArt>,
    out: Out<ImageArt>,
) -> Result<(), NodeError> {
    let o: UndistortOptions = ctx.options()?;
    let warp = warp_of(ctx, node, &o)?;
    let img = &ctx.get(image)?.0;
    let undistort = node == "undistort";
    let warped = if undistort {
        warp.undistort(img)
    } else {
        warp.redistort(img)
    };
    let warped = warped.map_err(|e| NodeError::msg(format!("{node}: {e}")))?;
    ctx.set(out, ImageArt(warped));
    if undistort {
        ctx.set(INTRINSICS_OUT, IntrinsicsArt(warp.pinhole.clone()));
    }
    Ok(())
}

fn run_undistort(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    run_warp(ctx, "undistort", PLATE, UNDISTORTED)
}

fn run_redistort(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    run_warp(ctx, "redistort", UNDISTORTED_IN, REDISTORTED)
}

fn run_write_st_map(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: StMapOptions = ctx.options()?;
    let path = crate::output_path(ctx, "path")?;
    if !path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
    {
        return Err(NodeError::msg(format!(
            "write_st_map: {}: an ST-map is a float EXR (use a .exr path)",
            path.display()
        )));
    }
    let warp = warp_of(ctx, "write_st_map", &o.framing)?;
    Ok(write_image(&path, &st_map(&warp, o.direction))?)
}

fn lens_ports(spec: NodeSpec) -> NodeSpec {
    spec.input(INTRINSICS).input(CAMERAS)
}

/// `undistort` or `redistort`: the lens ports, the image in and out, their options.
fn warp_node(
    name: &'static str,
    doc: &'static str,
    image: In<ImageArt>,
    out: Out<ImageArt>,
) -> NodeSpec {
    lens_ports(NodeSpec::new(name, doc).input(image))
        .output(out)
        .options::<UndistortOptions>()
}

const INTRINSICS: OptIn<IntrinsicsArt> = OptIn::new(
    "intrinsics",
    "the plate's K with its lens (`distortion`) and image size",
);
const CAMERAS: OptIn<CameraPathArt> = OptIn::new(
    "cameras",
    "a solved camera path whose K carries the lens (when `intrinsics` is not connected)",
);
const PLATE: In<ImageArt> = In::new("image", "the plate (the lens's size)");
const UNDISTORTED: Out<ImageArt> = Out::new("image", "the undistorted image");
const UNDISTORTED_IN: In<ImageArt> = In::new("image", "the undistorted image (K′'s size)");
const REDISTORTED: Out<ImageArt> = Out::new("image", "the image through the lens");
const INTRINSICS_OUT: Out<IntrinsicsArt> = Out::new(
    "intrinsics",
    "K′ of the undistorted image: the same focal lengths, no lens, its size",
);

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        warp_node(
            "undistort",
            "The plate as an ideal pinhole with the same focal length sees it: each output \
             pixel x′ samples the plate (bilinear) at K·distort(K′⁻¹x′). With overscan the \
             output is as large as the plate's undistorted footprint, so nothing is lost; \
             `intrinsics` out is K′ (no lens) with that size.",
            PLATE,
            UNDISTORTED,
        )
        .output(INTRINSICS_OUT),
        run_undistort,
    );
    r.register_fn(
        warp_node(
            "redistort",
            "An undistorted image (a pinhole render with `undistort`'s K′, same framing \
             options) seen through the lens again: each plate pixel x samples it at \
             K′·undistort(K⁻¹x). The inverse of `undistort`.",
            UNDISTORTED_IN,
            REDISTORTED,
        ),
        run_redistort,
    );
    r.register_fn(
        lens_ports(
            NodeSpec::new(
                "write_st_map",
                "Writes the lens warp as a Nuke ST-map: a float EXR whose red/green hold, per \
                 output pixel, the source position normalized 0–1, origin bottom-left (−1 where \
                 there is none). `undistort`: sized as the undistorted image, sampling the \
                 plate; `redistort`: sized as the plate, sampling the undistorted image. The \
                 write is atomic.",
            )
            .mode(Mode::Once)
            .threads(Threads::One)
            .output_file_param("path", "output .exr file"),
        )
        .options::<StMapOptions>(),
        run_write_st_map,
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use vfxgraph_engine::{InputValue, ParamValue, Value};
    use vfxgraph_geometry::lens::Distortion;
    use vfxgraph_geometry::Intrinsics;
    use vfxgraph_imaging::Image;

    fn lens() -> Intrinsics {
        Intrinsics::new(92.0, 92.0, 47.5, 26.5)
            .with_size(96, 54)
            .with_distortion(Distortion::BrownConrady {
                k1: -0.16,
                k2: 0.045,
                k3: 0.0,
                p1: 0.0008,
                p2: -0.0005,
            })
    }

    /// The nodes wire to the algorithm: undistort's output is larger with K′, redistort of it
    /// has the plate's size, write_st_map writes the map the algorithm computes; a missing lens
    /// is an error naming the node.
    #[test]
    fn nodes_run_the_warps() {
        let plate = Image::from_fn(96, 54, 3, |x, y, c| (x + 2 * y + c) as f32 / 200.0);
        let sp = spec("undistort");
        let ps = params(&sp, &[]);
        let dir = tempfile::tempdir().unwrap();
        let inputs = || {
            vec![
                (
                    "image",
                    InputValue::One(Value::new(ImageArt(plate.clone()))),
                ),
                (
                    "intrinsics",
                    InputValue::One(Value::new(IntrinsicsArt(lens()))),
                ),
            ]
        };
        let mut ctx = Context::for_test(&sp, &ps, dir.path(), None, inputs());
        run_undistort(&mut ctx).unwrap();
        let und = ctx.take_output::<ImageArt>("image").unwrap().0;
        let k2 = ctx.take_output::<IntrinsicsArt>("intrinsics").unwrap().0;
        let warp = LensWarp::new(&lens(), &UndistortOptions::default()).unwrap();
        assert_eq!(k2, warp.pinhole);
        assert_eq!(und, warp.undistort(&plate).unwrap());
        assert!(und.width > 96 && und.height > 54);

        let sp = spec("redistort");
        let ps = params(&sp, &[]);
        let mut ctx = Context::for_test(
            &sp,
            &ps,
            dir.path(),
            None,
            vec![
                ("image", InputValue::One(Value::new(ImageArt(und.clone())))),
                (
                    "intrinsics",
                    InputValue::One(Value::new(IntrinsicsArt(lens()))),
                ),
            ],
        );
        run_redistort(&mut ctx).unwrap();
        let back = ctx.take_output::<ImageArt>("image").unwrap().0;
        assert_eq!((back.width, back.height), (96, 54));

        let sp = spec("write_st_map");
        let ps = params(
            &sp,
            &[
                ("path", ParamValue::Str("map.exr".into())),
                ("direction", ParamValue::Str("redistort".into())),
            ],
        );
        let mut ctx = Context::for_test(
            &sp,
            &ps,
            dir.path(),
            None,
            vec![(
                "intrinsics",
                InputValue::One(Value::new(IntrinsicsArt(lens()))),
            )],
        );
        run_write_st_map(&mut ctx).unwrap();
        let map = vfxgraph_imaging::io::read_image(&dir.path().join("map.exr")).unwrap();
        assert_eq!(
            map,
            st_map(&warp, vfxgraph_geometry::st_map::StMapDirection::Redistort)
        );

        let sp = spec("undistort");
        let ps = params(&sp, &[]);
        let mut ctx = Context::for_test(
            &sp,
            &ps,
            dir.path(),
            None,
            vec![(
                "image",
                InputValue::One(Value::new(ImageArt(plate.clone()))),
            )],
        );
        let e = run_undistort(&mut ctx).unwrap_err().to_string();
        assert!(e.contains("undistort: no lens"), "{e}");
    }
}
