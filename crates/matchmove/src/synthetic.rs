//! A synthetic shot with known cameras, for testing the matchmove: a camera dollying and panning
//! through a field of textured points, observed by KLT-like tracks — finite lifetimes, features
//! lost when they leave the image and their slots refilled with new points (a new track), Gaussian
//! pixel noise, and a fraction of outlier tracks that drift away from their point as KLT windows
//! slide along edges.

#![allow(clippy::needless_range_loop)] // a simulation over frame and slot indices

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::rotation::axis_angle_to_r;
use vfxgraph_geometry::synthetic::gaussian;
use vfxgraph_klt::{LostReason, Track, Tracks};

/// What to generate.
#[derive(Clone, Debug)]
pub struct ShotOptions {
    /// Frames.
    pub frames: usize,
    /// Feature slots per frame.
    pub slots: usize,
    /// Pixel noise σ.
    pub noise: f64,
    /// Fraction of new tracks that drift (outliers).
    pub outlier_fraction: f64,
    /// Drift per frame of an outlier track, pixels (random walk σ).
    pub drift: f64,
    /// Mean track lifetime, frames (geometric).
    pub mean_track_length: f64,
    /// Sideways travel of the camera over the shot, scene units.
    pub travel: f64,
    /// Pan over the shot, radians.
    pub pan: f64,
    /// Amplitude of the camera's vertical bob, scene units (0 with `travel: 0`: a nodal pan).
    pub bob: f64,
    /// Focal length (px) of the first and the last frame, linear in between (equal: no zoom).
    pub focal: (f64, f64),
    /// Amplitude of a curve of the camera's path (scene units: up and down, and towards the
    /// scene), 0 for the straight track. A zoom needs it: along a straight track, or on an orbit,
    /// focal lengths that vary are not determined (Kahl, Triggs & Åström 2000).
    pub arc: f64,
    /// Seed.
    pub seed: u64,
}

impl Default for ShotOptions {
    fn default() -> Self {
        ShotOptions {
            frames: 150,
            slots: 150,
            noise: 0.5,
            outlier_fraction: 0.1,
            drift: 0.7,
            mean_track_length: 60.0,
            travel: 3.0,
            pan: 0.25,
            bob: 0.15,
            focal: (1100.0, 1100.0),
            arc: 0.0,
            seed: 1,
        }
    }
}

/// The generated shot and its truth.
#[derive(Clone, Debug)]
pub struct SyntheticShot {
    /// The tracks.
    pub tracks: Tracks,
    /// Intrinsics (1280×720) of the first frame.
    pub k: Intrinsics,
    /// The focal length of every frame, px.
    pub focals: Vec<f64>,
    /// True pose of every frame.
    pub truth: Vec<Pose>,
    /// Ids of the outlier tracks.
    pub outliers: Vec<u64>,
}

/// The true camera of frame `i` of `n`.
fn pose_at(i: usize, n: usize, o: &ShotOptions) -> Pose {
    let s = i as f64 / (n.max(2) - 1) as f64;
    let tau = std::f64::consts::TAU;
    let centre = Vector3::new(
        o.travel * s,
        o.bob * (3.0 * s).sin() + o.arc * (tau * s).sin(),
        0.4 * o.travel * s + o.arc * (0.5 * tau * s).sin(),
    );
    let tilt = 0.03 * (2.0 * s).sin() + 0.1 * o.arc * (tau * s).cos();
    let r = axis_angle_to_r(&Vector3::new(tilt, -o.pan * s, 0.01 * s));
    Pose::new(r, -(r * centre))
}

