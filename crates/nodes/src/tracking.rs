//! Feature-tracking nodes (book chapter 6): `klt_track`, `read_tracks`, `write_tracks`,
//! `draw_tracks`, and the `tracks` artifact.

use vfxgraph_engine::artifact::{decode_json, encode_json};
use vfxgraph_engine::fsutil::atomic_write;
use vfxgraph_engine::{
    ArtifactType, Context, Mode, NodeError, NodeSpec, ParamSpec, ParamType, ParamValue, PathRole,
    PortSpec, Registry,
};
use vfxgraph_imaging::Image;
use vfxgraph_vision::klt::{
    track_sequence, CornerParams, GrayImage, LkParams, TrackerParams, Tracks,
};

use crate::artifacts::ImageArt;
use crate::FnNode;

/// Feature tracks over a frame sequence (`tracks`): stable ids, per-frame observations, why
/// each track ended (book chapter 6; canonical encoding: the native JSON model).
#[derive(Clone, Debug, PartialEq)]
pub struct TracksArt(pub Tracks);

impl ArtifactType for TracksArt {
    const NAME: &'static str = "tracks";
    const DOC: &'static str = "Feature tracks (book ch. 6): frame numbers, feature slots, and \
        tracks with a stable id, a slot, the first frame, one (x, y) per frame (pixel centres \
        at integers, y down) and how the track was lost.";
    fn encode(&self, out: &mut Vec<u8>) {
        encode_json(&self.0, out);
    }
    fn decode(bytes: &[u8]) -> Result<Self, String> {
        let t: Tracks = decode_json(bytes)?;
        t.validate().map_err(|e| e.to_string())?;
        Ok(TracksArt(t))
    }
}

const FORMATS: &[&str] = &["book", "native"];

/// Registers the artifact and nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_artifact::<TracksArt>();
    r.register_node(FnNode::new(
        klt_spec(
            "klt_track",
            1.0,
            "KLT feature tracking (book ch. 6): Shi–Tomasi corners in the first frame, pyramidal \
                 Lucas–Kanade frame to frame, disposal of features that leave the image, become \
                 untrackable or whose window residual exceeds `max_residual` (6.5), and refill of \
                 lost slots with new corners that keep `min_distance` from live features. Tracks \
                 luminance on a 0–255 sRGB-encoded scale. The defaults add to the book a \
                 noise-adaptive residual threshold, a forward–backward check and drift \
                 correction, so grainy footage tracks; `noise_factor: 0, fb_threshold: 0, \
                 drift_correction: 0` is the book's tracker.",
        ),
        run_klt_track,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "read_tracks",
            "Reads tracks: the book's `f.txt` format (`Features per frame = N`, `Frame i`, \
             `x y status`) or the native JSON format, recognised by content.",
        )
        .mode(Mode::Once)
        .threads(vfxgraph_engine::Threads::One)
        .memory(vfxgraph_engine::Memory::Fixed(512))
        .param(ParamSpec::required(
            "path",
            ParamType::Path(PathRole::Input),
            "the tracks file",
        ))
        .output(PortSpec::one("tracks", TracksArt::NAME, "the tracks")),
        run_read_tracks,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "write_tracks",
            "Writes tracks atomically: `book` = the book's f.txt (status 0 tracked, -1 lost; \
             slots reused), `native` = JSON with ids and loss reasons.",
        )
        .mode(Mode::Once)
        .param(ParamSpec::required(
            "path",
            ParamType::Path(PathRole::Output),
            "the file to write",
        ))
        .param(ParamSpec::optional(
            "format",
            ParamType::Enum(FORMATS),
            ParamValue::Str("book".into()),
            "book | native",
        ))
        .input(PortSpec::one("tracks", TracksArt::NAME, "the tracks")),
        run_write_tracks,
    ));
    r.register_node(FnNode::new(
        NodeSpec::new(
            "draw_tracks",
            "Draws the tracks over each frame for a person to look at: each live track's path \
             over the last `trail` frames in a colour of its own, its current position as a \
             cross, and tracks lost at this frame as red squares.",
        )
        .mode(Mode::PerFrame)
        .param(ParamSpec::optional(
            "trail",
            ParamType::Int {
                min: 0,
                max: 100_000,
            },
            ParamValue::Int(15),
            "frames of path drawn behind each feature",
        ))
        .input(PortSpec::one("frames", ImageArt::NAME, "the frame"))
        .input(PortSpec::one("tracks", TracksArt::NAME, "the tracks"))
        .output(PortSpec::one(
            "image",
            ImageArt::NAME,
            "the frame with tracks drawn (RGB)",
        )),
        run_draw_tracks,
    ));
}

