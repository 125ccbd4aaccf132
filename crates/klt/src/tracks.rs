//! The tracks model (book 6.5 and chapter 7's input): stable track ids, per-frame observations
//! and why a track ended, with the book's `f.txt` format and a native JSON format.
//!
//! The book's tracker keeps `N` feature *slots*; when the feature of a slot is lost, the slot
//! is refilled by a new corner, which is a different scene point. Here every refill is a new
//! [`Track`] with a new id; the slot is kept so that the book's format can be written back.
//!
//! The book's `f.txt`: a line `Features per frame = N`, then per frame a line `Frame i` and N
//! lines `x y status` — status 0 = tracked, −1 = lost (the position is where tracking failed).
//! A track is a maximal run of status-0 lines of one slot. In that format a refill corner
//! found in the frame where its slot's feature was lost cannot be shown there (the line says
//! −1), so its first observation appears one frame later; an empty slot is written `0 0 -1`.
//! Coordinates are written with f32 precision (the shortest text that reads back the same
//! f32), which reproduces the book's 6-significant-digit file byte for byte.

use serde::{Deserialize, Serialize};

use super::KltError;

/// Why a feature stopped being tracked (book 6.5, disposal of windows).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LostReason {
    /// Its window left the image.
    LeftImage,
    /// The 2×2 system of book 6.3 was singular (too little texture).
    Singular,
    /// The window's residual exceeded the threshold (book 6.5).
    Residual,
    /// Tracking back did not return to the start (forward–backward check).
    ForwardBackward,
    /// The drift correction could not align the feature's first window within its bound: the
    /// window no longer looks like the feature (Shi & Tomasi's feature monitoring).
    Drift,
    /// Read from a file that does not say (the book's format).
    Unknown,
}

impl LostReason {
    /// The snake_case name used in the native format.
    pub fn name(self) -> &'static str {
        match self {
            LostReason::LeftImage => "left_image",
            LostReason::Singular => "singular",
            LostReason::Residual => "residual",
            LostReason::ForwardBackward => "forward_backward",
            LostReason::Drift => "drift",
            LostReason::Unknown => "unknown",
        }
    }
}

/// Where and why a track ended: the frame in which tracking failed (one after its last
/// observation), the position the tracker reached there, and the reason (book 6.5). Serialized
/// as the `lost` field of a [`Track`] (`{"frame", "at", "reason"}`), whatever the type's name.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackEnd {
    /// Index (into [`Tracks::frames`]) of the frame where tracking failed.
    pub frame: usize,
    /// Position reached in that frame when it failed.
    pub at: [f64; 2],
    /// Why.
    pub reason: LostReason,
}

/// One tracked scene point: consecutive observations from frame index `first` (book 6.2: the
/// window centres correlated by KLT are homologous points).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Track {
    /// Stable id, unique in its [`Tracks`]; a refilled slot gets a new id.
    pub id: u64,
    /// The feature slot (the book's index in each frame block).
    pub slot: usize,
    /// Index (into [`Tracks::frames`]) of the first observation.
    pub first: usize,
    /// Positions in frames `first, first + 1, …` (pixel centres at integers, y down).
    pub points: Vec<[f64; 2]>,
    /// How it ended, if it was lost before the sequence ended.
    pub lost: Option<TrackEnd>,
}

impl Track {
    /// Index of the frame after the last observation.
    pub fn end(&self) -> usize {
        self.first + self.points.len()
    }

    /// The observation in frame index `f`, if the track was seen there.
    pub fn at(&self, f: usize) -> Option<[f64; 2]> {
        f.checked_sub(self.first)
            .and_then(|k| self.points.get(k))
            .copied()
    }

    /// One frame of a sequence tracker (book 6.5): the track is seen at `pos` in frame index
    /// `frame`, or (`lost`) ends there for that reason, at `pos` when it is finite, else at its
    /// last observation. Returns whether it ended (its slot is then free).
    pub fn advance(&mut self, frame: usize, pos: [f64; 2], lost: Option<LostReason>) -> bool {
        let Some(reason) = lost else {
            self.points.push(pos);
            return false;
        };
        let at = if pos[0].is_finite() && pos[1].is_finite() {
            pos
        } else {
            self.points.last().copied().unwrap_or_default()
        };
        self.lost = Some(TrackEnd { frame, at, reason });
        true
    }
}