/// Generates a shot (module docs).
pub fn synthetic_shot(o: &ShotOptions) -> SyntheticShot {
    let mut rng = Pcg64::seed_from_u64(o.seed);
    let focals: Vec<f64> = (0..o.frames)
        .map(|i| o.focal.0 + (o.focal.1 - o.focal.0) * i as f64 / (o.frames.max(2) - 1) as f64)
        .collect();
    let ks: Vec<Intrinsics> = focals
        .iter()
        .map(|&f| Intrinsics::new(f, f, 639.5, 359.5).with_size(1280, 720))
        .collect();
    let k = ks[0].clone();
    let truth: Vec<Pose> = (0..o.frames).map(|i| pose_at(i, o.frames, o)).collect();
    let scene: Vec<Vector3<f64>> = (0..6000)
        .map(|_| {
            Vector3::new(
                rng.random_range(-8.0..12.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(5.0..16.0),
            )
        })
        .collect();
    let project = |f: usize, pi: usize| crate::structure::project(&ks[f], &truth[f], &scene[pi]);
    let sim = TrackSim {
        frames: o.frames,
        slots: o.slots,
        size: (1280.0, 720.0),
        noise: o.noise,
        outlier_fraction: o.outlier_fraction,
        drift: o.drift,
        mean_track_length: o.mean_track_length,
    };
    let (tracks, outliers) = simulate_tracks(&sim, scene.len(), &project, &mut rng);
    SyntheticShot {
        tracks,
        k,
        focals,
        truth,
        outliers,
    }
}

/// How features are tracked in [`simulate_tracks`].
#[derive(Clone, Debug)]
pub struct TrackSim {
    /// Frames.
    pub frames: usize,
    /// Feature slots per frame.
    pub slots: usize,
    /// Image width and height, pixels.
    pub size: (f64, f64),
    /// Pixel noise σ.
    pub noise: f64,
    /// Fraction of new tracks that drift (outliers).
    pub outlier_fraction: f64,
    /// Drift per frame of an outlier track, pixels (random walk σ).
    pub drift: f64,
    /// Mean track lifetime, frames (geometric).
    pub mean_track_length: f64,
}

/// KLT-like tracks of `points` scene points (module docs) whose image in frame f is
/// `project(f, point)` (`None`: not visible); returns the tracks and the outlier tracks' ids.
pub fn simulate_tracks(
    sim: &TrackSim,
    points: usize,
    project: &dyn Fn(usize, usize) -> Option<[f64; 2]>,
    rng: &mut Pcg64,
) -> (Tracks, Vec<u64>) {
    let (w, h) = sim.size;
    let inside = |q: [f64; 2]| q[0] >= 8.0 && q[0] < w - 8.0 && q[1] >= 8.0 && q[1] < h - 8.0;
    // Live features: (track index, point index, drift, remaining life).
    type Live = (usize, usize, [f64; 2], usize);
    let mut live: Vec<Option<Live>> = vec![None; sim.slots];
    let mut tracks: Vec<Track> = Vec::new();
    let mut outliers = Vec::new();
    for f in 0..sim.frames {
        // Advance or lose live features.
        for slot in 0..sim.slots {
            let Some((ti, pi, mut drift, life)) = live[slot] else {
                continue;
            };
            let q = project(f, pi);
            let lost = match q {
                Some(q) if inside(q) && life > 0 => {
                    if tracks[ti].points.len() > 1 && outliers.contains(&tracks[ti].id) {
                        drift[0] += sim.drift * gaussian(rng);
                        drift[1] += sim.drift * gaussian(rng);
                    }
                    tracks[ti].points.push([
                        q[0] + drift[0] + sim.noise * gaussian(rng),
                        q[1] + drift[1] + sim.noise * gaussian(rng),
                    ]);
                    live[slot] = Some((ti, pi, drift, life - 1));
                    None
                }
                Some(q) => Some(q),
                None => Some([0.0, 0.0]),
            };
            if let Some(at) = lost {
                tracks[ti].lost = Some(vfxgraph_klt::TrackEnd {
                    frame: f,
                    at,
                    reason: LostReason::LeftImage,
                });
                live[slot] = None;
            }
        }
        // Refill empty slots with visible points at least 10 px from live features.
        let mut positions: Vec<[f64; 2]> = live
            .iter()
            .flatten()
            .map(|(ti, ..)| *tracks[*ti].points.last().unwrap())
            .collect();
        for slot in 0..sim.slots {
            if live[slot].is_some() {
                continue;
            }
            for _ in 0..50 {
                let pi = rng.random_range(0..points);
                let Some(q) = project(f, pi) else {
                    continue;
                };
                if !inside(q)
                    || positions
                        .iter()
                        .any(|p| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) < 100.0)
                {
                    continue;
                }
                let id = tracks.len() as u64;
                if rng.random::<f64>() < sim.outlier_fraction {
                    outliers.push(id);
                }
                let u: f64 = rng.random::<f64>().max(1e-9);
                let life = (-u.ln() * sim.mean_track_length) as usize + 2;
                let obs = [
                    q[0] + sim.noise * gaussian(rng),
                    q[1] + sim.noise * gaussian(rng),
                ];
                tracks.push(Track {
                    id,
                    slot,
                    first: f,
                    points: vec![obs],
                    lost: None,
                });
                live[slot] = Some((tracks.len() - 1, pi, [0.0, 0.0], life));
                positions.push(q);
                break;
            }
        }
    }
    (
        Tracks {
            frames: (0..sim.frames as i64).collect(),
            slots: sim.slots,
            image_size: Some([sim.size.0 as u32, sim.size.1 as u32]),
            tracks,
        },
        outliers,
    )
}
