//! Frame patterns in file names: `%04d` (printf's width, zero-padded with a leading 0),
//! `%d`, or a run of `#` (its length the width, zero-padded), filled with a frame number — the
//! patterns of image sequences in graphs (engine) and in the files exports name (exchange).

/// True when `text` holds a frame pattern.
pub fn has_frame_pattern(text: &str) -> bool {
    format_frame(text, 0) != format_frame(text, 1)
}

/// The widest frame pattern accepted (`%32d`, 32 `#`): an `i64` has at most 19 digits, and a
/// width from a file must not reach the formatter's limit.
pub const MAX_FRAME_WIDTH: usize = 32;

/// Fills a frame pattern: `%04d`, `%d` or `####` (width = number of `#`). A pattern wider than
/// [`MAX_FRAME_WIDTH`] is left as it is (graph validation refuses it: [`check_frame_pattern`]).
pub fn format_frame(text: &str, frame: i64) -> String {
    try_format_frame(text, frame).unwrap_or_else(|_| text.to_string())
}

/// Refuses a frame pattern wider than [`MAX_FRAME_WIDTH`], with a message naming it.
pub fn check_frame_pattern(text: &str) -> Result<(), String> {
    try_format_frame(text, 0).map(|_| ()).map_err(|w| {
        format!("frame pattern of width {w} in `{text}` is wider than {MAX_FRAME_WIDTH} digits")
    })
}

/// [`format_frame`], or `Err(width)` for a pattern wider than [`MAX_FRAME_WIDTH`].
fn try_format_frame(text: &str, frame: i64) -> Result<String, usize> {
    let mut out = String::with_capacity(text.len() + 4);
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let mut j = i + 1;
            while j < b.len() && b[j].is_ascii_digit() {
                j += 1;
            }
            if j < b.len() && b[j] == b'd' {
                let spec = &text[i + 1..j];
                let width: usize = match spec.parse() {
                    Ok(w) if w <= MAX_FRAME_WIDTH => w,
                    Ok(w) => return Err(w),
                    Err(_) if spec.is_empty() => 0,
                    Err(_) => return Err(usize::MAX),
                };
                let zero = spec.starts_with('0');
                if zero {
                    out.push_str(&format!("{frame:0width$}"));
                } else {
                    out.push_str(&format!("{frame:width$}"));
                }
                i = j + 1;
                continue;
            }
        }
        if b[i] == b'#' {
            let mut j = i;
            while j < b.len() && b[j] == b'#' {
                j += 1;
            }
            let width = j - i;
            if width > MAX_FRAME_WIDTH {
                return Err(width);
            }
            out.push_str(&format!("{frame:0width$}"));
            i = j;
            continue;
        }
        let ch = text[i..].chars().next().expect("in bounds");
        out.push(ch);
        i += ch.len_utf8();
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression (fuzzing): a width from the file reached `format!`, which panics past 65535.
    #[test]
    fn too_wide_frame_patterns_are_refused_not_a_panic() {
        let wide = "out/f.%9223372036854775808d.png";
        assert_eq!(format_frame(wide, 3), wide);
        assert!(!has_frame_pattern(wide));
        let e = check_frame_pattern(wide).unwrap_err();
        assert!(e.contains("wider than 32") && e.contains(wide), "{e}");
        let hashes = format!("f.{}.exr", "#".repeat(70_000));
        assert!(check_frame_pattern(&hashes)
            .unwrap_err()
            .contains("width 70000"));
        assert_eq!(format_frame(&hashes, 1), hashes);
        assert!(check_frame_pattern("f.%032d.png").is_ok());
        assert!(check_frame_pattern("f.%33d.png").is_err());
        assert_eq!(format_frame(&"#".repeat(32), 5).len(), 32);
    }
}
