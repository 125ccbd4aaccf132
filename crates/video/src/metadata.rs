//! The camera a phone or camera recorded in a QuickTime / MP4 file's `moov` box: the focal
//! length as a 35 mm equivalent, the lens, make and model, and the picture's size as shown
//! (the video track's size turned by its display matrix: a portrait phone clip is taller than
//! wide).
//!
//! The items are QuickTime metadata (Apple, *QuickTime File Format Specification*, "Metadata":
//! a `meta` box whose `keys` box names each item, e.g.
//! `com.apple.quicktime.camera.focal_length.35mm_equivalent`, and whose `ilst` box holds the
//! values in `data` boxes typed by the well-known types: UTF-8, big-endian signed and unsigned
//! integers, IEEE floats). Phones write the `meta` box in `moov`; FFmpeg (`-movflags
//! use_metadata_tags`) writes it in `moov/udta`; both are read. The track's size and matrix
//! are the `tkhd` box's (ISO/IEC 14496-12 §8.3.2).
//!
//! Only the box headers on the way to `moov` are read, then `moov` itself, which is refused
//! above [`MAX_MOOV_BYTES`]; every box size is checked against its parent before use, so a
//! damaged file is an error, never an allocation it declares.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// The largest `moov` box read (a 2-hour clip's sample tables are a few MB).
pub const MAX_MOOV_BYTES: u64 = 256 << 20;

/// The metadata key of the focal length as a 35 mm equivalent (millimetres).
pub const KEY_FOCAL_35MM: &str = "com.apple.quicktime.camera.focal_length.35mm_equivalent";

/// What a QuickTime / MP4 file says of the camera.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CameraMetadata {
    /// The focal length giving the same diagonal field of view on a 36 × 24 mm frame, mm.
    pub focal_35mm: Option<f64>,
    /// The lens as recorded (e.g. "iPhone 12 back camera 4.2mm f/1.6").
    pub lens_model: Option<String>,
    /// The camera's maker.
    pub make: Option<String>,
    /// The camera's model.
    pub model: Option<String>,
    /// The video track's picture size as shown (its display matrix applied), px.
    pub display_size: Option<(u32, u32)>,
}

/// A box: its type and its payload's range in the buffer it was found in.
#[derive(Clone, Copy, Debug)]
struct BoxRef {
    kind: [u8; 4],
    start: usize,
    end: usize,
}

/// The boxes in `b[from..to]`, each checked to lie within it.
fn children(b: &[u8], from: usize, to: usize) -> Result<Vec<BoxRef>, String> {
    let mut out = Vec::new();
    let mut at = from;
    while at + 8 <= to {
        let size32 = u32::from_be_bytes(b[at..at + 4].try_into().unwrap()) as u64;
        let kind: [u8; 4] = b[at + 4..at + 8].try_into().unwrap();
        let (size, header) = match size32 {
            0 => ((to - at) as u64, 8),
            1 => {
                if at + 16 > to {
                    return Err(format!("box `{}` cut short", kind_str(kind)));
                }
                (
                    u64::from_be_bytes(b[at + 8..at + 16].try_into().unwrap()),
                    16,
                )
            }
            s => (s, 8),
        };
        if size < header as u64 || size > (to - at) as u64 {
            return Err(format!(
                "box `{}` declares {size} bytes, {} are left",
                kind_str(kind),
                to - at
            ));
        }
        out.push(BoxRef {
            kind,
            start: at + header,
            end: at + size as usize,
        });
        at += size as usize;
    }
    Ok(out)
}

fn kind_str(k: [u8; 4]) -> String {
    k.iter()
        .map(|&c| if c.is_ascii_graphic() { c as char } else { '?' })
        .collect()
}

fn find(b: &[u8], parent: BoxRef, kind: &[u8; 4]) -> Result<Option<BoxRef>, String> {
    Ok(children(b, parent.start, parent.end)?
        .into_iter()
        .find(|c| &c.kind == kind))
}

