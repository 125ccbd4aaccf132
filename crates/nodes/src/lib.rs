//! # vfxgraph-nodes
//!
//! The node catalog. Each module is one family of nodes; each node is a thin adapter: it reads
//! its params and inputs from the engine's [`Context`](vfxgraph_engine::Context), calls the
//! algorithm crate, and sets its outputs. No algorithm lives here.
//!
//! [`registry`] returns every artifact and node type, for the CLI and for tests: a node's
//! typed ports register their artifact types with it, so the families register in any order.

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

use vfxgraph_engine::{Context, NodeError, OptIn, Registry};

/// All artifact and node types of vfxgraph.
pub fn registry() -> Registry {
    let mut r = Registry::new();
    bundle::register(&mut r);
    calibration::register(&mut r);
    export::register(&mut r);
    hdr::register(&mut r);
    image_io::register(&mut r);
    image_ops::register(&mut r);
    lens::register(&mut r);
    local_scene::register(&mut r);
    matchmove::register(&mut r);
    modeling::register(&mut r);
    placement::register(&mut r);
    plate::register(&mut r);
    render::register(&mut r);
    shot::register(&mut r);
    tracking::register(&mut r);
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

/// K: input `port` (a node's `intrinsics`), else the K the camera path `path` carries (a
/// solve's, with its lens).
pub(crate) fn intrinsics_or_path_k<'a>(
    ctx: &'a Context<'_>,
    port: OptIn<artifacts::IntrinsicsArt>,
    path: Option<&'a vfxgraph_geometry::formats::CameraPath>,
) -> Result<Option<&'a vfxgraph_geometry::Intrinsics>, NodeError> {
    let k = ctx.get(port)?;
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
    use std::collections::BTreeMap;

    use vfxgraph_engine::{param, Kind, ParamValue, Params};

    /// A value of `kind` for a required param, so that a node's options structs read back
    /// without a graph.
    fn sample(kind: &Kind) -> ParamValue {
        match kind {
            Kind::Bool => ParamValue::Bool(false),
            Kind::Int { min, max } => ParamValue::Int(0.clamp(*min, *max)),
            Kind::Float { min, max } => ParamValue::Float(0.0_f64.clamp(*min, *max)),
            Kind::Str | Kind::Path(_) => ParamValue::Str(String::new()),
            Kind::Enum(choices) => ParamValue::Str(choices[0].to_string()),
            Kind::PathList(_) => ParamValue::List(Vec::new()),
            Kind::FloatList { len } => {
                ParamValue::List(vec![ParamValue::Float(0.0); len.unwrap_or(0)])
            }
        }
    }

    /// Walks every node type of the registry: each param comes from one of the node's options
    /// structs (but the file a file param names, which has no default), each declared default
    /// fits its param, and the declared defaults read back into each struct and describe it
    /// again unchanged (same kind, default, doc, cache role), so no default is written
    /// anywhere but a struct's `Default`.
    #[test]
    fn declared_defaults_are_the_options_structs_defaults() {
        let r = crate::registry();
        let mut structs = 0;
        for node in r.nodes() {
            let spec = node.spec();
            let name = spec.name;
            let mut values = BTreeMap::new();
            for p in &spec.params {
                let from_struct = spec.options.iter().any(|o| o.params.contains(&p.name));
                let file = p.default.is_none() && matches!(p.kind, Kind::Path(_));
                assert!(
                    from_struct || file,
                    "{name}.{}: declared outside an options struct",
                    p.name
                );
                if let Some(d) = &p.default {
                    assert_eq!(
                        param::check(&p.kind, d.clone()).as_ref(),
                        Ok(d),
                        "{name}.{}: the default does not fit",
                        p.name
                    );
                }
                let v = p.default.clone().unwrap_or_else(|| sample(&p.kind));
                values.insert(p.name.to_string(), v);
            }
            let declared = Params::new(values);
            for o in &spec.options {
                structs += 1;
                let again = (o.read_back)(&declared)
                    .unwrap_or_else(|e| panic!("{name} ({}): {e}", o.type_name));
                let names: Vec<&str> = again.iter().map(|d| d.name).collect();
                assert_eq!(names, o.params, "{name} ({})", o.type_name);
                for d in &again {
                    let p = spec.param_desc(d.name).expect("declared");
                    let at = format!("{name}.{} ({})", d.name, o.type_name);
                    assert_eq!(p.kind, d.kind, "{at}");
                    assert_eq!(p.doc, d.doc, "{at}");
                    assert_eq!(p.cosmetic, d.cosmetic, "{at}");
                    match &p.default {
                        Some(_) => assert_eq!(p.default, d.default, "{at}: read back"),
                        None => assert_eq!(d.default, None, "{at}: required"),
                    }
                }
            }
        }
        assert!(
            structs > 50,
            "only {structs} options structs in the registry"
        );
    }
}
