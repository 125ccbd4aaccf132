//! Solve a BAL file with everything free and print the figures as JSON (what
//! `vfxgraph bench ba` will print), or write a synthetic video-like BAL problem.
//!
//! ```text
//! cargo run --release -p vfxgraph-bundle --example bench_ba -- FILE \
//!     [--solver auto|dense|sparse|iterative] [--loss none|huber:A|cauchy:A] \
//!     [--max-iterations N] [--threads N] [--json]
//! cargo run --release -p vfxgraph-bundle --example bench_ba -- \
//!     --generate-video CAMERAS POINTS OUT.txt [--seed S] [--perturb SCALE]
//! ```

use std::process::ExitCode;

use vfxgraph_bundle::synthetic::{video_like, SyntheticModel, VideoConfig};
use vfxgraph_bundle::{solve_bal_file, write_bal, BalBenchOptions, LinearSolverKind, Loss};

fn usage() -> ExitCode {
    eprintln!(
        "usage: bench_ba FILE [--solver auto|dense|sparse|iterative] [--loss none|huber:A|cauchy:A] \
         [--max-iterations N] [--threads N] [--json]\n       \
         bench_ba --generate-video CAMERAS POINTS OUT [--seed S] [--perturb SCALE]"
    );
    ExitCode::from(2)
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut opts = BalBenchOptions::default();
    let mut file = None;
    let mut json = false;
    let mut generate: Option<(usize, usize, String)> = None;
    let mut seed = 1u64;
    let mut perturb = 1.0f64;
    let mut i = 0;
    while i < args.len() {
        let a = args[i].as_str();
        let val = |k: usize| args.get(i + k).cloned();
        match a {
            "--solver" => match val(1).as_deref().and_then(LinearSolverKind::parse) {
                Some(s) => {
                    opts.solver = s;
                    i += 1;
                }
                None => return usage(),
            },
            "--loss" => match val(1).as_deref().and_then(Loss::parse) {
                Some(l) => {
                    opts.loss = l;
                    i += 1;
                }
                None => return usage(),
            },
            "--max-iterations" => match val(1).and_then(|v| v.parse().ok()) {
                Some(n) => {
                    opts.max_iterations = n;
                    i += 1;
                }
                None => return usage(),
            },
            "--threads" => match val(1).and_then(|v| v.parse().ok()) {
                Some(n) => {
                    opts.num_threads = Some(n);
                    i += 1;
                }
                None => return usage(),
            },
            "--seed" => match val(1).and_then(|v| v.parse().ok()) {
                Some(n) => {
                    seed = n;
                    i += 1;
                }
                None => return usage(),
            },
            "--perturb" => match val(1).and_then(|v| v.parse().ok()) {
                Some(x) => {
                    perturb = x;
                    i += 1;
                }
                None => return usage(),
            },
            "--json" => json = true,
            "--generate-video" => {
                match (
                    val(1).and_then(|v| v.parse().ok()),
                    val(2).and_then(|v| v.parse().ok()),
                    val(3),
                ) {
                    (Some(c), Some(p), Some(out)) => generate = Some((c, p, out)),
                    _ => return usage(),
                }
                i += 3;
            }
            _ if !a.starts_with("--") && file.is_none() => file = Some(a.to_string()),
            _ => return usage(),
        }
        i += 1;
    }
    if let Some((cameras, points, out)) = generate {
        let (r, t, p) = VideoConfig::default().perturbation;
        let cfg = VideoConfig {
            cameras,
            points,
            model: SyntheticModel::Bal,
            seed,
            perturbation: (r * perturb, t * perturb, p * perturb),
            ..VideoConfig::default()
        };
        let s = video_like(&cfg);
        if let Err(e) = write_bal(&s.problem, &out) {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
        eprintln!(
            "wrote {out}: {} cameras, {} points, {} observations",
            s.problem.cameras.len(),
            s.problem.points.len(),
            s.problem.observations.len()
        );
        return ExitCode::SUCCESS;
    }
    let Some(file) = file else { return usage() };
    match solve_bal_file(&file, &opts) {
        Ok(r) => {
            if json {
                match serde_json::to_string(&r) {
                    Ok(s) => println!("{s}"),
                    Err(e) => {
                        eprintln!("error: {e}");
                        return ExitCode::FAILURE;
                    }
                }
            } else {
                println!(
                    "{file}: {} cameras, {} points, {} observations\n\
                     initial cost {:.10e}\nfinal cost   {:.10e} (RMS {:.4} px)\n\
                     {} iterations ({} accepted), {:.3} s solve ({:?}), {:?}",
                    r.cameras,
                    r.points,
                    r.observations,
                    r.initial_cost,
                    r.final_cost,
                    r.final_rms,
                    r.iterations,
                    r.successful_steps,
                    r.seconds,
                    r.linear_solver,
                    r.termination
                );
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
