//! # vfxgraph-nodes
//!
//! The node catalog. Each module is one family of nodes; each node is a thin adapter: it reads
//! its params and inputs from the engine's [`Context`](vfxgraph_engine::Context), calls the
//! algorithm crate, and sets its outputs. No algorithm lives here.
//!
//! [`registry`] returns every artifact and node type, for the CLI and for tests.

pub mod artifacts;
pub mod bundle;
pub mod calibration;
pub mod export;
pub mod hdr;
pub mod image_io;
pub mod image_ops;
pub mod lens;
pub mod local_scene;
pub mod matchmove;
pub mod modeling;
pub mod placement;
pub mod plate;
pub mod render;
pub mod shot;
#[cfg(test)]
mod testing;
pub mod tracking;
#[cfg(feature = "opencv")]
pub mod tracking_opencv;
pub mod video;

use vfxgraph_engine::{Context, NodeError, Registry};

/// All artifact and node types of vfxgraph.
pub fn registry() -> Registry {
    let mut r = Registry::new();
    artifacts::register(&mut r);
    calibration::register(&mut r);
    image_io::register(&mut r);
    image_ops::register(&mut r);
    lens::register(&mut r);
    tracking::register(&mut r);
    // After `tracking`, which registers the `tracks` artifact.
    bundle::register(&mut r);
    export::register(&mut r);
    matchmove::register(&mut r);
    modeling::register(&mut r);
    plate::register(&mut r);
    hdr::register(&mut r);
    render::register(&mut r);
    // After `render`, which registers the `scene` artifact.
    shot::register(&mut r);
    local_scene::register(&mut r);
    placement::register(&mut r);
    video::register(&mut r);
    #[cfg(feature = "opencv")]
    tracking_opencv::register(&mut r);
    #[cfg(not(feature = "opencv"))]
    r.register_unavailable(
        "klt_track_opencv",
        "it needs the `opencv` cargo feature, and this vfxgraph was built without opencv \
         (docs/guide/opencv.md: cargo build --features opencv)",
    );
    r
}

/// K: the `intrinsics` input, else the K the camera path `path` carries (a solve's, with its
/// lens).
pub(crate) fn intrinsics_or_path_k<'a>(
    ctx: &'a Context<'_>,
    path: Option<&'a vfxgraph_vision::formats::CameraPath>,
) -> Result<Option<&'a vfxgraph_vision::Intrinsics>, NodeError> {
    let k = ctx.input_opt::<artifacts::IntrinsicsArt>("intrinsics")?;
    Ok(k.map(|k| &k.0).or(path.and_then(|p| p.intrinsics.as_ref())))
}

/// The file of path param `param`, its folder created: for `write_image`, which refuses a
/// missing folder (the other writers create theirs).
pub(crate) fn output_path(ctx: &Context<'_>, param: &str) -> Result<std::path::PathBuf, NodeError> {
    let path = ctx.path(param);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .map_err(|e| NodeError::msg(format!("cannot create {}: {e}", parent.display())))?;
    }
    Ok(path)
}

