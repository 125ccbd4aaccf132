//! A shot's plate as its operations take it: (frame number, linear-radiance image) in frame
//! order, and the frames of it an operation asks for.

use vfxgraph_imaging::Image;

/// A frame the plate lacks, with the plate's frames.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("the plate has no frame {frame} (its frames are {range})")]
pub struct MissingFrame {
    /// The frame asked for.
    pub frame: i64,
    /// The plate's frames: `first–last`, or `none`.
    pub range: String,
}

/// The frames `frames` of `plate`, in that order (all of them when `frames` is empty); an error
/// names the first frame the plate lacks.
pub fn plate_frames<'a>(
    plate: &[(i64, &'a Image)],
    frames: &[i64],
) -> Result<Vec<(i64, &'a Image)>, MissingFrame> {
    if frames.is_empty() {
        return Ok(plate.to_vec());
    }
    let missing = |frame| MissingFrame {
        frame,
        range: match (plate.first(), plate.last()) {
            (Some(a), Some(b)) => format!("{}–{}", a.0, b.0),
            _ => "none".into(),
        },
    };
    let find = |f: &i64| plate.iter().find(|(g, _)| g == f).copied();
    frames
        .iter()
        .map(|f| find(f).ok_or_else(|| missing(*f)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_in_order_or_an_error_naming_the_range() {
        let (a, b) = (Image::new(1, 1, 3), Image::new(2, 1, 3));
        let plate = [(3, &a), (4, &b)];
        let got = plate_frames(&plate, &[4, 3]).unwrap();
        assert_eq!(got.iter().map(|p| p.0).collect::<Vec<_>>(), [4, 3]);
        assert_eq!(plate_frames(&plate, &[]).unwrap().len(), 2);
        let e = plate_frames(&plate, &[9]).unwrap_err().to_string();
        assert_eq!(e, "the plate has no frame 9 (its frames are 3–4)");
        let e = plate_frames(&[], &[1]).unwrap_err().to_string();
        assert_eq!(e, "the plate has no frame 1 (its frames are none)");
    }
}
