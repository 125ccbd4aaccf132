//! Artifact decoding for the viewers — the one module that knows the node catalog's artifact
//! types. An output of the last run is found through the engine's rerun record
//! ([`vfxgraph_engine::exec::last_run_entry`]), read from the store (verified) and decoded by
//! the registry; images (`image`, a layer of `layers`) become 8-bit previews encoded here on
//! the server, JSON-encoded artifacts (cameras, points, tracks, marks, reports) are passed on
//! as they are stored.
//!
//! Previews: exposure (stops) times the linear value, then the sRGB transfer curve, a plain
//! clamp (linear view), or a display/view transform of the graph's OpenColorIO config (the
//! studio's colour-managed view: [`output_colour`], [`DisplayView`]), 8 bits per channel, encoded as PNG with fast compression (exact: the
//! page reads pixels back from it) or JPEG (smaller, for scrubbing large plates). Decoded
//! images and encoded previews are kept in small in-memory LRU caches, so scrubbing frames a
//! second time costs no decode.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex};

use image::codecs::jpeg::JpegEncoder;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};
use vfxgraph_engine::artifact::DynArtifact;
use vfxgraph_engine::exec::{last_run_entry, recompute_uncached};
use vfxgraph_engine::store::Store;
use vfxgraph_engine::{Digest, Graph, Registry};
use vfxgraph_imaging::color::linear_to_srgb8;
use vfxgraph_imaging::colour::{ColourConfig, ColourTransform, WorkingSpace};
use vfxgraph_imaging::Image;
use vfxgraph_nodes::artifacts::ImageArt;

use crate::safety::ApiError;

/// Artifact types whose canonical encoding is JSON (served as they are stored).
pub const JSON_TYPES: &[&str] = &[
    "camera_path",
    "camera",
    "intrinsics",
    "points2d",
    "points3d",
    "point_cloud",
    "indices",
    "report",
    "tracks",
    "marks",
];

/// Artifact types shown in the frame viewer.
pub const IMAGE_TYPES: &[&str] = &["image", "layers"];

/// A small LRU map (most recent at the back), bounded by a count and a total weight (bytes).
struct Lru<V> {
    cap: usize,
    max_weight: usize,
    weight: usize,
    items: VecDeque<(String, V, usize)>,
}

impl<V: Clone> Lru<V> {
    fn new(cap: usize, max_weight: usize) -> Self {
        Lru {
            cap,
            max_weight,
            weight: 0,
            items: VecDeque::new(),
        }
    }
    fn get(&mut self, key: &str) -> Option<V> {
        let i = self.items.iter().position(|(k, _, _)| k == key)?;
        let item = self.items.remove(i)?;
        let v = item.1.clone();
        self.items.push_back(item);
        Some(v)
    }
    fn put(&mut self, key: String, v: V, weight: usize) {
        if let Some(i) = self.items.iter().position(|(k, _, _)| *k == key) {
            if let Some((_, _, w)) = self.items.remove(i) {
                self.weight -= w;
            }
        }
        self.items.push_back((key, v, weight));
        self.weight += weight;
        while self.items.len() > self.cap || (self.weight > self.max_weight && self.items.len() > 1)
        {
            if let Some((_, _, w)) = self.items.pop_front() {
                self.weight -= w;
            }
        }
    }
}

/// Decoded artifacts (by digest) and encoded previews (by digest and view settings).
pub struct PreviewCache {
    decoded: Mutex<Lru<Arc<dyn DynArtifact>>>,
    encoded: Mutex<Lru<Arc<Vec<u8>>>>,
    warming: Mutex<Option<(String, Arc<Warming>)>>,
    /// Display/view transforms made (a processor is built once per config, space, display
    /// and view).
    displays: Mutex<HashMap<String, Arc<ColourTransform>>>,
}

/// Most encoded preview bytes kept in memory (a 1280×720 JPEG preview is ~0.1 MB, a PNG ~1 MB).
pub const ENCODED_BYTES: usize = 512 << 20;

