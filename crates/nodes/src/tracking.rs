//! Feature-tracking nodes (book chapter 6): `klt_track`, `read_tracks`, `write_tracks`,
//! `draw_tracks`, and the `tracks` artifact.

use vfxgraph_engine::stream::Stream;
use vfxgraph_engine::{Context, In, Mode, NodeError, NodeSpec, Out, Registry, StreamIn};
use vfxgraph_klt::{
    draw_tracks, track_loaded, DrawTracksOptions, GrayImage, TrackerOptions, Tracks,
    WriteTracksOptions,
};

use crate::artifacts::{json_artifact, ImageArt};

json_artifact! {
    /// Feature tracks over a frame sequence (`tracks`): stable ids, per-frame observations, why
    /// each track ended (book chapter 6; canonical encoding: the native JSON model).
    TracksArt(Tracks), "tracks",
    "Feature tracks (book ch. 6): frame numbers, feature slots, and tracks with a stable id, a \
     slot, the first frame, one (x, y) per frame (pixel centres at integers, y down) and how the \
     track was lost.",
    check = Tracks::validate;
}

/// The trackers' frames.
pub(crate) const FRAMES: StreamIn<ImageArt> = StreamIn::new("frames", "the frames, in order");
/// The trackers' and `read_tracks`' tracks.
pub(crate) const TRACKS_OUT: Out<TracksArt> = Out::new("tracks", "the tracks");
const TRACKS: In<TracksArt> = In::new("tracks", "the tracks");
const FRAME: In<ImageArt> = In::new("frames", "the frame");
const DRAWN: Out<ImageArt> = Out::new("image", "the frame with tracks drawn (RGB)");

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        klt_spec(
            "klt_track",
            &TrackerOptions::default(),
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
    );
    r.register_fn(
        NodeSpec::new(
            "read_tracks",
            "Reads tracks: the book's `f.txt` format (`Features per frame = N`, `Frame i`, \
             `x y status`) or the native JSON format, recognised by content.",
        )
        .mode(Mode::Once)
        .threads(vfxgraph_engine::Threads::One)
        .memory(vfxgraph_engine::Memory::Fixed(512))
        .input_file_param("path", "the tracks file")
        .output(TRACKS_OUT),
        run_read_tracks,
    );
    r.register_fn(
        NodeSpec::new(
            "write_tracks",
            "Writes tracks atomically: `book` = the book's f.txt (status 0 tracked, -1 lost; \
             slots reused), `native` = JSON with ids and loss reasons.",
        )
        .mode(Mode::Once)
        .output_file_param("path", "the file to write")
        .options::<WriteTracksOptions>()
        .input(TRACKS),
        run_write_tracks,
    );
    r.register_fn(
        NodeSpec::new(
            "draw_tracks",
            "Draws the tracks over each frame for a person to look at: each live track's path \
             over the last `trail` frames in a colour of its own, its current position as a \
             cross, and tracks lost at this frame as red squares.",
        )
        .mode(Mode::PerFrame)
        .options::<DrawTracksOptions>()
        .input(FRAME)
        .input(TRACKS)
        .output(DRAWN),
        run_draw_tracks,
    );
}

/// The spec of `klt_track` and of its OpenCV cross-check `klt_track_opencv`: the params of
/// [`TrackerOptions`] with `defaults`' values (they differ in the default drift correction:
/// OpenCV's tracker has none), the same ports.
pub(crate) fn klt_spec(
    name: &'static str,
    defaults: &TrackerOptions,
    doc: &'static str,
) -> NodeSpec {
    NodeSpec::new(name, doc)
        .mode(Mode::Once)
        .options_from(defaults)
        .input(FRAMES)
        .output(TRACKS_OUT)
}

/// The frames of input `frames` as gray images (the trackers' input), read in parallel.
#[cfg(feature = "opencv")]
pub(crate) fn gray_frames(ctx: &Context<'_>) -> Result<Vec<(i64, GrayImage)>, NodeError> {
    use rayon::prelude::*;
    let frames = ctx.get(FRAMES)?;
    (0..frames.len())
        .into_par_iter()
        .map(|k| gray_frame(&frames, k))
        .collect()
}

/// Frame `k` of a stream as a gray image.
fn gray_frame(frames: &Stream<'_, ImageArt>, k: usize) -> Result<(i64, GrayImage), NodeError> {
    Ok((frames.frame(k), GrayImage::from_image(&frames.get(k)?.0)))
}

/// Tracks the plate a frame at a time: each frame is read (an uncached reader decodes it)
/// while the one before is tracked.
pub(crate) fn run_klt_track(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let params: TrackerOptions = ctx.options()?;
    let tracks = {
        let frames = ctx.get(FRAMES)?;
        let load = |k| gray_frame(&frames, k);
        track_loaded(frames.len(), load, &params, |x| ctx.progress(x))?
    };
    ctx.set(TRACKS_OUT, TracksArt(tracks));
    Ok(())
}

fn run_read_tracks(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let path = ctx.path("path");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| NodeError::msg(format!("cannot read {}: {e}", path.display())))?;
    let tracks =
        Tracks::parse(&text).map_err(|e| NodeError::msg(format!("{}: {e}", path.display())))?;
    ctx.set(TRACKS_OUT, TracksArt(tracks));
    Ok(())
}

fn run_write_tracks(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: WriteTracksOptions = ctx.options()?;
    let text = o.format.text(&ctx.get(TRACKS)?.0);
    crate::write_output(ctx, "path", text.as_bytes())
}

fn run_draw_tracks(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: DrawTracksOptions = ctx.options()?;
    let img = &ctx.get(FRAME)?.0;
    let tracks = &ctx.get(TRACKS)?.0;
    let drawn = draw_tracks(img, tracks, ctx.frame().unwrap_or(0), &o);
    ctx.set(DRAWN, ImageArt(drawn));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use vfxgraph_engine::{ArtifactType, InputValue, ParamValue, Value};
    use vfxgraph_imaging::draw::id_colour;
    use vfxgraph_imaging::Image;

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
