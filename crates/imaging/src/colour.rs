//! Colour management through OpenColorIO configs: the conversions between the colour spaces
//! files are encoded in and the scene-linear working space a graph computes in, and the
//! display/view transforms of previews.
//!
//! The transforms are OpenColorIO's (Academy Software Foundation, <https://opencolorio.org>),
//! evaluated by the pure-Rust port `ocio` (no system library): a config is the studio's own
//! (`--ocio FILE` or `$OCIO`, any OpenColorIO 2 config) or, by default, the ACES studio config
//! built into OpenColorIO, [`BUILTIN_CONFIG`], pinned to one version so that a graph's output
//! does not change with the library's idea of "latest". Colour spaces are named as that config
//! names them; the ones the readers and writers are checked with (`crates/imaging/tests/ocio.rs`,
//! within 1e-4 of PyOpenColorIO) are:
//!
//! | name | encoding, gamut | specification |
//! |---|---|---|
//! | `sRGB Encoded Rec.709 (sRGB)` | sRGB piecewise curve, Rec. 709 primaries, D65 | IEC 61966-2-1:1999 |
//! | `Camera Rec.709` | the BT.709 camera OETF, Rec. 709 | ITU-R BT.709-6 |
//! | `Linear Rec.709 (sRGB)` | linear, Rec. 709 | ITU-R BT.709-6 |
//! | `ACES2065-1` | linear, ACES AP0, ACES white | SMPTE ST 2065-1 |
//! | `ACEScg` | linear, ACES AP1 | Academy S-2014-004 |
//! | `ACEScct` | ACEScct log with its linear toe, AP1 | Academy S-2016-001 |
//! | `ARRI LogC3 (EI800)` | LogC3 at EI 800, ARRI Wide Gamut 3 | ARRI, "ALEXA Log C Curve — Usage in VFX" (2017) |
//! | `ARRI LogC4` | LogC4, ARRI Wide Gamut 4 | ARRI, "ARRI LogC4 Logarithmic Color Space — Specification" (2022) |
//! | `S-Log3 S-Gamut3.Cine` | S-Log3, S-Gamut3.Cine | Sony, "Technical Summary for S-Gamut3.Cine/S-Log3 and S-Gamut3/S-Log3" |
//! | `Rec.1886 Rec.709 - Display` | BT.1886 (gamma 2.4), Rec. 709, display-referred | ITU-R BT.1886 |
//! | `Rec.2100-HLG - Display` | hybrid log-gamma, Rec. 2020, 1000 nits | ITU-R BT.2100-2 |
//! | `Rec.2100-PQ - Display` | perceptual quantizer, Rec. 2020 | ITU-R BT.2100-2, SMPTE ST 2084 |
//!
//! Gamut conversions are the config's matrices: the camera vendors' own matrices to ACES2065-1
//! (ARRI's and Sony's, as the ACES CSC transforms give them) and Bradford adaptation between
//! the ACES white and D65 (OpenColorIO's `ACES-AP0_to_CIE-XYZ-D65_BFD` built-ins). A
//! display-referred space is reached from scene-linear through the config's default view
//! transform (in the built-in config, the ACES 2.0 output transform), as OpenColorIO does.
//!
//! A node's config is its `ocio_config` parameter (a graph states it once in `defaults:`; the
//! command line's `--ocio FILE`, or `$OCIO`, fills it in for every node that leaves it unset),
//! so the config's content is part of the cache keys; nothing here reads the environment.
//!
//! Everything a graph computes is scene-linear in its working space ([`WorkingSpace`]): linear
//! Rec. 709 by default (what vfxgraph always used: sRGB files decoded to linear light), or
//! ACEScg.

use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex, OnceLock};

use rayon::prelude::*;

use crate::error::ImageError;
use crate::image::Image;

/// The OpenColorIO config used when a node names none: the ACES studio
/// config of OpenColorIO 2.5 (ACES 2.0 output transforms).
pub const BUILTIN_CONFIG: &str = "ocio://studio-config-v4.0.0_aces-v2.0_ocio-v2.5";