impl Default for PreviewCache {
    fn default() -> Self {
        PreviewCache {
            decoded: Mutex::new(Lru::new(6, usize::MAX)),
            encoded: Mutex::new(Lru::new(4096, ENCODED_BYTES)),
            warming: Mutex::new(None),
            displays: Mutex::new(HashMap::new()),
        }
    }
}

/// The progress of encoding every frame's preview of one output ahead of the scrubber.
#[derive(Default)]
pub struct Warming {
    /// Frames to encode.
    pub total: usize,
    /// Frames encoded (or found encoded).
    pub done: std::sync::atomic::AtomicUsize,
    /// Frames without a preview (not run, not an image).
    pub failed: std::sync::atomic::AtomicUsize,
    /// Set when a newer warming replaced this one (its thread stops).
    pub stale: std::sync::atomic::AtomicBool,
}

impl Warming {
    /// `{total, done, failed}`.
    pub fn json(&self) -> serde_json::Value {
        use std::sync::atomic::Ordering::Relaxed;
        serde_json::json!({
            "total": self.total,
            "done": self.done.load(Relaxed),
            "failed": self.failed.load(Relaxed),
        })
    }
}

/// How to show an image.
#[derive(Clone, Debug)]
pub struct View {
    /// Exposure in stops (×2^stops before the transfer curve).
    pub exposure: f32,
    /// sRGB transfer curve (else a linear clamp).
    pub srgb: bool,
    /// JPEG instead of PNG.
    pub jpeg: bool,
    /// A display/view transform instead of the sRGB curve or the clamp.
    pub display: Option<DisplayView>,
}

impl View {
    /// What tells two views' previews apart (a part of the previews' cache keys).
    pub fn key(&self) -> String {
        let display = self.display.as_ref().map_or("", |d| d.label.as_str());
        format!("{}|{}|{}|{display}", self.exposure, self.srgb, self.jpeg)
    }
}

/// A display/view transform of an OpenColorIO config, from the space an output's values are
/// in to a display's encoding (the view's tone mapping included, as the config defines it).
#[derive(Clone, Debug)]
pub struct DisplayView {
    /// The config, the source space, the display and the view: the transform's identity.
    pub label: String,
    /// The transform.
    pub transform: Arc<ColourTransform>,
}

/// The colour of node `node`'s outputs: its own `ocio_config` and `working_space` parameters
/// when it has them, else those of the first node of the graph that has them (the graph's
/// `defaults:` put one value in every node that has the parameter), else the built-in config
/// and linear Rec. 709. A relative config path is the graph folder's, as the nodes read it.
pub fn output_colour(
    g: &Graph,
    node: usize,
) -> Result<(Arc<ColourConfig>, WorkingSpace), ApiError> {
    let param = |name: &str| -> Option<String> {
        let of = |i: usize| {
            g.nodes[i].params.get(name).and_then(|v| match v {
                vfxgraph_engine::ParamValue::Str(s) if !s.is_empty() => Some(s.clone()),
                _ => None,
            })
        };
        of(node).or_else(|| (0..g.nodes.len()).find_map(of))
    };
    let space = match param("working_space").as_deref() {
        None => WorkingSpace::default(),
        Some(name) => <WorkingSpace as vfxgraph_params::Choice>::from_choice(name)
            .ok_or_else(|| ApiError::bad(format!("unknown working space `{name}`")))?,
    };
    let path =
        param("ocio_config").map(|p| vfxgraph_engine::frames::resolve_path(&g.dir, &p, None));
    let config =
        ColourConfig::resolve(path.as_deref()).map_err(|e| ApiError::bad(e.to_string()))?;
    Ok((config, space))
}

/// One output of the last run: its type and digest.
pub struct Output {
    /// Artifact type name.
    pub ty: String,
    /// Content digest.
    pub digest: Digest,
    /// Where to recompute it: the output of an uncached reader is not in the store
    /// ([`vfxgraph_engine::NodeSpec::uncached`]).
    pub uncached: Option<Uncached>,
}

/// An uncached reader's instance: the graph, node index, frame and output port.
pub struct Uncached {
    graph: Arc<Graph>,
    node: usize,
    frame: Option<i64>,
    port: String,
}

