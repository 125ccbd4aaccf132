//! Renders a `.scn` scene and reports speed: the program `scripts/bench/cornell.sh` calls.
//!
//! ```text
//! cargo run --release -p vfxgraph-render --example render_scn -- SCENE.scn \
//!     [--spp N] [--max-depth D] [--seed S] [--threads T] [--width W --height H] \
//!     [--out PREFIX] [--exposure STOPS] [--time-budget SECONDS] [--diffuse-only]
//!     [--dump-scene FILE.json] [--light-sampling area|solid_angle]
//! ```
//! `--diffuse-only` drops the Blinn–Phong lobes (keeps ρd) so peers without that BRDF can render
//! the same scene; `--dump-scene` writes the scene (after the size override) as JSON for
//! `scripts/bench/cornell_mitsuba.py`.
//! Writes PREFIX.pfm (linear HDR) and PREFIX.png (Reinhard-free sRGB clip after exposure), and
//! prints one JSON line: paths, wall and CPU seconds, paths per CPU-second, NaN count, and the
//! mean over pixels and channels of the variance of each pixel's mean (`mean_variance`).
//! With `--time-budget`, renders with doubling spp until the budget would be exceeded (for
//! equal-time comparisons) and reports the spp it reached.

use std::path::PathBuf;

use vfxgraph_imaging::{tonemap, write_image, Operator};
use vfxgraph_render::light::LightSampling;
use vfxgraph_render::{
    parse_scn, render, Brdf, ConstantEnvironment, Lambert, RenderSettings, World,
};

fn cpu_seconds() -> f64 {
    // utime + stime of this process from /proc (Linux), in clock ticks of 1/100 s.
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            let rest = &s[s.rfind(')')? + 2..];
            let f: Vec<&str> = rest.split_whitespace().collect();
            Some((f[11].parse::<f64>().ok()? + f[12].parse::<f64>().ok()?) / 100.0)
        })
        .unwrap_or(f64::NAN)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut scene_path = None;
    let mut settings = RenderSettings {
        spp: 64,
        max_depth: 3,
        ..Default::default()
    };
    let (mut threads, mut out, mut exposure, mut size, mut budget) =
        (0usize, None::<PathBuf>, 0.0f32, None, None::<f64>);
    let (mut diffuse_only, mut dump) = (false, None::<PathBuf>);
    let mut light_sampling = LightSampling::Area;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut val = || it.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--spp" => settings.spp = val()?.parse()?,
            "--max-depth" => settings.max_depth = val()?.parse()?,
            "--seed" => settings.seed = val()?.parse()?,
            "--threads" => threads = val()?.parse()?,
            "--out" => out = Some(PathBuf::from(val()?)),
            "--exposure" => exposure = val()?.parse()?,
            "--time-budget" => budget = Some(val()?.parse()?),
            "--diffuse-only" => diffuse_only = true,
            "--dump-scene" => dump = Some(PathBuf::from(val()?)),
            "--light-sampling" => {
                light_sampling = match val()?.as_str() {
                    "area" => LightSampling::Area,
                    "solid_angle" => LightSampling::SolidAngle,
                    o => return Err(format!("--light-sampling {o}: area or solid_angle").into()),
                }
            }
            "--width" => {
                let w: usize = val()?.parse()?;
                size = Some((w, size.map_or(0, |s: (usize, usize)| s.1)));
            }
            "--height" => {
                let h: usize = val()?.parse()?;
                size = Some((size.map_or(0, |s: (usize, usize)| s.0), h));
            }
            s if !s.starts_with("--") => scene_path = Some(PathBuf::from(s)),
            s => return Err(format!("unknown option {s}").into()),
        }
    }
    let path = scene_path.ok_or("usage: render_scn SCENE.scn [options]")?;
    let text = std::fs::read_to_string(&path)?;
    let mut scene = parse_scn(&text).map_err(|e| format!("{}:{e}", path.display()))?;
    // A .scn scene always has a camera (its view, or the language's default one).
    let mut camera = scene.camera.clone().ok_or("the scene has no camera")?;
    if let Some((w, h)) = size {
        camera = camera.resized(w, h);
    }
    if diffuse_only {
        for o in &mut scene.objects {
            if let Brdf::BlinnPhong(b) = o.material {
                o.material = Brdf::Lambert(Lambert { albedo: b.diffuse });
            }
        }
    }
    if let Some(d) = &dump {
        std::fs::write(d, serde_json::to_vec_pretty(&scene)?)?;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let threads = pool.current_num_threads();
    let world = World::with_light_sampling(&scene, light_sampling);
    let env = ConstantEnvironment {
        radiance: scene.background,
    };
    let cpu0 = cpu_seconds();
    let t0 = std::time::Instant::now();
    let result = pool.install(|| -> Result<_, vfxgraph_render::RenderError> {
        match budget {
            None => Ok(render(&world, &env, &camera, &settings, &|_| {}, None)?),
            Some(b) => {
                // Equal-time mode: the largest spp whose render fits the budget, predicted
                // from a 1-spp probe (rendering time is linear in spp).
                let probe = RenderSettings { spp: 1, ..settings };
                let p = render(&world, &env, &camera, &probe, &|_| {}, None)?;
                let spp = ((b / p.stats.seconds.max(1e-6)).floor() as u32).max(1);
                Ok(render(
                    &world,
                    &env,
                    &camera,
                    &RenderSettings { spp, ..settings },
                    &|_| {},
                    None,
                )?)
            }
        }
    })?;
    let wall = t0.elapsed().as_secs_f64();
    let cpu = cpu_seconds() - cpu0;
    let stats = result.stats;
    println!(
        "{{\"scene\": {:?}, \"width\": {}, \"height\": {}, \"spp\": {}, \"max_depth\": {}, \"threads\": {}, \
         \"paths\": {}, \"render_seconds\": {:.3}, \"wall_seconds\": {:.3}, \"cpu_seconds\": {:.3}, \
         \"paths_per_cpu_second\": {:.0}, \"nonfinite\": {}, \"light_sampling\": \"{:?}\", \
         \"mean_variance\": {:.6e}}}",
        path.display().to_string(),
        camera.width,
        camera.height,
        stats.paths / (camera.width * camera.height) as u64,
        settings.max_depth,
        threads,
        stats.paths,
        stats.seconds,
        wall,
        cpu,
        stats.paths as f64 / cpu,
        stats.nonfinite,
        light_sampling,
        result.variance.data.iter().map(|&v| v as f64).sum::<f64>()
            / result.variance.data.len() as f64
    );
    if let Some(prefix) = out {
        if let Some(dir) = prefix.parent() {
            std::fs::create_dir_all(dir)?;
        }
        write_image(&prefix.with_extension("pfm"), &result.image)?;
        write_image(
            &prefix.with_extension("png"),
            &tonemap(&result.image, Operator::Srgb, exposure),
        )?;
    }
    Ok(())
}
