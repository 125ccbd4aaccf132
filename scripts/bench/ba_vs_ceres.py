#!/usr/bin/env python3
"""Bundle adjustment: vfxgraph vs Ceres on the same BAL problems, in one run.

Builds our `bench_ba` example (release) and a C++ Ceres harness (scripts/bench/ba_ceres.cc,
SnavelyReprojectionError with autodiff as Ceres' bundle_adjuster example, compiled with g++ into a
temporary directory against Debian's libceres-dev), generates the synthetic video-like problem,
then solves every problem with both, with SPARSE_SCHUR and DENSE_SCHUR, the same loss and the same
iteration cap, and prints: best wall time of each over --repeats runs, the time each takes to reach
the same cost (the worse of the two final costs), ours / Ceres', and both final costs.

    python3 scripts/bench/ba_vs_ceres.py [--repeats 3] [--threads 2] [--max-iterations 50]
        [--loss none|huber:A|cauchy:A] [--problems ladybug,video300] [--solvers sparse,dense]
        [--cameras 300] [--points 50000] [--perturb 1] [--json OUT.json]

Timings on a shared machine are noisy: the best of several runs is reported.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
LADYBUG = os.path.join(ROOT, "..", "shared", "data", "bal_ladybug_49", "problem-49-7776-pre.txt")


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, text=True, **kw)


def ensure_ceres():
    if os.path.exists("/usr/include/ceres/ceres.h") and shutil.which("g++"):
        return
    if os.geteuid() != 0:
        sys.exit("libceres-dev and g++ are needed: sudo apt-get install libceres-dev g++")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    run(["apt-get", "update", "-qq"], env=env)
    run(["apt-get", "install", "-y", "-qq", "--no-install-recommends", "libceres-dev", "g++"], env=env)


def build_ours():
    out = run(["cargo", "build", "--release", "-p", "vfxgraph-bundle", "--example", "bench_ba",
               "--message-format=json"], cwd=ROOT, stdout=subprocess.PIPE).stdout
    exe = None
    for line in out.splitlines():
        try:
            msg = json.loads(line)
        except json.JSONDecodeError:
            continue
        if msg.get("reason") == "compiler-artifact" and msg.get("target", {}).get("name") == "bench_ba":
            exe = msg.get("executable") or exe
    if not exe:
        sys.exit("could not find the bench_ba executable")
    return exe


def build_ceres(tmp):
    exe = os.path.join(tmp, "ba_ceres")
    run(["g++", "-O3", "-std=c++17", os.path.join(ROOT, "scripts", "bench", "ba_ceres.cc"),
         "-I/usr/include/eigen3", "-lceres", "-lglog", "-o", exe])
    return exe


def solve(cmd):
    out = run(cmd, stdout=subprocess.PIPE).stdout.strip().splitlines()[-1]
    return json.loads(out)


def best_of(cmd, repeats):
    runs = [solve(cmd) for _ in range(repeats)]
    return min(runs, key=lambda r: r["seconds"]), runs


def time_to(trace, target):
    for t, c in trace:
        if c <= target:
            return t
    return float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--max-iterations", type=int, default=50)
    ap.add_argument("--loss", default="none")
    ap.add_argument("--problems", default="ladybug,video300")
    ap.add_argument("--solvers", default="sparse,dense")
    ap.add_argument("--cameras", type=int, default=300)
    ap.add_argument("--points", type=int, default=50000)
    ap.add_argument("--perturb", type=float, default=1.0,
                    help="scale of the synthetic problem's initial pose/point errors")
    ap.add_argument("--json", help="also write all figures to this file")
    args = ap.parse_args()

    ensure_ceres()
    ours = build_ours()
    rows = []
    with tempfile.TemporaryDirectory(prefix="ba_vs_ceres_") as tmp:
        ceres = build_ceres(tmp)
        problems = []
        for name in args.problems.split(","):
            if name == "ladybug":
                problems.append(("ladybug-49", LADYBUG))
            elif name.startswith("video"):
                path = os.path.join(tmp, f"video_{args.cameras}x{args.points}.txt")
                run([ours, "--generate-video", str(args.cameras), str(args.points), path,
                     "--perturb", str(args.perturb)])
                problems.append((f"video-{args.cameras}x{args.points}", path))
            else:
                sys.exit(f"unknown problem {name}")
        common = ["--loss", args.loss, "--max-iterations", str(args.max_iterations),
                  "--threads", str(args.threads)]
        for pname, path in problems:
            for solver in args.solvers.split(","):
                o, o_runs = best_of([ours, path, "--solver", solver, "--json"] + common, args.repeats)
                c, c_runs = best_of([ceres, path, "--solver", solver] + common, args.repeats)
                target = max(o["final_cost"], c["final_cost"])
                o_t, c_t = time_to(o["trace"], target), time_to(c["trace"], target)
                row = {
                    "problem": pname, "solver": solver, "observations": o["observations"],
                    "ours_seconds": o["seconds"], "ceres_seconds": c["seconds"],
                    "ours_seconds_all": [r["seconds"] for r in o_runs],
                    "ceres_seconds_all": [r["seconds"] for r in c_runs],
                    "ours_time_to_target": o_t, "ceres_time_to_target": c_t,
                    "ratio_time_to_target": o_t / c_t, "ratio_total": o["seconds"] / c["seconds"],
                    "ours_final_cost": o["final_cost"], "ceres_final_cost": c["final_cost"],
                    "ours_initial_cost": o["initial_cost"], "ceres_initial_cost": c["initial_cost"],
                    "ours_iterations": o["iterations"], "ceres_iterations": c["iterations"],
                }
                rows.append(row)
                print(f"{pname:>18} {solver:>6}: ours {o['seconds']:7.3f} s ({o['iterations']} it, "
                      f"cost {o['final_cost']:.6f})  ceres {c['seconds']:7.3f} s ({c['iterations']} it, "
                      f"cost {c['final_cost']:.6f})  time to cost {target:.6f}: ours/ceres = "
                      f"{o_t:.3f}/{c_t:.3f} = {o_t / c_t:.3f}  (total {o['seconds'] / c['seconds']:.3f})",
                      flush=True)
    print(f"\nbest of {args.repeats} runs each, {args.threads} threads, loss {args.loss}, "
          f"max {args.max_iterations} iterations")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