/// Finds output `port` of node `node_id` at `frame` in the last run's entry.
pub fn find_output(
    graph: &Graph,
    store: &Store,
    node_id: &str,
    port: &str,
    frame: Option<i64>,
) -> Result<Output, ApiError> {
    let node = graph
        .index_of(node_id)
        .ok_or_else(|| ApiError::not_found(format!("no node `{node_id}` in the graph")))?;
    let gn = &graph.nodes[node];
    if !gn.spec().outputs.iter().any(|p| p.name == port) {
        return Err(ApiError::not_found(format!(
            "node `{node_id}` has no output `{port}`"
        )));
    }
    let frame = if graph.instances_of(gn) > 1 || gn.per_frame {
        let f = frame
            .ok_or_else(|| ApiError::bad(format!("`{node_id}` is per-frame: give a frame")))?;
        if !graph.frames.frames().contains(&f) {
            return Err(ApiError::not_found(format!(
                "frame {f} is not in the graph's range"
            )));
        }
        Some(f)
    } else {
        None
    };
    let entry = last_run_entry(graph, store, node, frame).ok_or_else(|| {
        ApiError::not_found(format!(
            "`{node_id}`{} has no cached output yet (run the graph)",
            frame.map(|f| format!(" frame {f}")).unwrap_or_default()
        ))
    })?;
    let out = entry
        .outputs
        .iter()
        .find(|o| o.port == port)
        .ok_or_else(|| ApiError::not_found(format!("`{node_id}.{port}` was not stored")))?;
    let digest = Digest::from_hex(&out.digest)
        .ok_or_else(|| ApiError::internal("a corrupt digest in the cache entry"))?;
    let uncached = (!gn.spec().cache_outputs).then(|| Uncached {
        graph: Arc::new(graph.clone()),
        node,
        frame,
        port: port.to_string(),
    });
    Ok(Output {
        ty: out.ty.clone(),
        digest,
        uncached,
    })
}

impl PreviewCache {
    /// The display/view transform from `space` to `display`'s `view` (the display's first
    /// view when `view` is `None`) of `config`; unknown names are errors listing the config's.
    pub fn display_view(
        &self,
        config: &ColourConfig,
        space: WorkingSpace,
        display: &str,
        view: Option<&str>,
    ) -> Result<DisplayView, ApiError> {
        let view = match view {
            Some(v) => v.to_string(),
            None => config.views(display).into_iter().next().ok_or_else(|| {
                ApiError::bad(format!(
                    "no display `{display}` in the OpenColorIO config {} (displays: {})",
                    config.source(),
                    config.displays().join(", ")
                ))
            })?,
        };
        let label = format!("{}|{}|{display}|{view}", config.source(), space.name());
        let made = self
            .displays
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(&label)
            .cloned();
        let transform = match made {
            Some(t) => t,
            None => {
                let t = config
                    .display_view(space.name(), display, &view)
                    .map_err(|e| ApiError::bad(e.to_string()))?;
                let t = Arc::new(t);
                self.displays
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .insert(label.clone(), t.clone());
                t
            }
        };
        Ok(DisplayView { label, transform })
    }

    /// The decoded artifact of `out`: a verified read from the store, or an uncached reader's
    /// output recomputed (checked against the run's digest).
    pub fn artifact(
        &self,
        store: &Store,
        registry: &Registry,
        out: &Output,
    ) -> Result<Arc<dyn DynArtifact>, ApiError> {
        let key = out.digest.to_hex();
        if let Some(a) = self
            .decoded
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(&key)
        {
            return Ok(a);
        }
        let art = match &out.uncached {
            Some(u) => recompute_uncached(&u.graph, u.node, u.frame, &u.port, &out.digest)
                .map_err(ApiError::conflict)?
                .data()
                .clone(),
            None => {
                let (ty, bytes) = store.get_object(&out.digest).ok_or_else(|| {
                    ApiError::not_found("the output's object is no longer in the cache (run again)")
                })?;
                registry.decode(&ty, &bytes).map_err(|e| {
                    ApiError::internal(format!("cannot decode the `{ty}` object: {e}"))
                })?
            }
        };
        self.decoded
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .put(key, art.clone(), 1);
        Ok(art)
    }

