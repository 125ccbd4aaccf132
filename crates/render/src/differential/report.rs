//! The `differential_render` node's report of one render.

use vfxgraph_params::Choice;

use super::{CompositeMode, DifferentialOutput};
use crate::camera::Camera;
use crate::render::RenderSettings;

impl DifferentialOutput {
    /// The report of this render of frame `frame` by `camera` with `settings`, composited in
    /// `mode` (over a plate when `plate`): image size, samples and counters — not the time, so
    /// the report is the same on every machine.
    pub fn report(
        &self,
        frame: Option<i64>,
        camera: &Camera,
        settings: &RenderSettings,
        mode: CompositeMode,
        plate: bool,
    ) -> serde_json::Value {
        let s = &self.stats;
        serde_json::json!({
            "frame": frame,
            "width": camera.width,
            "height": camera.height,
            "spp": settings.spp,
            "max_depth": settings.max_depth,
            "mode": mode.choice(),
            "plate": plate,
            "traced_pixels": s.traced_pixels,
            "mean_spp_traced": s.samples as f64 / s.traced_pixels.max(1) as f64,
            "pixels": s.pixels,
            "paths_with_objects": s.paths_with,
            "paths_without_objects": s.paths_without,
        })
    }
}
