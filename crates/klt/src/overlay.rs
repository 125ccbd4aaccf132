//! Tracks for a person to look at: drawn over their frame ([`draw_tracks`]) or written as text
//! ([`TracksFormat`]).

use vfxgraph_imaging::draw::{cross, id_colour, line, square};
use vfxgraph_imaging::Image;

use super::tracks::Tracks;

/// The options of [`draw_tracks`] (the `draw_tracks` node's params).
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct DrawTracksOptions {
    /// frames of path drawn behind each feature
    #[param(range = 0..=100_000)]
    pub trail: usize,
}

impl Default for DrawTracksOptions {
    fn default() -> Self {
        DrawTracksOptions { trail: 15 }
    }
}

/// `img` (as RGB) with the tracks of `frame` drawn over it: each live track's path over the
/// last `trail` frames in a colour of its own ([`id_colour`]), its current position as a
/// cross, and the tracks lost at this frame as red squares. A frame the tracks do not cover is
/// returned undrawn.
pub fn draw_tracks(img: &Image, tracks: &Tracks, frame: i64, o: &DrawTracksOptions) -> Image {
    let mut img = img.to_rgb();
    let Some(fi) = tracks.frames.iter().position(|&f| f == frame) else {
        return img;
    };
    for t in &tracks.tracks {
        if let Some(p) = t.at(fi) {
            let c = id_colour(t.id);
            let from = fi.saturating_sub(o.trail).max(t.first);
            for g in from..fi {
                if let (Some(a), Some(b)) = (t.at(g), t.at(g + 1)) {
                    line(&mut img, a, b, c);
                }
            }
            cross(&mut img, p[0].round() as i64, p[1].round() as i64, 3, c);
        }
        if let Some(l) = t.lost.filter(|l| l.frame == fi) {
            let (x, y) = (l.at[0].round() as i64, l.at[1].round() as i64);
            square(&mut img, x, y, 3, [1.0, 0.0, 0.0]);
        }
    }
    img
}

/// A tracks file format (the `write_tracks` node's `format`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum TracksFormat {
    /// The book's f.txt (status 0 tracked, -1 lost; slots reused): [`Tracks::to_book`].
    #[default]
    Book,
    /// JSON with ids and loss reasons: [`Tracks::to_native`].
    Native,
}

/// The options of writing tracks (the `write_tracks` node's params besides its path).
#[derive(Clone, Debug, Default, PartialEq, vfxgraph_params::Options)]
pub struct WriteTracksOptions {
    /// book | native
    pub format: TracksFormat,
}

impl TracksFormat {
    /// `tracks` as this format's text.
    pub fn text(self, tracks: &Tracks) -> String {
        match self {
            TracksFormat::Book => tracks.to_book(),
            TracksFormat::Native => tracks.to_native(),
        }
    }
}