    /// The encoded preview of `out` (layer `layer` of a `layers` artifact).
    pub fn preview(
        &self,
        store: &Store,
        registry: &Registry,
        out: &Output,
        layer: Option<&str>,
        view: &View,
    ) -> Result<Arc<Vec<u8>>, ApiError> {
        let key = format!(
            "{}|{}|{}",
            out.digest.to_hex(),
            layer.unwrap_or(""),
            view.key()
        );
        if let Some(b) = self
            .encoded
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(&key)
        {
            return Ok(b);
        }
        let art = self.artifact(store, registry, out)?;
        let img = image_of(art.as_ref(), layer)?;
        let bytes = Arc::new(encode_preview(img, view)?);
        let n = bytes.len();
        self.encoded
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .put(key, bytes.clone(), n);
        Ok(bytes)
    }

    /// The warming of `key` (a new one, replacing — and stopping — any other, when `key` is
    /// not the current one; `true` with it when the caller must start its thread).
    pub fn warming(&self, key: &str, total: usize) -> (Arc<Warming>, bool) {
        let mut w = self.warming.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((k, cur)) = w.as_ref() {
            if k == key {
                return (cur.clone(), false);
            }
            cur.stale.store(true, std::sync::atomic::Ordering::Relaxed);
        }
        let new = Arc::new(Warming {
            total,
            ..Default::default()
        });
        *w = Some((key.to_string(), new.clone()));
        (new, true)
    }
}

/// The layer names of an image artifact (`None` for a plain image).
pub fn layer_names(art: &dyn DynArtifact) -> Option<Vec<String>> {
    art.as_any()
        .downcast_ref::<vfxgraph_nodes::shot::LayersArt>()
        .map(|l| l.0.iter().map(|(n, _)| n.clone()).collect())
}