/// The scene-linear space a graph computes in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, vfxgraph_params::Choice)]
pub enum WorkingSpace {
    /// Linear light with the Rec. 709 / sRGB primaries and D65 white (`Linear Rec.709
    /// (sRGB)`): what 8/16-bit sRGB files decode to.
    #[default]
    #[param(name = "linear_rec709")]
    LinearRec709,
    /// ACEScg: linear light with the ACES AP1 primaries (Academy S-2014-004).
    #[param(name = "acescg")]
    AcesCg,
}

impl WorkingSpace {
    /// The colour space's name in OpenColorIO's ACES configs.
    pub fn name(self) -> &'static str {
        match self {
            WorkingSpace::LinearRec709 => LINEAR_REC709,
            WorkingSpace::AcesCg => "ACEScg",
        }
    }
}

/// The name of linear Rec. 709 in the ACES configs: what the file readers' default decoding
/// (sRGB curves, DPX transfer characteristics; float formats as stored) gives.
pub const LINEAR_REC709: &str = "Linear Rec.709 (sRGB)";

/// An OpenColorIO config, loaded and checked: the colour spaces, displays and views it names.
pub struct ColourConfig {
    config: ocio::Config,
    /// The file or `ocio://` name it was loaded from.
    source: String,
}

impl std::fmt::Debug for ColourConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ColourConfig({})", self.source)
    }
}

/// Loaded configs by source, with the bytes they were loaded from (a file that changes is
/// loaded again).
type Loaded = HashMap<String, (Vec<u8>, Arc<ColourConfig>)>;

fn loaded() -> &'static Mutex<Loaded> {
    static LOADED: OnceLock<Mutex<Loaded>> = OnceLock::new();
    LOADED.get_or_init(Mutex::default)
}

impl ColourConfig {
    /// The built-in ACES studio config ([`BUILTIN_CONFIG`]), loaded once.
    pub fn builtin() -> Arc<ColourConfig> {
        static BUILTIN: OnceLock<Arc<ColourConfig>> = OnceLock::new();
        BUILTIN
            .get_or_init(|| {
                let config = ocio::Config::create_from_file(BUILTIN_CONFIG)
                    .expect("the built-in OpenColorIO config parses");
                Arc::new(ColourConfig {
                    config,
                    source: BUILTIN_CONFIG.to_string(),
                })
            })
            .clone()
    }

    /// The config of `path` (an `.ocio` file, an `.ocioz` archive or an `ocio://` built-in
    /// name), loaded once per content. Errors name the file and say what is wrong in it.
    pub fn open(path: &Path) -> Result<Arc<ColourConfig>, ImageError> {
        let source = path.to_string_lossy().to_string();
        if source.starts_with("ocio://") {
            if source == BUILTIN_CONFIG {
                return Ok(Self::builtin());
            }
            return Self::load(&source, Vec::new());
        }
        let bytes = std::fs::read(path).map_err(|e| ImageError::Io {
            path: path.to_path_buf(),
            source: e,
        })?;
        Self::load(&source, bytes)
    }

    fn load(source: &str, bytes: Vec<u8>) -> Result<Arc<ColourConfig>, ImageError> {
        let mut cache = loaded().lock().unwrap_or_else(|e| e.into_inner());
        if let Some((b, c)) = cache.get(source) {
            if *b == bytes {
                return Ok(c.clone());
            }
        }
        let config = ocio::Config::create_from_file(source)
            .and_then(|c| c.validate().map(|()| c))
            .map_err(|e| colour_err(format!("OpenColorIO config {source}: {}", e.message())))?;
        let c = Arc::new(ColourConfig {
            config,
            source: source.to_string(),
        });
        cache.insert(source.to_string(), (bytes, c.clone()));
        Ok(c)
    }

    /// The config a graph uses: `path` when given (relative paths as the caller resolved them),
    /// else the built-in one. The environment is not read here: what a node computes depends
    /// only on its parameters (the command line puts `$OCIO` into them, so it is in the cache
    /// keys and a farm task uses its submit's config).
    pub fn resolve(path: Option<&Path>) -> Result<Arc<ColourConfig>, ImageError> {
        match path.filter(|p| !p.as_os_str().is_empty()) {
            Some(p) => Self::open(p),
            None => Ok(Self::builtin()),
        }
    }

    /// Where the config was loaded from (a file, or an `ocio://` name).
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The names of the config's active colour spaces, in its order.
    pub fn colour_spaces(&self) -> Vec<String> {
        (0..self.config.num_color_spaces())
            .map(|i| self.config.color_space_name_by_index(i).to_string())
            .collect()
    }