/// The spec shared by `klt_track` and its OpenCV cross-check `klt_track_opencv`: the same
/// params, defaults and ports.
/// The spec of `klt_track` and of `klt_track_opencv`, which differ in their default drift
/// correction (OpenCV's tracker has none).
pub(crate) fn klt_spec(name: &'static str, drift_default: f64, doc: &'static str) -> NodeSpec {
    let pos = |min: f64, max: f64| ParamType::Float { min, max };
    NodeSpec::new(name, doc)
        .mode(Mode::Once)
        .param(ParamSpec::optional(
            "features",
            ParamType::Int {
                min: 0,
                max: 100_000,
            },
            ParamValue::Int(0),
            "feature slots per frame (the book's N: 150); 0 = from the frame size, one per \
             36 × 36 px block and at least 150 (400 at 960 × 540)",
        ))
        .param(ParamSpec::optional(
            "min_distance",
            pos(0.0, 10_000.0),
            ParamValue::Float(10.0),
            "minimum distance between features, pixels",
        ))
        .param(ParamSpec::optional(
            "quality",
            pos(0.0, 1.0),
            ParamValue::Float(1e-5),
            "corner score threshold relative to the best corner (OpenCV qualityLevel)",
        ))
        .param(ParamSpec::optional(
            "window",
            ParamType::Int { min: 3, max: 255 },
            ParamValue::Int(21),
            "LK window side, pixels (odd)",
        ))
        .param(ParamSpec::optional(
            "levels",
            ParamType::Int { min: 0, max: 12 },
            ParamValue::Int(3),
            "pyramid levels above the image",
        ))
        .param(ParamSpec::optional(
            "iterations",
            ParamType::Int { min: 1, max: 1000 },
            ParamValue::Int(30),
            "maximum LK iterations per level",
        ))
        .param(ParamSpec::optional(
            "epsilon",
            pos(0.0, 10.0),
            ParamValue::Float(0.01),
            "LK stops when a step is shorter than this, pixels",
        ))
        .param(ParamSpec::optional(
            "max_residual",
            pos(0.0, 1e9),
            ParamValue::Float(12.0),
            "a feature whose window RMS residual (0–255 gray levels) exceeds this is lost",
        ))
        .param(ParamSpec::optional(
            "noise_factor",
            pos(0.0, 1e6),
            ParamValue::Float(3.0),
            "…or this many times the frame pair's measured noise √(σa² + σb²) when larger \
             (grainy footage); 0 = max_residual only (the book)",
        ))
        .param(ParamSpec::optional(
            "fb_threshold",
            pos(0.0, 1e9),
            ParamValue::Float(1.0),
            "forward–backward check: lost if tracking back misses the start by more than \
             this many pixels; 0 = off",
        ))
        .param(ParamSpec::optional(
            "replace_lost",
            ParamType::Bool,
            ParamValue::Bool(true),
            "refill lost slots with new corners (book 6.5)",
        ))
        .param(ParamSpec::optional(
            "border",
            pos(0.0, 10_000.0),
            ParamValue::Float(10.0),
            "no corners closer than this to the edge; features closer are lost",
        ))
        .param(ParamSpec::optional(
            "drift_correction",
            pos(0.0, 1e3),
            ParamValue::Float(drift_default),
            "re-align each step to the feature's first window and keep that position when it \
             moves less than this many pixels (no drift along long tracks); 0 = off, the \
             book's frame-to-frame tracker",
        ))
        .input(PortSpec::sequence(
            "frames",
            ImageArt::NAME,
            "the frames, in order",
        ))
        .output(PortSpec::one("tracks", TracksArt::NAME, "the tracks"))
}

pub(crate) fn tracker_params(ctx: &Context<'_>) -> TrackerParams {
    let p = ctx.params();
    let window = p.i64("window") as usize;
    let fb = p.f64("fb_threshold") as f32;
    TrackerParams {
        corners: CornerParams {
            max_corners: p.i64("features") as usize,
            quality: p.f64("quality") as f32,
            min_distance: p.f64("min_distance") as f32,
            block_size: 3,
        },
        lk: LkParams {
            window,
            levels: p.i64("levels") as usize,
            max_iterations: p.i64("iterations") as u32,
            epsilon: p.f64("epsilon") as f32,
            ..LkParams::default()
        },
        max_residual: p.f64("max_residual") as f32,
        noise_factor: p.f64("noise_factor") as f32,
        fb_threshold: (fb > 0.0).then_some(fb),
        replace_lost: p.bool("replace_lost"),
        border: p.f64("border") as f32,
        drift_correction: Some(p.f64("drift_correction") as f32).filter(|&d| d > 0.0),
    }
}

