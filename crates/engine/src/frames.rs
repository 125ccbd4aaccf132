//! Frame ranges: `0..=239`, `0..240`, `1-10,15,20-40:2`, or a single frame.

use std::fmt;
use std::path::{Path, PathBuf};

pub use vfxgraph_fsutil::frame_pattern::{
    check_frame_pattern, format_frame, has_frame_pattern, MAX_FRAME_WIDTH,
};

/// A sorted set of distinct frame numbers.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct FrameSet {
    frames: Vec<i64>,
}

impl FrameSet {
    /// The frames in increasing order.
    pub fn frames(&self) -> &[i64] {
        &self.frames
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Builds from any frames (sorted, deduplicated).
    pub fn from_frames(mut frames: Vec<i64>) -> Self {
        frames.sort_unstable();
        frames.dedup();
        FrameSet { frames }
    }

    /// Parses a range expression. Comma-separated items, each one of: `N`, `A..B` (exclusive),
    /// `A..=B` (inclusive), `A-B` (inclusive), optionally followed by `:STEP`.
    pub fn parse(text: &str) -> Result<FrameSet, String> {
        const LIMIT: usize = 10_000_000;
        let mut frames = Vec::new();
        for item in text.split(',') {
            let item = item.trim();
            if item.is_empty() {
                return Err(format!("empty item in frame range `{text}`"));
            }
            let (range, step) = match item.split_once(':') {
                Some((r, s)) => {
                    let step: i64 = s
                        .trim()
                        .parse()
                        .map_err(|_| format!("bad step `{s}` in `{item}`"))?;
                    if step <= 0 {
                        return Err(format!("step must be positive in `{item}`"));
                    }
                    (r.trim(), step)
                }
                None => (item, 1),
            };
            let num = |s: &str| -> Result<i64, String> {
                s.trim()
                    .parse::<i64>()
                    .map_err(|_| format!("`{s}` is not a frame number (in `{item}`)"))
            };
            let (a, b) = if let Some((a, b)) = range.split_once("..=") {
                (num(a)?, num(b)?)
            } else if let Some((a, b)) = range.split_once("..") {
                let end = num(b)?
                    .checked_sub(1)
                    .ok_or_else(|| format!("range `{item}` is empty (end before start)"))?;
                (num(a)?, end)
            } else if let Some(pos) = range
                .char_indices()
                .skip(1)
                .find(|&(_, c)| c == '-')
                .map(|(p, _)| p)
            {
                (num(&range[..pos])?, num(&range[pos + 1..])?)
            } else {
                let n = num(range)?;
                (n, n)
            };
            if b < a {
                return Err(format!("range `{item}` is empty (end before start)"));
            }
            let mut f = a;
            while f <= b {
                frames.push(f);
                if frames.len() > LIMIT {
                    return Err(format!("frame range `{text}` has more than {LIMIT} frames"));
                }
                match f.checked_add(step) {
                    Some(next) => f = next,
                    None => break,
                }
            }
        }
        Ok(FrameSet::from_frames(frames))
    }
}

impl fmt::Display for FrameSet {
    /// Compact form: runs of consecutive frames as `A-B`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut i = 0;
        let fr = &self.frames;
        while i < fr.len() {
            let mut j = i;
            while j + 1 < fr.len() && fr[j + 1] == fr[j] + 1 {
                j += 1;
            }
            if i > 0 {
                write!(f, ",")?;
            }
            if j > i {
                write!(f, "{}-{}", fr[i], fr[j])?;
            } else {
                write!(f, "{}", fr[i])?;
            }
            i = j + 1;
        }
        Ok(())
    }
}

/// Resolves a path parameter: relative paths are taken from `base`; a frame pattern is filled
/// in when `frame` is given (`%04d`-style printf width, `%d`, or a run of `#` for the width).
pub fn resolve_path(base: &Path, text: &str, frame: Option<i64>) -> PathBuf {
    let text = match frame {
        Some(f) => format_frame(text, f),
        None => text.to_string(),
    };
    let p = Path::new(&text);
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base.join(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forms() {
        assert_eq!(FrameSet::parse("0..=3").unwrap().frames(), &[0, 1, 2, 3]);
        assert_eq!(FrameSet::parse("0..3").unwrap().frames(), &[0, 1, 2]);
        assert_eq!(
            FrameSet::parse("1-3,15,20-26:2").unwrap().frames(),
            &[1, 2, 3, 15, 20, 22, 24, 26]
        );
        assert_eq!(FrameSet::parse("7").unwrap().frames(), &[7]);
        assert_eq!(
            FrameSet::parse("-3-1").unwrap().frames(),
            &[-3, -2, -1, 0, 1]
        );
        assert_eq!(FrameSet::parse("3,1,2,2").unwrap().to_string(), "1-3");
    }

    #[test]
    fn errors() {
        assert!(FrameSet::parse("5..=1").is_err());
        assert!(FrameSet::parse("a-b").is_err());
        assert!(FrameSet::parse("1-5:0").is_err());
        assert!(FrameSet::parse("1,,2").is_err());
    }

    /// Regression (found in review while writing the graph target): an empty or non-ASCII
    /// range was sliced at byte 1 (a panic), and the ends of the i64 range overflowed.
    #[test]
    fn odd_ranges_are_errors_or_frames_never_panics() {
        for text in [":5", "é-3", "1é-3", "-", "0..-9223372036854775808"] {
            assert!(FrameSet::parse(text).is_err(), "{text}");
        }
        assert_eq!(
            FrameSet::parse("9223372036854775806-9223372036854775807:5")
                .unwrap()
                .frames(),
            &[9223372036854775806]
        );
        assert_eq!(
            FrameSet::parse("-9223372036854775808..-9223372036854775806")
                .unwrap()
                .frames(),
            &[i64::MIN, i64::MIN + 1]
        );
    }

    #[test]
    fn frame_patterns() {
        assert_eq!(format_frame("f.%04d.png", 7), "f.0007.png");
        assert_eq!(format_frame("f.####.png", 12), "f.0012.png");
        assert_eq!(format_frame("f.%d.png", 12), "f.12.png");
        assert_eq!(format_frame("plain.png", 12), "plain.png");
        assert!(has_frame_pattern("a_##.exr"));
        assert!(!has_frame_pattern("a.exr"));
        assert_eq!(
            resolve_path(Path::new("/g"), "x/%03d.png", Some(5)),
            PathBuf::from("/g/x/005.png")
        );
    }
}