    /// The config's displays, in its order.
    pub fn displays(&self) -> Vec<String> {
        (0..self.config.num_displays())
            .map(|i| self.config.display(i))
            .collect()
    }

    /// The views of `display`, in the config's order.
    pub fn views(&self, display: &str) -> Vec<String> {
        (0..self.config.num_views(display))
            .map(|i| self.config.view(display, i))
            .collect()
    }

    /// Checks that `name` is a colour space (or role, or alias) of the config: an error names
    /// the config and the name and suggests close names.
    pub fn check_space(&self, name: &str) -> Result<(), ImageError> {
        if self.config.get_color_space(name).is_some() {
            return Ok(());
        }
        Err(colour_err(format!(
            "no colour space `{name}` in the OpenColorIO config {}{}",
            self.source,
            suggestions(name, &self.colour_spaces())
        )))
    }

    /// The conversion from colour space `src` to `dst`. Unknown names are errors naming the
    /// config ([`Self::check_space`]).
    pub fn transform(&self, src: &str, dst: &str) -> Result<ColourTransform, ImageError> {
        self.check_space(src)?;
        self.check_space(dst)?;
        let p = self.config.get_processor(src, dst).map_err(|e| {
            colour_err(format!(
                "OpenColorIO config {}: from `{src}` to `{dst}`: {}",
                self.source,
                e.message()
            ))
        })?;
        Ok(ColourTransform::new(p, format!("`{src}` to `{dst}`")))
    }

    /// The display/view transform from scene-linear space `src` to `display`'s `view` (a
    /// preview: tone mapping and the display's encoding, as the config defines the view).
    pub fn display_view(
        &self,
        src: &str,
        display: &str,
        view: &str,
    ) -> Result<ColourTransform, ImageError> {
        self.check_space(src)?;
        let displays = self.displays();
        if !displays.iter().any(|d| d == display) {
            return Err(colour_err(format!(
                "no display `{display}` in the OpenColorIO config {}{}",
                self.source,
                suggestions(display, &displays)
            )));
        }
        let views = self.views(display);
        if !views.iter().any(|v| v == view) {
            return Err(colour_err(format!(
                "display `{display}` of the OpenColorIO config {} has no view `{view}`{}",
                self.source,
                suggestions(view, &views)
            )));
        }
        let p = self
            .config
            .get_display_view_processor(src, display, view)
            .map_err(|e| {
                colour_err(format!(
                    "OpenColorIO config {}: `{src}` to `{display}` / `{view}`: {}",
                    self.source,
                    e.message()
                ))
            })?;
        Ok(ColourTransform::new(
            p,
            format!("`{src}` to `{display}` / `{view}`"),
        ))
    }
}

/// A colour conversion ready to apply to pixels (OpenColorIO's CPU processor).
#[derive(Clone, Debug)]
pub struct ColourTransform {
    cpu: ocio::CpuProcessor,
    identity: bool,
    label: String,
}

impl ColourTransform {
    fn new(p: ocio::Processor, label: String) -> ColourTransform {
        let cpu = p.default_cpu_processor();
        ColourTransform {
            identity: cpu.is_no_op(),
            cpu,
            label,
        }
    }

    /// True when the conversion changes nothing (the same space, or spaces the config says
    /// are one): [`Self::apply`] then leaves the pixels as they are, bit for bit.
    pub fn is_identity(&self) -> bool {
        self.identity
    }

    /// What it converts, for messages: "`A` to `B`".
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The conversion of one RGB value.
    pub fn apply_rgb(&self, rgb: [f32; 3]) -> [f32; 3] {
        let mut p = rgb;
        if !self.identity {
            self.cpu.apply_rgb(&mut p);
        }
        p
    }

