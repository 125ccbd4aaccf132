//! Video file nodes: `read_video` reads what phones and cameras write (the book's chapter 6
//! tracks such footage) frame by frame, through `vfxgraph-video`: H.264 MP4 by the bundled
//! OpenH264 reader (no system library), everything else — B-frames, HEVC, ProRes, DNxHR, VP9,
//! AV1, MJPEG, in MP4, MOV, MKV, MXF — through the system's FFmpeg executables; with `backend:
//! opencv` (a build with the `opencv` cargo feature) any file OpenCV's VideoCapture opens.

use vfxgraph_engine::{Context, Mode, NodeError, NodeSpec, Out, Registry, SeqIn, Threads};
use vfxgraph_imaging::colour::{ReadColour, WorkingSpace, WriteColour};
use vfxgraph_imaging::{Image, Operator};
use vfxgraph_video::{open_shared, write_video, ReadVideoOptions, WriteVideoOptions};

use crate::artifacts::ImageArt;

const FRAME: Out<ImageArt> = Out::new("sequence", "the frame's image");
const FRAMES: SeqIn<ImageArt> = SeqIn::new("sequence", "the frames, in order");

/// Registers the nodes of this module.
pub fn register(r: &mut Registry) {
    r.register_fn(
        NodeSpec::new(
            "read_video",
            "Reads frame f of the graph's range from a video file (frame 0 is the first \
             picture shown; frames in presentation order) as a linear-light RGB image: Y'CbCr \
             (8–16 bits, 4:2:0, 4:2:2, 4:4:4) converted with the matrix and range the stream \
             declares (BT.709 for HD, BT.601 below, when it does not), decoded with the sRGB \
             curve as PNG frames are (with `colour_space`, those code values converted from \
             that OpenColorIO colour space to the working space instead); a phone's rotation \
             applied. H.264 MP4 by the bundled \
             reader, every other codec through FFmpeg (`ffmpeg` on the PATH or \
             $VFXGRAPH_FFMPEG).",
        )
        .mode(Mode::PerFrame)
        .input_file_param("path", "the video file, relative to the graph file")
        .options::<ReadVideoOptions>()
        .options::<ReadColour>()
        .output(FRAME),
        run_read_video,
    );
    r.register_fn(
        NodeSpec::new(
            "write_video",
            "Writes the frames of a sequence, in frame order, as an H.264 .mp4 a person can \
             play (OpenH264 encoder, bundled; Y'CbCr 4:2:0, limited range, BT.709 declared \
             in the stream). The input is linear light: it is tone-mapped (`tonemap`: clip \
             as a PNG is, or Reinhard for HDR) and sRGB-encoded — or, with `view`, put \
             through that OpenColorIO display/view transform (a preview; `tonemap: srgb`). Frames must be one even \
             size. The write is atomic.",
        )
        .threads(Threads::One)
        .mode(Mode::Once)
        .output_file_param("path", "the .mp4 file, relative to the graph file")
        .options::<WriteVideoOptions>()
        .options::<WriteColour>()
        .input(FRAMES),
        run_write_video,
    );
}

fn run_read_video(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: ReadVideoOptions = ctx.options()?;
    let video = open_shared(&ctx.path("path"), o.backend)?;
    let mut img = video.frame(ctx.frame().unwrap_or(0))?;
    let colour: ReadColour = ctx.options()?;
    let config = crate::image_io::ocio_config(ctx);
    let path = ctx.path("path");
    colour.convert_decoded(&mut img, config.as_deref(), &path.display().to_string())?;
    ctx.set(FRAME, ImageArt(img));
    Ok(())
}