/// Writes `bytes` atomically to the file of path param `param` (the one writer: folders
/// created, fsync), naming the file in the error.
pub(crate) fn write_output(ctx: &Context<'_>, param: &str, bytes: &[u8]) -> Result<(), NodeError> {
    let path = ctx.path(param);
    vfxgraph_engine::fsutil::atomic_write(&path, bytes)
        .map_err(|e| NodeError::msg(format!("cannot write {}: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use crate::testing::check_defaults;
    use vfxgraph_engine::ParamValue;
    use vfxgraph_imaging::{colour, hdr};
    use vfxgraph_render as render;
    use vfxgraph_video as video;
    use vfxgraph_vision::{camera_path, klt};

    /// Every node type whose params come from an options struct, and that struct: the nodes
    /// of a family are listed here when the family is converted.
    type Check = fn(&str) -> Vec<&'static str>;
    const OPTIONS: &[(&str, Check)] = &[
        (
            "matchmove",
            check_defaults::<vfxgraph_vision::matchmove::MatchmoveOptions>,
        ),
        (
            "relax",
            check_defaults::<vfxgraph_vision::matchmove::RelaxParams>,
        ),
        (
            "bundle_adjust",
            check_defaults::<vfxgraph_vision::bundle::SequenceAdjustOptions>,
        ),
        (
            "global_bundle_adjust",
            check_defaults::<vfxgraph_vision::matchmove::GlobalParams>,
        ),
        (
            "write_cameras",
            check_defaults::<vfxgraph_vision::formats::WriteCamerasOptions>,
        ),
        (
            "undistort",
            check_defaults::<vfxgraph_vision::undistort::UndistortOptions>,
        ),
        (
            "redistort",
            check_defaults::<vfxgraph_vision::undistort::UndistortOptions>,
        ),
        (
            "write_st_map",
            check_defaults::<vfxgraph_vision::st_map::StMapOptions>,
        ),
        ("read_exposure_stack", check_defaults::<hdr::StackOptions>),
        ("align_exposures", check_defaults::<hdr::AlignOptions>),
        ("hdr_calibrate", check_defaults::<hdr::CalibrateOptions>),
        ("hdr_to_ldr", check_defaults::<hdr::LdrOptions>),
        (
            "plot_response",
            check_defaults::<vfxgraph_imaging::draw::PlotOptions>,
        ),
        ("probe_to_equirect", check_defaults::<hdr::ProbeOptions>),
        ("dome", check_defaults::<vfxgraph_render::dome::DomeOptions>),
        ("render", check_defaults::<vfxgraph_render::RenderOptions>),
        (
            "fit_catcher",
            check_defaults::<render::catcher_fit::FitCatcherOptions>,
        ),
        (
            "differential_render",
            check_defaults::<render::differential::DifferentialOptions>,
        ),
        (
            "composite",
            check_defaults::<render::differential::CompositeOptions>,
        ),
        (
            "write_layers",
            check_defaults::<vfxgraph_imaging::io::LayersOptions>,
        ),
        (
            "exposure",
            check_defaults::<vfxgraph_imaging::ExposureOptions>,
        ),
        (
            "tonemap",
            check_defaults::<vfxgraph_imaging::TonemapOptions>,
        ),
        (
            "constant",
            check_defaults::<vfxgraph_imaging::ConstantOptions>,
        ),
        ("blur", check_defaults::<vfxgraph_imaging::BlurOptions>),
        (
            "place_scene",
            check_defaults::<render::placement::place::PlaceOptions>,
        ),
        (
            "catcher_from_points",
            check_defaults::<render::placement::place::CatcherOptions>,
        ),
        (
            "export_cameras",
            check_defaults::<vfxgraph_vision::export::ExportOptions>,
        ),
        ("klt_track", check_defaults::<klt::TrackerParams>),
        ("write_tracks", check_defaults::<klt::WriteTracksOptions>),
        ("draw_tracks", check_defaults::<klt::DrawTracksOptions>),
        ("read_video", check_defaults::<video::ReadVideoOptions>),
        ("write_video", check_defaults::<video::WriteVideoOptions>),
        (
            "synthetic_camera_path",
            check_defaults::<camera_path::SyntheticPathOptions>,
        ),
        (
            "project_marks",
            check_defaults::<camera_path::ProjectMarksOptions>,
        ),
        (
            "calibrate_camera",
            check_defaults::<vfxgraph_vision::calibration::CalibrateParams>,
        ),
        (
            "two_view",
            check_defaults::<vfxgraph_vision::two_view::TwoViewParams>,
        ),
        (
            "proxy_from_points",
            check_defaults::<render::proxy::ProxyOptions>,
        ),
        (
            "catcher_texture",
            check_defaults::<render::local_scene::LocalTextureOptions>,
        ),
        ("catcher_texture", check_defaults::<render::ImageSize>),
        ("read_image", check_defaults::<colour::ReadColour>),
        ("read_image_sequence", check_defaults::<colour::ReadColour>),
        ("write_image", check_defaults::<colour::WriteColour>),
        ("write_image", check_defaults::<colour::KeepPlate>),
        ("write_image_sequence", check_defaults::<colour::KeepPlate>),
        (
            "write_image_sequence",
            check_defaults::<colour::WriteColour>,
        ),
        ("read_video", check_defaults::<colour::ReadColour>),
        ("write_video", check_defaults::<colour::WriteColour>),
        ("differential_render", check_defaults::<colour::ReadColour>),
        ("composite", check_defaults::<colour::ReadColour>),
    ];

    /// Walks every node type: those with an options struct declare exactly its defaults; any
    /// other param with a default is a path left empty (no file), so no default is written
    /// outside an options struct.
    #[test]
    fn declared_defaults_are_the_options_structs_defaults() {
        let r = crate::registry();
        let mut checked = 0;
        for node in r.nodes() {
            let spec = node.spec();
            let name = spec.name;
            let mut from_struct = Vec::new();
            for (_, check) in OPTIONS.iter().filter(|(n, _)| *n == name) {
                from_struct.extend(check(name));
                checked += 1;
            }
            for p in &spec.params {
                let empty = match &p.default {
                    None => true,
                    Some(ParamValue::Str(s)) => s.is_empty(),
                    Some(ParamValue::List(l)) => l.is_empty(),
                    Some(_) => false,
                };
                assert!(
                    empty || from_struct.contains(&p.name),
                    "{name}.{}: default {:?} written outside an options struct",
                    p.name,
                    p.default
                );
            }
        }
        assert_eq!(
            checked,
            OPTIONS.len(),
            "every listed node type is registered"
        );
    }
}