    /// Converts the colour of `img` in place: RGB and RGBA images (alpha is not a colour and
    /// stays), and gray images as R = G = B (the result's first channel kept; gray stays gray
    /// only for conversions that keep the neutral axis, as all the listed ones do). Two
    /// channels are gray + alpha. Rows in parallel; the result does not depend on the thread
    /// count.
    pub fn apply(&self, img: &mut Image) {
        if self.identity {
            return;
        }
        let c = img.channels;
        let row = img.width * c;
        if row == 0 {
            return;
        }
        img.data.par_chunks_mut(row).for_each(|line| match c {
            3 => self.cpu.apply_rgb_slice(line),
            4 => {
                // Colour through the processor, alpha as it was (OpenColorIO leaves it too,
                // but it is not a colour to convert).
                let alphas: Vec<f32> = line.iter().skip(3).step_by(4).copied().collect();
                self.cpu.apply_rgba_slice(line);
                for (px, a) in line.chunks_exact_mut(4).zip(alphas) {
                    px[3] = a;
                }
            }
            _ => {
                for px in line.chunks_exact_mut(c) {
                    let g = px[0];
                    px[0] = self.apply_rgb([g, g, g])[1];
                }
            }
        });
    }
}

/// The colour management of a file reader: the file's colour space, the working space and the
/// config naming them (the readers' params).
#[derive(Clone, Debug, Default, PartialEq, vfxgraph_params::Options)]
pub struct ReadColour {
    /// the file's colour space, as the OpenColorIO config names it (e.g. `ARRI LogC3 (EI800)`,
    /// `ACEScct`, `sRGB Encoded Rec.709 (sRGB)`); its code values are converted to the working
    /// space. Empty: the format's own meaning — sRGB for 8/16-bit PNG, JPEG and TIFF, the DPX
    /// header's transfer, float formats linear Rec. 709
    pub colour_space: String,
    /// the graph's scene-linear working space: linear_rec709 (Rec. 709 / sRGB primaries) |
    /// acescg (ACES AP1)
    pub working_space: WorkingSpace,
    /// an OpenColorIO config (.ocio or .ocioz) naming the colour spaces; empty: the ACES studio
    /// config built into OpenColorIO (`--ocio FILE` or $OCIO set it for every node)
    #[param(path = "input")]
    pub ocio_config: String,
}

/// The colour management of a file writer (the writers' params).
#[derive(Clone, Debug, Default, PartialEq, vfxgraph_params::Options)]
pub struct WriteColour {
    /// the file's colour space, as the OpenColorIO config names it: the working space's values
    /// are converted to it and written as code values. Empty: the format's own meaning (sRGB for
    /// 8/16-bit PNG, JPEG and TIFF, DPX 10-bit Cineon log, float formats linear Rec. 709)
    pub colour_space: String,
    /// a preview's view (e.g. `ACES 2.0 - SDR 100 nits (Rec.709)`, `Un-tone-mapped`): the
    /// display/view transform of `display` is applied and its display code values written;
    /// excludes `colour_space`. Empty: none
    pub view: String,
    /// the display of `view` (e.g. `sRGB - Display`, `Rec.2100-PQ - Display`); empty: the
    /// config's default display
    pub display: String,
    /// the graph's scene-linear working space: linear_rec709 | acescg
    pub working_space: WorkingSpace,
    /// an OpenColorIO config (.ocio or .ocioz); empty: the built-in ACES studio config
    /// (`--ocio FILE` or $OCIO set it for every node)
    #[param(path = "input")]
    pub ocio_config: String,
}

/// The plate an image writer keeps the code values of (the writers' `plate` param).
#[derive(Clone, Debug, Default, PartialEq, vfxgraph_params::Options)]
pub struct KeepPlate {
    /// the plate file (pattern) the image was composited over, in the format, depth and colour
    /// space written here: every pixel the graph left as the plate reads (the working-space
    /// values equal bit for bit) is written with the plate's own code values, so the output is
    /// the plate bit for bit wherever nothing was added — whatever the colour space's round
    /// trip does to the last bit. Empty: none
    #[param(path = "input")]
    pub plate: String,
}

impl ReadColour {
    /// Reads the image file `path` into the working space. `config` is the config file as the
    /// caller resolved `ocio_config` (None when empty). With no colour space and the default
    /// working space this is [`crate::read_image`], bit for bit.
    pub fn read(&self, path: &Path, config: Option<&Path>) -> Result<Image, ImageError> {
        let at = |e: ImageError| e.at_path(path);
        if self.colour_space.is_empty() {
            let mut img = crate::io::read_image(path)?;
            if self.working_space != WorkingSpace::LinearRec709 {
                let c = ColourConfig::resolve(config).map_err(at)?;
                c.transform(LINEAR_REC709, self.working_space.name())
                    .map_err(at)?
                    .apply(&mut img);
            }
            return Ok(img);
        }
        let c = ColourConfig::resolve(config).map_err(at)?;
        let t = c
            .transform(&self.colour_space, self.working_space.name())
            .map_err(at)?;
        let mut img = crate::io::read_image_as(path, crate::io::Values::Codes)?;
        t.apply(&mut img);
        Ok(img)
    }