fn run_write_video(ctx: &mut Context<'_>) -> Result<(), NodeError> {
    let o: WriteVideoOptions = ctx.options()?;
    let colour: WriteColour = ctx.options()?;
    let path = ctx.path("path");
    let managed = !colour.colour_space.is_empty() || !colour.view.is_empty();
    if managed && (o.tonemap != Operator::Srgb || o.exposure != 0.0) {
        return Err(NodeError::msg(format!(
            "{}: `colour_space`/`view` give the frames' codes, so `tonemap` must be srgb and \
             `exposure` 0 (tone mapping is the view's)",
            path.display()
        )));
    }
    let frames = crate::artifacts::image_sequence(ctx, FRAMES)?;
    if !managed && colour.working_space == WorkingSpace::LinearRec709 {
        return Ok(write_video(&path, &frames, &o)?);
    }
    let mut images: Vec<Image> = frames.iter().map(|(_, i)| (*i).clone()).collect();
    let config = crate::image_io::ocio_config(ctx);
    colour.convert_for_srgb_encoder(&mut images, config.as_deref(), &path.display().to_string())?;
    let frames: Vec<(i64, &Image)> = frames.iter().map(|(f, _)| *f).zip(&images).collect();
    Ok(write_video(&path, &frames, &o)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{params, spec};
    use std::path::Path;
    use vfxgraph_engine::{InputValue, ParamValue, Value};
    use vfxgraph_imaging::Image;
    use vfxgraph_klt::{track_sequence, GrayImage, TrackerOptions};
    use vfxgraph_video::{write_mp4, ColorInfo, Matrix, Video};

    /// A smooth random-ish texture translated by `(dx, dy)` pixels (linear light, gray).
    fn texture(w: usize, h: usize, dx: f32, dy: f32) -> Image {
        Image::from_fn(w, h, 3, |x, y, _| {
            let (x, y) = (x as f32 - dx, y as f32 - dy);
            let v = 0.45
                + 0.2 * (0.21 * x + 0.5 * (0.13 * y).sin()).sin()
                + 0.15 * (0.17 * y + 0.4 * (0.11 * x).cos()).cos()
                + 0.1 * (0.07 * x * 0.9 + 0.05 * y).sin();
            vfxgraph_imaging::color::srgb_to_linear(v.clamp(0.0, 1.0))
        })
    }

    fn read(dir: &Path, file: &str, frame: i64) -> Result<Image, NodeError> {
        read_with(dir, file, frame, "native")
    }

    fn read_with(dir: &Path, file: &str, frame: i64, backend: &str) -> Result<Image, NodeError> {
        let s = spec("read_video");
        let p = params(
            &s,
            &[
                ("path", ParamValue::Str(file.into())),
                ("backend", ParamValue::Str(backend.into())),
            ],
        );
        let mut ctx = Context::for_test(&s, &p, dir, Some(frame), vec![]);
        run_read_video(&mut ctx)?;
        Ok(ctx.take_output::<ImageArt>("sequence").unwrap().0)
    }

    #[test]
    fn frames_of_a_video_track_its_motion() {
        let dir = tempfile::tempdir().unwrap();
        // 8 frames moving (1.5, −0.75) px per frame.
        let (w, h, n) = (160, 120, 8);
        let src: Vec<Image> = (0..n)
            .map(|k| texture(w, h, 1.5 * k as f32, -0.75 * k as f32))
            .collect();
        let color = ColorInfo {
            matrix: Matrix::Bt601,
            full_range: false,
            matrix_from_stream: true,
        };
        write_mp4(&dir.path().join("clip.mp4"), &src, 25.0, 4, 6, color).unwrap();
        let frames: Vec<Image> = (0..n as i64)
            .map(|f| read(dir.path(), "clip.mp4", f).unwrap())
            .collect();
        let grays: Vec<(i64, GrayImage)> = frames
            .iter()
            .enumerate()
            .map(|(f, img)| (f as i64, GrayImage::from_image(img)))
            .collect();
        let refs: Vec<(i64, &GrayImage)> = grays.iter().map(|(f, g)| (*f, g)).collect();
        let mut tp = TrackerOptions::default();
        tp.corners.max_corners = 40;
        tp.corners.min_distance = 8.0;
        let tracks = track_sequence(&refs, &tp, |_| {}).unwrap();
        // Features followed over the whole clip move by the known motion.
        let mut errs = Vec::new();
        for t in tracks
            .tracks
            .iter()
            .filter(|t| t.first == 0 && t.points.len() == n)
        {
            let (a, b) = (t.points[0], t.points[n - 1]);
            let want = [1.5 * (n - 1) as f64, -0.75 * (n - 1) as f64];
            errs.push(((b[0] - a[0] - want[0]).powi(2) + (b[1] - a[1] - want[1]).powi(2)).sqrt());
        }
        errs.sort_by(f64::total_cmp);
        assert!(errs.len() >= 20, "{} full-length tracks", errs.len());
        let med = errs[errs.len() / 2];
        eprintln!("{} tracks, median end-point error {med} px", errs.len());
        assert!(
            med < 0.1,
            "median end-point error over {} frames: {med} px",
            n - 1
        );
    }

    #[test]
    fn bad_files_and_frames_are_errors_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let e = read(dir.path(), "nope.mp4", 0).unwrap_err();
        assert!(e.message.contains("nope.mp4"), "{e}");
        std::fs::write(dir.path().join("text.mp4"), b"hello, not a video").unwrap();
        let e = read(dir.path(), "text.mp4", 0).unwrap_err();
        assert!(e.message.contains("text.mp4"), "{e}");
        let src: Vec<Image> = (0..3).map(|k| texture(32, 32, k as f32, 0.0)).collect();
        let color = ColorInfo {
            matrix: Matrix::Bt709,
            full_range: false,
            matrix_from_stream: true,
        };
        write_mp4(&dir.path().join("short.mp4"), &src, 25.0, 0, 10, color).unwrap();
        assert!(read(dir.path(), "short.mp4", 2).is_ok());
        let e = read(dir.path(), "short.mp4", 3).unwrap_err();
        assert!(
            e.message.contains("short.mp4") && e.message.contains("3 frames"),
            "{e}"
        );
    }

    /// Runs `write_video` on `frames` (numbered from `first`) with extra params.
    fn write_video(
        dir: &Path,
        file: &str,
        first: i64,
        frames: &[Image],
        extra: &[(&str, ParamValue)],
    ) -> Result<(), NodeError> {
        let s = spec("write_video");
        let mut ps = vec![("path", ParamValue::Str(file.into()))];
        ps.extend(extra.iter().cloned());
        let p = params(&s, &ps);
        let seq = frames
            .iter()
            .enumerate()
            .map(|(k, img)| (first + k as i64, Value::new(ImageArt(img.clone()))))
            .collect();
        let inputs = vec![("sequence", InputValue::Sequence(seq))];
        let mut ctx = Context::for_test(&s, &p, dir, None, inputs);
        run_write_video(&mut ctx)
    }

    #[test]
    fn write_video_round_trips_through_the_reader() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h, n) = (96, 64, 10);
        let src: Vec<Image> = (0..n)
            .map(|k| texture(w, h, 1.25 * k as f32, 0.5 * k as f32))
            .collect();
        write_video(
            dir.path(),
            "out/clip.mp4",
            100,
            &src,
            &[("fps", ParamValue::Float(23.976))],
        )
        .unwrap();
        let v = Video::open(&dir.path().join("out/clip.mp4")).unwrap();
        assert_eq!(v.frame_count(), n);
        assert_eq!(v.size(), (w, h));
        assert!((v.fps() - 23.976).abs() < 1e-3, "fps {}", v.fps());
        // Each decoded frame is its source frame (sRGB codes, mean |Δ| < 1 % of full scale;
        // the next frame's texture is ≥ 5× further away, so frame order is checked too).
        for (k, img) in src.iter().enumerate() {
            let got = v.frame(k as i64).unwrap();
            let d = |a: &Image, b: &Image| {
                let (ga, gb) = (GrayImage::from_image(a), GrayImage::from_image(b));
                ga.data
                    .iter()
                    .zip(&gb.data)
                    .map(|(x, y)| (x - y).abs())
                    .sum::<f32>()
                    / ga.data.len() as f32
                    / 255.0
            };
            let own = d(&got, img);
            assert!(own < 0.01, "frame {k}: mean |Δ| {own}");
            if let Some(next) = src.get(k + 1) {
                assert!(
                    d(&got, next) > 5.0 * own,
                    "frame {k} looks like frame {}",
                    k + 1
                );
            }
        }
        // Reinhard maps HDR values below white: a 4.0 image is not clipped to white.
        let bright = vec![Image::from_fn(32, 32, 3, |_, _, _| 4.0); 2];
        write_video(dir.path(), "hdr.mp4", 0, &bright, &[]).unwrap();
        write_video(
            dir.path(),
            "hdr_r.mp4",
            0,
            &bright,
            &[("tonemap", ParamValue::Str("reinhard".into()))],
        )
        .unwrap();
        let luma = |f: &str| {
            let img = Video::open(&dir.path().join(f)).unwrap().frame(0).unwrap();
            GrayImage::from_image(&img).data[500] / 255.0
        };
        assert!(luma("hdr.mp4") > 0.97, "clipped: {}", luma("hdr.mp4"));
        // Linear 4/(1+4) = 0.8, i.e. sRGB code 0.906 (the gray image holds sRGB codes).
        let (r, want) = (
            luma("hdr_r.mp4"),
            vfxgraph_imaging::color::linear_to_srgb(0.8),
        );
        assert!((r - want).abs() < 0.02, "reinhard: {r}, want {want}");
    }

    #[test]
    fn write_video_refuses_what_h264_cannot_hold() {
        let dir = tempfile::tempdir().unwrap();
        let odd = vec![Image::new(33, 32, 3); 2];
        let e = write_video(dir.path(), "a.mp4", 0, &odd, &[]).unwrap_err();
        assert!(
            e.message.contains("33×32") && e.message.contains("even"),
            "{e}"
        );
        let mixed = vec![Image::new(32, 32, 3), Image::new(64, 32, 3)];
        let e = write_video(dir.path(), "b.mp4", 5, &mixed, &[]).unwrap_err();
        assert!(
            e.message.contains("frame 6") && e.message.contains("64×32"),
            "{e}"
        );
        let e = write_video(dir.path(), "c.mp4", 0, &[], &[]).unwrap_err();
        assert!(
            e.message.contains("no frames") && e.message.contains("c.mp4"),
            "{e}"
        );
        for f in ["a.mp4", "b.mp4", "c.mp4"] {
            assert!(!dir.path().join(f).exists(), "{f} half-written");
        }
    }

    #[cfg(not(feature = "opencv"))]
    #[test]
    fn the_opencv_backend_says_how_to_get_it() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("clip.mov"), b"anything").unwrap();
        let e = read_with(dir.path(), "clip.mov", 0, "opencv").unwrap_err();
        for want in [
            "read_video",
            "backend",
            "--features opencv",
            "libopencv-dev",
        ] {
            assert!(e.message.contains(want), "{want}: {e}");
        }
    }

    /// The same clip through both backends: the same frames (luma within 0.005 of full
    /// scale on average; OpenCV's chroma conversion differs slightly), the same range.
    #[cfg(feature = "opencv")]
    #[test]
    fn opencv_backend_reads_the_same_frames() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h, n) = (96, 64, 6);
        let src: Vec<Image> = (0..n)
            .map(|k| texture(w, h, 1.5 * k as f32, 0.5 * k as f32))
            .collect();
        let color = ColorInfo {
            matrix: Matrix::Bt601,
            full_range: false,
            matrix_from_stream: true,
        };
        write_mp4(&dir.path().join("clip.mp4"), &src, 25.0, 3, 6, color).unwrap();
        for f in [3, 0, 5, 1] {
            let a = read_with(dir.path(), "clip.mp4", f, "opencv").unwrap();
            let b = read(dir.path(), "clip.mp4", f).unwrap();
            let (ga, gb) = (GrayImage::from_image(&a), GrayImage::from_image(&b));
            let d: f32 = ga
                .data
                .iter()
                .zip(&gb.data)
                .map(|(x, y)| (x - y).abs())
                .sum::<f32>()
                / ga.data.len() as f32;
            assert!(d < 0.005 * 255.0, "frame {f}: mean |Δ luma| {d} of 255");
        }
        let e = read_with(dir.path(), "clip.mp4", n as i64, "opencv").unwrap_err();
        assert!(
            e.message.contains("clip.mp4") && e.message.contains("6 frames"),
            "{e}"
        );
        let e = read_with(dir.path(), "nope.webm", 0, "opencv").unwrap_err();
        assert!(e.message.contains("nope.webm"), "{e}");
        std::fs::write(dir.path().join("text.mkv"), b"hello, not a video").unwrap();
        let e = read_with(dir.path(), "text.mkv", 0, "opencv").unwrap_err();
        assert!(e.message.contains("text.mkv"), "{e}");
    }

    /// A preview through a display/view: the MP4's frames, read back as code values (`Raw`),
    /// are the ACES 2.0 SDR view's sRGB display codes of the scene-linear frames, to within
    /// the codec (mean |Δ| under 1 % of full scale); a tone map with a view is refused.
    #[test]
    fn write_video_previews_through_a_display_view() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (64, 48);
        // Scene-linear, past 1 (the view tone-maps the highlights).
        let src: Vec<Image> = (0..3)
            .map(|k| {
                let t = texture(w, h, k as f32, 0.0);
                Image::from_fn(w, h, 3, |x, y, c| 6.0 * t.get(x, y, c))
            })
            .collect();
        let view = ParamValue::Str("ACES 2.0 - SDR 100 nits (Rec.709)".into());
        write_video(dir.path(), "v.mp4", 0, &src, &[("view", view.clone())]).unwrap();
        let t = vfxgraph_imaging::colour::ColourConfig::builtin()
            .display_view(
                "Linear Rec.709 (sRGB)",
                "sRGB - Display",
                "ACES 2.0 - SDR 100 nits (Rec.709)",
            )
            .unwrap();
        for (k, img) in src.iter().enumerate() {
            let s = spec("read_video");
            let p = params(
                &s,
                &[
                    ("path", ParamValue::Str("v.mp4".into())),
                    ("colour_space", ParamValue::Str("Raw".into())),
                ],
            );
            let mut ctx = Context::for_test(&s, &p, dir.path(), Some(k as i64), vec![]);
            run_read_video(&mut ctx).unwrap();
            let got = ctx.take_output::<ImageArt>("sequence").unwrap().0;
            let mut want = img.clone();
            t.apply(&mut want);
            let mean = got
                .data
                .iter()
                .zip(&want.data)
                .map(|(a, b)| (a - b).abs())
                .sum::<f32>()
                / got.data.len() as f32;
            assert!(mean < 0.01, "frame {k}: mean |Δ| {mean}");
            // Not what the default sRGB clip writes (a mean |Δ| of 0.18 from it).
            let clip = img
                .data
                .iter()
                .zip(&got.data)
                .map(|(a, b)| {
                    (vfxgraph_imaging::color::linear_to_srgb(a.clamp(0.0, 1.0)) - b).abs()
                })
                .sum::<f32>()
                / got.data.len() as f32;
            assert!(clip > 10.0 * mean, "frame {k}: {clip} from the clip");
        }
        let e = write_video(
            dir.path(),
            "r.mp4",
            0,
            &src,
            &[
                ("view", view),
                ("tonemap", ParamValue::Str("reinhard".into())),
            ],
        )
        .unwrap_err();
        assert!(
            e.message.contains("r.mp4") && e.message.contains("tonemap"),
            "{e}"
        );
    }
}