/// Feature tracks over a sequence of frames (book chapter 6's output, chapter 7's input).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Tracks {
    /// Frame numbers of the sequence, in order; observations refer to indices into this.
    pub frames: Vec<i64>,
    /// Number of feature slots (the book's "features per frame").
    pub slots: usize,
    /// The tracks, by increasing id.
    pub tracks: Vec<Track>,
    /// Width and height of the frames the tracks were measured on, pixels, when known (the
    /// tracker records them; the book's text format has none). A solve with the focal length
    /// unknown takes its image size from here.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_size: Option<[u32; 2]>,
}

#[derive(Serialize, Deserialize)]
struct NativeFile {
    format: String,
    version: u32,
    #[serde(flatten)]
    tracks: Tracks,
}

const NATIVE_FORMAT: &str = "vfxgraph-tracks";

/// The largest frame number (in magnitude) a tracks file may hold: a billion frames, 16 months
/// at 24 fps; beyond, a number from a file is an error, not a shot.
pub const MAX_FRAME_NUMBER: u64 = 1_000_000_000;

/// The most feature slots a tracks file may declare (either format).
pub const MAX_SLOTS: usize = 10_000_000;

impl Tracks {
    /// The last observation of each track `live` holds (a tracker's slots), in slot order.
    pub fn last_points<'a>(
        &'a self,
        live: &'a [Option<usize>],
    ) -> impl Iterator<Item = [f64; 2]> + 'a {
        live.iter()
            .flatten()
            .map(|&k| self.tracks[k].points.last().copied().unwrap_or_default())
    }

    /// Starts a track with the next id in feature slot `slot`, seen at `pos` in frame index
    /// `first` (a refill, book 6.5); returns its index.
    pub fn start(&mut self, slot: usize, first: usize, pos: [f64; 2]) -> usize {
        let k = self.tracks.len();
        self.tracks.push(Track {
            id: k as u64,
            slot,
            first,
            points: vec![pos],
            lost: None,
        });
        k
    }

    /// Every track seen in frame index `f`, as (id, position), by increasing slot.
    pub fn observations(&self, f: usize) -> Vec<(u64, [f64; 2])> {
        let mut v: Vec<(usize, u64, [f64; 2])> = self
            .tracks
            .iter()
            .filter_map(|t| t.at(f).map(|p| (t.slot, t.id, p)))
            .collect();
        v.sort_by_key(|a| (a.0, a.1));
        v.into_iter().map(|(_, id, p)| (id, p)).collect()
    }

    /// Every `stride`-th frame of the sequence (indices 0, stride, 2·stride, …) with the
    /// tracks' observations in them: a keyframe subsequence, for searches that need the
    /// whole shot's span but not every frame. Tracks seen in none of them are dropped; ids and
    /// slots are kept. `stride` 0 is taken as 1.
    pub fn every(&self, stride: usize) -> Tracks {
        let s = stride.max(1);
        let frames: Vec<i64> = self.frames.iter().copied().step_by(s).collect();
        let tracks = self
            .tracks
            .iter()
            .filter_map(|t| {
                let first = t.first.div_ceil(s);
                let points: Vec<[f64; 2]> = (first * s..t.end())
                    .step_by(s)
                    .filter_map(|f| t.at(f))
                    .collect();
                (!points.is_empty()).then_some(Track {
                    id: t.id,
                    slot: t.slot,
                    first,
                    points,
                    lost: None,
                })
            })
            .collect();
        Tracks {
            frames,
            slots: self.slots,
            tracks,
            image_size: self.image_size,
        }
    }

    /// The track with this id.
    pub fn get(&self, id: u64) -> Option<&Track> {
        self.tracks
            .binary_search_by_key(&id, |t| t.id)
            .ok()
            .map(|i| &self.tracks[i])
    }

    /// Checks the invariants: frame numbers increase and lie within ±[`MAX_FRAME_NUMBER`], at
    /// most [`MAX_SLOTS`] slots, ids increase, observations and
    /// losses lie inside the frame range, slots are below `slots`, and a slot holds at most one
    /// track per frame. The work and memory grow with the tracks, not with `slots` × frames
    /// (both are numbers from a file).
    pub fn validate(&self) -> Result<(), KltError> {
        let bad = |m: String| Err(KltError::BadTracks(m));
        let n = self.frames.len();
        if let Some(f) = self
            .frames
            .iter()
            .find(|f| f.unsigned_abs() > MAX_FRAME_NUMBER)
        {
            return bad(format!(
                "frame {f}: frame numbers lie within ±{MAX_FRAME_NUMBER}"
            ));
        }
        if let Some(w) = self.frames.windows(2).find(|w| w[1] <= w[0]) {
            return bad(format!(
                "frame {} after frame {}: frames must increase",
                w[1], w[0]
            ));
        }
        if self.slots > MAX_SLOTS {
            return bad(format!(
                "{} feature slots (at most {MAX_SLOTS})",
                self.slots
            ));
        }
        for (k, t) in self.tracks.iter().enumerate() {
            if k > 0 && self.tracks[k - 1].id >= t.id {
                return bad(format!("track ids not increasing at id {}", t.id));
            }
            if t.slot >= self.slots {
                return bad(format!(
                    "track {} in slot {} of {}",
                    t.id, t.slot, self.slots
                ));
            }
            if t.first
                .checked_add(t.points.len())
                .is_none_or(|end| end > n)
            {
                return bad(format!("track {} runs past the last frame", t.id));
            }
            if let Some(l) = t.lost {
                if l.frame != t.end() || l.frame >= n {
                    return bad(format!("track {} lost at frame index {}", t.id, l.frame));
                }
            }
            if t.points.iter().flatten().any(|v| !v.is_finite()) {
                return bad(format!("track {} has a non-finite point", t.id));
            }
        }
        // Per slot, the tracks' frame ranges must not overlap.
        let mut spans: Vec<(usize, usize, usize)> = self
            .tracks
            .iter()
            .filter(|t| !t.points.is_empty())
            .map(|t| (t.slot, t.first, t.end()))
            .collect();
        spans.sort_unstable();
        for w in spans.windows(2) {
            let ((slot, _, end), (next_slot, next_first, _)) = (w[0], w[1]);
            if slot == next_slot && next_first < end {
                return bad(format!(
                    "slot {slot} holds two tracks in frame index {next_first}"
                ));
            }
        }
        Ok(())
    }

    /// Writes the book's `f.txt` format (see the module doc).
    pub fn to_book(&self) -> String {
        const EMPTY: ([f64; 2], i32) = ([0.0, 0.0], -1);
        let n = self.frames.len();
        let mut grid = vec![EMPTY; n * self.slots];
        for t in &self.tracks {
            for (k, p) in t.points.iter().enumerate() {
                if let Some(c) = grid.get_mut((t.first + k) * self.slots + t.slot) {
                    *c = (*p, 0);
                }
            }
        }
        for t in &self.tracks {
            if let Some(l) = t.lost {
                if let Some(c) = grid.get_mut(l.frame * self.slots + t.slot) {
                    *c = (l.at, -1);
                }
            }
        }
        let mut s = format!("Features per frame = {}\n", self.slots);
        for (fi, f) in self.frames.iter().enumerate() {
            s.push_str(&format!("Frame {f}\n"));
            for (p, st) in &grid[fi * self.slots..(fi + 1) * self.slots] {
                s.push_str(&format!("{} {} {st}\n", p[0] as f32, p[1] as f32));
            }
        }
        s
    }

    /// Reads the book's `f.txt` format. Each maximal run of status-0 lines of a slot becomes a
    /// track (ids in order of first frame, then slot); a −1 line right after a run records the
    /// loss (reason [`LostReason::Unknown`]). Errors name the line, or the invariant
    /// ([`Tracks::validate`]) the file breaks.
    pub fn from_book(text: &str) -> Result<Tracks, KltError> {
        let perr = |line: usize, m: &str| KltError::Parse {
            line,
            message: m.to_string(),
        };
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty());
        let (ln, head) = lines.next().ok_or_else(|| perr(1, "empty file"))?;
        let slots: usize = head
            .strip_prefix("Features per frame")
            .and_then(|r| r.trim_start().strip_prefix('='))
            .and_then(|r| r.trim().parse().ok())
            .ok_or_else(|| perr(ln, "expected `Features per frame = N`"))?;
        if slots > MAX_SLOTS {
            return Err(perr(ln, "too many features per frame"));
        }
        let mut frames = Vec::new();
        // Per frame, per slot: (point, tracked).
        let mut cells: Vec<([f64; 2], bool)> = Vec::new();
        let mut cur: Option<usize> = None;
        let mut last_line = ln;
        for (ln, l) in lines {
            last_line = ln;
            if let Some(rest) = l.strip_prefix("Frame") {
                if let Some(c) = cur {
                    if c != slots {
                        return Err(perr(
                            ln,
                            &format!("previous frame has {c} of {slots} lines"),
                        ));
                    }
                }
                let f: i64 = rest
                    .trim()
                    .parse()
                    .map_err(|_| perr(ln, "expected `Frame <integer>`"))?;
                frames.push(f);
                cur = Some(0);
                continue;
            }
            let Some(c) = cur.as_mut() else {
                return Err(perr(ln, "a point line before the first `Frame` line"));
            };
            if *c >= slots {
                return Err(perr(ln, &format!("more than {slots} lines in a frame")));
            }
            let mut it = l.split_whitespace();
            let mut num = || -> Option<f64> { it.next()?.parse::<f64>().ok() };
            let (x, y, st) = match (num(), num(), num()) {
                (Some(x), Some(y), Some(s)) if x.is_finite() && y.is_finite() => (x, y, s),
                _ => return Err(perr(ln, "expected `x y status`")),
            };
            if it.next().is_some() {
                return Err(perr(ln, "expected `x y status`"));
            }
            cells.push(([x, y], st == 0.0));
            *c += 1;
        }
        if let Some(c) = cur {
            if c != slots {
                return Err(perr(
                    last_line,
                    &format!("last frame has {c} of {slots} lines"),
                ));
            }
        }
        let n = frames.len();
        let mut tracks = Vec::new();
        for f in 0..n {
            for s in 0..slots {
                let (_, ok) = cells[f * slots + s];
                let starts = ok && (f == 0 || !cells[(f - 1) * slots + s].1);
                if !starts {
                    continue;
                }
                let mut points = Vec::new();
                let mut g = f;
                while g < n && cells[g * slots + s].1 {
                    points.push(cells[g * slots + s].0);
                    g += 1;
                }
                let lost = (g < n).then(|| TrackEnd {
                    frame: g,
                    at: cells[g * slots + s].0,
                    reason: LostReason::Unknown,
                });
                tracks.push(Track {
                    id: tracks.len() as u64,
                    slot: s,
                    first: f,
                    points,
                    lost,
                });
            }
        }
        let out = Tracks {
            frames,
            slots,
            image_size: None,
            tracks,
        };
        out.validate()?;
        Ok(out)
    }

    /// The native format: JSON `{"format": "vfxgraph-tracks", "version": 1, "frames": [...],
    /// "slots": N, "tracks": [{"id", "slot", "first", "points": [[x, y], ...], "lost":
    /// {"frame", "at", "reason"} | null}]}` — full f64 precision, ids and loss reasons kept.
    pub fn to_native(&self) -> String {
        let file = NativeFile {
            format: NATIVE_FORMAT.into(),
            version: 1,
            tracks: self.clone(),
        };
        serde_json::to_string(&file).unwrap_or_default()
    }

    /// Reads the native format and checks its invariants.
    pub fn from_native(text: &str) -> Result<Tracks, KltError> {
        let file: NativeFile = serde_json::from_str(text).map_err(|e| KltError::Parse {
            line: e.line(),
            message: e.to_string(),
        })?;
        if file.format != NATIVE_FORMAT || file.version != 1 {
            return Err(KltError::Parse {
                line: 1,
                message: format!("not a {NATIVE_FORMAT} v1 file"),
            });
        }
        file.tracks.validate()?;
        Ok(file.tracks)
    }

    /// Reads either format, recognised by its first non-blank character (`{` = native).
    pub fn parse(text: &str) -> Result<Tracks, KltError> {
        if text.trim_start().starts_with('{') {
            Tracks::from_native(text)
        } else {
            Tracks::from_book(text)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Tracks {
        Tracks {
            frames: vec![10, 11, 12, 13],
            slots: 2,
            image_size: None,
            tracks: vec![
                Track {
                    id: 0,
                    slot: 0,
                    first: 0,
                    points: vec![[1.5, 2.0], [2.5, 2.25]],
                    lost: Some(TrackEnd {
                        frame: 2,
                        at: [3.0, -1.0],
                        reason: LostReason::LeftImage,
                    }),
                },
                Track {
                    id: 1,
                    slot: 1,
                    first: 0,
                    points: vec![[5.0, 6.0]; 4],
                    lost: None,
                },
                Track {
                    id: 2,
                    slot: 0,
                    first: 3,
                    points: vec![[7.0, 8.0]],
                    lost: None,
                },
            ],
        }
    }

    #[test]
    fn book_round_trip_and_runs() {
        let t = sample();
        t.validate().unwrap();
        let text = t.to_book();
        assert_eq!(
            text,
            "Features per frame = 2\nFrame 10\n1.5 2 0\n5 6 0\nFrame 11\n2.5 2.25 0\n5 6 0\n\
             Frame 12\n3 -1 -1\n5 6 0\nFrame 13\n7 8 0\n5 6 0\n"
        );
        let back = Tracks::from_book(&text).unwrap();
        back.validate().unwrap();
        assert_eq!(back.frames, t.frames);
        assert_eq!(back.tracks.len(), 3);
        assert_eq!(back.tracks[0].points, t.tracks[0].points);
        assert_eq!(back.tracks[0].lost.unwrap().reason, LostReason::Unknown);
        assert_eq!(back.tracks[2].first, 3);
        assert_eq!(back.to_book(), text);
        assert_eq!(t.observations(3), vec![(2, [7.0, 8.0]), (1, [5.0, 6.0])]);
    }

    #[test]
    fn frame_numbers_are_bounded_and_increase() {
        let text = "Features per frame = 1\nFrame 9223372036854775807\n1 2 0\n";
        let e = Tracks::parse(text).unwrap_err().to_string();
        assert!(
            e.contains("9223372036854775807") && e.contains("within"),
            "{e}"
        );
        let text = "Features per frame = 1\nFrame 5\n1 2 0\nFrame 3\n1 2 0\n";
        let e = Tracks::parse(text).unwrap_err().to_string();
        assert!(e.contains("frame 3 after frame 5"), "{e}");
        let mut t = sample();
        t.frames[2] = -(MAX_FRAME_NUMBER as i64) - 1;
        assert!(t.validate().is_err());
        assert!(Tracks::parse("Features per frame = 1\nFrame -1000000000\n1 2 0\n").is_ok());
    }

    #[test]
    fn every_keeps_the_observations_of_the_kept_frames() {
        let t = sample();
        let e = t.every(2);
        e.validate().unwrap();
        assert_eq!(e.frames, vec![10, 12]);
        // Track 0 (frames 0, 1) keeps frame 0; track 1 frames 0 and 2; track 2 (frame 3) none.
        assert_eq!(e.tracks.len(), 2);
        assert_eq!((e.tracks[0].id, e.tracks[0].first), (0, 0));
        assert_eq!(e.tracks[0].points, vec![[1.5, 2.0]]);
        assert_eq!(e.tracks[1].points, vec![[5.0, 6.0]; 2]);
        assert_eq!(
            t.every(1),
            Tracks {
                tracks: t
                    .tracks
                    .iter()
                    .map(|tr| Track {
                        lost: None,
                        ..tr.clone()
                    })
                    .collect(),
                ..t.clone()
            }
        );
        let late = t.every(3);
        assert_eq!(late.frames, vec![10, 13]);
        assert_eq!(late.observations(1), vec![(2, [7.0, 8.0]), (1, [5.0, 6.0])]);
    }

    #[test]
    fn native_round_trip_is_exact() {
        let mut t = sample();
        t.tracks[1].points[2] = [0.1 + 0.2, 1.0 / 3.0];
        let back = Tracks::parse(&t.to_native()).unwrap();
        assert_eq!(back, t);
    }

    #[test]
    fn bad_files_name_the_line() {
        for (text, line) in [
            ("", 1),
            ("Features per frame = x\n", 1),
            ("Features per frame = 1\n1 2 0\n", 2),
            ("Features per frame = 1\nFrame 0\n1 2\n", 3),
            ("Features per frame = 1\nFrame 0\n1 2 0\n1 2 0\n", 4),
            ("Features per frame = 2\nFrame 0\n1 2 0\nFrame 1\n", 4),
        ] {
            match Tracks::parse(text) {
                Err(KltError::Parse { line: l, .. }) => assert_eq!(l, line, "{text:?}"),
                other => panic!("{text:?}: {other:?}"),
            }
        }
        assert!(Tracks::parse("{\"format\":\"x\"}").is_err());
        let mut t = sample();
        t.tracks[2].first = 1; // overlaps track 0 in slot 0
        assert!(t.validate().is_err());
        assert!(Tracks::from_native(&t.to_native()).is_err());
    }

    /// Regression (fuzzing): a native file's `slots` sized a frames × slots grid before
    /// anything was checked (`"slots": 99999999999` asked for 400 GB); an index past the
    /// frames overflowed `first + len`.
    #[test]
    fn native_files_with_huge_numbers_are_errors_without_allocating() {
        let text = sample().to_native();
        let huge = text.replace("\"slots\":2", "\"slots\":99999999999");
        assert_ne!(huge, text);
        let e = Tracks::from_native(&huge).unwrap_err().to_string();
        assert!(
            e.contains("99999999999 feature slots (at most 10000000)"),
            "{e}"
        );
        let at_max = text.replace("\"slots\":2", "\"slots\":10000000");
        assert_eq!(Tracks::from_native(&at_max).unwrap().slots, MAX_SLOTS);
        let mut t = sample();
        t.tracks[2].first = usize::MAX;
        let e = Tracks::from_native(&t.to_native()).unwrap_err().to_string();
        assert!(e.contains("track 2 runs past the last frame"), "{e}");
        // The overlap test without the grid: same slot, overlapping ranges, either order.
        let mut t = sample();
        t.tracks[2].first = 1;
        t.tracks[2].points = vec![[0.0, 0.0]];
        let e = t.validate().unwrap_err().to_string();
        assert!(
            e.contains("slot 0 holds two tracks in frame index 1"),
            "{e}"
        );
        let mut t = sample();
        t.tracks[2].first = 2; // right after track 0 ends in slot 0: allowed
        t.tracks[0].lost = None;
        t.validate().unwrap();
    }

    #[test]
    fn the_books_f_txt_loads_and_writes_back_byte_for_byte() {
        let Some(path) = vfxgraph_testdata::path("book-demo/f.txt") else {
            return;
        };
        let text = std::fs::read_to_string(path).unwrap();
        let t = Tracks::from_book(&text).unwrap();
        t.validate().unwrap();
        assert_eq!(t.slots, 150);
        assert_eq!(t.frames.len(), 286);
        let lost = t.tracks.iter().filter(|t| t.lost.is_some()).count();
        assert_eq!(lost, 141); // the file's 141 `-1` lines
        assert_eq!(t.to_book(), text);
    }
}