    /// The conversion of an image the format's decoder made linear Rec. 709 (sRGB-decoded
    /// video frames, say) into the working space: from `colour_space` when one is named (the
    /// decoder's sRGB curve undone first, as the frames' code values), else from linear
    /// Rec. 709. `what` names the source in errors.
    pub fn convert_decoded(
        &self,
        img: &mut Image,
        config: Option<&Path>,
        what: &str,
    ) -> Result<(), ImageError> {
        let named = |e: ImageError| colour_err(format!("{what}: {e}"));
        if self.colour_space.is_empty() && self.working_space == WorkingSpace::LinearRec709 {
            return Ok(());
        }
        let c = ColourConfig::resolve(config).map_err(named)?;
        if self.colour_space.is_empty() {
            c.transform(LINEAR_REC709, self.working_space.name())
                .map_err(named)?
                .apply(img);
            return Ok(());
        }
        let t = c
            .transform(&self.colour_space, self.working_space.name())
            .map_err(named)?;
        for_colour(img, crate::color::linear_to_srgb);
        t.apply(img);
        Ok(())
    }
}

impl WriteColour {
    /// The transform to the file's values and whether they are code values: `None` and
    /// [`Values::Linear`](crate::io::Values::Linear) when the format's own encoding of linear
    /// Rec. 709 is wanted from a linear Rec. 709 working space (nothing to convert).
    pub fn transform(
        &self,
        config: Option<&Path>,
    ) -> Result<(Option<ColourTransform>, crate::io::Values), ImageError> {
        use crate::io::Values;
        let work = self.working_space.name();
        if !self.view.is_empty() {
            if !self.colour_space.is_empty() {
                return Err(colour_err(format!(
                    "`colour_space` (`{}`) and `view` (`{}`) both given: a file is written in                      one or through the other",
                    self.colour_space, self.view
                )));
            }
            let c = ColourConfig::resolve(config)?;
            let display = if self.display.is_empty() {
                c.config.default_display()
            } else {
                self.display.clone()
            };
            let t = c.display_view(work, &display, &self.view)?;
            return Ok((Some(t), Values::Codes));
        }
        if !self.display.is_empty() {
            return Err(colour_err(format!(
                "`display` (`{}`) given without a `view`",
                self.display
            )));
        }
        if self.colour_space.is_empty() {
            if self.working_space == WorkingSpace::LinearRec709 {
                return Ok((None, Values::Linear));
            }
            let c = ColourConfig::resolve(config)?;
            return Ok((Some(c.transform(work, LINEAR_REC709)?), Values::Linear));
        }
        let c = ColourConfig::resolve(config)?;
        Ok((Some(c.transform(work, &self.colour_space)?), Values::Codes))
    }

    /// Writes `img` (in the working space) to `path` in the file's colour space, view or the
    /// format's own encoding ([`Self::transform`]). With none of them and the default working
    /// space this is [`crate::write_image`], bit for bit.
    pub fn write(&self, path: &Path, img: &Image, config: Option<&Path>) -> Result<(), ImageError> {
        self.write_keeping(path, img, config, None)
    }