/// The metadata of a file on disk (only `moov` is read into memory).
pub fn camera_metadata(path: &Path) -> Result<CameraMetadata, String> {
    let mut f = File::open(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let len = f
        .metadata()
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?
        .len();
    let mut at = 0u64;
    while at + 8 <= len {
        let mut head = [0u8; 16];
        f.seek(SeekFrom::Start(at)).map_err(|e| e.to_string())?;
        let n = (len - at).min(16) as usize;
        f.read_exact(&mut head[..n]).map_err(|e| e.to_string())?;
        let size32 = u32::from_be_bytes(head[0..4].try_into().unwrap()) as u64;
        let kind: [u8; 4] = head[4..8].try_into().unwrap();
        let (size, header) = match size32 {
            0 => (len - at, 8u64),
            1 if n == 16 => (u64::from_be_bytes(head[8..16].try_into().unwrap()), 16),
            1 => return Err(format!("{}: top-level box cut short", path.display())),
            s => (s, 8),
        };
        if size < header || size > len - at {
            return Err(format!(
                "{}: box `{}` at byte {at} declares {size} bytes, the file has {} left",
                path.display(),
                kind_str(kind),
                len - at
            ));
        }
        if &kind == b"moov" {
            if size > MAX_MOOV_BYTES {
                return Err(format!(
                    "{}: a `moov` box of {size} bytes (at most {MAX_MOOV_BYTES} are read)",
                    path.display()
                ));
            }
            let mut moov = vec![0u8; size as usize];
            f.seek(SeekFrom::Start(at)).map_err(|e| e.to_string())?;
            f.read_exact(&mut moov).map_err(|e| e.to_string())?;
            return moov_metadata(&moov).map_err(|e| format!("{}: {e}", path.display()));
        }
        at += size;
    }
    Err(format!(
        "{}: no `moov` box (not a QuickTime / MP4 file)",
        path.display()
    ))
}

/// The metadata of a whole `moov` box (its header included).
pub fn moov_metadata(moov: &[u8]) -> Result<CameraMetadata, String> {
    let top = children(moov, 0, moov.len())?;
    let moov_box = top
        .into_iter()
        .find(|c| &c.kind == b"moov")
        .ok_or("no `moov` box")?;
    let mut m = CameraMetadata::default();
    let mut items = Vec::new();
    for c in children(moov, moov_box.start, moov_box.end)? {
        match &c.kind {
            b"meta" => items.extend(meta_items(moov, c)?),
            b"udta" => {
                if let Some(meta) = find(moov, c, b"meta")? {
                    items.extend(meta_items(moov, meta)?);
                }
            }
            b"trak" if m.display_size.is_none() => m.display_size = video_track_size(moov, c)?,
            _ => {}
        }
    }
    for (key, value) in items {
        match key.as_str() {
            KEY_FOCAL_35MM => m.focal_35mm = value.number().filter(|f| *f > 0.0),
            "com.apple.quicktime.camera.lens_model" => m.lens_model = value.text(),
            "com.apple.quicktime.make" => m.make = value.text(),
            "com.apple.quicktime.model" => m.model = value.text(),
            _ => {}
        }
    }
    Ok(m)
}

/// A metadata value as typed by its `data` box.
#[derive(Clone, Debug, PartialEq)]
enum Item {
    Text(String),
    Number(f64),
    Other,
}

impl Item {
    fn number(&self) -> Option<f64> {
        match self {
            Item::Number(v) => Some(*v),
            Item::Text(s) => s.trim().parse().ok(),
            Item::Other => None,
        }
        .filter(|v: &f64| v.is_finite())
    }

    fn text(&self) -> Option<String> {
        match self {
            Item::Text(s) => Some(s.clone()),
            _ => None,
        }
    }
}

/// The (key, value) items of a QuickTime `meta` box.
fn meta_items(b: &[u8], meta: BoxRef) -> Result<Vec<(String, Item)>, String> {
    // QuickTime's `meta` has no version/flags; ISO's (a full box) has 4 bytes of them.
    let mut inner = meta;
    if inner.end - inner.start >= 8 && &b[inner.start + 4..inner.start + 8] != b"hdlr" {
        inner.start += 4;
    }
    let boxes = children(b, inner.start, inner.end)?;
    let (Some(keys), Some(ilst)) = (
        boxes.iter().find(|c| &c.kind == b"keys"),
        boxes.iter().find(|c| &c.kind == b"ilst"),
    ) else {
        return Ok(Vec::new());
    };
    // keys: version/flags, entry count, then (size, namespace, name) entries.
    if keys.end - keys.start < 8 {
        return Err("`keys` box cut short".into());
    }
    let count = u32::from_be_bytes(b[keys.start + 4..keys.start + 8].try_into().unwrap());
    let mut names = Vec::new();
    let mut at = keys.start + 8;
    for _ in 0..count {
        if at + 8 > keys.end {
            return Err("`keys` box cut short".into());
        }
        let size = u32::from_be_bytes(b[at..at + 4].try_into().unwrap()) as usize;
        if size < 8 || size > keys.end - at {
            return Err(format!("a `keys` entry declares {size} bytes"));
        }
        names.push(String::from_utf8_lossy(&b[at + 8..at + size]).into_owned());
        at += size;
    }
    let mut out = Vec::new();
    for item in children(b, ilst.start, ilst.end)? {
        let index = u32::from_be_bytes(item.kind) as usize;
        let Some(name) = index.checked_sub(1).and_then(|i| names.get(i)) else {
            continue;
        };
        let Some(data) = find(b, item, b"data")? else {
            continue;
        };
        if data.end - data.start < 8 {
            return Err("a `data` box cut short".into());
        }
        let ty = u32::from_be_bytes(b[data.start..data.start + 4].try_into().unwrap()) & 0xFF_FFFF;
        let v = &b[data.start + 8..data.end];
        let be = |n: usize| -> Option<u64> {
            (v.len() == n).then(|| v.iter().fold(0u64, |a, &x| (a << 8) | x as u64))
        };
        let value = match ty {
            1 => Item::Text(String::from_utf8_lossy(v).into_owned()),
            // Big-endian signed integer of 1, 2, 3, 4 or 8 bytes.
            21 => match v.len() {
                1 | 2 | 3 | 4 | 8 => {
                    let raw = be(v.len()).unwrap();
                    let shift = 64 - 8 * v.len() as u32;
                    Item::Number((((raw << shift) as i64) >> shift) as f64)
                }
                _ => Item::Other,
            },
            22 => match v.len() {
                1 | 2 | 3 | 4 | 8 => Item::Number(be(v.len()).unwrap() as f64),
                _ => Item::Other,
            },
            23 => be(4).map_or(Item::Other, |x| {
                Item::Number(f32::from_bits(x as u32) as f64)
            }),
            24 => be(8).map_or(Item::Other, |x| Item::Number(f64::from_bits(x))),
            _ => Item::Other,
        };
        out.push((name.clone(), value));
    }
    Ok(out)
}

/// The picture size of a video track as shown: `tkhd`'s width and height (16.16 fixed point),
/// swapped when its matrix turns the picture a quarter turn. `None` for other tracks.
fn video_track_size(b: &[u8], trak: BoxRef) -> Result<Option<(u32, u32)>, String> {
    let is_video = match find(b, trak, b"mdia")? {
        Some(mdia) => match find(b, mdia, b"hdlr")? {
            Some(h) => h.end - h.start >= 12 && &b[h.start + 8..h.start + 12] == b"vide",
            None => false,
        },
        None => false,
    };
    let Some(tkhd) = find(b, trak, b"tkhd")?.filter(|_| is_video) else {
        return Ok(None);
    };
    let p = &b[tkhd.start..tkhd.end];
    // version 0: 4 + 4·5 bytes before the reserved/layer fields; version 1: 4 + 8 + 8 + 4 + 4 + 8.
    let head = match p.first() {
        Some(0) => 4 + 20,
        Some(1) => 4 + 32,
        _ => return Err("`tkhd` box of an unknown version".into()),
    };
    // reserved 8, layer 2, group 2, volume 2, reserved 2, matrix 36, width 4, height 4.
    let m = head + 16;
    if p.len() < m + 44 {
        return Err("`tkhd` box cut short".into());
    }
    let word = |i: usize| i32::from_be_bytes(p[i..i + 4].try_into().unwrap());
    let (a, bq) = (word(m), word(m + 4));
    let w = (word(m + 36) as u32) >> 16;
    let h = (word(m + 40) as u32) >> 16;
    if w == 0 || h == 0 {
        return Ok(None);
    }
    // A quarter turn: a = 0 and b = ±1 (16.16).
    Ok(Some(if a == 0 && bq != 0 { (h, w) } else { (w, h) }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed(kind: &[u8; 4], payload: &[u8]) -> Vec<u8> {
        let mut v = ((payload.len() + 8) as u32).to_be_bytes().to_vec();
        v.extend_from_slice(kind);
        v.extend_from_slice(payload);
        v
    }

    /// A `moov` as a phone writes it: `meta` directly in `moov`, the focal length a signed
    /// 16-bit integer, a portrait video track (1920 × 1080 turned a quarter).
    fn phone_moov(focal: &[u8], ty: u32) -> Vec<u8> {
        let names = [KEY_FOCAL_35MM, "com.apple.quicktime.model"];
        let mut keys = vec![0, 0, 0, 0];
        keys.extend_from_slice(&(names.len() as u32).to_be_bytes());
        for n in names {
            keys.extend_from_slice(&((n.len() + 8) as u32).to_be_bytes());
            keys.extend_from_slice(b"mdta");
            keys.extend_from_slice(n.as_bytes());
        }
        let data = |ty: u32, v: &[u8]| {
            let mut p = ty.to_be_bytes().to_vec();
            p.extend_from_slice(&[0, 0, 0, 0]);
            p.extend_from_slice(v);
            boxed(b"data", &p)
        };
        let mut ilst = boxed(&1u32.to_be_bytes(), &data(ty, focal));
        ilst.extend(boxed(&2u32.to_be_bytes(), &data(1, b"iPhone 12")));
        let mut meta = boxed(b"hdlr", &[0; 24]);
        meta.extend(boxed(b"keys", &keys));
        meta.extend(boxed(b"ilst", &ilst));
        // tkhd version 0 with a 90° matrix (a = 0, b = 1, c = −1, d = 0, w = 1).
        let mut tkhd = vec![0u8; 4 + 20 + 16];
        let one = 0x0001_0000i32;
        for v in [0, one, 0, -one, 0, 0, 0, 0, 0x4000_0000] {
            tkhd.extend_from_slice(&v.to_be_bytes());
        }
        tkhd.extend_from_slice(&(1920u32 << 16).to_be_bytes());
        tkhd.extend_from_slice(&(1080u32 << 16).to_be_bytes());
        let mut hdlr = vec![0u8; 8];
        hdlr.extend_from_slice(b"vide");
        hdlr.extend_from_slice(&[0; 12]);
        let mdia = boxed(b"mdia", &boxed(b"hdlr", &hdlr));
        let mut trak = boxed(b"tkhd", &tkhd);
        trak.extend(mdia);
        let mut moov = boxed(b"trak", &trak);
        moov.extend(boxed(b"meta", &meta));
        boxed(b"moov", &moov)
    }

    #[test]
    fn reads_a_phones_focal_length_and_portrait_size() {
        let m = moov_metadata(&phone_moov(&26i16.to_be_bytes(), 21)).unwrap();
        assert_eq!(m.focal_35mm, Some(26.0));
        assert_eq!(m.model.as_deref(), Some("iPhone 12"));
        assert_eq!(m.display_size, Some((1080, 1920)));
        // The same as an unsigned byte, a float and text.
        for (v, ty) in [
            (vec![26u8], 22),
            (26.0f32.to_bits().to_be_bytes().to_vec(), 23),
            (b"26".to_vec(), 1),
        ] {
            assert_eq!(
                moov_metadata(&phone_moov(&v, ty)).unwrap().focal_35mm,
                Some(26.0)
            );
        }
        // A negative or unparsable focal length is none.
        assert_eq!(
            moov_metadata(&phone_moov(&(-3i16).to_be_bytes(), 21))
                .unwrap()
                .focal_35mm,
            None
        );
        assert_eq!(
            moov_metadata(&phone_moov(b"wide", 1)).unwrap().focal_35mm,
            None
        );
    }

    #[test]
    fn damaged_boxes_are_errors_not_allocations() {
        let good = phone_moov(&26i16.to_be_bytes(), 21);
        // Every truncation and every corrupted size byte: an error or a result, never a panic.
        for cut in 0..good.len() {
            let _ = moov_metadata(&good[..cut]);
        }
        for i in 0..good.len() {
            for v in [0u8, 1, 0x7F, 0xFF] {
                let mut bad = good.clone();
                bad[i] = v;
                let _ = moov_metadata(&bad);
            }
        }
        let mut huge = good.clone();
        huge[0..4].copy_from_slice(&u32::MAX.to_be_bytes());
        assert!(moov_metadata(&huge).unwrap_err().contains("declares"));
    }
}