pub(crate) fn run_klt_track(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let params = tracker_params(ctx);
    let frames = ctx.sequence::<ImageArt>("frames")?;
    let grays: Vec<(i64, GrayImage)> = frames
        .iter()
        .map(|(f, img)| (*f, GrayImage::from_image(&img.0)))
        .collect();
    let refs: Vec<(i64, &GrayImage)> = grays.iter().map(|(f, g)| (*f, g)).collect();
    let tracks = track_sequence(&refs, &params, |x| ctx.progress(x))
        .map_err(|e| NodeError::msg(format!("klt_track: {e}")))?;
    ctx.output("tracks", TracksArt(tracks));
    Ok(())
}

fn run_read_tracks(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let path = ctx.path("path");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| NodeError::msg(format!("cannot read {}: {e}", path.display())))?;
    let tracks =
        Tracks::parse(&text).map_err(|e| NodeError::msg(format!("{}: {e}", path.display())))?;
    ctx.output("tracks", TracksArt(tracks));
    Ok(())
}

fn run_write_tracks(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let tracks = &ctx.input::<TracksArt>("tracks")?.0;
    let text = match ctx.params().str("format") {
        "native" => tracks.to_native(),
        _ => tracks.to_book(),
    };
    let path = ctx.path("path");
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .map_err(|e| NodeError::msg(format!("cannot create {}: {e}", parent.display())))?;
    }
    atomic_write(&path, text.as_bytes())
        .map_err(|e| NodeError::msg(format!("cannot write {}: {e}", path.display())))?;
    Ok(())
}