    /// [`Self::write`], keeping the code values of `plate` ([`KeepPlate`]): the plate is read
    /// as a reader in this colour space would read it (its values as this writer writes them,
    /// then converted to the working space); where a pixel of `img` equals the plate's there
    /// bit for bit, the plate's file values are written instead of the converted ones.
    pub fn write_keeping(
        &self,
        path: &Path,
        img: &Image,
        config: Option<&Path>,
        plate: Option<&Path>,
    ) -> Result<(), ImageError> {
        let (t, values) = self.transform(config).map_err(|e| e.at_path(path))?;
        let mut out = img.clone();
        if let Some(t) = &t {
            t.apply(&mut out);
        }
        if let Some(plate) = plate {
            if !self.view.is_empty() {
                return Err(colour_err(format!(
                    "{}: `plate` keeps a plate's codes, a `view` is a preview of the image: not \
                     both",
                    path.display()
                )));
            }
            let file = crate::io::read_image_as(plate, values)?;
            let mut read = file.clone();
            if !self.colour_space.is_empty() || self.working_space != WorkingSpace::LinearRec709 {
                let c = ColourConfig::resolve(config).map_err(|e| e.at_path(plate))?;
                let src = if self.colour_space.is_empty() {
                    LINEAR_REC709
                } else {
                    self.colour_space.as_str()
                };
                c.transform(src, self.working_space.name())
                    .map_err(|e| e.at_path(plate))?
                    .apply(&mut read);
            }
            if (read.width, read.height, read.channels) != (img.width, img.height, img.channels) {
                return Err(colour_err(format!(
                    "{}: the plate {} is {}×{}×{}, the image {}×{}×{}",
                    path.display(),
                    plate.display(),
                    read.width,
                    read.height,
                    read.channels,
                    img.width,
                    img.height,
                    img.channels
                )));
            }
            let c = img.channels;
            for (((o, i), r), f) in out
                .data
                .chunks_exact_mut(c)
                .zip(img.data.chunks_exact(c))
                .zip(read.data.chunks_exact(c))
                .zip(file.data.chunks_exact(c))
            {
                if i.iter().zip(r).all(|(a, b)| a.to_bits() == b.to_bits()) {
                    o.copy_from_slice(f);
                }
            }
        }
        crate::io::write_image_as(path, &out, values)
    }

    /// The frames of a writer whose encoder takes linear Rec. 709 and applies the sRGB curve
    /// (video): converted, and for code values ([`Self::transform`]) the sRGB curve undone so
    /// that the encoder's curve gives the codes back. `what` names the file in errors.
    pub fn convert_for_srgb_encoder(
        &self,
        frames: &mut [Image],
        config: Option<&Path>,
        what: &str,
    ) -> Result<(), ImageError> {
        let (t, values) = self
            .transform(config)
            .map_err(|e| colour_err(format!("{what}: {e}")))?;
        for img in frames {
            if let Some(t) = &t {
                t.apply(img);
            }
            if values == crate::io::Values::Codes {
                for_colour(img, |v| crate::color::srgb_to_linear(v.clamp(0.0, 1.0)));
            }
        }
        Ok(())
    }
}

/// Applies `f` to the colour samples of `img` (not alpha).
fn for_colour(img: &mut Image, f: impl Fn(f32) -> f32 + Sync) {
    let c = img.channels;
    let alpha = c == 2 || c == 4;
    img.data.par_iter_mut().enumerate().for_each(|(i, v)| {
        if !(alpha && i % c == c - 1) {
            *v = f(*v);
        }
    });
}

fn colour_err(message: String) -> ImageError {
    ImageError::Colour(message)
}