/// The image of an `image` artifact, or the named (default: first) layer of a `layers` one.
pub fn image_of<'a>(art: &'a dyn DynArtifact, layer: Option<&str>) -> Result<&'a Image, ApiError> {
    if let Some(i) = art.as_any().downcast_ref::<ImageArt>() {
        return Ok(&i.0);
    }
    if let Some(l) = art
        .as_any()
        .downcast_ref::<vfxgraph_nodes::shot::LayersArt>()
    {
        let found = match layer {
            Some(name) => l.0.iter().find(|(n, _)| n == name),
            None => l.0.first(),
        };
        return found.map(|(_, img)| img).ok_or_else(|| {
            ApiError::not_found(format!(
                "no layer `{}` (layers: {})",
                layer.unwrap_or(""),
                l.0.iter()
                    .map(|(n, _)| n.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        });
    }
    Err(ApiError::bad(format!(
        "a `{}` is not an image",
        art.type_name()
    )))
}

/// `T[c]`: the least linear value that [`linear_to_srgb8`] maps above code `c` (found by
/// bisection on the f32 bit patterns, once), so the transfer curve of a whole frame is 8
/// comparisons a value instead of a `powf`, with exactly the same codes.
fn srgb_thresholds() -> &'static [f32; 255] {
    static T: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        std::array::from_fn(|c| {
            let (mut lo, mut hi) = (0u32, 1f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if linear_to_srgb8(f32::from_bits(mid)) as usize > c {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            f32::from_bits(lo)
        })
    })
}

/// [`linear_to_srgb8`] by the thresholds (NaN → 0 as there).
fn srgb8_fast(v: f32) -> u8 {
    srgb_thresholds().partition_point(|&t| t <= v) as u8
}

/// 8-bit RGB (or grey) bytes of `img` under `view`.
pub fn display_bytes(img: &Image, view: &View) -> (Vec<u8>, ExtendedColorType) {
    let gain = 2f32.powf(view.exposure);
    if let Some(d) = &view.display {
        // Exposed RGB (a grey image as three equal channels) through the transform, whose
        // output is the display's code values.
        let cc = img.color_channels();
        let mut rgb = Image {
            width: img.width,
            height: img.height,
            channels: 3,
            data: Vec::with_capacity(img.width * img.height * 3),
        };
        for px in img.data.chunks_exact(img.channels.max(1)) {
            if cc >= 3 {
                rgb.data.extend(px[..3].iter().map(|v| v * gain));
            } else {
                rgb.data.extend([px[0] * gain; 3]);
            }
        }
        d.transform.apply(&mut rgb);
        let to8 = |v: f32| {
            if v.is_nan() {
                0
            } else {
                (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
            }
        };
        return (
            rgb.data.iter().map(|&v| to8(v)).collect(),
            ExtendedColorType::Rgb8,
        );
    }
    let to8 = |v: f32| -> u8 {
        let v = v * gain;
        if view.srgb {
            srgb8_fast(v)
        } else if v.is_nan() {
            0
        } else {
            (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
        }
    };
    let cc = img.color_channels();
    let (out_c, ty) = if cc >= 3 {
        (3, ExtendedColorType::Rgb8)
    } else {
        (1, ExtendedColorType::L8)
    };
    let mut out = Vec::with_capacity(img.width * img.height * out_c);
    for px in img.data.chunks_exact(img.channels.max(1)) {
        for &v in &px[..out_c] {
            out.push(to8(v));
        }
    }
    (out, ty)
}

/// Encodes the preview of `img`.
pub fn encode_preview(img: &Image, view: &View) -> Result<Vec<u8>, ApiError> {
    if img.width == 0 || img.height == 0 {
        return Err(ApiError::bad("the image is empty"));
    }
    let (bytes, ty) = display_bytes(img, view);
    let mut out = Vec::new();
    let (w, h) = (img.width as u32, img.height as u32);
    let r = if view.jpeg {
        JpegEncoder::new_with_quality(&mut out, 90).write_image(&bytes, w, h, ty)
    } else {
        PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Sub)
            .write_image(&bytes, w, h, ty)
    };
    r.map_err(|e| ApiError::internal(format!("cannot encode the preview: {e}")))?;
    Ok(out)
}

/// The linear values of pixel (x, y), or a 400 outside the image.
pub fn pixel(img: &Image, x: i64, y: i64) -> Result<Vec<f32>, ApiError> {
    if x < 0 || y < 0 || x as usize >= img.width || y as usize >= img.height {
        return Err(ApiError::bad(format!(
            "pixel ({x}, {y}) is outside the {}×{} image",
            img.width, img.height
        )));
    }
    Ok(img.pixel(x as usize, y as usize).to_vec())
}

/// The stored JSON of a JSON-encoded artifact.
pub fn json_bytes(art: &dyn DynArtifact) -> Result<Vec<u8>, ApiError> {
    if !JSON_TYPES.contains(&art.type_name()) {
        return Err(ApiError::bad(format!(
            "a `{}` has no JSON form",
            art.type_name()
        )));
    }
    let mut out = Vec::new();
    art.encode_into(&mut out);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exposure_and_transfer() {
        let img = Image::from_vec(2, 1, 3, vec![0.25, 0.5, 1.0, 0.0, 2.0, f32::NAN]).unwrap();
        let lin = View {
            exposure: 0.0,
            srgb: false,
            jpeg: false,
            display: None,
        };
        let (b, _) = display_bytes(&img, &lin);
        assert_eq!(b, vec![64, 128, 255, 0, 255, 0]);
        let up = View {
            exposure: 1.0,
            ..lin.clone()
        };
        let (b, _) = display_bytes(&img, &up);
        assert_eq!(&b[..3], &[128, 255, 255]);
        let srgb = View { srgb: true, ..lin };
        let (b, _) = display_bytes(&img, &srgb);
        assert_eq!(b[0], linear_to_srgb8(0.25));
        assert!(b[0] > 64, "sRGB lifts the mid-tones");
        let png = encode_preview(&img, &srgb).unwrap();
        assert_eq!(&png[1..4], b"PNG");
    }

    /// The built-in config's un-tone-mapped sRGB view of linear Rec. 709 is the sRGB curve
    /// (IEC 61966-2-1), and of ACEScg the same after the AP1 → Rec. 709 primaries; the ACES
    /// 2.0 SDR view tone-maps (highlights above 1 stay below white, mid-grey sits darker than
    /// the plain curve puts it). Grey images are shown as three equal channels.
    #[test]
    fn a_display_view_transform_is_the_configs() {
        let cache = PreviewCache::default();
        let config = ColourConfig::builtin();
        let plain = |space| {
            cache
                .display_view(&config, space, "sRGB - Display", Some("Un-tone-mapped"))
                .unwrap()
        };
        let values = [0.0, 0.001, 0.0031, 0.05, 0.18, 0.5, 0.9, 1.0];
        let img = Image::from_vec(values.len(), 1, 1, values.to_vec()).unwrap();
        let view = View {
            exposure: 0.0,
            srgb: true,
            jpeg: false,
            display: Some(plain(WorkingSpace::LinearRec709)),
        };
        let (b, ty) = display_bytes(&img, &view);
        assert_eq!(ty, ExtendedColorType::Rgb8);
        for (px, &v) in b.chunks(3).zip(&values) {
            let want = linear_to_srgb8(v) as i32;
            assert!(
                px.iter().all(|&c| (c as i32 - want).abs() <= 1),
                "{v}: {px:?} against the sRGB curve's {want}"
            );
        }
        // A colour in ACEScg: converted to Rec. 709 primaries (the ACEScg → linear Rec. 709
        // transform, itself checked against PyOpenColorIO), then the curve.
        let ap1 = [0.3f32, 0.2, 0.1];
        let mut to709 = Image::from_vec(1, 1, 3, ap1.to_vec()).unwrap();
        config
            .transform("ACEScg", vfxgraph_imaging::colour::LINEAR_REC709)
            .unwrap()
            .apply(&mut to709);
        let img = Image::from_vec(1, 1, 3, ap1.to_vec()).unwrap();
        let view = View {
            display: Some(plain(WorkingSpace::AcesCg)),
            ..view
        };
        let (b, _) = display_bytes(&img, &view);
        for (c, &v) in b.iter().zip(&to709.data) {
            assert!(
                (*c as i32 - linear_to_srgb8(v) as i32).abs() <= 1,
                "{b:?} {to709:?}"
            );
        }
        let aces = cache
            .display_view(&config, WorkingSpace::AcesCg, "sRGB - Display", None)
            .unwrap();
        assert!(
            aces.label.contains("ACES"),
            "the display's first view: {}",
            aces.label
        );
        let img = Image::from_vec(2, 1, 1, vec![0.18, 4.0]).unwrap();
        let (b, _) = display_bytes(
            &img,
            &View {
                display: Some(aces),
                ..view
            },
        );
        assert!(b[0] < linear_to_srgb8(0.18), "{b:?}");
        assert!(b[3] < 255 && b[3] > b[0], "{b:?}");
        let e = cache
            .display_view(&config, WorkingSpace::AcesCg, "Cinema", None)
            .unwrap_err();
        assert!(e.message.contains("sRGB - Display"), "{}", e.message);
    }

    #[test]
    fn fast_transfer_curve_is_exact() {
        let mut v = -0.5f32;
        while v < 1.5 {
            assert_eq!(srgb8_fast(v), linear_to_srgb8(v), "{v}");
            v += 1.0 / 65536.0;
        }
        for v in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0, 1.0, 1e-9] {
            assert_eq!(srgb8_fast(v), linear_to_srgb8(v), "{v}");
        }
    }

    #[test]
    fn pixel_bounds() {
        let img = Image::from_vec(2, 1, 1, vec![0.5, 0.75]).unwrap();
        assert_eq!(pixel(&img, 1, 0).unwrap(), vec![0.75]);
        assert!(pixel(&img, 2, 0).is_err());
        assert!(pixel(&img, -1, 0).is_err());
    }
}