/// A bright, fully saturated colour (linear RGB) from a track id.
fn id_colour(id: u64) -> [f32; 3] {
    let h = (id.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as f32 / (1u64 << 24) as f32;
    let h6 = h * 6.0;
    let x = 1.0 - (h6 % 2.0 - 1.0).abs();
    let (r, g, b) = match h6 as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    [r, g, b]
}

fn plot(img: &mut Image, x: i64, y: i64, c: [f32; 3]) {
    if x >= 0 && y >= 0 && (x as usize) < img.width && (y as usize) < img.height {
        img.pixel_mut(x as usize, y as usize)[..3].copy_from_slice(&c);
    }
}

fn line(img: &mut Image, a: [f64; 2], b: [f64; 2], c: [f32; 3]) {
    let n = ((b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil() as i64).clamp(1, 100_000);
    for k in 0..=n {
        let t = k as f64 / n as f64;
        let x = a[0] + (b[0] - a[0]) * t;
        let y = a[1] + (b[1] - a[1]) * t;
        plot(img, x.round() as i64, y.round() as i64, c);
    }
}

fn run_draw_tracks(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let trail = ctx.params().i64("trail").max(0) as usize;
    let frame = ctx.frame().unwrap_or(0);
    let mut img = ctx.input::<ImageArt>("frames")?.0.to_rgb();
    let tracks = &ctx.input::<TracksArt>("tracks")?.0;
    if let Some(fi) = tracks.frames.iter().position(|&f| f == frame) {
        for t in &tracks.tracks {
            if let Some(p) = t.at(fi) {
                let c = id_colour(t.id);
                let from = fi.saturating_sub(trail).max(t.first);
                for g in from..fi {
                    if let (Some(a), Some(b)) = (t.at(g), t.at(g + 1)) {
                        line(&mut img, a, b, c);
                    }
                }
                let (x, y) = (p[0].round() as i64, p[1].round() as i64);
                for d in -3..=3 {
                    plot(&mut img, x + d, y, c);
                    plot(&mut img, x, y + d, c);
                }
            }
            if let Some(l) = t.lost.filter(|l| l.frame == fi) {
                let (x, y) = (l.at[0].round() as i64, l.at[1].round() as i64);
                for d in -3..=3 {
                    for (dx, dy) in [(d, -3), (d, 3), (-3, d), (3, d)] {
                        plot(&mut img, x + dx, y + dy, [1.0, 0.0, 0.0]);
                    }
                }
            }
        }
    }
    ctx.output("image", ImageArt(img));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use vfxgraph_engine::{InputValue, Value};

    /// A textured frame whose content moves by (1.5, 0.75) px per frame.
    fn frame(k: usize) -> Image {
        let (dx, dy) = (1.5 * k as f32, 0.75 * k as f32);
        Image::from_fn(160, 120, 3, |x, y, _| {
            let (x, y) = (x as f32 + dx, y as f32 + dy);
            0.3 + 0.2 * (x * 0.21).sin() * (y * 0.17).cos() + 0.15 * ((x - 1.3 * y) * 0.09).sin()
        })
    }

    #[test]
    fn track_write_read_draw() {
        let dir = tempfile::tempdir().unwrap();
        let ks = spec("klt_track");
        let kp = params(&ks, &[("features", ParamValue::Int(40))]);
        let seq: Vec<(i64, Value)> = (0..4)
            .map(|k| (10 + k as i64, Value::new(ImageArt(frame(k)))))
            .collect();
        let mut ctx = Context::for_test(
            &ks,
            &kp,
            dir.path(),
            None,
            vec![("frames", InputValue::Sequence(seq))],
        );
        run_klt_track(&mut ctx).unwrap();
        let tracks = ctx.take_output::<TracksArt>("tracks").unwrap();
        assert_eq!(tracks.0.frames, vec![10, 11, 12, 13]);
        assert!(tracks.0.tracks.len() >= 20);
        // The content moves by (-1.5, -0.75) per frame (the image samples x + dx).
        for t in &tracks.0.tracks {
            for w in t.points.windows(2) {
                assert!((w[1][0] - w[0][0] + 1.5).abs() < 0.1, "{t:?}");
                assert!((w[1][1] - w[0][1] + 0.75).abs() < 0.1, "{t:?}");
            }
        }
        // Artifact round trip.
        let mut bytes = Vec::new();
        tracks.encode(&mut bytes);
        assert_eq!(TracksArt::decode(&bytes).unwrap(), tracks);
        assert!(TracksArt::decode(b"{}").is_err());
        // Write both formats and read them back.
        for fmt in ["book", "native"] {
            let ws = spec("write_tracks");
            let wp = params(
                &ws,
                &[
                    ("path", ParamValue::Str(format!("out/t.{fmt}"))),
                    ("format", ParamValue::Str(fmt.into())),
                ],
            );
            let mut ctx = Context::for_test(
                &ws,
                &wp,
                dir.path(),
                None,
                vec![("tracks", InputValue::One(Value::new(tracks.clone())))],
            );
            run_write_tracks(&mut ctx).unwrap();
            let rs = spec("read_tracks");
            let rp = params(&rs, &[("path", ParamValue::Str(format!("out/t.{fmt}")))]);
            let mut ctx = Context::for_test(&rs, &rp, dir.path(), None, vec![]);
            run_read_tracks(&mut ctx).unwrap();
            let back = ctx.take_output::<TracksArt>("tracks").unwrap();
            if fmt == "native" {
                assert_eq!(back, tracks);
            } else {
                // The book's format keeps every tracked observation (a refill found in the
                // frame its slot was lost shows one frame later, see `Tracks`).
                let tracked = |t: &Tracks| -> Vec<String> {
                    t.to_book()
                        .lines()
                        .map(|l| {
                            if l.ends_with(" -1") {
                                "lost".into()
                            } else {
                                l.into()
                            }
                        })
                        .collect()
                };
                assert_eq!(tracked(&back.0), tracked(&tracks.0));
            }
        }
        // Draw frame 12: coloured pixels appear where features are.
        let ds = spec("draw_tracks");
        let dp = params(&ds, &[]);
        let mut ctx = Context::for_test(
            &ds,
            &dp,
            dir.path(),
            Some(12),
            vec![
                ("frames", InputValue::One(Value::new(ImageArt(frame(2))))),
                ("tracks", InputValue::One(Value::new(tracks.clone()))),
            ],
        );
        run_draw_tracks(&mut ctx).unwrap();
        let img = ctx.take_output::<ImageArt>("image").unwrap().0;
        assert_eq!((img.width, img.height, img.channels), (160, 120, 3));
        let p = tracks.0.tracks[0].at(2).unwrap();
        let px = img.pixel(p[0].round() as usize, p[1].round() as usize);
        assert_eq!(&px[..3], &id_colour(tracks.0.tracks[0].id));
    }

    #[test]
    fn errors_are_reported_not_panics() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("bad.txt"),
            "Features per frame = 2\nFrame 0\n1 2 0\n",
        )
        .unwrap();
        let rs = spec("read_tracks");
        for name in ["missing.txt", "bad.txt"] {
            let rp = params(&rs, &[("path", ParamValue::Str(name.into()))]);
            let mut ctx = Context::for_test(&rs, &rp, dir.path(), None, vec![]);
            let e = run_read_tracks(&mut ctx).unwrap_err();
            assert!(e.message.contains(name), "{e}");
        }
        // Frames of different sizes.
        let ks = spec("klt_track");
        let kp = params(&ks, &[]);
        let seq = vec![
            (0, Value::new(ImageArt(frame(0)))),
            (1, Value::new(ImageArt(Image::new(10, 10, 3)))),
        ];
        let mut ctx = Context::for_test(
            &ks,
            &kp,
            dir.path(),
            None,
            vec![("frames", InputValue::Sequence(seq))],
        );
        assert!(run_klt_track(&mut ctx)
            .unwrap_err()
            .message
            .contains("size"));
    }
}