/// ": did you mean ..." with the names sharing a word with `name` (case-insensitive), else the
/// list of all names.
fn suggestions(name: &str, names: &[String]) -> String {
    let lower = name.to_lowercase();
    let words: Vec<&str> = lower
        .split(|c: char| !c.is_alphanumeric())
        .filter(|w| w.len() >= 2)
        .collect();
    let close: Vec<&String> = names
        .iter()
        .filter(|n| {
            let n = n.to_lowercase();
            words.iter().any(|w| n.contains(w))
        })
        .collect();
    if !close.is_empty() && close.len() <= 8 {
        let list: Vec<String> = close.iter().map(|n| format!("`{n}`")).collect();
        format!(" (did you mean {}?)", list.join(", "))
    } else {
        let list: Vec<String> = names.iter().map(|n| format!("`{n}`")).collect();
        format!(" (it has {})", list.join(", "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_config_has_the_listed_spaces_and_the_working_spaces() {
        let c = ColourConfig::builtin();
        for name in [
            "sRGB Encoded Rec.709 (sRGB)",
            "Camera Rec.709",
            LINEAR_REC709,
            "ACES2065-1",
            "ACEScg",
            "ACEScct",
            "ARRI LogC3 (EI800)",
            "ARRI LogC4",
            "S-Log3 S-Gamut3.Cine",
            "Rec.1886 Rec.709 - Display",
            "Rec.2100-HLG - Display",
            "Rec.2100-PQ - Display",
        ] {
            c.check_space(name).unwrap();
        }
        assert!(c.transform("ACEScg", "ACEScg").unwrap().is_identity());
        assert!(!c
            .transform(
                WorkingSpace::LinearRec709.name(),
                WorkingSpace::AcesCg.name()
            )
            .unwrap()
            .is_identity());
    }

    /// 18% grey in LogC3 (EI 800) is code 0.391007 (ARRI's table), and linear Rec. 709
    /// 0.18 is sRGB 0.461356 (IEC 61966-2-1).
    #[test]
    fn known_points() {
        let c = ColourConfig::builtin();
        let t = c.transform(LINEAR_REC709, "ARRI LogC3 (EI800)").unwrap();
        let v = t.apply_rgb([0.18; 3]);
        assert!(v.iter().all(|x| (x - 0.391_007).abs() < 1e-5), "{v:?}");
        let t = c
            .transform(LINEAR_REC709, "sRGB Encoded Rec.709 (sRGB)")
            .unwrap();
        let v = t.apply_rgb([0.18; 3]);
        assert!(v.iter().all(|x| (x - 0.461_356).abs() < 1e-5), "{v:?}");
    }

    #[test]
    fn unknown_names_are_errors_naming_the_config_and_suggesting() {
        let c = ColourConfig::builtin();
        let e = c.transform("LogC3", "ACEScg").unwrap_err().to_string();
        assert!(
            e.contains("`LogC3`") && e.contains(BUILTIN_CONFIG) && e.contains("ARRI LogC3 (EI800)"),
            "{e}"
        );
        let e = c
            .display_view("ACEScg", "sRGB - Display", "Filmic")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`Filmic`") && e.contains("Un-tone-mapped"),
            "{e}"
        );
    }

    #[test]
    fn a_malformed_config_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("studio.ocio");
        std::fs::write(&p, "ocio_profile_version: 2\nroles: [unclosed\n").unwrap();
        let e = ColourConfig::open(&p).unwrap_err().to_string();
        assert!(e.contains("studio.ocio") && e.contains("line 3"), "{e}");
        // A transform this port of OpenColorIO does not know: named, with the file.
        std::fs::write(
            &p,
            "ocio_profile_version: 2\nroles: {default: raw}\ncolorspaces:\n  - !<ColorSpace>\n    \
             name: raw\n    from_scene_reference: !<NoSuchTransform> {}\n",
        )
        .unwrap();
        let e = ColourConfig::open(&p).unwrap_err().to_string();
        assert!(
            e.contains("studio.ocio") && e.contains("line 6") && e.contains("NoSuchTransform"),
            "{e}"
        );
        let e = ColourConfig::open(&dir.path().join("none.ocio"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.ocio"), "{e}");
    }

    #[test]
    fn apply_keeps_alpha_and_gray() {
        let c = ColourConfig::builtin();
        let t = c.transform(LINEAR_REC709, "ACEScg").unwrap();
        let mut img = Image::from_vec(1, 1, 4, vec![0.5, 0.2, 0.1, 0.25]).unwrap();
        t.apply(&mut img);
        assert_eq!(img.data[3], 0.25);
        let want = t.apply_rgb([0.5, 0.2, 0.1]);
        assert_eq!(&img.data[..3], &want);
        let mut gray = Image::from_vec(2, 1, 1, vec![0.18, 1.0]).unwrap();
        t.apply(&mut gray);
        assert!((gray.data[0] - 0.18).abs() < 1e-5 && (gray.data[1] - 1.0).abs() < 1e-5);
    }

    /// A studio's own config, written with the transforms such configs are built from
    /// (BuiltinTransform, LogCameraTransform, MatrixTransform, ExponentWithLinearTransform,
    /// ExponentTransform, ColorSpaceTransform, GroupTransform, directions), converts as the
    /// built-in config does (itself checked against PyOpenColorIO): identical values, the
    /// bound (1e-6) an allowance for the order in which equal matrices are composed.
    #[test]
    fn a_studio_config_file_converts_as_the_builtin_one() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("studio.ocio");
        // LogC3 (EI 800) and sRGB spelled out with the constants of ARRI's and IEC 61966-2-1's
        // curves and the ACES CSC matrices, the linear spaces by built-in transforms.
        let text = r#"ocio_profile_version: 2.4
roles: {default: ACES2065-1, scene_linear: ACEScg}
displays: {sRGB: [!<View> {name: Raw, colorspace: ACES2065-1}]}
colorspaces:
  - !<ColorSpace>
    name: ACES2065-1
  - !<ColorSpace>
    name: ACEScg
    to_scene_reference: !<BuiltinTransform> {style: ACEScg_to_ACES2065-1}
  - !<ColorSpace>
    name: Linear Rec.709 (sRGB)
    from_scene_reference: !<GroupTransform>
      children:
        - !<BuiltinTransform> {style: ACEScg_to_ACES2065-1, direction: inverse}
        - !<BuiltinTransform> {style: UTILITY - ACES-AP1_to_LINEAR-REC709_BFD}
  - !<ColorSpace>
    name: LogC3 by hand
    to_scene_reference: !<GroupTransform>
      children:
        - !<LogCameraTransform> {base: 10, log_side_slope: 0.247189638318671, log_side_offset: 0.385536998692443, lin_side_slope: 5.55555555555556, lin_side_offset: 0.0522722750251688, lin_side_break: 0.0105909904954696, direction: inverse}
        - !<MatrixTransform> {matrix: [0.680205505106279, 0.236136601606481, 0.0836578932872398, 0, 0.0854149797421404, 1.01747087860704, -0.102885858349182, 0, 0.00205652166929683, -0.0625625003847921, 1.06050597871549, 0, 0, 0, 0, 1]}
  - !<ColorSpace>
    name: LogC3 builtin
    to_scene_reference: !<BuiltinTransform> {style: ARRI_ALEXA-LOGC-EI800-AWG_to_ACES2065-1}
  - !<ColorSpace>
    name: sRGB by hand
    to_scene_reference: !<GroupTransform>
      children:
        - !<ExponentWithLinearTransform> {gamma: 2.4, offset: 0.055}
        - !<ColorSpaceTransform> {src: Linear Rec.709 (sRGB), dst: ACES2065-1}
  - !<ColorSpace>
    name: Gamma 2.2 by hand
    from_scene_reference: !<GroupTransform>
      children:
        - !<ColorSpaceTransform> {src: ACES2065-1, dst: Linear Rec.709 (sRGB)}
        - !<ExponentTransform> {value: 2.2, style: pass_thru, direction: inverse}
"#;
        std::fs::write(&p, text).unwrap();
        let studio = ColourConfig::open(&p).unwrap();
        let builtin = ColourConfig::builtin();
        let values = [-0.02f32, 0.0, 0.01, 0.0929, 0.18, 0.391, 0.5, 0.8, 1.0];
        let mut worst = 0.0f32;
        for (ours, theirs) in [
            ("LogC3 by hand", "ARRI LogC3 (EI800)"),
            ("LogC3 builtin", "ARRI LogC3 (EI800)"),
            ("sRGB by hand", "sRGB Encoded Rec.709 (sRGB)"),
            ("Gamma 2.2 by hand", "Gamma 2.2 Encoded Rec.709"),
        ] {
            for work in [LINEAR_REC709, "ACEScg"] {
                let a = studio.transform(ours, work).unwrap();
                let b = builtin.transform(theirs, work).unwrap();
                for &v in &values {
                    for rgb in [[v, v, v], [v, 0.5 * v + 0.1, 0.2]] {
                        let (x, y) = (a.apply_rgb(rgb), b.apply_rgb(rgb));
                        for k in 0..3 {
                            let e = (x[k] - y[k]).abs() / y[k].abs().max(1.0);
                            assert!(e < 1e-6, "{ours} to {work} at {rgb:?}: {x:?} vs {y:?}");
                            worst = worst.max(e);
                        }
                    }
                }
            }
        }
        eprintln!("studio config vs built-in: worst {worst:e}");
        assert!(worst < 1e-6, "worst {worst}");
        // A name of this config only, and the builtin's names absent from it: errors naming
        // the file.
        let e = studio
            .transform("ACEScct", "ACEScg")
            .unwrap_err()
            .to_string();
        assert!(e.contains("studio.ocio") && e.contains("`ACEScct`"), "{e}");
    }
}
